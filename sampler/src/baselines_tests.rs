//! The engine baselines' mechanisms: virtual offset and relocation on a closed box (the
//! functions, then the four bakes), the fills against their definitions, validity-weighted
//! lookups.

use lightvol_core::samples::samples;

use super::*;
use crate::relocate::DDGI_MAX_OFFSET;
use glam::DVec2;
use lightvol_scene::builder::SceneBuilder;
use lightvol_scene::material::Material;

/// A closed unit box `[-0.5, 0.5]³`, faces outward, single-sided.
fn closed_box() -> lightvol_scene::Scene {
    let mut b = SceneBuilder::new("box");
    let m = b.add_material(Material::diffuse("grey", [0.5; 3])).unwrap();
    let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z) * 0.5;
    let quads = [
        [c(-1., -1., 1.), c(1., -1., 1.), c(1., 1., 1.), c(-1., 1., 1.)],
        [c(-1., -1., -1.), c(-1., 1., -1.), c(1., 1., -1.), c(1., -1., -1.)],
        [c(1., -1., -1.), c(1., 1., -1.), c(1., 1., 1.), c(1., -1., 1.)],
        [c(-1., -1., -1.), c(-1., -1., 1.), c(-1., 1., 1.), c(-1., 1., -1.)],
        [c(-1., 1., -1.), c(-1., 1., 1.), c(1., 1., 1.), c(1., 1., -1.)],
        [c(-1., -1., -1.), c(1., -1., -1.), c(1., -1., 1.), c(-1., -1., 1.)],
    ];
    for q in quads {
        b.add_triangle([q[0], q[1], q[2]], [DVec2::ZERO; 3], m).unwrap();
        b.add_triangle([q[0], q[2], q[3]], [DVec2::ZERO; 3], m).unwrap();
    }
    b.build().unwrap()
}

/// Inside the box every ray meets a back face; APV's offset (search 0.6 > the 0.5 to the
/// nearest wall) takes the capture point out, where no ray does; DDGI moves the probe
/// towards the nearest back face by at most 0.45 × spacing per axis, and out of the box when
/// the wall is within that reach.
#[test]
fn inside_probes_are_offset_out_or_relocated_within_the_limit() {
    let scene = closed_box();
    let tracer = Tracer::new(&scene);
    let inside = DVec3::new(0.1, -0.05, 0.2);
    let v = probe_rays(&tracer, inside, 1, 7);
    assert_eq!(v.back_fraction, 1.0);
    let (d, t) = v.closest_back.unwrap();
    assert!(t > 0.0 && t < 0.5 * 3f64.sqrt() + 1e-9 && (d.length() - 1.0).abs() < 1e-12);
    // APV.
    let moved = apv_offset(inside, &v, 0.6, 0.01);
    assert!(moved.abs().max_element() > 0.5, "{moved} still inside");
    assert_eq!(probe_rays(&tracer, moved, 1, 7).back_fraction, 0.0, "the offset point still sees back faces");
    assert_eq!(apv_offset(inside, &v, 0.05, 0.01), inside, "no back face within the search: no offset");
    // DDGI, spacing 1 per axis: a limited move towards the closest back face.
    let r = ddgi_relocate(inside, &v, [1.0; 3]);
    let off = r - inside;
    assert!(off.abs().max_element() <= DDGI_MAX_OFFSET + 1e-12, "{off}");
    assert!(off.dot(d) > 0.0 && off.length() > 0.0);
    // Near a wall (0.1 from +z), the relocation reaches outside.
    let near = DVec3::new(0.0, 0.0, 0.4);
    let vn = probe_rays(&tracer, near, 1, 7);
    let rn = ddgi_relocate(near, &vn, [1.0; 3]);
    assert!(rn.z > 0.5, "{rn}");
    assert_eq!(probe_rays(&tracer, rn, 1, 7).back_fraction, 0.0);
    // Outside, nothing moves.
    let out = DVec3::new(0.0, 0.0, 2.0);
    let vo = probe_rays(&tracer, out, 1, 7);
    assert_eq!(vo.back_fraction, 0.0);
    assert_eq!(ddgi_relocate(out, &vo, [1.0; 3]), out);
}

/// Random data on a 4×3×3 grid with some invalid nodes.
fn fixture() -> (GridSpec, Vec<f64>, Vec<bool>, usize) {
    let grid = GridSpec::new([0.0; 3], [3.0, 4.0, 2.0], [4, 3, 3]).unwrap();
    let k = 3;
    let n = grid.node_count();
    let data: Vec<f64> = (0..n * k).map(|i| ((i * 37 % 101) as f64) * 0.01 - 0.3).collect();
    let valid: Vec<bool> = (0..n).map(|i| i % 4 != 1 && i != 17).collect();
    (grid, data, valid, k)
}

