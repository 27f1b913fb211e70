//! Surface bake of two intersecting boxes (the scene of the surface tests' dark-leak check)
//! with the domain-of-interest treatment on (`fix`) against off (`keep`) at equal samples per
//! texel: wall time per bake; the reports (rays by kind, invalid texels) are printed once.

use lightvol_core::samples::samples;

use divan::Bencher;
use lightvol_core::progress::BakeControl;
use lightvol_scene::{
    DVec2, DVec3, Environment, Material, MeshAttributes, Scene, SceneBuilder, Tracer, Transport,
    TransportSettings, TriangleRef,
};
use lightvol_surface::{BasisChoice, InvalidTexels, SurfaceSettings, bake_surface};

fn main() {
    let scene = boxes();
    let tracer = Tracer::new(&scene);
    let t = Transport::new(&scene, &tracer, TransportSettings::default());
    for mode in ["fix", "keep"] {
        let out = bake_surface(&t, &settings(mode), &BakeControl::default()).unwrap();
        eprintln!("{mode}: {:?}", out.report);
    }
    divan::main();
}

/// In-domain samples per texel.
const SAMPLES: u32 = 64;

fn settings(mode: &str) -> SurfaceSettings {
    SurfaceSettings {
        basis: BasisChoice::parse("hbasis_mod6").unwrap(),
        samples: samples(SAMPLES),
        texels_per_unit: 16.0,
        invalid: if mode == "fix" { InvalidTexels::Fix } else { InvalidTexels::Keep },
        ..SurfaceSettings::default()
    }
}

/// One box as a lightmap object: five faces (no bottom), one chart each in a 3 × 2 grid.
fn add_box(b: &mut SceneBuilder, name: &str, lo: DVec3, hi: DVec3, material: u32) {
    let c = |x: usize, y: usize, z: usize| DVec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z]);
    let faces = [
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
        [c(0, 1, 0), c(0, 0, 0), c(0, 0, 1), c(0, 1, 1)],
        [c(1, 1, 0), c(0, 1, 0), c(0, 1, 1), c(1, 1, 1)],
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
    ];
    let k = (1.0 / 3.0 - 0.08) / (hi - lo).max_element();
    let (mut p, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    for (f, q) in faces.iter().enumerate() {
        let origin = DVec2::new((f % 3) as f64 / 3.0 + 0.04, (f / 3) as f64 * 0.5 + 0.04);
        let (es, et) = (q[1] - q[0], q[3] - q[0]);
        let base = p.len() as u32;
        for (s, t) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            p.push(q[0] + es * s + et * t);
            uv.push(origin + DVec2::new(s * es.length() * k, t * et.length() * k));
        }
        tris.push([base, base + 1, base + 2]);
        tris.push([base, base + 2, base + 3]);
    }
    let mesh = b.add_mesh(MeshAttributes {
        name: name.into(),
        positions: p.clone(),
        uv1: Some(uv.clone()),
        ..MeshAttributes::default()
    });
    for (face, ids) in tris.into_iter().enumerate() {
        let r = TriangleRef { mesh, face: face as u32, vertices: ids };
        b.add_mesh_triangle(ids.map(|i| p[i as usize]), ids.map(|i| uv[i as usize]), material, r).unwrap();
    }
}

fn boxes() -> Scene {
    let mut b = SceneBuilder::new("boxes");
    let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
    let g = b.add_material(Material::diffuse("ground", [0.3; 3])).unwrap();
    b.add_quad(
        [
            DVec3::new(-6.0, -6.0, 0.0),
            DVec3::new(6.0, -6.0, 0.0),
            DVec3::new(6.0, 6.0, 0.0),
            DVec3::new(-6.0, 6.0, 0.0),
        ],
        g,
    )
    .unwrap();
    add_box(&mut b, "A", DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 1.5), m);
    add_box(&mut b, "B", DVec3::new(0.3, -0.5, 0.0), DVec3::new(1.8, 0.5, 1.0), m);
    b.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
    b.sun = Some(lightvol_scene::Sun::from_angles(35.0, 20.0, [3.0; 3], 0.00465));
    b.build().unwrap()
}

#[divan::bench(args = ["fix", "keep"], sample_count = 3, sample_size = 1)]
fn intersecting_boxes(bencher: Bencher<'_, '_>, mode: &str) {
    let scene = boxes();
    let tracer = Tracer::new(&scene);
    let t = Transport::new(&scene, &tracer, TransportSettings::default());
    let s = settings(mode);
    bencher.bench(|| bake_surface(&t, &s, &BakeControl::default()).unwrap().report.rays.total());
}
