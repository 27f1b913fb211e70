//! Accessor reading (glTF 2.0 §3.6): every component type, `normalized` integers (as
//! `KHR_mesh_quantization` uses them for positions, normals, tangents and UVs), strided
//! buffer views, sparse substitution (§3.6.2.3), and accessors without a buffer view (all
//! zeros, then sparse values).
//!
//! Every offset is checked against its buffer view and buffer; the element count is capped
//! by [`MAX_ACCESSOR_VALUES`] so a file cannot ask for an allocation it does not back, and
//! an accessor without a buffer view (zeros the file does not store) by the much smaller
//! [`MAX_UNBACKED_VALUES`].

use serde_json::Value;

/// Most values (elements × components) one accessor may produce: 2^27, i.e. 1 GiB as f64,
/// far above any mesh a bake can hold, far below what would abort the process.
pub(crate) const MAX_ACCESSOR_VALUES: u64 = 1 << 27;

/// Most values an accessor without a `bufferView` may produce, and (see
/// [`unstored_values`]) all such accessors of one load together: 2^20 (8 MiB as f64). Their
/// zeros are stored nowhere, so without this a few bytes of JSON (`"count": 44739242`)
/// would allocate gigabytes; sparse-only accessors in real files (morph targets, small
/// edits) are far smaller.
pub(crate) const MAX_UNBACKED_VALUES: u64 = 1 << 20;

/// A component type (glTF 2.0 §3.6.2.2, Table 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Component {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl Component {
    fn from_code(c: u64) -> Option<Self> {
        Some(match c {
            5120 => Self::I8,
            5121 => Self::U8,
            5122 => Self::I16,
            5123 => Self::U16,
            5125 => Self::U32,
            5126 => Self::F32,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::U32 | Self::F32 => 4,
        }
    }

    /// Reads one component at `b[0..size]`; `normalized` integers map to [0, 1] or [-1, 1]
    /// by glTF 2.0 §3.11's equations (`max(c / 127, -1)` for signed bytes and so on).
    fn read(self, b: &[u8], normalized: bool) -> f64 {
        match self {
            Self::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::I8 => {
                let c = f64::from(b[0] as i8);
                if normalized { (c / 127.0).max(-1.0) } else { c }
            }
            Self::U8 => {
                let c = f64::from(b[0]);
                if normalized { c / 255.0 } else { c }
            }
            Self::I16 => {
                let c = f64::from(i16::from_le_bytes([b[0], b[1]]));
                if normalized { (c / 32767.0).max(-1.0) } else { c }
            }
            Self::U16 => {
                let c = f64::from(u16::from_le_bytes([b[0], b[1]]));
                if normalized { c / 65535.0 } else { c }
            }
        }
    }
}

fn components_of(ty: &str) -> Option<usize> {
    Some(match ty {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// The bytes of buffer view `view` and its stride (`None`: tightly packed).
fn view_bytes<'a>(
    json: &Value,
    buffers: &'a [Vec<u8>],
    view: u64,
) -> Result<(&'a [u8], Option<usize>), String> {
    let v = json
        .get("bufferViews")
        .and_then(|a| a.get(view as usize))
        .ok_or_else(|| format!("buffer view {view} does not exist"))?;
    let buffer = v
        .get("buffer")
        .and_then(Value::as_u64)
        .ok_or_else(|| format!("bufferViews[{view}] has no buffer"))?;
    let data = buffers
        .get(buffer as usize)
        .ok_or_else(|| format!("bufferViews[{view}] refers to buffer {buffer}, which does not exist"))?;
    let offset = v.get("byteOffset").and_then(Value::as_u64).unwrap_or(0);
    let length = v
        .get("byteLength")
        .and_then(Value::as_u64)
        .ok_or_else(|| format!("bufferViews[{view}] has no byteLength"))?;
    let end = offset.checked_add(length).filter(|&e| e <= data.len() as u64).ok_or_else(|| {
        format!(
            "bufferViews[{view}] (bytes {offset}..+{length}) runs past buffer {buffer} ({} bytes)",
            data.len()
        )
    })?;
    let stride = v.get("byteStride").and_then(Value::as_u64).map(|s| s as usize);
    Ok((&data[offset as usize..end as usize], stride))
}

/// An accessor's values, flattened: `count × components` numbers.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Values {
    /// Components per element (1 for SCALAR, 3 for VEC3, ...).
    pub components: usize,
    /// The numbers, element after element.
    pub data: Vec<f64>,
}

impl Values {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len().checked_div(self.components).unwrap_or(0)
    }

    /// Element `i` as an array of `N` numbers (missing components are 0).
    pub fn get<const N: usize>(&self, i: usize) -> [f64; N] {
        let mut out = [0.0; N];
        let row = &self.data[i * self.components..(i + 1) * self.components];
        for (o, v) in out.iter_mut().zip(row) {
            *o = *v;
        }
        out
    }
}

