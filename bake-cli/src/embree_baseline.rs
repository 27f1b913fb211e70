//! `lightvol bench --embree`: lightvol's tracer against Embree 3 on the same triangles and
//! the same rays, in one run.
//!
//! Embree is reached through a small C program (`embree/embree_trace.c`, compiled here with
//! the system C compiler against Debian's `libembree-dev`) that reads the triangles and rays
//! from a file, traces them with Embree's single-ray API on 1 or more threads (best of
//! several passes) and writes every ray's result back. The default build therefore stays
//! pure Rust, and no Rust code calls C (the workspace keeps `unsafe` to the GPU crate).
//!
//! Two workloads, as in a bake: closest hit with origins uniform in the scene bounds and
//! uniform directions, and occlusion toward one direction (a sun). Results are compared ray
//! by ray: hit/miss agreement and, where both hit, the relative distance difference.
//!
//! Embree runs at its best: with the kernels it picks for this CPU at run time (the report
//! names them, read from Embree's own device report, [`chosen_isa`]) and flush-to-zero and
//! denormals-are-zero set on every thread, as Embree asks; a forced-SSE2 Embree row (one
//! thread) stands beside it for reference. lightvol runs the kernel its tracer chose at run
//! time (`lightvol_isa`: AVX2 where the CPU has it), with a row for its SSE2 kernel, the one
//! every x86-64 machine runs.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, bail};
use lightvol_scene::{BuildQuality, DVec3, Isa, Levels, Scene, Tracer};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use serde_json::{Value, json};

const SOURCE: &str = include_str!("../embree/embree_trace.c");

/// Passes per measurement; the best is reported (the least disturbed by other load). The
/// passes of lightvol and Embree alternate (each Embree pass its own run of the harness).
const REPEATS: u32 = 5;

/// Relative distance difference below which two hits count as the same surface point:
/// both tracers intersect in f32, with differently ordered arithmetic (a few ulps, 1e-6),
/// at distances up to the scene size; 1e-4 leaves room for grazing hits.
const SAME_HIT_REL: f64 = 1e-4;

/// Compiles the Embree harness into `dir`.
fn build_harness(dir: &Path) -> anyhow::Result<PathBuf> {
    let src = dir.join("embree_trace.c");
    std::fs::write(&src, SOURCE).context("writing the Embree harness")?;
    let exe = dir.join("embree_trace");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".to_owned());
    let out = Command::new(&cc)
        .args(["-O2", "-o"])
        .arg(&exe)
        .arg(&src)
        .args(["-lembree3", "-lpthread", "-lm"])
        .output()
        .with_context(|| format!("running the C compiler '{cc}' (set CC)"))?;
    if !out.status.success() {
        bail!(
            "building the Embree baseline failed (it needs Debian's libembree-dev and a C compiler): {}",
            String::from_utf8_lossy(&out.stderr).lines().next().unwrap_or("")
        );
    }
    Ok(exe)
}

/// The ISA target Embree runs, from its device report (`verbose=1`): the widest target
/// that is both supported by the CPU and compiled into the library, which is the one Embree
/// dispatches to. The report's `Config` block lists them on two lines:
/// `Targets : SSE SSE2 … AVX2 AVX512  (supported)` and
/// `SSE2 SSE4.2 AVX AVX2 AVX512  (compile time enabled)`.
fn chosen_isa(report: &str) -> Option<String> {
    let lines: Vec<&str> = report.lines().collect();
    let i = lines.iter().rposition(|l| l.contains("(supported)"))?;
    let words = |l: &str| -> Vec<String> {
        let l = l.split('(').next().unwrap_or("");
        let l = l.split_once(':').map_or(l, |(_, r)| r);
        l.split_whitespace().map(str::to_owned).collect()
    };
    let supported = words(lines[i]);
    let enabled = lines.get(i + 1).filter(|l| l.contains("(compile time enabled)")).map(|l| words(l))?;
    enabled.into_iter().rev().find(|t| supported.contains(t))
}

/// Which Embree kernels a run uses.
#[derive(Clone, Copy, PartialEq, Eq)]
enum EmbreeIsa {
    /// The kernels Embree picks for this CPU.
    Native,
    /// SSE2, forced (`isa=sse2`).
    Sse2,
}

