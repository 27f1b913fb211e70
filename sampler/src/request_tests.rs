//! Tests of bake requests: which settings go together, records, labels and keys.
use super::*;
use lightvol_core::samples::samples;

fn grid(m: Method) -> BakeRequest {
    BakeRequest::new(BakeMethod::Grid(m), samples(16))
}

const LSQ: Fit = Fit::LeastSquares { lambda: 0.1 };

#[test]
fn compatible_requests_validate() {
    for m in [Method::Point, Method::Prefilter, Method::Doi, Method::DoiPaper, Method::DoiNode] {
        assert_eq!(grid(m).validate(), Ok(()));
        let g = BakeRequest { gradients: Some(GradientChoice::MethodDefault), ..grid(m) };
        assert_eq!(g.validate(), Ok(()), "{m:?}");
    }
    // Point sampling ignores the fit: it always averages.
    assert_eq!(BakeRequest { fit: LSQ, ..grid(Method::Point) }.validate(), Ok(()));
    assert_eq!(BakeRequest { fit: LSQ, ..grid(Method::Point) }.label(), "point");
    assert_eq!(BakeRequest { fit: LSQ, ..grid(Method::DoiPaper) }.label(), "doi-paper fit=lsq:0.1");
}

#[test]
fn the_record_states_every_setting() {
    let r = BakeRequest {
        fit: LSQ,
        coeffs: 16,
        transport: TransportSettings { bounces: 3, russian_roulette: false, ..TransportSettings::default() },
        ..grid(Method::DoiPaper)
    };
    let rec = r.record();
    assert_eq!((rec.method.as_str(), rec.samples_per_unit, rec.coeffs), ("doi-paper", 16, 16));
    assert_eq!(rec.fit, FitRecord::LeastSquares { lambda: 0.1 });
    assert_eq!((rec.bounces, rec.russian_roulette, rec.direct_light.as_str()), (3, false, "all"));
    assert_eq!((rec.gradients, rec.octree), (None, None));
    let g = BakeRequest { gradients: Some(GradientChoice::MethodDefault), ..grid(Method::Doi) }.record();
    assert_eq!((g.gradients.as_deref(), g.fit), (Some("central"), FitRecord::Average));
    let apv = BakeRequest::new(BakeMethod::Baseline(Baseline::Apv), samples(16)).record();
    assert_eq!(apv.method, "point+apv");
}

/// Every file of one octree bake shares the key; the level-0 shards carry the base
/// label, the assembled volume and the uniform bakes the plain one.
#[test]
fn files_are_labelled_and_keyed_by_the_request() {
    let maze = lightvol_scene::builtin("maze").unwrap();
    let octree = |shard, level| BakeRequest {
        shard,
        seed: 7,
        adaptive: Some(AdaptiveRequest { settings: AdaptiveSettings::default(), level, from_shards: false }),
        ..grid(Method::Doi)
    };
    let whole = octree(None, None);
    let base = octree(Some((1, 3)), None);
    let level1 = octree(Some((2, 3)), Some(1));
    assert_eq!(whole.file_label(), "doi");
    assert_eq!(base.file_label(), "doi adaptive-level-0");
    assert_eq!(octree(Some((0, 3)), Some(0)).file_label(), "doi adaptive-level-0");
    assert_eq!(level1.file_label(), "doi");
    assert_eq!(BakeRequest { fit: LSQ, ..grid(Method::DoiPaper) }.file_label(), "doi-paper fit=lsq:0.1");
    let key = whole.key(&maze.scene, &maze.grid);
    assert_eq!(base.key(&maze.scene, &maze.grid), key);
    assert_eq!(level1.key(&maze.scene, &maze.grid), key);
    assert!(key.contains(" doi 16 coeffs=9 "), "{key}");
    assert!(key.ends_with(&format!("lightvol={}", lightvol_scene::fingerprint::VERSION)), "{key}");
    assert_ne!(grid(Method::Doi).key(&maze.scene, &maze.grid), key, "the octree settings are keyed");

    let m = base.metadata(&maze.scene, UpAxis::Y, &key, 1234);
    assert_eq!((m.method.as_str(), m.sampling_rays, m.seed), ("doi adaptive-level-0", 1234, 7));
    assert_eq!((m.shard_index, m.shard_count, m.frame), (1, 3, UpAxis::Y));
    assert_eq!(m.scene_hash, lightvol_scene::fingerprint::scene_hash(&maze.scene, &key));
    assert_eq!(m.units, "relative");
    assert_eq!(m.settings, Some(base.record()));
    let w = whole.metadata(&maze.scene, UpAxis::Z, &key, 99);
    assert_eq!((w.method.as_str(), w.sampling_rays, w.shard_index, w.shard_count), ("doi", 99, 0, 1));
    assert_eq!(w.scene_hash, m.scene_hash);
}

