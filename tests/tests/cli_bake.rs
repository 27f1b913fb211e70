//! The CLI's bake pipeline end to end: bake → info → export → merge, sharded bakes merged
//! against the whole bake, and bad input.

use lightvol_volume::io::exr::read_exr;

mod common;
use common::{ok, run, s};

/// Two shards merged equal the whole bake bit for bit: the Eq. 6 sums are exact fixed-point
/// integers, so the order of the additions changes nothing.
#[test]
fn bake_info_export_and_sharded_merge() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["--samples", "16", "--res", "8,8,4", "--quiet", "--seed", "7"];
    let whole = d.join("whole.exr");
    let mut a = vec!["bake", "builtin:maze", "-o", s(&whole)];
    a.extend_from_slice(&common);
    ok(&a);
    for k in 0..2 {
        let out = d.join(format!("part{k}.exr"));
        let shard = format!("{k}/2");
        let mut a = vec!["bake", "builtin:maze", "--shard", &shard, "-o", s(&out)];
        a.extend_from_slice(&common);
        ok(&a);
        assert!(d.join(format!("part{k}.lvacc")).is_file());
    }
    let merged = d.join("merged.exr");
    ok(&["merge", s(&d.join("part1.exr")), s(&d.join("part0.lvacc")), "-o", s(&merged)]);
    let (w, m) = (read_exr(&whole).unwrap(), read_exr(&merged).unwrap());
    assert_eq!(w.spec().res(), m.spec().res());
    assert_eq!(m.metadata().shard_count, 1, "a complete merge is no longer a shard");
    assert_eq!(w.data(), m.data());
    assert_eq!(w.weights(), m.weights());
    // info and export on the merged volume.
    ok(&["info", s(&merged)]);
    ok(&["info", s(&merged), "--json"]);
    for (fmt, ext) in [("ktx2", "ktx2"), ("dds", "dds"), ("bevy", "ktx2"), ("json", "json")] {
        let out = d.join(format!("export_{fmt}.{ext}"));
        ok(&["export", s(&merged), "--format", fmt, "-o", s(&out)]);
        assert!(out.metadata().unwrap().len() > 0);
    }
    // The same bake twice is bit-identical (and with one thread).
    let again = d.join("again.exr");
    let mut a = vec!["bake", "builtin:maze", "-o", s(&again), "--threads", "1"];
    a.extend_from_slice(&common);
    ok(&a);
    assert_eq!(read_exr(&again).unwrap().data(), w.data());
}

/// `bake --method` takes the engine baselines: each writes a volume file, only `point+apv`'s
/// with a validity mask, which `info` reports and the KTX2 export carries; the options a
/// baseline cannot honour are refused in one line.
#[test]
fn bake_writes_engine_baselines() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["--samples", "8", "--res", "10,10,4", "--quiet", "--seed", "3"];
    for name in ["point+validity", "point+apv", "point+vlm", "point+ddgi"] {
        let out = d.join(format!("{name}.exr"));
        let mut a = vec!["bake", "builtin:city", "--method", name, "-o", s(&out)];
        a.extend_from_slice(&common);
        ok(&a);
        let vol = read_exr(&out).unwrap();
        assert_eq!(vol.metadata().method, name);
        assert_eq!(vol.validity().is_some(), name == "point+apv", "{name}");
        if name != "point+ddgi" {
            // The city's buildings are closed: nodes inside them are invalid (weight 0).
            assert!(vol.weights().contains(&0.0), "{name} invalidated nothing");
        }
    }
    let apv = d.join("point+apv.exr");
    let vol = read_exr(&apv).unwrap();
    let mask = vol.validity().unwrap();
    assert!(mask.invalid_count() > 0);
    let zero: Vec<bool> = vol.weights().iter().map(|&w| w != 0.0).collect();
    assert_eq!(mask.as_slice(), zero.as_slice(), "the mask is the validity the weights record");
    ok(&["info", s(&apv)]);
    let ktx = d.join("apv.ktx2");
    ok(&["export", s(&apv), "--format", "ktx2", "-o", s(&ktx)]);
    assert_eq!(lightvol_volume::io::ktx2::read_ktx2(&ktx).unwrap().validity(), Some(mask));
    let out = d.join("refused.exr");
    for (extra, needle) in [
        (vec!["--shard", "0/2"], "--shard"),
        (vec!["--gradients"], "--gradients"),
        (vec!["--keep-accumulator"], "--keep-accumulator"),
        (vec!["--adaptive"], "--adaptive"),
    ] {
        let mut a = vec!["bake", "builtin:city", "--method", "point+apv", "-o", s(&out)];
        a.extend_from_slice(&extra);
        let err = run(&a).expect_err("must fail");
        assert!(!err.contains('\n') && err.contains(needle) && err.contains("point+apv"), "{err}");
        assert!(!out.exists());
    }
    let err = run(&["bake", "builtin:city", "--method", "point+unity", "-o", s(&out)]).unwrap_err();
    assert!(err.contains("point+apv") && err.contains("doi"), "{err}");
}