/// Reads accessor `index`.
pub(crate) fn read(json: &Value, buffers: &[Vec<u8>], index: u64) -> Result<Values, String> {
    let a = json
        .get("accessors")
        .and_then(|a| a.get(index as usize))
        .ok_or_else(|| format!("accessor {index} does not exist"))?;
    let bad = |what: &str| format!("accessors[{index}]: {what}");
    let comp = a
        .get("componentType")
        .and_then(Value::as_u64)
        .and_then(Component::from_code)
        .ok_or_else(|| bad("unknown componentType"))?;
    let ty = a.get("type").and_then(Value::as_str).unwrap_or("");
    let n = components_of(ty).ok_or_else(|| bad(&format!("unknown type {ty:?}")))?;
    let count = a.get("count").and_then(Value::as_u64).ok_or_else(|| bad("no count"))?;
    let normalized = a.get("normalized").and_then(Value::as_bool).unwrap_or(false);
    if count.saturating_mul(n as u64) > MAX_ACCESSOR_VALUES {
        return Err(bad(&format!(
            "{count} elements of {ty} exceed the reader's limit of {MAX_ACCESSOR_VALUES} values"
        )));
    }
    let view = a.get("bufferView").and_then(Value::as_u64);
    if view.is_none() && count.saturating_mul(n as u64) > MAX_UNBACKED_VALUES {
        return Err(bad(&format!(
            "{count} elements of {ty} without a bufferView exceed the reader's limit of {MAX_UNBACKED_VALUES} values for data the file does not store"
        )));
    }
    if n > 4 && comp.size() < 4 {
        // Matrix columns of 1- and 2-byte components are padded to 4 bytes (§3.6.2.4).
        return Err(bad("matrices of 8- or 16-bit components are not supported"));
    }
    let count = count as usize;
    let elem = n * comp.size();
    // The view is checked before anything is allocated: until then `count` is only the
    // file's word (a 16-element view claiming 2^27 values used to allocate 1 GiB first).
    let backing = match view {
        None => None,
        Some(view) => {
            let (bytes, stride) = view_bytes(json, buffers, view).map_err(|e| bad(&e))?;
            let stride = stride.unwrap_or(elem);
            if stride < elem {
                return Err(bad(&format!("byteStride {stride} is smaller than the element size {elem}")));
            }
            let offset = a.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            if count > 0 {
                let need = (count - 1)
                    .checked_mul(stride)
                    .and_then(|x| x.checked_add(offset))
                    .and_then(|x| x.checked_add(elem));
                if need.is_none_or(|need| need > bytes.len()) {
                    return Err(bad(&format!(
                        "{count} elements at offset {offset}, stride {stride} run past buffer view {view} ({} bytes)",
                        bytes.len()
                    )));
                }
            }
            Some((bytes, stride, offset))
        }
    };
    let mut data = vec![0.0; count * n];
    if let Some((bytes, stride, offset)) = backing {
        for i in 0..count {
            let at = offset + i * stride;
            for c in 0..n {
                let o = at + c * comp.size();
                data[i * n + c] = comp.read(&bytes[o..o + comp.size()], normalized);
            }
        }
    }
    if let Some(sparse) = a.get("sparse") {
        let k =
            sparse.get("count").and_then(Value::as_u64).ok_or_else(|| bad("sparse without count"))? as usize;
        if k > count {
            return Err(bad(&format!("sparse count {k} exceeds count {count}")));
        }
        let idx = sparse.get("indices").ok_or_else(|| bad("sparse without indices"))?;
        let vals = sparse.get("values").ok_or_else(|| bad("sparse without values"))?;
        let icomp = idx
            .get("componentType")
            .and_then(Value::as_u64)
            .and_then(Component::from_code)
            .filter(|c| matches!(c, Component::U8 | Component::U16 | Component::U32))
            .ok_or_else(|| bad("sparse indices need an unsigned componentType"))?;
        let slice = |part: &Value, size: usize, what: &str| -> Result<Vec<u8>, String> {
            let view = part
                .get("bufferView")
                .and_then(Value::as_u64)
                .ok_or_else(|| bad(&format!("sparse {what} without bufferView")))?;
            let (bytes, _) = view_bytes(json, buffers, view).map_err(|e| bad(&e))?;
            let off = part.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
            let end = k.checked_mul(size).and_then(|x| x.checked_add(off)).filter(|&e| e <= bytes.len());
            let end = end.ok_or_else(|| bad(&format!("sparse {what} run past buffer view {view}")))?;
            Ok(bytes[off..end].to_vec())
        };
        let ib = slice(idx, icomp.size(), "indices")?;
        let vb = slice(vals, elem, "values")?;
        for j in 0..k {
            let i = icomp.read(&ib[j * icomp.size()..(j + 1) * icomp.size()], false) as usize;
            if i >= count {
                return Err(bad(&format!("sparse index {i} is out of range (count {count})")));
            }
            for c in 0..n {
                let o = j * elem + c * comp.size();
                data[i * n + c] = comp.read(&vb[o..o + comp.size()], normalized);
            }
        }
    }
    Ok(Values { components: n, data })
}

