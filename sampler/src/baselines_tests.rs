//! The engine baselines' mechanisms: virtual offset and relocation on a closed box, the
//! fills against their definitions, validity-weighted lookups.

use super::*;
use crate::scene::{Material, SceneBuilder};
use glam::DVec2;

/// A closed unit box `[-0.5, 0.5]³`, faces outward, single-sided.
fn closed_box() -> crate::Scene {
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

/// Validity-weighted lookups: with every corner valid they are the plain trilinear lookup;
/// with invalid corners, those corners' values do not matter, and the valid corners'
/// weights are renormalised.
#[test]
fn validity_weighted_lookups_ignore_invalid_corners() {
    let grid = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
    let n = grid.node_count();
    let data: Vec<f32> = (0..n * 27).map(|i| ((i * 53 % 97) as f32) * 0.01).collect();
    let vol = IrradianceVolume::new(grid.clone(), 9, data.clone(), vec![1.0; n]).unwrap();
    let all = vec![true; n];
    let (p, nn) = ([0.7, 1.3, 0.4], [0.0, 0.6, 0.8]);
    let plain = vol.irradiance_reference(p, nn);
    let e = validity_weighted_irradiance(&vol, &all, p, nn);
    for c in 0..3 {
        assert!((e[c] - plain[c]).abs() < 1e-12);
    }
    // Invalidate two corners of the point's cell and scramble their coefficients.
    let (nodes, w) = grid.trilinear_world(p);
    let mut valid = all.clone();
    valid[nodes[0]] = false;
    valid[nodes[5]] = false;
    let mut scrambled = data;
    for &bad in &[nodes[0], nodes[5]] {
        for v in &mut scrambled[bad * 27..(bad + 1) * 27] {
            *v += 5.0;
        }
    }
    let vol2 = IrradianceVolume::new(grid, 9, scrambled, vec![1.0; n]).unwrap();
    let a = validity_weighted_irradiance(&vol, &valid, p, nn);
    let b = validity_weighted_irradiance(&vol2, &valid, p, nn);
    assert_eq!(a, b, "invalid corners' values leaked into the lookup");
    // The renormalised weights, by hand: each valid corner's own irradiance.
    let wsum: f64 = (0..8).filter(|&c| valid[nodes[c]]).map(|c| w[c]).sum();
    let mut want = [0.0; 3];
    for c in (0..8).filter(|&c| valid[nodes[c]]) {
        let corner = vol.spec().node_coords(nodes[c]);
        let at = vol.spec().node_position_world(corner[0], corner[1], corner[2]);
        let ec = vol.irradiance_reference(at, nn);
        for ch in 0..3 {
            want[ch] += w[c] / wsum * ec[ch];
        }
    }
    for ch in 0..3 {
        assert!((a[ch] - want[ch]).abs() < 1e-12, "{a:?} vs {want:?}");
    }
}
