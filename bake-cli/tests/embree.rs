//! The Embree baseline of `lightvol bench --embree` (Debian's `libembree-dev`, compiled at
//! run time): on a vendored real scene it runs, reports both throughputs and their ratio
//! for closest hit and occlusion on 1 and 2 threads with the ISA Embree picked, and beside
//! a forced-SSE2 Embree, and lightvol's tracer and Embree agree ray by ray. Throughput itself is measured, not asserted.
//!
//! Without Embree (no `embree3/rtcore.h` or no C compiler) the test says so in one loud line
//! and passes, unless `LIGHTVOL_REQUIRE_EMBREE=1` (set by `.ci/run`).

mod common;

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_lightvol");

fn embree_available() -> bool {
    common::available_or_loud(
        std::path::Path::new("/usr/include/embree3/rtcore.h").is_file(),
        "LIGHTVOL_REQUIRE_EMBREE",
        "EMBREE BASELINE NOT RUN: no /usr/include/embree3/rtcore.h (apt-get install libembree-dev)",
    )
}

#[test]
fn embree_baseline_runs_and_agrees() {
    if !embree_available() {
        return;
    }
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/occlusion_room/room.glb");
    let o =
        Command::new(BIN).args(["bench", "--embree", "--scene", scene, "--rays", "50000"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["triangles"], 63_720);
    // Embree runs the kernels it picks for this CPU (named from its own report), and a
    // forced-SSE2 row stands beside them.
    let isa = r["embree_isa"].as_str().unwrap();
    assert!(["SSE2", "SSE4.2", "AVX", "AVX2", "AVX512"].contains(&isa), "Embree's ISA: {isa}");
    for w in ["closest_hit", "occlusion"] {
        let sse2 = &r[w]["1_thread_embree_sse2"];
        assert_eq!(sse2["embree_isa"], "SSE2", "{w}: the forced row runs SSE2");
        assert!(sse2["embree_mrays_per_second"].as_f64().unwrap() > 0.0);
        assert!(sse2["agreement"]["hit_or_miss_agree"].as_f64().unwrap() >= 0.9999, "{w}: SSE2 agreement");
    }
    for w in ["closest_hit", "occlusion"] {
        for t in ["1_thread", "2_thread"] {
            let e = &r[w][t];
            let (l, em) = (
                e["lightvol_mrays_per_second"].as_f64().unwrap(),
                e["embree_mrays_per_second"].as_f64().unwrap(),
            );
            assert!(
                l > 0.0 && em > 0.0 && (e["lightvol_over_embree"].as_f64().unwrap() - l / em).abs() < 1e-9
            );
            // Hit or miss: identical but for rays that graze an edge or vertex (both tracers
            // are f32 and neither is watertight): at most 1 in 10,000.
            let agree = e["agreement"]["hit_or_miss_agree"].as_f64().unwrap();
            assert!(agree >= 0.9999, "{w} {t}: hit/miss agreement {agree}");
            if w == "closest_hit" {
                let same = e["agreement"]["same_hit_point"].as_f64().unwrap();
                assert!(same >= 0.9999, "{w} {t}: same hit point for {same} of the rays both hit");
            }
        }
    }
}