#[test]
fn the_uniform_bake_refuses_baselines_and_octrees() {
    let maze = lightvol_scene::builtin("maze").unwrap();
    let tracer = lightvol_scene::Tracer::new(&maze.scene);
    let t = Transport::new(&maze.scene, &tracer, TransportSettings::default());
    let p = Provenance { frame: UpAxis::Z, key: "" };
    let apv = BakeRequest::new(BakeMethod::Baseline(Baseline::Apv), samples(4));
    let e = bake_uniform(&t, &maze.scene, &maze.grid, &apv, p, &BakeControl::default()).err().unwrap();
    assert!(matches!(e, UniformBakeError::Request(RequestError::NotUniform("point+apv"))), "{e}");
    let settings = AdaptiveSettings::default();
    let octree = BakeRequest {
        adaptive: Some(AdaptiveRequest { settings, level: None, from_shards: false }),
        ..grid(Method::Doi)
    };
    let e = bake_uniform(&t, &maze.scene, &maze.grid, &octree, p, &BakeControl::default()).err().unwrap();
    assert!(matches!(e, UniformBakeError::Request(RequestError::NotUniform(_))), "{e}");
}

#[test]
fn incompatible_requests_are_refused() {
    let err = |r: BakeRequest| r.validate().unwrap_err();
    assert!(matches!(err(BakeRequest { fit: LSQ, ..grid(Method::Doi) }), RequestError::FitNeedsCells { .. }));
    assert_eq!(
        err(BakeRequest {
            fit: LSQ,
            gradients: Some(GradientChoice::MethodDefault),
            ..grid(Method::Prefilter)
        }),
        RequestError::FitWithGradients(LSQ)
    );
    let basis = Some(GradientChoice::Estimator(GradientEstimator::Basis));
    assert_eq!(
        err(BakeRequest { gradients: basis, ..grid(Method::Doi) }),
        RequestError::BasisNeedsCells(Method::Doi)
    );
    let apv = BakeRequest::new(BakeMethod::Baseline(Baseline::Apv), samples(16));
    assert_eq!(
        err(BakeRequest { shard: Some((0, 2)), ..apv }),
        RequestError::Baseline { baseline: Baseline::Apv, with: Conflict::Shard }
    );
    let adaptive =
        Some(AdaptiveRequest { settings: AdaptiveSettings::default(), level: Some(1), from_shards: false });
    assert_eq!(
        err(BakeRequest { adaptive: adaptive.clone(), ..grid(Method::Doi) }),
        RequestError::LevelNeedsShard
    );
    assert_eq!(
        err(BakeRequest { adaptive: adaptive.clone(), shard: Some((0, 2)), ..grid(Method::Doi) }),
        RequestError::LevelNeedsShards(1)
    );
    assert_eq!(
        err(BakeRequest { adaptive, keep_accumulator: true, ..grid(Method::Doi) }),
        RequestError::Adaptive(Conflict::KeepAccumulator)
    );
}