/// VLM: an invalid node becomes exactly the mean of its valid 3×3×3 neighbours, valid nodes
/// are untouched (each found here by brute force over coordinates).
#[test]
fn vlm_fill_is_the_neighbour_mean() {
    let (grid, data, valid, k) = fixture();
    let mut filled = data.clone();
    fill_vlm(&grid, &mut filled, &valid, k);
    for node in 0..valid.len() {
        if valid[node] {
            assert_eq!(filled[node * k..(node + 1) * k], data[node * k..(node + 1) * k]);
            continue;
        }
        let a = grid.node_coords(node);
        let ns: Vec<usize> = (0..valid.len())
            .filter(|&m| m != node && valid[m])
            .filter(|&m| {
                let b = grid.node_coords(m);
                (0..3).all(|i| (i64::from(a[i]) - i64::from(b[i])).abs() <= 1)
            })
            .collect();
        assert!(!ns.is_empty());
        for c in 0..k {
            let mean = ns.iter().map(|&m| data[m * k + c]).sum::<f64>() / ns.len() as f64;
            assert!((filled[node * k + c] - mean).abs() < 1e-15, "node {node}");
        }
    }
}

/// APV dilation: the 1/d² weights over valid neighbours within one cell, d in world units
/// (the grid's spacing is anisotropic here: 1 × 2 × 1).
#[test]
fn apv_dilation_weights_by_inverse_squared_distance() {
    let (grid, data, valid, k) = fixture();
    let mut filled = data.clone();
    dilate_apv(&grid, &mut filled, &valid, k);
    let sp = [1.0, 2.0, 1.0];
    for node in (0..valid.len()).filter(|&n| !valid[n]) {
        let a = grid.node_coords(node);
        let (mut acc, mut ws) = (vec![0.0; k], 0.0);
        for m in (0..valid.len()).filter(|&m| m != node && valid[m]) {
            let b = grid.node_coords(m);
            let d: [i64; 3] = std::array::from_fn(|i| i64::from(b[i]) - i64::from(a[i]));
            if d.iter().any(|v| v.abs() > 1) {
                continue;
            }
            let w = 1.0 / (0..3).map(|i| (d[i] as f64 * sp[i]).powi(2)).sum::<f64>();
            ws += w;
            for c in 0..k {
                acc[c] += w * data[m * k + c];
            }
        }
        for c in 0..k {
            assert!((filled[node * k + c] - acc[c] / ws).abs() < 1e-14, "node {node}");
        }
    }
}

/// `point+apv`'s lookups are the volume's validity-weighted lookups
/// ([`lightvol_volume::validity`]; tested there against values computed by hand): here,
/// on a baseline-shaped volume, the mask makes the invalid corners' values irrelevant, a
/// mask of valid nodes only changes no bit, and the f64 reference the comparison reads
/// agrees with the f32 lookup a renderer uses.
#[test]
fn validity_weighted_lookups_ignore_invalid_corners() {
    let grid = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
    let n = grid.node_count();
    let data: Vec<f32> = (0..n * 27).map(|i| ((i * 53 % 97) as f32) * 0.01).collect();
    let plain = IrradianceVolume::new(grid.clone(), 9, data.clone(), vec![1.0; n]).unwrap();
    let (p, nn) = ([0.7, 1.3, 0.4], [0.0, 0.6, 0.8]);
    let all = plain.clone().with_validity(ValidityMask::new(vec![true; n])).unwrap();
    assert_eq!(all.irradiance_reference(p, nn), plain.irradiance_reference(p, nn));
    // Invalidate two corners of the point's cell and scramble their coefficients.
    let (nodes, w) = grid.trilinear_world(p);
    let valid: Vec<bool> = (0..n).map(|i| i != nodes[0] && i != nodes[5]).collect();
    let masked = plain.clone().with_validity(ValidityMask::new(valid.clone())).unwrap();
    let mut scrambled = masked.clone();
    for bad in [nodes[0], nodes[5]] {
        let v: Vec<f32> = scrambled.node(bad).iter().map(|x| x + 5.0).collect();
        scrambled.set_node(bad, &v).unwrap();
    }
    let a = masked.irradiance_reference(p, nn);
    assert_eq!(a, scrambled.irradiance_reference(p, nn), "invalid corners' values leaked into the lookup");
    // The renormalised weights: each valid corner's own irradiance, weighted w / Σ_valid w.
    let wsum: f64 = (0..8).filter(|&c| valid[nodes[c]]).map(|c| w[c]).sum();
    let mut want = [0.0; 3];
    for c in (0..8).filter(|&c| valid[nodes[c]]) {
        let corner = grid.node_coords(nodes[c]);
        let ec = plain.irradiance_reference(grid.node_position_world(corner[0], corner[1], corner[2]), nn);
        for ch in 0..3 {
            want[ch] += w[c] / wsum * ec[ch];
        }
    }
    let fast = masked.irradiance(p.map(|v| v as f32), nn.map(|v| v as f32));
    for ch in 0..3 {
        // Sums of 8 × 9 products of O(1) numbers, in another order: a few ulps of ~10.
        assert!((a[ch] - want[ch]).abs() < 1e-12, "{a:?} vs {want:?}");
        // f32 weights and coefficients of O(1), 27-term sums (the volume crate's bound).
        assert!((f64::from(fast[ch]) - a[ch]).abs() < 1e-4, "{fast:?} vs {a:?}");
    }
}

