//! The glTF 2.0 containers: `.gltf` JSON with external or `data:` buffers, and the binary
//! `.glb` (glTF 2.0 §4.4: a 12-byte header, then a JSON chunk and an optional BIN chunk).
//!
//! Everything here is bounds-checked: a truncated or lying file is an error naming what is
//! wrong, never a panic or an allocation sized by a number from the file.

use std::path::Path;

use serde_json::Value;

/// A parsed document: the JSON root and the GLB's BIN chunk, if any.
#[derive(Debug)]
pub(crate) struct Document {
    /// The JSON root object.
    pub json: Value,
    /// The binary chunk of a GLB (the data of a buffer without `uri`).
    pub blob: Option<Vec<u8>>,
}

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    b.get(at..at.checked_add(4)?).map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// Parses `.gltf` text or `.glb` bytes.
pub(crate) fn parse(bytes: &[u8]) -> Result<Document, String> {
    let (json, blob) = if bytes.starts_with(GLB_MAGIC) {
        let version = u32_at(bytes, 4).ok_or("GLB header truncated")?;
        if version != 2 {
            return Err(format!("GLB version {version} (only glTF 2.0 is read)"));
        }
        let length = u32_at(bytes, 8).ok_or("GLB header truncated")? as usize;
        if length > bytes.len() {
            return Err(format!("GLB header says {length} bytes, the file has {}", bytes.len()));
        }
        let body = &bytes[..length];
        let mut at = 12;
        let mut json: Option<&[u8]> = None;
        let mut blob: Option<&[u8]> = None;
        while at < body.len() {
            let len = u32_at(body, at).ok_or("GLB chunk header truncated")? as usize;
            let kind = u32_at(body, at + 4).ok_or("GLB chunk header truncated")?;
            let start = at + 8;
            let end = start.checked_add(len).filter(|&e| e <= body.len()).ok_or_else(|| {
                format!("GLB chunk at byte {at} claims {len} bytes past the end of the file")
            })?;
            match kind {
                CHUNK_JSON if json.is_none() => json = Some(&body[start..end]),
                CHUNK_BIN if blob.is_none() && json.is_some() => blob = Some(&body[start..end]),
                _ => {} // unknown chunks are skipped (glTF 2.0 §4.4.3.1)
            }
            // Chunks are 4-byte aligned.
            at = end.next_multiple_of(4);
        }
        (json.ok_or("GLB has no JSON chunk")?, blob.map(<[u8]>::to_vec))
    } else {
        (bytes, None)
    };
    let json: Value = serde_json::from_slice(json).map_err(|e| format!("invalid JSON: {e}"))?;
    if !json.is_object() {
        return Err("the JSON root is not an object".into());
    }
    let version = json.pointer("/asset/version").and_then(Value::as_str).unwrap_or("");
    if !version.starts_with('2') {
        return Err(format!("asset.version {version:?} (only glTF 2.0 is read)"));
    }
    Ok(Document { json, blob })
}

/// Decodes standard base64 (RFC 4648 §4), ignoring whitespace; `=` padding optional.
pub(crate) fn base64_decode(s: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let mut acc = 0u32;
    let mut bits = 0;
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Some(out)
}

/// Encodes standard base64 with padding (RFC 4648 §4): what a glTF writer needs to embed
/// buffers and images in `data:` URIs, which the loader decodes.
#[must_use]
pub fn base64_encode(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in data.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            out.push(if k <= c.len() { A[(n >> (18 - 6 * k) & 63) as usize] as char } else { '=' });
        }
    }
    out
}

