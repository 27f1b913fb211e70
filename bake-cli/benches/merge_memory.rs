//! Peak memory of `lightvol merge` on many shards: 64 shard files of a 64³ grid with 9 SH
//! coefficients per channel (`cargo bench -p lightvol --bench merge_memory`; the sizes can
//! be changed with `LIGHTVOL_BENCH_SHARDS` and `LIGHTVOL_BENCH_RES`).
//!
//! The merge runs in a child process (this benchmark re-executed), so its peak resident
//! memory (`VmHWM`) is the merge's alone. It is reported next to the memory of one
//! accumulator in memory (17 bytes per sum) and of the finalized f32 volume, as ratios.
//! This is a measurement, not a test: timings and memory depend on the machine.

use std::path::PathBuf;

use lightvol_volume::io::accumulator::write_accumulator;
use lightvol_volume::{Accumulator, BakeMetadata, GridSpec};

fn vm_hwm_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kib| kib * 1024)
}

fn env_or(k: &str, d: u32) -> u32 {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("--merge-child") {
        let mut a = vec!["lightvol".to_owned(), "merge".to_owned()];
        a.extend(args[2..].iter().cloned());
        let code = lightvol::run_from_args(a).expect("merge");
        println!("child_vm_hwm_bytes {}", vm_hwm_bytes());
        std::process::exit(if code == std::process::ExitCode::SUCCESS { 0 } else { 1 });
    }
    if args.iter().any(|a| a == "--list") {
        return; // cargo bench asks benches for their list; this one has none
    }
    let shards = env_or("LIGHTVOL_BENCH_SHARDS", 64);
    let res = env_or("LIGHTVOL_BENCH_RES", 64);
    let coeffs = 9;
    let dir = tempfile::tempdir().expect("temp dir");
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [res; 3]).expect("grid");
    let n = spec.node_count();
    let basis = [0.28, 0.1, -0.2, 0.3, 0.05, -0.05, 0.12, 0.0, 0.02];
    let t0 = std::time::Instant::now();
    let mut files: Vec<PathBuf> = Vec::new();
    for k in 0..shards {
        let mut acc = Accumulator::new(spec.clone(), coeffs).expect("accumulator");
        let (lo, hi) = (n * k as usize / shards as usize, n * (k as usize + 1) / shards as usize);
        for node in lo..hi {
            acc.add(node, 0.5, [1.0 + node as f64 * 1e-6, 2.0, 3.0], &basis);
        }
        let meta = BakeMetadata {
            method: "doi".into(),
            shard_index: k,
            shard_count: shards,
            scene_hash: "bench".into(),
            ..BakeMetadata::default()
        };
        let p = dir.path().join(format!("shard-{k}.lvacc"));
        write_accumulator(&p, &acc, &meta).expect("write shard");
        files.push(p);
    }
    let shard_bytes = std::fs::metadata(&files[0]).map_or(0, |m| m.len());
    eprintln!(
        "wrote {shards} shards of {res}^3 ({shard_bytes} bytes each) in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    let out = dir.path().join("merged.exr");
    let t1 = std::time::Instant::now();
    let o = std::process::Command::new(std::env::current_exe().expect("self"))
        .arg("--merge-child")
        .args(&files)
        .arg("-o")
        .arg(&out)
        .output()
        .expect("run the merge child");
    let secs = t1.elapsed().as_secs_f64();
    assert!(o.status.success(), "merge failed: {}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let peak: u64 =
        text.lines().find_map(|l| l.strip_prefix("child_vm_hwm_bytes ")?.parse().ok()).expect("child peak");
    let sums = (n * (coeffs * 3 + 2)) as u64;
    let acc_bytes = sums * 17;
    let volume_bytes = (n * (coeffs * 3 + 1) * 4) as u64;
    let report = serde_json::json!({
        "shards": shards,
        "res": res,
        "coeffs": coeffs,
        "merge_seconds": secs,
        "merge_peak_bytes": peak,
        "accumulator_bytes": acc_bytes,
        "f32_volume_bytes": volume_bytes,
        "shard_file_bytes": shard_bytes,
        "peak_over_accumulator": peak as f64 / acc_bytes as f64,
        "peak_over_f32_volume": peak as f64 / volume_bytes as f64,
        "peak_over_all_shards_in_memory": peak as f64 / (acc_bytes * u64::from(shards)) as f64,
    });
    println!("{}", serde_json::to_string_pretty(&report).expect("json"));
}
