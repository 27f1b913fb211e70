//! Which glTF extensions the file uses, where, and what the loader does with each.
//!
//! The rule follows from what an extension can change:
//! - **supported** ones are read ([`SUPPORTED`]);
//! - one that appears only inside `materials`, `textures`, `images` or `samplers` changes
//!   appearance, not geometry: the core material or image is used, and a *required* one is
//!   a warning rather than the refusal glTF 2.0 §3.12 prescribes, because a bake of the
//!   core material is still the right geometry;
//! - one on `meshes`, primitives, `accessors`, `bufferViews`, `buffers` or `nodes`
//!   (`KHR_draco_mesh_compression`, `EXT_meshopt_compression`, ...) changes what the
//!   geometry is: if required, loading stops with one line naming it and a primitive that
//!   uses it; if only used, the file carries core data beside it and that is read.

use serde_json::Value;

use crate::scene::ExtensionReport;

/// Extensions the loader reads.
pub const SUPPORTED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "EXT_mesh_gpu_instancing",
];

const APPEARANCE: &[&str] = &["materials", "textures", "images", "samplers"];
const GEOMETRY: &[&str] = &["meshes", "primitives", "accessors", "bufferViews", "buffers", "nodes"];

/// Records `(extension, where)` for every `extensions` object under `v`.
fn scan(v: &Value, place: &str, found: &mut Vec<(String, String)>) {
    match v {
        Value::Object(map) => {
            if let Some(Value::Object(ext)) = map.get("extensions") {
                for k in ext.keys() {
                    if !found.iter().any(|(n, p)| n == k && p == place) {
                        found.push((k.clone(), place.to_owned()));
                    }
                }
            }
            for (k, child) in map {
                let inner = if place == "meshes" && k == "primitives" { "primitives" } else { place };
                if k != "extensions" && k != "extras" {
                    scan(child, inner, found);
                }
            }
        }
        Value::Array(a) => a.iter().for_each(|c| scan(c, place, found)),
        _ => {}
    }
}

fn strings(json: &Value, key: &str) -> Vec<String> {
    json.get(key)
        .and_then(Value::as_array)
        .map_or_else(Vec::new, |a| a.iter().filter_map(Value::as_str).map(str::to_owned).collect())
}

/// A primitive that uses the geometry extension `name` (for the error message).
fn user_of(json: &Value, name: &str) -> String {
    let has = |v: &Value| v.get("extensions").and_then(|e| e.get(name)).is_some();
    let arr = |k: &str| json.get(k).and_then(Value::as_array).cloned().unwrap_or_default();
    let (accessors, views) = (arr("accessors"), arr("bufferViews"));
    let view_hit = |vi: Option<u64>| {
        vi.and_then(|i| views.get(i as usize)).is_some_and(|v| {
            has(v)
                || v.get("buffer")
                    .and_then(Value::as_u64)
                    .and_then(|b| arr("buffers").get(b as usize).cloned())
                    .is_some_and(|b| has(&b))
        })
    };
    let acc_hit = |ai: u64| {
        accessors
            .get(ai as usize)
            .is_some_and(|a| has(a) || view_hit(a.get("bufferView").and_then(Value::as_u64)))
    };
    for (m, mesh) in arr("meshes").iter().enumerate() {
        let mname = mesh
            .get("name")
            .and_then(Value::as_str)
            .map_or_else(|| format!("mesh {m}"), |n| format!("mesh '{n}'"));
        let prims = mesh.get("primitives").and_then(Value::as_array).cloned().unwrap_or_default();
        for (p, prim) in prims.iter().enumerate() {
            let mut ids: Vec<u64> = prim
                .get("attributes")
                .and_then(Value::as_object)
                .map_or_else(Vec::new, |o| o.values().filter_map(Value::as_u64).collect());
            ids.extend(prim.get("indices").and_then(Value::as_u64));
            if has(mesh) || has(prim) || ids.into_iter().any(acc_hit) {
                return format!("{mname} primitive {p}");
            }
        }
    }
    for (i, node) in arr("nodes").iter().enumerate() {
        if has(node) {
            return node
                .get("name")
                .and_then(Value::as_str)
                .map_or_else(|| format!("node {i}"), |n| format!("node '{n}'"));
        }
    }
    "the file".to_owned()
}

