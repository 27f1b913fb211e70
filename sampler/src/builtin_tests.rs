//! The built-in scenes bake soundly: tests that need the bake and the domain-of-interest test.

use lightvol_core::samples::samples;

use crate::bake::bake;
use crate::domain::{classify_point, classify_points};
use crate::settings::BakeSettings;
use lightvol_core::progress::BakeControl;
use lightvol_scene::DVec3;
use lightvol_scene::builtin::{BUILTIN_NAMES, builtin, city, city_buildings, interior, maze, maze_walls};
use lightvol_scene::bvh::Tracer;
use lightvol_scene::diagnostics::winding_report;
use lightvol_scene::transport::{Transport, TransportSettings};

/// Every built-in scene is consistently wound (closed solids), bakes with `doi`
/// finding back faces, and its plates contain both inside and outside points.
#[test]
fn builtins_are_sound() {
    for name in BUILTIN_NAMES {
        let b = builtin(name).unwrap();
        assert_eq!(b.scene.report.degenerate_skipped, 0, "{name}");
        assert_eq!(winding_report(&b.scene, 1e-6).inconsistent_edges, 0, "{name}");
        let tracer = Tracer::new(&b.scene);
        let t = Transport::new(&b.scene, &tracer, TransportSettings::default());
        let s = BakeSettings { samples: samples(8), ..Default::default() };
        let (_, stats) = bake(&t, &b.grid, &s, &BakeControl::default()).unwrap().finish();
        assert!(stats.cells_with_back_faces > 0 && stats.samples_kept > 0, "{name}: {stats}");
        let plate = b.plate(b.plate_heights[0], [24, 24]);
        let mask = classify_points(&tracer, &plate, 64, 9);
        let inside = mask.iter().filter(|&&m| m).count();
        assert!(inside > 0 && inside < plate.len(), "{name}: {inside}/{}", plate.len());
    }
}

/// Interior: the room is in the domain, the thick walls, the bed bars and the table top
/// are not; outside the window is open space.
#[test]
fn interior_domain() {
    let b = interior();
    let tr = Tracer::new(&b.scene);
    let inside = |p: DVec3| classify_point(&tr, p, 256, 3).inside;
    assert!(inside(DVec3::new(3.0, 2.5, 1.5)));
    assert!(!inside(DVec3::new(-0.15, 2.5, 1.5)), "inside the -X wall");
    assert!(!inside(DVec3::new(3.0, 2.5, 3.15)), "inside the ceiling slab");
    assert!(!inside(DVec3::new(0.4 + 0.1 + 0.025, 1.2, 0.475)), "inside a bed bar");
    assert!(!inside(DVec3::new(4.4, 3.0, 0.745)), "inside the table top");
    assert!(inside(DVec3::new(3.0, 6.0, 1.5)), "outside, in front of the window");
}

/// City and maze: streets are inside, buildings and walls outside, underground outside.
#[test]
fn city_and_maze_domain() {
    let c = city();
    let tr = Tracer::new(&c.scene);
    for (lo, hi) in city_buildings() {
        let mid = (lo + hi) / 2.0;
        assert!(!classify_point(&tr, mid, 128, 1).inside);
        assert!(classify_point(&tr, DVec3::new(hi.x + 0.5, mid.y, 1.0), 128, 2).inside);
    }
    assert!(!classify_point(&tr, DVec3::new(0.0, 0.0, -0.5), 64, 3).inside);
    let m = maze();
    let tr = Tracer::new(&m.scene);
    for (lo, hi) in maze_walls() {
        assert!(!classify_point(&tr, (lo + hi) / 2.0, 128, 4).inside);
    }
}
