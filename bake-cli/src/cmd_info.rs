//! `lightvol info`: describe a volume file (uniform, with or without the SH gradients
//! of \[Oat05\], or adaptive), as lightvol-volume's `info::describe` gives it.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Context;
use serde_json::Value;

use crate::cli::InfoArgs;

/// The description `info --json` prints (lightvol-volume's `info::describe`).
fn describe(path: &Path) -> anyhow::Result<Value> {
    let opened = lightvol_volume::open(path).with_context(|| format!("reading {}", path.display()))?;
    let mut info = lightvol_volume::info::describe(&opened, path)
        .with_context(|| format!("describing {}", path.display()))?;
    let is_exr = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        let bytes = lightvol_volume::io::util::read_bounded(path)?;
        if lightvol_volume::io::groups::has_groups(&bytes)? {
            let g = lightvol_volume::io::groups::grouped_exr_from_bytes(&bytes)
                .with_context(|| format!("reading the light groups of {}", path.display()))?;
            info["light_groups"] = serde_json::json!({
                "names": g.names(),
                "bytes": g.layer_bytes(),
                "sum_error": g.sum_error(),
            });
        }
    }
    Ok(info)
}

/// The text lines `info` prints for the octree section.
fn print_octree(info: &Value) {
    let o = &info["octree"];
    println!(
        "octree      levels {}..{} (finest used {}), cull tolerance {} x value scale {:.4}, budget {}",
        o["min_level"],
        o["max_level"],
        o["levels_used"],
        o["cull_tolerance"],
        o["value_scale"].as_f64().unwrap_or(f64::NAN),
        o["memory_budget"].as_u64().map_or_else(|| "none".to_owned(), |b| format!("{b} bytes"))
    );
    println!("            level    cells   leaves    split  created   stored   culled    empty");
    for l in o["levels"].as_array().into_iter().flatten() {
        let n = |k: &str| l[k].as_u64().unwrap_or(0);
        println!(
            "            {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
            n("level"),
            n("cells"),
            n("leaves"),
            n("split"),
            n("created_nodes"),
            n("stored_nodes"),
            n("culled_nodes"),
            n("empty_nodes")
        );
    }
    let r = &o["finest_res"];
    println!(
        "memory      {} bytes ({} stored nodes: coefficients, base weights, 8-byte keys, split bitmaps; lookup index {} bytes more); uniform {}x{}x{} grid of the finest level: {} bytes",
        o["memory_bytes"], o["stored_nodes"], o["index_bytes"], r[0], r[1], r[2], o["finest_uniform_bytes"]
    );
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// The text form of a brick volume's description.
fn print_bricks(info: &Value) {
    let n = |k: &str| info[k].as_u64().unwrap_or(0);
    let mib = |k: &str| n(k) as f64 / 1048576.0;
    println!("volume      {}", info["file"].as_str().unwrap_or("?"));
    println!(
        "bricks      {} bricks of {}^3 probes ({} cells per axis), per level {}, finest level {}",
        n("bricks"),
        n("brick_probes"),
        n("brick_cells"),
        info["bricks_per_level"],
        n("finest_level")
    );
    println!("indirection {} texels, {} stream cells", info["indirection_res"], n("stream_cells"));
    println!("SH          {} coefficients per channel, RGB radiance", n("coeffs"));
    println!(
        "memory      {:.3} MiB of probes (RGBA16F), {:.3} MiB of indirection (RGBA8)",
        mib("probe_bytes"),
        mib("indirection_bytes")
    );
    let m = &info["metadata"];
    println!(
        "bake        method {}, {} samples, seed {}, {} frame",
        m["method"].as_str().unwrap_or("?"),
        m["samples"],
        m["seed"],
        m["frame"].as_str().unwrap_or("?")
    );
}

fn print_text(info: &Value) {
    if info["kind"] == "bricks" {
        print_bricks(info);
        return;
    }
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
        print_octree(info);
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
        None => println!("validity    no mask"),
    }
    if let Some(names) = info["light_groups"]["names"].as_array() {
        let names: Vec<&str> = names.iter().filter_map(Value::as_str).collect();
        println!(
            "groups      {} light groups ({}), {} bytes; relit as baked they differ from the whole by {:.1e} of the largest coefficient (f32 rounding, and a sky transfer's band limit)",
            names.len(),
            names.join(", "),
            info["light_groups"]["bytes"],
            f(&info["light_groups"]["sum_error"])
        );
    }
    match info["reach"]["limited_nodes"].as_u64() {
        Some(n) => println!(
            "reach       node reach, {n} nodes limited (lookups leave out nodes on the far side of a wall)"
        ),
        None => println!("reach       none"),
    }
    let mem = &info["memory"];
    println!(
        "memory      {} bytes at run time ({} floats = {} bytes per node{}{}{}); file data {} bytes with bake weights",
        mem["runtime_bytes"],
        mem["floats_per_node"],
        mem["bytes_per_node"],
        if has_grads { ", SH and gradients" } else { ", SH" },
        if info["validity"].is_null() { "" } else { ", plus 1 byte of validity mask" },
        if info["reach"].is_null() { "" } else { ", plus 24 bytes of node reach" },
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
pub(crate) fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let info = describe(&args.volume)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print_text(&info);
    }
    Ok(ExitCode::SUCCESS)
}