/// Classifies every extension the file names. Returns the reports and the warnings to
/// record, or the one-line error for a required geometry extension.
pub(crate) fn classify(json: &Value) -> Result<(Vec<ExtensionReport>, Vec<String>), String> {
    let used = strings(json, "extensionsUsed");
    let required = strings(json, "extensionsRequired");
    let mut found = Vec::new();
    if let Value::Object(root) = json {
        if let Some(Value::Object(ext)) = root.get("extensions") {
            found.extend(ext.keys().map(|k| (k.clone(), "root".to_owned())));
        }
        for (k, v) in root {
            if !matches!(k.as_str(), "extensions" | "extras" | "extensionsUsed" | "extensionsRequired") {
                scan(v, k, &mut found);
            }
        }
    }
    let mut names: Vec<String> = Vec::new();
    for n in used.iter().chain(&required).chain(found.iter().map(|(n, _)| n)) {
        if !names.contains(n) {
            names.push(n.clone());
        }
    }
    let mut reports = Vec::new();
    let mut warnings = Vec::new();
    for name in names {
        let used_in: Vec<String> = found.iter().filter(|(n, _)| *n == name).map(|(_, p)| p.clone()).collect();
        let req = required.contains(&name);
        let treatment = if SUPPORTED.contains(&name.as_str()) {
            "supported".to_owned()
        } else if used_in.iter().any(|p| GEOMETRY.contains(&p.as_str())) {
            if req {
                return Err(format!(
                    "{name} (required) on {}: geometry extension not supported; export without it",
                    user_of(json, &name)
                ));
            }
            "geometry extension not supported; not required, so the core data is used".to_owned()
        } else if !used_in.is_empty() && used_in.iter().all(|p| APPEARANCE.contains(&p.as_str())) {
            let what = if used_in.iter().any(|p| p == "materials") { "material" } else { "texture" };
            let t = format!(
                "{what} extension not supported, core {} used",
                if what == "material" { "material" } else { "image" }
            );
            if req {
                warnings.push(format!("{name}: {t}"));
            }
            t
        } else {
            let t = if used_in.is_empty() {
                "not supported; appears in no object, ignored"
            } else {
                "not supported, ignored"
            };
            if req {
                warnings.push(format!("{name} (required): {t}"));
            }
            t.to_owned()
        };
        reports.push(ExtensionReport { name, required: req, used_in, treatment });
    }
    Ok((reports, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A required material-only extension warns; a required geometry extension is an error
    /// naming the primitive; an optional geometry extension is reported and ignored.
    #[test]
    fn classification_by_location() {
        let j = json!({
            "extensionsUsed": ["AMD_split_roughnessMetallic", "KHR_lights_punctual", "EXT_meshopt_compression", "MSFT_texture_dds"],
            "extensionsRequired": ["AMD_split_roughnessMetallic"],
            "extensions": {"KHR_lights_punctual": {"lights": []}},
            "materials": [{"extensions": {"AMD_split_roughnessMetallic": {}}}],
            "textures": [{"extensions": {"MSFT_texture_dds": {"source": 0}}}],
            "bufferViews": [{"buffer": 0, "byteLength": 4, "extensions": {"EXT_meshopt_compression": {}}}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 1, "type": "SCALAR"}],
            "meshes": [{"name": "leaf", "primitives": [{"attributes": {"POSITION": 0}}]}]
        });
        let (r, w) = classify(&j).unwrap();
        assert_eq!(w, ["AMD_split_roughnessMetallic: material extension not supported, core material used"]);
        let t = |n: &str| r.iter().find(|e| e.name == n).unwrap().treatment.clone();
        assert_eq!(t("KHR_lights_punctual"), "supported");
        assert!(t("EXT_meshopt_compression").contains("core data is used"));
        assert_eq!(t("MSFT_texture_dds"), "texture extension not supported, core image used");
        let mut j2 = j.clone();
        j2["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
        let e = classify(&j2).unwrap_err();
        assert_eq!(
            e,
            "EXT_meshopt_compression (required) on mesh 'leaf' primitive 0: geometry extension not supported; export without it"
        );
    }
}
