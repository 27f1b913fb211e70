//! `lightvol demo --quick` writes index.html, the PNG panels,
//! the plot and a report.json per scene that follows the documented schema.

use serde_json::Value;

fn check_schema(r: &Value) {
    assert!(r["scene"].is_string());
    assert!(matches!(r["up"].as_str(), Some("y-up" | "z-up")));
    assert!(r["plate"]["height"].is_f64());
    let res = r["plate"]["res"].as_array().expect("plate.res");
    assert_eq!(res.len(), 2);
    assert!(res.iter().all(|v| v.as_u64().is_some_and(|n| n >= 2)));
    assert!(r["plate"]["valid_points"].as_u64().is_some());
    let gres = r["grid"]["res"].as_array().expect("grid.res");
    assert_eq!(gres.len(), 3);
    let bounds = r["grid"]["bounds"].as_array().expect("grid.bounds");
    assert_eq!(bounds.len(), 2);
    assert!(bounds.iter().all(|c| c.as_array().is_some_and(|a| a.len() == 3 && a.iter().all(Value::is_f64))));
    assert!(r["reference"]["samples"].as_u64().is_some_and(|n| n > 0));
    let methods = r["methods"].as_object().expect("methods");
    for name in ["point", "prefilter", "doi-paper", "doi"] {
        let m = &methods[name];
        assert!(m["samples"].as_u64().is_some(), "{name}.samples");
        for k in ["sampling", "query", "total"] {
            assert!(m["rays"][k].as_u64().is_some(), "{name}.rays.{k}");
        }
        assert!(m["rays"]["total"].as_u64() >= m["rays"]["sampling"].as_u64());
        for k in ["seconds", "rel_rmse", "bias", "too_dark", "too_dark_near", "too_bright"] {
            let v = m[k].as_f64().unwrap_or_else(|| panic!("{name}.{k}"));
            assert!(v.is_finite(), "{name}.{k} = {v}");
        }
        for k in ["too_dark", "too_dark_near", "too_bright"] {
            assert!((0.0..=1.0).contains(&m[k].as_f64().unwrap()), "{name}.{k} is a share");
        }
    }
}