/// Decodes `%XX` escapes of a relative URI (RFC 3986 §2.1).
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && let Some(h) = b.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok())
            && let Ok(v) = u8::from_str_radix(h, 16)
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Reads a buffer or image URI: `data:[mime][;base64],...`, or a file relative to `base`.
/// The media type is not needed: images are told apart by their first bytes.
pub(crate) fn read_uri(uri: &str, base: Option<&Path>) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (head, data) = rest.split_once(',').ok_or("data URI without ','")?;
        return if head.ends_with(";base64") {
            base64_decode(data).ok_or_else(|| "data URI is not valid base64".to_owned())
        } else {
            Ok(percent_decode(data).into_bytes())
        };
    }
    if uri.contains("://") {
        return Err(format!("'{uri}' is not a local file (only relative paths and data URIs are read)"));
    }
    let base = base.ok_or_else(|| format!("'{uri}' is an external file, and the document has no folder"))?;
    let path = base.join(percent_decode(uri));
    // Only regular files: a device such as `/dev/zero` never ends (it used to be read until
    // memory ran out) and opening a FIFO blocks. The check is on the path, before opening.
    let meta = std::fs::metadata(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    if !meta.is_file() {
        return Err(format!("{} is not a regular file", path.display()));
    }
    std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Loads every buffer: the GLB blob for `buffers[0]` without `uri`, else its URI. A buffer
/// shorter than its `byteLength` is an error, and so is a later buffer without `uri`
/// (glTF 2.0 §4.4.3.3: only the first buffer may be the BIN chunk; each such buffer used to
/// get its own copy of the blob, so a few bytes of JSON per entry cost the whole chunk).
pub(crate) fn load_buffers(doc: &Document, base: Option<&Path>) -> Result<Vec<Vec<u8>>, String> {
    let Some(list) = doc.json.get("buffers") else { return Ok(Vec::new()) };
    let list = list.as_array().ok_or("'buffers' is not an array")?;
    let mut out = Vec::with_capacity(list.len());
    for (i, b) in list.iter().enumerate() {
        let want = b
            .get("byteLength")
            .and_then(Value::as_u64)
            .ok_or_else(|| format!("buffers[{i}] has no byteLength"))?;
        let data = match b.get("uri").and_then(Value::as_str) {
            Some(uri) => read_uri(uri, base).map_err(|e| format!("buffers[{i}]: {e}"))?,
            None if i == 0 => doc
                .blob
                .clone()
                .ok_or_else(|| format!("buffers[{i}] has no uri and the file has no BIN chunk"))?,
            None => {
                return Err(format!("buffers[{i}] has no uri (only buffers[0] can be the GLB's BIN chunk)"));
            }
        };
        if (data.len() as u64) < want {
            return Err(format!("buffers[{i}] has {} bytes, byteLength says {want}", data.len()));
        }
        out.push(data);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Base64 against RFC 4648 §10's test vectors.
    #[test]
    fn base64_rfc_vectors() {
        for (enc, dec) in [
            ("", ""),
            ("Zg==", "f"),
            ("Zm8=", "fo"),
            ("Zm9v", "foo"),
            ("Zm9vYg==", "foob"),
            ("Zm9vYmE=", "fooba"),
            ("Zm9vYmFy", "foobar"),
        ] {
            assert_eq!(base64_decode(enc).unwrap(), dec.as_bytes());
        }
        assert!(base64_decode("Zm9v*").is_none());
        for (enc, dec) in [("Zg==", "f"), ("Zm8=", "fo"), ("Zm9vYmFy", "foobar")] {
            assert_eq!(base64_encode(dec.as_bytes()), enc);
        }
    }

    /// Only `buffers[0]` is the BIN chunk; a second buffer without `uri` is an error, not
    /// another copy of the chunk.
    #[test]
    fn only_the_first_buffer_is_the_bin_chunk() {
        let doc = |buffers: &str| Document {
            json: serde_json::from_str(&format!(r#"{{"asset":{{"version":"2.0"}},"buffers":{buffers}}}"#))
                .unwrap(),
            blob: Some(vec![7; 8]),
        };
        assert_eq!(load_buffers(&doc(r#"[{"byteLength":8}]"#), None).unwrap(), [vec![7; 8]]);
        let e =
            load_buffers(&doc(r#"[{"byteLength":8},{"byteLength":0},{"byteLength":0}]"#), None).unwrap_err();
        assert_eq!(e, "buffers[1] has no uri (only buffers[0] can be the GLB's BIN chunk)");
    }

    /// URIs naming devices are refused, whichever way they reach them; files still read.
    #[cfg(unix)]
    #[test]
    fn only_regular_files_are_read() {
        let base = Path::new(env!("CARGO_MANIFEST_DIR"));
        for uri in ["/dev/zero", "../../../../../../../../../../../dev/zero", "/dev/null", "."] {
            let e = read_uri(uri, Some(base)).unwrap_err();
            assert!(e.ends_with("is not a regular file"), "{uri}: {e}");
        }
        assert!(read_uri("Cargo.toml", Some(base)).unwrap().starts_with(b"[package]"));
    }

    #[test]
    fn percent_escapes() {
        assert_eq!(percent_decode("a%20b%zz%2"), "a b%zz%2");
    }

    /// Truncated, lying and foreign GLB headers are errors, not panics.
    #[test]
    fn glb_headers_are_checked() {
        let json = br#"{"asset":{"version":"2.0"}}"#;
        let mut glb = b"glTF".to_vec();
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&(12 + 8 + json.len() as u32).to_le_bytes());
        glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        glb.extend_from_slice(json);
        assert!(parse(&glb).is_ok());
        for cut in 0..glb.len() {
            let _ = parse(&glb[..cut]);
        }
        let mut lying = glb.clone();
        lying[12] = 0xff;
        assert!(parse(&lying).unwrap_err().contains("past the end"));
        let mut v1 = glb;
        v1[4] = 1;
        assert!(parse(&v1).unwrap_err().contains("version 1"));
        assert!(parse(br#"{"asset":{"version":"1.0"}}"#).unwrap_err().contains("2.0"));
    }
}