/// Every kind of bad input is one clear line, an error (no panic: a panic
/// fails this test), and leaves no output file behind.
#[test]
fn bad_input_is_refused_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.exr");
    let o = s(&out);
    let malformed_obj = d.join("bad.obj");
    std::fs::write(&malformed_obj, "v 0 0 0\nv 1 0 0\nf 1 2 7\nthis is not obj\n").unwrap();
    let malformed_gltf = d.join("bad.gltf");
    std::fs::write(&malformed_gltf, "{ \"asset\": { \"version\": \"2.0\" }, \"meshes\": [ {").unwrap();
    let empty_obj = d.join("empty.obj");
    std::fs::write(&empty_obj, "# nothing here\nv 0 0 0\n").unwrap();
    let nan_obj = d.join("nan.obj");
    std::fs::write(&nan_obj, "v 0 0 0\nv 1 0 NaN\nv 0 1 0\nf 1 2 3\n").unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["bake".into(), s(&d.join("missing.obj")).into(), "-o".into(), o.into()], "missing.obj"),
        (vec!["bake".into(), s(&malformed_obj).into(), "-o".into(), o.into()], "bad.obj"),
        (vec!["bake".into(), s(&malformed_gltf).into(), "-o".into(), o.into()], "bad.gltf"),
        (vec!["bake".into(), s(&empty_obj).into(), "-o".into(), o.into()], "empty"),
        (vec!["bake".into(), s(&nan_obj).into(), "-o".into(), o.into()], "finite"),
        (
            vec!["bake".into(), "builtin:city".into(), "--res".into(), "0,0,0".into(), "-o".into(), o.into()],
            "--res",
        ),
        (
            vec![
                "bake".into(),
                "builtin:city".into(),
                "--bounds".into(),
                "1,0,0,0,1,1".into(),
                "-o".into(),
                o.into(),
            ],
            "--bounds",
        ),
        (
            vec![
                "bake".into(),
                "builtin:city".into(),
                "--res".into(),
                "4000,4000,4000".into(),
                "-o".into(),
                o.into(),
            ],
            "GiB",
        ),
        (
            vec![
                "bake".into(),
                "builtin:city".into(),
                "--sun".into(),
                "NaN,0,1:3".into(),
                "-o".into(),
                o.into(),
            ],
            "--sun",
        ),
        (
            vec![
                "bake".into(),
                "builtin:city".into(),
                "--sun".into(),
                "0,0,1:NaN".into(),
                "-o".into(),
                o.into(),
            ],
            "--sun",
        ),
        (vec!["bake".into(), "builtin:nowhere".into(), "-o".into(), o.into()], "nowhere"),
        (
            vec!["bake".into(), "builtin:city".into(), "--shard".into(), "2/2".into(), "-o".into(), o.into()],
            "--shard",
        ),
        (
            vec!["bake".into(), "builtin:city".into(), "--samples".into(), "0".into(), "-o".into(), o.into()],
            "samples",
        ),
    ];
    for (args, needle) in &cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let err = run(&a).expect_err(&format!("lightvol {} must fail", a.join(" ")));
        assert!(!err.contains('\n'), "one line: {err}");
        assert!(err.to_lowercase().contains(&needle.to_lowercase()), "'{err}' should mention '{needle}'");
        assert!(!out.exists(), "no output after: lightvol {}", a.join(" "));
    }
    // Mismatched merges: different grids.
    let a = d.join("a.exr");
    let b = d.join("b.exr");
    ok(&[
        "bake",
        "builtin:maze",
        "--samples",
        "4",
        "--res",
        "4,4,3",
        "--shard",
        "0/2",
        "--quiet",
        "-o",
        s(&a),
    ]);
    ok(&[
        "bake",
        "builtin:maze",
        "--samples",
        "4",
        "--res",
        "5,4,3",
        "--shard",
        "1/2",
        "--quiet",
        "-o",
        s(&b),
    ]);
    let err = run(&["merge", s(&a), s(&b), "-o", o]).unwrap_err();
    assert!(!err.contains('\n') && (err.contains("same bake") || err.contains("grid")), "{err}");
    // A finalized volume without its accumulator cannot be merged.
    let c = d.join("c.exr");
    ok(&["bake", "builtin:maze", "--samples", "4", "--res", "4,4,3", "--quiet", "-o", s(&c)]);
    let err = run(&["merge", s(&c), s(&a), "-o", o]).unwrap_err();
    assert!(err.contains("accumulator"), "{err}");
    assert!(!out.exists());
}

