//! Small glTF scenes for the surface-map CLI tests, written by hand (embedded base64
//! buffers) so that every attribute is under the test's control.

use std::path::{Path, PathBuf};

/// Standard base64 of `bytes`.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(A[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// One triangle-list mesh: positions (glTF, +Y up), optional UV sets, triangles.
pub struct Mesh {
    /// Mesh name.
    pub name: &'static str,
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// TEXCOORD_0.
    pub uv0: Option<Vec<[f32; 2]>>,
    /// TEXCOORD_1.
    pub uv1: Option<Vec<[f32; 2]>>,
    /// Triangles (counter-clockwise = front).
    pub indices: Vec<[u16; 3]>,
}

/// The unit plane `x, z ∈ [-0.5, 0.5]`, `y = 0`, normal +Y (lightvol +Z), both UV sets
/// `(x + 0.5, z + 0.5)`.
pub fn plane(name: &'static str) -> Mesh {
    let positions = vec![[-0.5, 0.0, -0.5], [-0.5, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 0.0, -0.5]];
    let uv: Vec<[f32; 2]> = positions.iter().map(|p: &[f32; 3]| [p[0] + 0.5, p[2] + 0.5]).collect();
    Mesh { name, positions, uv0: Some(uv.clone()), uv1: Some(uv), indices: vec![[0, 1, 2], [0, 2, 3]] }
}

/// Writes `meshes` (one node each) as a `.gltf` with an embedded buffer.
pub fn write_gltf(dir: &Path, file: &str, meshes: &[Mesh]) -> PathBuf {
    let mut buf: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut json_meshes = Vec::new();
    let mut nodes = Vec::new();
    let mut push = |buf: &mut Vec<u8>, data: Vec<u8>, target: u32, acc: String| -> usize {
        while !buf.len().is_multiple_of(4) {
            buf.push(0);
        }
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{},"target":{target}}}"#,
            buf.len(),
            data.len()
        ));
        buf.extend_from_slice(&data);
        accessors.push(acc.replace("VIEW", &(views.len() - 1).to_string()));
        accessors.len() - 1
    };
    for (mi, m) in meshes.iter().enumerate() {
        let n = m.positions.len();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in &m.positions {
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        let pos = push(
            &mut buf,
            m.positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
            34962,
            format!(
                r#"{{"bufferView":VIEW,"componentType":5126,"count":{n},"type":"VEC3","min":{lo:?},"max":{hi:?}}}"#
            ),
        );
        let mut attrs = format!(r#""POSITION":{pos}"#);
        for (set, uv) in [(0, &m.uv0), (1, &m.uv1)] {
            if let Some(uv) = uv {
                let a = push(
                    &mut buf,
                    uv.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
                    34962,
                    format!(r#"{{"bufferView":VIEW,"componentType":5126,"count":{n},"type":"VEC2"}}"#),
                );
                attrs.push_str(&format!(r#","TEXCOORD_{set}":{a}"#));
            }
        }
        let idx = push(
            &mut buf,
            m.indices.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
            34963,
            format!(
                r#"{{"bufferView":VIEW,"componentType":5123,"count":{},"type":"SCALAR"}}"#,
                m.indices.len() * 3
            ),
        );
        json_meshes.push(format!(
            r#"{{"name":"{}","primitives":[{{"attributes":{{{attrs}}},"indices":{idx}}}]}}"#,
            m.name
        ));
        nodes.push(format!(r#"{{"mesh":{mi}}}"#));
    }
    let node_ids: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],"meshes":[{}],"accessors":[{}],"bufferViews":[{}],"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        node_ids.join(","),
        nodes.join(","),
        json_meshes.join(","),
        accessors.join(","),
        views.join(","),
        buf.len(),
        base64(&buf)
    );
    let path = dir.join(file);
    std::fs::write(&path, json).unwrap();
    path
}

/// Runs the CLI in-process; `Err` is the one-line error.
pub fn run(args: &[&str]) -> Result<std::process::ExitCode, String> {
    lightvol::run_from_args(std::iter::once("lightvol").chain(args.iter().copied()))
        .map_err(|e| format!("{e:#}").replace('\n', " "))
}