/// The four baselines baked on a grid around the closed box, whose centre node sees only
/// back faces: `point+validity` and `point+vlm` invalidate it where it stands, `point+apv`
/// moves its capture point out of the box (and attaches the mask), `point+ddgi` relocates it
/// by at most 0.45 × spacing per axis and invalidates nothing; outside nodes stay valid and
/// in place for all four.
#[test]
fn baselines_treat_a_probe_inside_a_closed_box() {
    let mut scene = closed_box();
    scene.environment = lightvol_scene::Environment::UniformSky { sky: [1.0; 3], ground: Some([0.5; 3]) };
    let tracer = Tracer::new(&scene);
    let t = Transport::new(&scene, &tracer, lightvol_scene::TransportSettings::default());
    // Spacing 1: the centre node (1, 1, 1) sits at the box's centre, 0.5 from every wall,
    // beyond APV's search (0.2 × spacing) and DDGI's reach (0.45 × spacing per axis): APV
    // leaves it where it is, DDGI moves it towards a wall but not out. The other 26 nodes
    // are outside the box.
    let grid = GridSpec::new([-1.0; 3], [1.0; 3], [3, 3, 3]).unwrap();
    let centre = grid.node_index(1, 1, 1);
    let settings =
        BakeSettings { method: crate::Method::Point, samples: samples(16), ..BakeSettings::default() };
    let spacing = 1.0;
    for b in Baseline::ALL {
        let bake = bake_baseline(&t, &grid, &settings, b).unwrap();
        assert_eq!(bake.volume.validity().is_some(), b == Baseline::Apv, "{}", b.name());
        for node in (0..grid.node_count()).filter(|&i| i != centre) {
            assert!(bake.valid[node], "{}: outside node {node} invalid", b.name());
            let [i, j, k] = grid.node_coords(node);
            assert_eq!(
                bake.capture[node],
                DVec3::from_array(grid.node_position_world(i, j, k)),
                "{}",
                b.name()
            );
        }
        let moved = bake.capture[centre];
        match b {
            Baseline::Validity | Baseline::Vlm => {
                assert!(!bake.valid[centre]);
                assert_eq!(moved, DVec3::ZERO);
                assert_eq!(bake.filled, 1, "the centre is filled from its 26 valid neighbours");
                assert_eq!(bake.volume.weights()[centre], 0.0);
            }
            Baseline::Apv => {
                // The nearest wall is 0.5 away, beyond the 0.2 search: no offset, invalid.
                assert_eq!(moved, DVec3::ZERO);
                assert!(!bake.valid[centre]);
                assert!(!bake.volume.validity().unwrap().is_valid(centre));
                assert_eq!(bake.volume.validity().unwrap().invalid_count(), 1);
            }
            Baseline::Ddgi => {
                assert!(bake.valid[centre], "DDGI relocates instead of invalidating");
                let off = moved - DVec3::ZERO;
                assert!(off.length() > 0.0, "the centre probe was not relocated");
                assert!(off.abs().max_element() <= DDGI_MAX_OFFSET * spacing + 1e-12, "{off}");
            }
        }
        assert_eq!(bake.invalid_nodes(), usize::from(b != Baseline::Ddgi));
        assert_eq!(bake.moved_nodes(&grid), usize::from(b == Baseline::Ddgi));
    }
    // A grid whose centre node is 0.15 × spacing from a wall: APV's virtual offset (search
    // 0.2 × spacing) takes the capture point out of the box, where it is valid.
    let near = GridSpec::new([-1.0, -1.0, -0.35 - 2.0], [1.0, 1.0, -0.35 + 2.0], [3, 3, 3]).unwrap();
    // Spacing: x, y 1; z 2. The centre node (0, 0, -0.35) is 0.15 from the bottom wall
    // z = -0.5; the smallest spacing is 1, so the search reaches 0.2.
    let bake = bake_baseline(&t, &near, &settings, Baseline::Apv).unwrap();
    let c = near.node_index(1, 1, 1);
    let moved = bake.capture[c];
    assert!(moved.z < -0.5, "{moved} still inside the box");
    assert!(bake.valid[c], "the offset capture point sees back faces");
    assert!(bake.volume.validity().unwrap().is_valid(c));
    assert_eq!(bake.moved_nodes(&near), 1);
    assert_eq!(probe_rays(&tracer, moved, 1, 7).back_fraction, 0.0);
}