/// `bake --fit lsq`: the least-squares node fit writes a volume that differs from the Eq. 6
/// bake of the same samples, records the fit in the method metadata, and refuses shards,
/// kept accumulators and gradients (whose sums assume Eq. 6) with one clear line and no
/// output file.
#[test]
fn least_squares_fit_bakes_and_refuses_what_it_cannot_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["--method", "doi-paper", "--samples", "16", "--res", "8,7,5", "--quiet", "--seed", "3"];
    let avg = d.join("avg.exr");
    let lsq = d.join("lsq.exr");
    let mut a = vec!["bake", "builtin:interior", "-o", s(&avg)];
    a.extend_from_slice(&common);
    ok(&a);
    let mut a = vec!["bake", "builtin:interior", "--fit", "lsq:0.5", "-o", s(&lsq)];
    a.extend_from_slice(&common);
    ok(&a);
    let (va, vl) = (read_exr(&avg).unwrap(), read_exr(&lsq).unwrap());
    assert_eq!(vl.metadata().method, "doi-paper fit=lsq:0.5");
    assert_eq!(va.weights(), vl.weights(), "same samples, same domain weights");
    assert_ne!(va.data(), vl.data());
    // Same DC level overall: the fit redistributes light between nodes, it does not add any.
    let dc_mean = |v: &lightvol_volume::IrradianceVolume| {
        (0..v.spec().node_count()).map(|n| f64::from(v.node(n)[0])).sum::<f64>()
            / v.spec().node_count() as f64
    };
    // Relative tolerance: the two fits weight the boundary nodes differently, a few percent.
    const DC_MEAN_REL: f64 = 0.1;
    assert!(
        (dc_mean(&va) - dc_mean(&vl)).abs() <= DC_MEAN_REL * dc_mean(&va),
        "{} {}",
        dc_mean(&va),
        dc_mean(&vl)
    );
    // Shards and kept accumulators carry the mass matrix (tests/tests/shards.rs); gradients
    // still need the average fit.
    {
        let out = d.join("refused.exr");
        let mut a = vec!["bake", "builtin:interior", "--fit", "lsq", "-o", s(&out), "--gradients"];
        a.extend_from_slice(&common);
        let e = run(&a).expect_err("must be refused");
        assert!(e.contains("--fit lsq"), "{e}");
        assert!(!out.exists() && !out.with_extension("lvacc").exists());
    }
    let e = run(&["bake", "builtin:interior", "--fit", "lsq:-1", "-o", s(&d.join("x.exr"))]).unwrap_err();
    assert!(e.contains("lsq"), "{e}");
}