/// One workload's input for the Embree harness (the triangles in the world frame, one
/// level, and the rays), written once to `dir/{tag}.bin` and traced by [`embree_pass`],
/// one timed pass per run.
fn embree_input(
    dir: &Path,
    tag: &str,
    scene: &Scene,
    rays: &[(DVec3, DVec3)],
    occlusion: bool,
    threads: u32,
    isa: EmbreeIsa,
) -> anyhow::Result<PathBuf> {
    let n = scene.triangle_count();
    let mut input = Vec::with_capacity(24 + n * 36 + rays.len() * 24);
    input.extend_from_slice(b"LVEB");
    for v in [u32::from(occlusion), threads, 1, u32::from(isa == EmbreeIsa::Sse2), n as u32] {
        input.extend_from_slice(&v.to_le_bytes());
    }
    for t in scene.world_triangles() {
        for p in t.v {
            for c in p.to_array() {
                input.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
    }
    input.extend_from_slice(&(rays.len() as u32).to_le_bytes());
    for (o, d) in rays {
        for c in o.to_array().into_iter().chain(d.to_array()) {
            input.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    input.extend_from_slice(&f32::INFINITY.to_le_bytes());
    let path = dir.join(format!("{tag}.bin"));
    std::fs::write(&path, &input).context("writing the rays for Embree")?;
    Ok(path)
}

/// One timed pass of the Embree harness over `input` (`rays` rays): `(seconds, build
/// seconds, per-ray results, the ISA target it ran)`.
fn embree_pass(exe: &Path, input: &Path, rays: usize) -> anyhow::Result<(f64, f64, Vec<f32>, String)> {
    let outp = input.with_extension("out");
    let st = Command::new(exe).arg(input).arg(&outp).output().context("running the Embree harness")?;
    if !st.status.success() {
        bail!("the Embree harness failed: {}", String::from_utf8_lossy(&st.stderr).trim());
    }
    let b = std::fs::read(&outp).context("reading Embree's results")?;
    if b.len() != 16 + 4 * rays {
        bail!("the Embree harness wrote {} bytes for {rays} rays", b.len());
    }
    let f64_at = |i: usize| f64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
    let res = b[16..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes"))).collect();
    let isa = chosen_isa(&String::from_utf8_lossy(&st.stdout)).unwrap_or_else(|| "unknown".to_owned());
    Ok((f64_at(0), f64_at(8), res, isa))
}

/// One timed pass of lightvol's tracer over `rays` in `pool`: `(seconds, results)` in
/// Embree's encoding.
fn lightvol_pass(
    tracer: &Tracer,
    pool: &rayon::ThreadPool,
    rays: &[(DVec3, DVec3)],
    occlusion: bool,
) -> (f64, Vec<f32>) {
    use rayon::prelude::*;
    let t0 = Instant::now();
    let out = pool.install(|| {
        rays.par_iter()
            .with_min_len(4096)
            .map(|(o, d)| {
                if occlusion {
                    f32::from(u8::from(tracer.occluded(*o, *d, 0.0, f64::INFINITY)))
                } else {
                    tracer.closest_hit(*o, *d, 0.0, f64::INFINITY).map_or(-1.0, |h| h.t as f32)
                }
            })
            .collect()
    });
    (t0.elapsed().as_secs_f64(), out)
}

/// The fastest of a measurement's passes and the results of its last.
struct Best<R> {
    seconds: f64,
    results: R,
}

impl<R> Best<R> {
    fn offer(slot: &mut Option<Self>, seconds: f64, results: R) {
        let seconds = slot.as_ref().map_or(seconds, |b| b.seconds.min(seconds));
        *slot = Some(Self { seconds, results });
    }
}

/// Ray-by-ray agreement of two result lists.
fn agreement(a: &[f32], b: &[f32], occlusion: bool) -> Value {
    let (mut same_kind, mut both_hit, mut same_point, mut worst) = (0usize, 0usize, 0usize, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let (hx, hy) = if occlusion { (x > 0.5, y > 0.5) } else { (x >= 0.0, y >= 0.0) };
        same_kind += usize::from(hx == hy);
        if !occlusion && hx && hy {
            both_hit += 1;
            let rel = f64::from((x - y).abs()) / f64::from(x.abs().max(y.abs()).max(1e-6));
            worst = worst.max(rel);
            same_point += usize::from(rel <= SAME_HIT_REL);
        }
    }
    let n = a.len().max(1) as f64;
    json!({
        "hit_or_miss_agree": same_kind as f64 / n,
        "both_hit": both_hit,
        "same_hit_point": if both_hit == 0 { 1.0 } else { same_point as f64 / both_hit as f64 },
        "same_hit_tolerance_rel": SAME_HIT_REL,
        "largest_distance_difference_rel": worst,
    })
}

/// Rays a bake traces, in a bake's order: cell by cell over a grid of 16 cells along the
/// scene's longest axis, 8 points uniform in the cell with uniform directions (Algorithm 2's
/// sampling rays), each hit followed by a cosine-distributed bounce from the hit point
/// (closest-hit rays), and a shadow ray toward a sun (jittered in a 0.27° cone) from each
/// hit point (occlusion rays). Returns `count` of each.
fn bake_mix(tracer: &Tracer, scene: &Scene, count: usize, rng: &mut SplitMix64) -> [Vec<(DVec3, DVec3)>; 2] {
    const SAMPLES_PER_CELL: usize = 8;
    let (lo, hi) = scene.bounds();
    let pad = (hi - lo) * 0.05 + DVec3::splat(1e-3);
    let (lo, hi) = (lo - pad, hi + pad);
    let ext = hi - lo;
    let cells = (ext / ext.max_element() * 16.0).ceil().max(DVec3::ONE);
    let size = ext / cells;
    let n = [cells.x as usize, cells.y as usize, cells.z as usize];
    let eps = scene.epsilon();
    let sun = DVec3::new(0.3, 0.2, 1.0).normalize();
    let (mut closest, mut shadow) = (Vec::with_capacity(count), Vec::with_capacity(count));
    'outer: loop {
        for c in 0..n[0] * n[1] * n[2] {
            let cell = DVec3::new((c % n[0]) as f64, ((c / n[0]) % n[1]) as f64, (c / (n[0] * n[1])) as f64);
            for _ in 0..SAMPLES_PER_CELL {
                let o = lo + (cell + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())) * size;
                let d = DVec3::from(sample_uniform_sphere([rng.next_f64(), rng.next_f64()]));
                closest.push((o, d));
                if let Some(h) = tracer.closest_hit(o, d, 0.0, f64::INFINITY) {
                    let n = if h.from_behind { -h.normal } else { h.normal };
                    let x = o + d * h.t + n * eps;
                    let local =
                        lightvol_sh::sampling::sample_cosine_hemisphere([rng.next_f64(), rng.next_f64()]);
                    let frame = lightvol_sh::sampling::Frame::from_normal(n.to_array());
                    closest.push((x, DVec3::from(frame.to_world(local))));
                    let jitter =
                        DVec3::from(sample_uniform_sphere([rng.next_f64(), rng.next_f64()])) * 0.0047;
                    shadow.push((x, (sun + jitter).normalize()));
                }
                if closest.len() >= count && shadow.len() >= count {
                    break 'outer;
                }
            }
        }
        if shadow.is_empty() {
            // Nothing to hit: the shadow workload starts from the sampling points.
            shadow = closest.iter().map(|&(o, _)| (o, sun)).collect();
        }
    }
    closest.truncate(count);
    shadow.truncate(count);
    [closest, shadow]
}

/// The comparison on `scene` with `count` rays (seeded), lightvol's BVH built at `quality`
/// (Embree's at its medium quality), for 1 and 2 threads: throughputs
/// in Mrays/s, their ratios (lightvol / Embree), hit agreement, and BVH build times, for
/// four workloads: closest hits with origins uniform in the bounds and uniform directions,
/// occlusion from those origins toward a sun, and the bake's own mix (cell samples, their
/// cosine bounces and sun shadow rays).
///
/// # Errors
/// When the harness cannot be built (no `libembree-dev` or no C compiler) or fails.
pub(crate) fn compare(
    scene: &Scene,
    count: usize,
    seed: u64,
    quality: BuildQuality,
    levels: Levels,
) -> anyhow::Result<Value> {
    let dir = tempfile::tempdir().context("temporary folder")?;
    let exe = build_harness(dir.path())?;
    let (lo, hi) = scene.bounds();
    let mut rng = SplitMix64::new(seed);
    let closest: Vec<(DVec3, DVec3)> = (0..count)
        .map(|_| {
            let o = DVec3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
            (o, DVec3::from(sample_uniform_sphere([rng.next_f64(), rng.next_f64()])))
        })
        .collect();
    let sun = DVec3::new(0.3, 0.2, 1.0).normalize();
    let shadow: Vec<(DVec3, DVec3)> = closest.iter().map(|(o, _)| (*o, sun)).collect();
    let t0 = Instant::now();
    let mut tracer = pool_build(scene, quality, levels)?;
    let native = tracer.isa();
    let lightvol_build = t0.elapsed().as_secs_f64();
    let mut out = json!({
        "triangles": scene.triangle_count(),
        "unique_triangles": scene.unique_triangle_count(),
        "instances": scene.instances.len(),
        "rays": count,
        "repeats_best_of": REPEATS,
        "lightvol_bvh_quality": format!("{quality:?}").to_lowercase(),
        "lightvol_isa": native.name(),
        "lightvol_levels": if tracer.placements() > 1 { "two" } else { "one" },
        "build_seconds": { "lightvol_1_thread": lightvol_build },
    });
    let [mix_closest, mix_shadow] = bake_mix(&tracer, scene, count, &mut rng);
    for (name, rays, occ) in [
        ("closest_hit", &closest, false),
        ("occlusion", &shadow, true),
        ("bake_mix_closest_hit", &mix_closest, false),
        ("bake_mix_occlusion", &mix_shadow, true),
    ] {
        let mut entry = json!({});
        for threads in [1u32, 2] {
            // lightvol's SSE2 kernel (the one every x86-64 runs) and Embree's forced SSE2
            // kernels stand beside the native ones on one thread.
            let sse2_rows = threads == 1;
            let native_in = embree_input(dir.path(), "native", scene, rays, occ, threads, EmbreeIsa::Native)?;
            let sse2_in = if sse2_rows {
                Some(embree_input(dir.path(), "sse2", scene, rays, occ, 1, EmbreeIsa::Sse2)?)
            } else {
                None
            };
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads as usize)
                .build()
                .context("thread pool")?;
            let (mut lv, mut lv_sse2, mut em, mut em_sse2) = (None, None, None, None);
            let mut embree_build = f64::INFINITY;
            // The passes of all four alternate, so that a burst of other load on a shared
            // machine slows each of them alike instead of one whole measurement.
            for _ in 0..REPEATS {
                let (t, r) = lightvol_pass(&tracer, &pool, rays, occ);
                Best::offer(&mut lv, t, r);
                if sse2_rows && native != Isa::Sse2 {
                    tracer.set_isa(Isa::Sse2).map_err(anyhow::Error::msg)?;
                    let (t, _) = lightvol_pass(&tracer, &pool, rays, occ);
                    tracer.set_isa(native).map_err(anyhow::Error::msg)?;
                    Best::offer(&mut lv_sse2, t, ());
                }
                let (t, build, r, isa) = embree_pass(&exe, &native_in, rays.len())?;
                embree_build = embree_build.min(build);
                Best::offer(&mut em, t, (r, isa));
                if let Some(input) = &sse2_in {
                    let (t, _, r, isa) = embree_pass(&exe, input, rays.len())?;
                    Best::offer(&mut em_sse2, t, (r, isa));
                }
            }
            let (Some(lv), Some(em)) = (lv, em) else { bail!("no passes were run") };
            if threads == 1 && !occ {
                out["build_seconds"]["embree_1_thread"] = json!(embree_build);
            }
            out["embree_isa"] = json!(em.results.1);
            let mrays = |seconds: f64| count as f64 / seconds / 1e6;
            let (lm, emr) = (mrays(lv.seconds), mrays(em.seconds));
            entry[format!("{threads}_thread")] = json!({
                "lightvol_mrays_per_second": lm,
                "embree_mrays_per_second": emr,
                "lightvol_over_embree": lm / emr,
                "agreement": agreement(&lv.results, &em.results.0, occ),
            });
            if let Some(s) = lv_sse2 {
                let sm = mrays(s.seconds);
                entry["1_thread_lightvol_sse2"] = json!({
                    "lightvol_isa": Isa::Sse2.name(),
                    "lightvol_mrays_per_second": sm,
                    "lightvol_over_embree": sm / emr,
                });
            }
            if let Some(s) = em_sse2 {
                let sm = mrays(s.seconds);
                entry["1_thread_embree_sse2"] = json!({
                    "embree_isa": s.results.1,
                    "embree_mrays_per_second": sm,
                    "lightvol_over_embree": lm / sm,
                    "agreement": agreement(&lv.results, &s.results.0, occ),
                });
            }
        }
        out[name] = entry;
    }
    Ok(out)
}

/// The tracer built on one thread (as the build time above is reported).
fn pool_build(scene: &Scene, quality: BuildQuality, levels: Levels) -> anyhow::Result<Tracer> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().context("thread pool")?;
    Ok(pool.install(|| Tracer::build(scene, quality, levels)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `Config` block of Embree 3.13.5's device report on an AVX-512 machine, with and
    /// without `isa=sse2`: the widest target both supported and compiled in.
    #[test]
    fn the_isa_embree_runs_is_read_from_its_report() {
        let native = "  Config\n    Threads : default\n    ISA     : XMM YMM ZMM SSE SSE2 AVX2 AVX512F\n    Targets : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 AVX AVXI AVX2 AVX512  (supported)\n              SSE2 SSE4.2 AVX AVX2 AVX512  (compile time enabled)\n    Features: raymasks\n";
        assert_eq!(chosen_isa(native).as_deref(), Some("AVX512"));
        let sse2 = "    Targets : SSE SSE2  (supported)\n              SSE2 SSE4.2 AVX AVX2 AVX512  (compile time enabled)\n";
        assert_eq!(chosen_isa(sse2).as_deref(), Some("SSE2"));
        let avx2 = "    Targets : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 AVX AVXI AVX2  (supported)\n              SSE2 SSE4.2 AVX AVX2 AVX512  (compile time enabled)\n";
        assert_eq!(chosen_isa(avx2).as_deref(), Some("AVX2"));
        assert_eq!(chosen_isa("no report"), None);
    }
}