/// How many values reading accessor `index` allocates that the file does not store: all of
/// them (`count` × components) without a buffer view, else none.
pub(crate) fn unstored_values(json: &Value, index: u64) -> u64 {
    let Some(a) = json.get("accessors").and_then(|a| a.get(index as usize)) else { return 0 };
    if a.get("bufferView").and_then(Value::as_u64).is_some() {
        return 0;
    }
    let n = a.get("type").and_then(Value::as_str).and_then(components_of).unwrap_or(0) as u64;
    a.get("count").and_then(Value::as_u64).unwrap_or(0).saturating_mul(n)
}

/// How many elements of accessor `index` the file stores: all of them with a buffer view,
/// else only the sparse ones (the rest are zeros).
pub(crate) fn stored_elements(json: &Value, index: u64) -> u64 {
    let Some(a) = json.get("accessors").and_then(|a| a.get(index as usize)) else { return 0 };
    let count = a.get("count").and_then(Value::as_u64).unwrap_or(0);
    if a.get("bufferView").and_then(Value::as_u64).is_some() {
        count
    } else {
        a.pointer("/sparse/count").and_then(Value::as_u64).unwrap_or(0).min(count)
    }
}

/// Reads an index accessor (unsigned integer SCALAR, glTF 2.0 §3.7.2.1).
pub(crate) fn read_indices(json: &Value, buffers: &[Vec<u8>], index: u64) -> Result<Vec<u32>, String> {
    let a = json.get("accessors").and_then(|a| a.get(index as usize));
    let comp = a.and_then(|a| a.get("componentType")).and_then(Value::as_u64);
    if !matches!(comp, Some(5121 | 5123 | 5125)) {
        return Err(format!("index accessor {index} is not of an unsigned integer type"));
    }
    let v = read(json, buffers, index)?;
    if v.components != 1 {
        return Err(format!("index accessor {index} is not SCALAR"));
    }
    Ok(v.data.into_iter().map(|x| x as u32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Normalized integers follow glTF 2.0 §3.11: c/127 clamped at -1 for signed bytes,
    /// c/65535 for unsigned shorts; non-normalized integers keep their value.
    #[test]
    fn normalized_components() {
        assert_eq!(Component::I8.read(&[0x81], true), -1.0); // -127/127
        assert_eq!(Component::I8.read(&[0x80], true), -1.0); // -128/127 clamps
        assert_eq!(Component::I8.read(&[0x7f], true), 1.0);
        assert_eq!(Component::U16.read(&65535u16.to_le_bytes(), true), 1.0);
        assert_eq!(Component::I16.read(&(-2i16).to_le_bytes(), false), -2.0);
        assert_eq!(Component::U8.read(&[51], true), 0.2);
    }

    /// A strided view, a sparse substitution and a view-less sparse accessor.
    #[test]
    fn strided_and_sparse() {
        // Two interleaved u16 VEC2 at stride 8: (1, 2), (3, 4); sparse indices u8 [1], values (9, 9).
        let mut b = Vec::new();
        for v in [1u16, 2, 0, 0, 3, 4, 0, 0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.push(1);
        b.extend_from_slice(&[0, 0, 0]);
        for v in [9u16, 9] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let j = json!({
            "bufferViews": [
                {"buffer": 0, "byteLength": 16, "byteStride": 8},
                {"buffer": 0, "byteOffset": 16, "byteLength": 1},
                {"buffer": 0, "byteOffset": 20, "byteLength": 4}],
            "accessors": [
                {"bufferView": 0, "componentType": 5123, "count": 2, "type": "VEC2"},
                {"bufferView": 0, "componentType": 5123, "count": 2, "type": "VEC2",
                 "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5121}, "values": {"bufferView": 2}}},
                {"componentType": 5123, "count": 3, "type": "VEC2",
                 "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5121}, "values": {"bufferView": 2}}},
                {"bufferView": 0, "componentType": 5123, "count": 3, "type": "VEC2"}]
        });
        let bufs = vec![b];
        assert_eq!(read(&j, &bufs, 0).unwrap().data, [1.0, 2.0, 3.0, 4.0]);
        assert_eq!(read(&j, &bufs, 1).unwrap().data, [1.0, 2.0, 9.0, 9.0]);
        assert_eq!(read(&j, &bufs, 2).unwrap().data, [0.0, 0.0, 9.0, 9.0, 0.0, 0.0]);
        assert!(read(&j, &bufs, 3).unwrap_err().contains("run past"));
        assert!(read(&j, &bufs, 9).unwrap_err().contains("does not exist"));
    }

    /// An accessor without a buffer view is zeros the file does not store: a large count is
    /// refused before anything is allocated (it used to allocate 1 GiB here, and the
    /// primitive built on it several more), a small one still reads.
    #[test]
    fn unbacked_accessors_are_capped() {
        let m = MAX_ACCESSOR_VALUES / 3;
        let j = json!({"accessors": [
            {"componentType": 5126, "count": m, "type": "VEC3"},
            {"componentType": 5126, "count": MAX_UNBACKED_VALUES / 3 + 1, "type": "VEC3"},
            {"componentType": 5126, "count": MAX_UNBACKED_VALUES, "type": "SCALAR"},
            {"bufferView": "0", "componentType": 5126, "count": m, "type": "VEC3"}]});
        for i in [0, 1, 3] {
            let e = read(&j, &[], i).unwrap_err();
            assert!(e.contains("without a bufferView exceed"), "{e}");
        }
        assert_eq!(read(&j, &[], 2).unwrap().data.len() as u64, MAX_UNBACKED_VALUES);
    }

    /// A view too short for the count is an error before the values are allocated (the
    /// allocation itself is checked by the counting allocator of `tests/gltf_fuzz.rs`,
    /// which found it: 16 vertices nudged to 16777216 held 384 MiB).
    #[test]
    fn short_views_fail_before_allocating() {
        let j = json!({
            "bufferViews": [{"buffer": 0, "byteLength": 12}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": MAX_ACCESSOR_VALUES / 3, "type": "VEC3"}]});
        let e = read(&j, &[vec![0; 12]], 0).unwrap_err();
        assert!(
            e.contains("44739242 elements at offset 0, stride 12 run past buffer view 0 (12 bytes)"),
            "{e}"
        );
    }
}
