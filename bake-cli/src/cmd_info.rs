//! `lightvol info`: describe a volume file.

use std::process::ExitCode;

use anyhow::Context;
use lightvol_volume::exr_io::read_exr;

use crate::cli::InfoArgs;

/// Runs `lightvol info`.
pub fn run(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let vol = read_exr(&args.volume).with_context(|| format!("reading {}", args.volume.display()))?;
    let spec = vol.spec();
    let (min, max) = spec.bounds();
    let zero_weight = vol.weights().iter().filter(|&&w| w == 0.0).count();
    let meta = vol.metadata();
    let info = serde_json::json!({
        "file": args.volume.display().to_string(),
        "grid": { "res": spec.res(), "bounds": [min, max], "cell_size": spec.cell_size(),
                  "nodes": spec.node_count(), "placement": spec.placement().map(|p| p.to_world_matrix()) },
        "sh": { "coeffs": vol.coeffs(), "bands": vol.bands(),
                "convention": "real orthonormal, index l(l+1)+m, no Condon-Shortley phase, +z polar",
                "quantity": "incident radiance" },
        "bake": meta,
        "zero_weight_nodes": zero_weight,
        "memory_bytes": vol.memory_bytes(),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(ExitCode::SUCCESS);
    }
    let [nx, ny, nz] = spec.res();
    println!("volume      {}", args.volume.display());
    println!("grid        {nx} x {ny} x {nz} nodes ({} total)", spec.node_count());
    println!(
        "bounds      [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
        min[0], min[1], min[2], max[0], max[1], max[2]
    );
    let c = spec.cell_size();
    println!("cell size   {:.4} x {:.4} x {:.4}", c[0], c[1], c[2]);
    if let Some(p) = spec.placement() {
        println!("placement   {:?}", p.to_world_matrix());
    }
    println!("SH          {} coefficients per channel ({} bands), RGB radiance", vol.coeffs(), vol.bands());
    println!("convention  real orthonormal, index l(l+1)+m, no Condon-Shortley phase, +z polar axis");
    println!(
        "bake        method {}, {} samples, seed {}, shard {}/{}, scene {}",
        meta.method,
        meta.samples,
        meta.seed,
        meta.shard_index,
        meta.shard_count,
        if meta.scene_hash.is_empty() { "-" } else { &meta.scene_hash }
    );
    println!("units       {}", meta.units);
    println!("zero-weight {zero_weight} nodes (filled from neighbours)");
    println!("memory      {} bytes (f32)", vol.memory_bytes());
    Ok(ExitCode::SUCCESS)
}
