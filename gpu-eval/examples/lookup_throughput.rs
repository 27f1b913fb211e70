//! Volume lookups per second on the Vulkan device, with the CPU batch lookup
//! (lightvol-volume, rayon) measured in the same run as the baseline.
//!
//! ```text
//! cargo run --release -p lightvol-gpu --example lookup_throughput -- \
//!     [--queries N] [--coeffs 4|9|16] [--res R] [--repeats K] [--pattern coherent|random]
//! ```
//!
//! GPU time comes from timestamps written around `K` back-to-back dispatches of the same
//! batch (upload and readback excluded); the CPU figure is the median of a few
//! `irradiance_batch` calls on all cores. "Query I/O" is the 36 bytes each query moves
//! (point, normal, result), a lower bound on its memory traffic. On lavapipe (Mesa's CPU
//! Vulkan driver) the numbers are only a functional check.

use std::process::ExitCode;
use std::time::Instant;

use lightvol_gpu::lookup::{LookupBatch, Quantity};
use lightvol_gpu::synthetic::{random_queries, smooth_random_volume};
use lightvol_gpu::{GpuContext, VolumeLookup};
use lightvol_volume::GridSpec;

struct Args {
    queries: usize,
    coeffs: usize,
    res: u32,
    repeats: u32,
    coherent: bool,
}

fn parse() -> Result<Args, String> {
    let mut a = Args { queries: 1 << 20, coeffs: 9, res: 32, repeats: 10, coherent: true };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let v = it.next().ok_or_else(|| format!("{k} needs a value"))?;
        let num = |v: &str| v.parse::<usize>().map_err(|e| format!("{k} {v}: {e}"));
        match k.as_str() {
            "--queries" => a.queries = num(&v)?.max(1),
            "--coeffs" => a.coeffs = num(&v)?,
            "--res" => a.res = u32::try_from(num(&v)?.max(2)).map_err(|e| e.to_string())?,
            "--repeats" => a.repeats = u32::try_from(num(&v)?.max(1)).map_err(|e| e.to_string())?,
            "--pattern" => {
                a.coherent = match v.as_str() {
                    "coherent" => true,
                    "random" => false,
                    _ => return Err(format!("--pattern {v}: want coherent or random")),
                }
            }
            _ => return Err(format!("unknown option {k}")),
        }
    }
    Ok(a)
}

/// Points on a lattice filling the box, x fastest (neighbouring invocations read
/// neighbouring cells), normals varying slowly.
fn coherent_queries(spec: &GridSpec, n: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let side = (n as f64).cbrt().ceil() as usize;
    let (min, max) = spec.bounds();
    let mut p = Vec::with_capacity(n);
    let mut d = Vec::with_capacity(n);
    for q in 0..n {
        let idx = [q % side, (q / side) % side, q / (side * side)];
        let g: [f64; 3] =
            std::array::from_fn(|a| min[a] + (max[a] - min[a]) * (idx[a] as f64 + 0.5) / side as f64);
        p.push(spec.to_world(g).map(|v| v as f32));
        let t = q as f64 / n as f64 * std::f64::consts::TAU;
        let v = [t.cos() * 0.6, t.sin() * 0.6, 0.8];
        d.push(v.map(|x| x as f32));
    }
    (p, d)
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("lookup_throughput: {e}");
            return ExitCode::FAILURE;
        }
    };
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lookup_throughput: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(a: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let ctx = GpuContext::new()?;
    println!("device: {}", ctx.device_info());
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [a.res; 3])?;
    let vol = smooth_random_volume(spec.clone(), a.coeffs, 1)?;
    let (points, dirs) = if a.coherent {
        coherent_queries(&spec, a.queries)
    } else {
        random_queries(&spec, a.queries, 0.0, 2)
    };
    let lookup = VolumeLookup::new(&ctx, &vol)?;
    let mut batch = lookup.batch(&points, &dirs)?;
    // Warm-up (pipeline compilation in some drivers happens on first use).
    lookup.run(&mut batch, Quantity::Irradiance, 1)?;
    let stats = lookup.run(&mut batch, Quantity::Irradiance, a.repeats)?;
    let gpu_out = batch.read()?;

    let mut cpu_out = vec![[0.0f32; 3]; a.queries];
    let mut cpu_times = Vec::new();
    for _ in 0..5 {
        let t = Instant::now();
        vol.irradiance_batch(&points, &dirs, &mut cpu_out)?;
        cpu_times.push(t.elapsed().as_secs_f64());
    }
    cpu_times.sort_by(f64::total_cmp);
    let cpu_s = cpu_times[cpu_times.len() / 2];
    let identical = gpu_out.iter().zip(&cpu_out).filter(|(g, c)| g == c).count();

    let total = a.queries as f64 * f64::from(a.repeats);
    println!(
        "volume: {}^3 nodes x {} coeffs ({:.1} MiB f32); {} queries ({}), {} repeats",
        a.res,
        a.coeffs,
        lookup.volume_bytes() as f64 / f64::from(1u32 << 20),
        a.queries,
        if a.coherent { "coherent" } else { "random" },
        a.repeats
    );
    let cpu_rate = a.queries as f64 / cpu_s;
    match stats.gpu_seconds {
        Some(g) => {
            let rate = total / g;
            println!(
                "gpu: {:.3} ms per batch, {:.3e} lookups/s, query I/O {:.2} GB/s",
                g / f64::from(a.repeats) * 1e3,
                rate,
                rate * LookupBatch::QUERY_BYTES as f64 * 1e-9
            );
            println!(
                "cpu ({} threads): {:.3} ms per batch, {:.3e} lookups/s; gpu/cpu = {:.2}",
                std::thread::available_parallelism().map_or(1, usize::from),
                cpu_s * 1e3,
                cpu_rate,
                rate / cpu_rate
            );
        }
        None => println!(
            "gpu: no timestamps on this queue; wall {:.3} ms for {} repeats incl. submit; cpu {:.3e} lookups/s",
            stats.wall_seconds * 1e3,
            a.repeats,
            cpu_rate
        ),
    }
    println!("results bit-identical to the CPU: {identical} of {}", a.queries);
    Ok(())
}