/// `bake --target`: the fitted volume records its target in the file and in every export's
/// sidecar, changes the node values but not the grid, and is refused where the fit cannot
/// run (a shard, an engine baseline, an octree, gradients, a negative λ) in one line,
/// writing nothing; `--target lightvol` only smooths.
#[test]
fn target_bakes_record_the_engine_and_refuse_what_they_cannot_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["--samples", "16", "--quiet", "--seed", "3"];
    let plain = d.join("plain.exr");
    let three = d.join("three.exr");
    let mut a = vec!["bake", "builtin:maze", "-o", s(&plain)];
    a.extend_from_slice(&common);
    ok(&a);
    let mut a = vec!["bake", "builtin:maze", "--target", "three", "-o", s(&three)];
    a.extend_from_slice(&common);
    ok(&a);
    let (vp, vt) = (read_exr(&plain).unwrap(), read_exr(&three).unwrap());
    assert_eq!(vt.metadata().method, "doi target=three");
    let rec = vt.metadata().settings.as_ref().and_then(|r| r.target.clone()).expect("a target record");
    assert_eq!((rec.lookup.as_str(), rec.lambda), ("three", lightvol_sampler::target::TARGET_LAMBDA_OFFSET));
    assert_eq!(rec.smoothing, Some(lightvol_sampler::denoise::DEFAULT_SMOOTHING));
    // Without the smoothing the fit starts from the bake's own values: another volume,
    // recorded without a τ.
    let unsmoothed = d.join("unsmoothed.exr");
    let mut a =
        vec!["bake", "builtin:maze", "--target", "three", "--target-smoothing", "off", "-o", s(&unsmoothed)];
    a.extend_from_slice(&common);
    ok(&a);
    let vu = read_exr(&unsmoothed).unwrap();
    assert_ne!(vu.data(), vt.data());
    assert_eq!(
        vu.metadata().settings.as_ref().and_then(|r| r.target.clone()).and_then(|r| r.smoothing),
        None
    );
    assert_eq!(vp.spec(), vt.spec());
    assert_ne!(vp.data(), vt.data());
    assert!(vp.reach().is_some() && vt.reach().is_none(), "no engine reads a reach");
    let out = d.join("three.ktx2");
    ok(&["export", s(&three), "--format", "three", "-o", s(&out)]);
    let sidecar: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("three.ktx2.json")).unwrap()).unwrap();
    assert_eq!(sidecar["bake"]["settings"]["target"]["lookup"], "three");
    // `--target lightvol` smooths the bake's noisy nodes and fits nothing: the same grid and
    // node reach, other values, the target recorded; without the smoothing it is the plain
    // bake.
    let smoothed = d.join("lightvol.exr");
    let mut a = vec!["bake", "builtin:maze", "--target", "lightvol", "-o", s(&smoothed)];
    a.extend_from_slice(&common);
    ok(&a);
    let vl = read_exr(&smoothed).unwrap();
    assert_eq!(vl.metadata().method, "doi target=lightvol");
    assert_eq!(vl.spec(), vp.spec());
    assert!(vl.reach().is_some() && vl.reach() == vp.reach(), "the node reach is kept");
    assert_ne!(vl.data(), vp.data());
    let same = d.join("same.exr");
    let mut a =
        vec!["bake", "builtin:maze", "--target", "lightvol", "--target-smoothing", "off", "-o", s(&same)];
    a.extend_from_slice(&common);
    ok(&a);
    let vs = read_exr(&same).unwrap();
    assert_eq!((vs.data(), vs.metadata().method.as_str()), (vp.data(), "doi"));
    // The fit's settings without a target are refused.
    let e =
        run(&["bake", "builtin:maze", "--target-lambda", "0.3", "-o", s(&same)]).expect_err("needs --target");
    assert!(e.contains("--target"), "{e}");
    for (extra, says) in [
        (&["--shard", "0/2"][..], "a shard"),
        (&["--keep-accumulator"][..], "keeping the accumulator"),
        (&["--method", "point+apv"][..], "an engine baseline"),
        (&["--adaptive"][..], "an octree bake"),
        (&["--gradients"][..], "gradients"),
        (&["--target-lambda=-1"][..], "--target-lambda"),
        (&["--target-smoothing", "0"][..], "--target-smoothing"),
    ] {
        let out = d.join("refused.exr");
        let mut a = vec!["bake", "builtin:maze", "--target", "bevy", "-o", s(&out)];
        a.extend_from_slice(&common);
        a.extend_from_slice(extra);
        let e = run(&a).expect_err("must be refused");
        assert!(e.contains(says) && !e.contains('\n'), "{extra:?}: {e}");
        assert!(!out.exists() && !out.with_extension("lvacc").exists(), "{extra:?}");
    }
}

/// A targeted bake in pieces writes the whole bake's bytes: shards baked with `--target
/// lightvol` carry their nodes' error estimates and the merge smooths the merged set; a
/// checkpointed bake runs any target, an engine's fit included, on its finished sums; a
/// kept accumulator merges back to its own bake.
#[test]
fn targeted_bakes_in_pieces_equal_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bake = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let mut a = vec!["bake", "builtin:maze", "--samples", "16", "--seed", "5", "--quiet", "-o", s(&out)];
        a.extend_from_slice(extra);
        ok(&a);
        out
    };
    let bytes = |p: &std::path::Path| std::fs::read(p).unwrap();
    let whole = bake("whole.exr", &["--target", "lightvol"]);
    let plain = bake("plain.exr", &[]);
    assert_ne!(bytes(&whole), bytes(&plain), "the smoothing changes the maze's values at 16 samples");
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let shard = format!("{k}/3");
            bake(&format!("s{k}.exr"), &["--target", "lightvol", "--shard", &shard]).with_extension("lvacc")
        })
        .collect();
    let merged = d.join("merged.exr");
    // In any order.
    ok(&["merge", s(&shards[2]), s(&shards[0]), s(&shards[1]), "-o", s(&merged)]);
    assert_eq!(bytes(&merged), bytes(&whole), "merged shards smoothed as the whole bake");
    let kept = bake("kept.exr", &["--target", "lightvol", "--keep-accumulator"]);
    assert_eq!(bytes(&kept), bytes(&whole));
    let remerged = d.join("remerged.exr");
    ok(&["merge", s(&kept.with_extension("lvacc")), "-o", s(&remerged)]);
    assert_eq!(bytes(&remerged), bytes(&whole), "a kept accumulator merges back to its bake");
    for target in ["lightvol", "three"] {
        let w = bake(&format!("w-{target}.exr"), &["--target", target]);
        let ck = d.join(format!("ck-{target}"));
        let c = bake(
            &format!("c-{target}.exr"),
            &["--target", target, "--checkpoint", s(&ck), "--checkpoint-pieces", "4"],
        );
        assert_eq!(bytes(&c), bytes(&w), "--target {target} checkpointed");
    }
}
