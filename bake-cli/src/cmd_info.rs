//! `lightvol info`: describe a volume file (uniform, with or without the SH gradients
//! of \[Oat05\], or adaptive: see [`crate::adaptive_files`]).

use std::path::Path;
use std::process::ExitCode;

use anyhow::Context;
use lightvol_sampler::eval::uniform_memory_bytes;
use lightvol_volume::AnyVolume;
use lightvol_volume::gradient::floats_per_sample;
use serde_json::{Value, json};

use crate::cli::InfoArgs;
use crate::gradient_args::floats_table;

/// The description `info --json` prints (`"kind": "uniform"` or `"adaptive"`).
pub fn describe(path: &Path) -> anyhow::Result<Value> {
    let opened = lightvol_volume::open(path).with_context(|| format!("reading {}", path.display()))?;
    let (vol, grads) = match &opened {
        AnyVolume::Adaptive(vol) => return crate::adaptive_files::describe(vol, path),
        AnyVolume::Uniform(vol) => (vol, None),
        AnyVolume::Gradient(g) => (&g.volume, Some(&g.gradients)),
    };
    let has_grads = grads.is_some();
    let floats = floats_per_sample(vol.bands(), has_grads);
    // Coordinates in the scene file's frame (the file stores the internal one).
    let frame = vol.metadata().frame;
    let spec = &lightvol_volume::frame::grid_in_file_frame(vol.spec(), frame)
        .with_context(|| format!("{}: grid in the {} frame", path.display(), frame.name()))?;
    let (min, max) = spec.bounds();
    let zero_weight = vol.weights().iter().filter(|&&w| w == 0.0).count();
    let mask_bytes = vol.validity().map_or(0, lightvol_volume::ValidityMask::memory_bytes);
    let validity =
        vol.validity().map(|m| json!({ "invalid_nodes": m.invalid_count(), "memory_bytes": mask_bytes }));
    Ok(json!({
        "file": path.display().to_string(),
        "kind": "uniform",
        "grid": { "frame": frame, "res": spec.res(), "bounds": [min, max], "cell_size": spec.cell_size(),
                  "nodes": spec.node_count(), "placement": spec.placement().map(|p| p.to_world_matrix()) },
        "sh": { "coeffs": vol.coeffs(), "bands": vol.bands(),
                "convention": "real orthonormal, index l(l+1)+m, no Condon-Shortley phase, +z polar",
                "frame": "z-up (lightvol's internal frame; exports are in the grid's frame)",
                "quantity": "incident radiance" },
        "bake": vol.metadata(),
        "zero_weight_nodes": zero_weight,
        "memory_bytes": vol.memory_bytes(),
        "gradients": has_grads,
        "validity": validity,
        "memory": { "floats_per_node": floats, "bytes_per_node": floats * 4,
                    "runtime_bytes": uniform_memory_bytes(vol.spec(), vol.bands(), has_grads) + mask_bytes,
                    "gradient_bytes": grads.as_ref().map_or(0, |g| g.memory_bytes()),
                    "floats_per_sample_by_order": floats_table(vol.bands()) },
    }))
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn print_text(info: &Value) {
    let g = &info["grid"];
    let res = |i: usize| g["res"][i].as_u64().unwrap_or(0);
    let b = |k: usize, i: usize| f(&g["bounds"][k][i]);
    println!("volume      {}", info["file"].as_str().unwrap_or("?"));
    println!(
        "grid        {} x {} x {} nodes ({} total), {} frame",
        res(0),
        res(1),
        res(2),
        g["nodes"],
        g["frame"].as_str().unwrap_or("?")
    );
    println!(
        "bounds      [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
        b(0, 0),
        b(0, 1),
        b(0, 2),
        b(1, 0),
        b(1, 1),
        b(1, 2)
    );
    let c = |i: usize| f(&g["cell_size"][i]);
    println!("cell size   {:.4} x {:.4} x {:.4}", c(0), c(1), c(2));
    if !g["placement"].is_null() {
        println!("placement   {}", g["placement"]);
    }
    println!(
        "SH          {} coefficients per channel ({} bands), RGB radiance",
        info["sh"]["coeffs"], info["sh"]["bands"]
    );
    println!("convention  real orthonormal, index l(l+1)+m, no Condon-Shortley phase, +z polar axis");
    let m = &info["bake"];
    let hash = m["scene_hash"].as_str().unwrap_or("");
    println!(
        "bake        method {}, {} samples, seed {}, shard {}/{}, scene {}",
        m["method"].as_str().unwrap_or("?"),
        m["samples"],
        m["seed"],
        m["shard_index"],
        m["shard_count"],
        if hash.is_empty() { "-" } else { hash }
    );
    println!("units       {}", m["units"].as_str().unwrap_or("?"));
    println!("zero-weight {} nodes (filled from neighbours)", info["zero_weight_nodes"]);
    if info["kind"] == "adaptive" {
        crate::adaptive_files::print_octree(info);
        return;
    }
    let has_grads = info["gradients"].as_bool().unwrap_or(false);
    println!(
        "gradients   {}",
        if has_grads { "yes (per-node world gradient of every coefficient, [Oat05])" } else { "no" }
    );
    match info["validity"]["invalid_nodes"].as_u64() {
        Some(n) => {
            println!("validity    mask of {} invalid nodes (lookups renormalise over valid corners)", n)
        }
        None => println!("validity    no mask (plain trilinear lookups)"),
    }
    let mem = &info["memory"];
    println!(
        "memory      {} bytes at run time ({} floats = {} bytes per node{}{}); file data {} bytes with bake weights",
        mem["runtime_bytes"],
        mem["floats_per_node"],
        mem["bytes_per_node"],
        if has_grads { ", SH and gradients" } else { ", SH" },
        if info["validity"].is_null() { "" } else { ", plus 1 byte of validity mask" },
        info["memory_bytes"].as_u64().unwrap_or(0) + mem["gradient_bytes"].as_u64().unwrap_or(0)
    );
    println!("[Oat05]     floats per sample: order | SH | SH + gradients");
    for r in mem["floats_per_sample_by_order"].as_array().into_iter().flatten() {
        println!(
            "                                 {:>5} | {:>2} | {:>3}",
            r["order"], r["floats"], r["floats_with_gradients"]
        );
    }
}

/// Runs `lightvol info`.
pub fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let info = describe(&args.volume)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print_text(&info);
    }
    Ok(ExitCode::SUCCESS)
}