#[test]
fn demo_quick_writes_everything() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let code =
        lightvol::run_from_args(["lightvol", "demo", "--quick", "--quiet", "-o", out.to_str().unwrap()])
            .unwrap_or_else(|e| panic!("demo --quick: {e:#}"));
    assert_eq!(code, std::process::ExitCode::SUCCESS);
    let index = std::fs::read_to_string(out.join("index.html")).expect("index.html");
    for scene in ["city", "interior", "maze"] {
        let text = std::fs::read_to_string(out.join(scene).join("report.json")).expect("report.json");
        let r: Value = serde_json::from_str(&text).expect("report.json parses");
        check_schema(&r);
        for m in ["point", "prefilter", "doi-paper", "doi"] {
            for kind in ["panel", "error"] {
                let png = out.join(scene).join(format!("{kind}_{m}.png"));
                let bytes = std::fs::read(&png).unwrap_or_else(|_| panic!("{}", png.display()));
                assert_eq!(&bytes[1..4], b"PNG", "{} is a PNG", png.display());
                assert!(
                    index.contains(&format!("{scene}/{kind}_{m}.png")),
                    "index.html shows {kind}_{m} of {scene}"
                );
            }
        }
    }
    // The embedded real interior: baked from the file the demo writes beside its results,
    // with its licence, under sky and bounce light, with doi and the engines' fixes.
    let room = out.join("occlusion_room");
    assert!(room.join("room.glb").metadata().unwrap().len() > 1_000_000);
    assert!(std::fs::read_to_string(room.join("LICENSE.txt")).unwrap().contains("MIT License"));
    let r: Value = serde_json::from_str(&std::fs::read_to_string(room.join("report.json")).unwrap()).unwrap();
    for m in ["point", "doi-paper", "doi", "point+validity", "point+apv", "point+vlm", "point+ddgi"] {
        assert!(r["methods"][m]["rel_rmse"].as_f64().is_some_and(f64::is_finite), "occlusion_room: {m}");
    }
    // The sky change: the real interior under the embedded sunset (written beside its
    // results with its licence), a fresh bake against the volumes relit from the white sky
    // by the sky transfer and by APV's sky occlusion, each drawn.
    let sunset = out.join("occlusion_room_sunset");
    assert!(sunset.join("sunset.exr").metadata().unwrap().len() > 10_000);
    assert!(std::fs::read_to_string(sunset.join("LICENSE-sunset.txt")).unwrap().contains("CC0"));
    let r: Value =
        serde_json::from_str(&std::fs::read_to_string(sunset.join("report.json")).unwrap()).unwrap();
    let label = r["views"][0]["camera"].as_str().expect("a view of the sky change");
    for m in ["doi", "doi+relit", "doi+skyocc"] {
        assert!(r["methods"][m]["rel_rmse"].as_f64().is_some_and(f64::is_finite), "sky change: {m}");
        let f = format!("occlusion_room_sunset/view_{label}_{m}.png");
        assert!(index.contains(&f), "index.html shows {f}");
    }
    // Every scene has a view: the path-traced reference, point, the best engine baseline
    // by the view's relative RMSE, doi, and doi's volume as three.js and Bevy read it, each
    // shown in index.html.
    for scene in ["city", "interior", "maze", "occlusion_room"] {
        let r: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(scene).join("report.json")).unwrap())
                .unwrap();
        let view = &r["views"][0];
        let label = view["camera"].as_str().expect("a view");
        let rel = |m: &str| view["methods"][m]["rel_rmse"].as_f64();
        let best = ["point+validity", "point+apv", "point+vlm", "point+ddgi"]
            .into_iter()
            .filter(|m| rel(m).is_some())
            .min_by(|a, b| rel(a).unwrap().total_cmp(&rel(b).unwrap()))
            .expect("an engine baseline in the view");
        for m in ["reference", "point", best, "doi", "doi@three", "doi@bevy"] {
            let f = format!("{scene}/view_{label}_{m}.png");
            assert!(index.contains(&f), "index.html shows {f}");
        }
        // The views come first; the full tables and panels are folded below them.
        let section = &index[index.find(&format!("<h2>{scene}</h2>")).expect("a section")..];
        let first_view = section.find(&format!("view_{label}_doi@three.png")).unwrap();
        let folded = section.find("<details>").expect("folded details");
        assert!(first_view < folded, "{scene}: the views come before the folded tables");
        assert!(section[..folded].find(&format!("{scene}/panel_")).is_none(), "{scene}: panels are folded");
        // three.js and Bevy read doi's volume: their views differ from lightvol's.
        for engine in ["doi@three", "doi@bevy"] {
            assert!(rel(engine).is_some_and(f64::is_finite), "{scene}: {engine} has a relative RMSE");
        }
    }
    // Every file index.html names exists.
    let mut named = 0;
    for attr in ["src=\"", "href=\""] {
        for part in index.split(attr).skip(1) {
            let target = &part[..part.find('"').expect("closing quote")];
            if target.starts_with("http") || target.starts_with('#') {
                continue;
            }
            assert!(out.join(target).is_file(), "index.html names {target}, which does not exist");
            named += 1;
        }
    }
    assert!(named > 50, "index.html names {named} files");
    for f in ["sweep.svg", "sweep.png"] {
        assert!(out.join(f).metadata().unwrap().len() > 100, "{f}");
    }
    assert!(std::fs::read_to_string(out.join("sweep.svg")).unwrap().contains("<polyline"));
    // The error-vs-memory study on city and interior (plot, numbers, index.html),
    // and the gradient and adaptive entries in every report with their memory.
    for scene in ["city", "interior"] {
        let text =
            std::fs::read_to_string(out.join(scene).join("memory_sweep.json")).expect("memory_sweep.json");
        let r: Value = serde_json::from_str(&text).expect("memory_sweep.json parses");
        let pts = r["points"].as_array().expect("points");
        for series in
            ["uniform", "uniform+taylor", "uniform+hermite", "doi", "adaptive", "adaptive1", "bricks"]
        {
            let n = pts.iter().filter(|p| p["series"] == series).count();
            assert_eq!(n, r["scales"].as_array().unwrap().len(), "{scene}: {series} at every scale");
        }
        for p in pts {
            assert!(p["memory_bytes"].as_u64().is_some_and(|m| m > 0));
            assert!(p["rel_rmse"].as_f64().is_some_and(f64::is_finite));
        }
        for f in ["memory_sweep.svg", "memory_sweep.png"] {
            assert!(out.join(scene).join(f).metadata().unwrap().len() > 100, "{scene}/{f}");
        }
        assert!(index.contains(&format!("{scene}/memory_sweep.svg")));
        let text = std::fs::read_to_string(out.join(scene).join("report.json")).unwrap();
        let rep: Value = serde_json::from_str(&text).unwrap();
        for m in [
            "point",
            "doi",
            "doi-paper",
            "doi-paper+lsq",
            "doi-paper+taylor",
            "doi-paper+hermite",
            "adaptive",
            "adaptive1",
            "doi-node",
            "point+validity",
            "point+apv",
            "point+vlm",
            "point+ddgi",
        ] {
            assert!(rep["methods"][m]["memory_bytes"].as_u64().is_some(), "{scene}: {m}.memory_bytes");
        }
        let mem = |m: &str| rep["methods"][m]["memory_bytes"].as_u64().unwrap();
        assert_eq!(mem("doi-paper+hermite"), 4 * mem("doi-paper"), "[Oat05]: gradients quadruple the floats");
        // The octrees get the uniform doi grid's bytes (its coefficients and node reach).
        assert!(mem("adaptive") <= mem("doi") && mem("adaptive1") <= mem("doi"), "{scene}: equal memory");
    }
}
