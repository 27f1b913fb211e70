//! Tests of the two gradient estimators: convergence to the exact gradient on analytic
//! fields and on a scene.

use super::*;
use lightvol_core::samples::samples;
use lightvol_scene::builder::SceneBuilder;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::lights::Environment;
use lightvol_scene::material::Material;
use lightvol_scene::transport::TransportSettings;
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::quadrature::SphereQuadrature;
use lightvol_volume::grid::Placement;

/// A smooth analytic radiance field, polynomial of degree ≤ 2 in ω (so 9 SH coefficients
/// hold it exactly and a degree-4 quadrature projects it exactly), smooth in x.
fn field(x: DVec3, w: DVec3) -> [f64; 3] {
    let a = 2.0 + 0.5 * (0.8 * x.x + 0.3).sin() * (0.5 * x.y).cos();
    let b = 0.4 * x.z + 0.3 * (0.6 * x.y).sin();
    let c = 0.2 * x.x * x.y - 0.1 * x.z * x.z;
    let v = a + b * w.z + c * w.x * w.y + 0.25 * (0.7 * x.z).cos() * w.x;
    [v, 0.5 * v, 0.25 * v + 0.1]
}

/// The exact coefficients `∫ L(x, ω) Y_j(ω) dω` of [`field`] (9 per channel, `[coeff][rgb]`).
fn exact_coeffs(q: &SphereQuadrature, x: DVec3) -> Vec<f64> {
    let mut out = vec![0.0; 27];
    let mut y = [0.0; 9];
    for n in q.nodes() {
        eval_into(3, n.dir, &mut y);
        let l = field(x, DVec3::from_array(n.dir));
        for m in 0..27 {
            out[m] += n.weight * l[m % 3] * y[m / 3];
        }
    }
    out
}

/// Step of the finite-difference gradient of the exact field: truncation `h² f'''/6 ~ 1e-9`,
/// cancellation `1e-16 · 10 / h ~ 1e-11`.
const FD_STEP: f64 = 1e-4;

/// The finite-difference gradient of the exact field, `[coeff][rgb][xyz]`.
fn exact_gradient(q: &SphereQuadrature, x: DVec3) -> Vec<f64> {
    let mut g = vec![0.0; 81];
    for a in 0..3 {
        let e = DVec3::from_array(std::array::from_fn(|b| if a == b { FD_STEP } else { 0.0 }));
        let (p, m) = (exact_coeffs(q, x + e), exact_coeffs(q, x - e));
        for c in 0..27 {
            g[3 * c + a] = (p[c] - m[c]) / (2.0 * FD_STEP);
        }
    }
    g
}

fn node_pos(grid: &GridSpec, node: usize) -> DVec3 {
    let [i, j, k] = grid.node_coords(node);
    DVec3::from_array(grid.node_position_world(i, j, k))
}

fn interior(grid: &GridSpec, node: usize) -> bool {
    let c = grid.node_coords(node);
    (0..3).all(|a| c[a] > 0 && c[a] + 1 < grid.res()[a])
}

/// Largest |estimate − exact| over the chosen nodes, and the largest |exact| (scale).
fn max_error(grid: &GridSpec, est: &[f32], pick: impl Fn(usize) -> bool) -> (f64, f64) {
    let q = SphereQuadrature::exact_for_degree(4);
    let (mut err, mut scale) = (0.0f64, 0.0f64);
    for node in (0..grid.node_count()).filter(|&n| pick(n)) {
        let g = exact_gradient(&q, node_pos(grid, node));
        for (m, gv) in g.iter().enumerate() {
            err = err.max((f64::from(est[node * 81 + m]) - gv).abs());
            scale = scale.max(gv.abs());
        }
    }
    (err, scale)
}

/// Estimator (a): central differences of QMC point projections (common random
/// numbers, h = Δ/16) converge to the finite-difference gradient of the exact field as the
/// direction count grows. Measured max abs error over all 27 nodes and 81 components
/// (largest component 1.355): 1.6e-1, 8.3e-3, 5.6e-4 at 64, 1024, 16384 directions.
#[test]
fn central_differences_converge_on_analytic_field() {
    let grid = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
    let h = default_offset(&grid);
    assert!((h - 1.0 / 16.0).abs() < 1e-15);
    let mut errs = Vec::new();
    for samples in [64u32, 1024, 16384] {
        let g = central_differences(&grid, 9, h, |node, x| {
            point_projection_field(&field, x, 9, samples, 3, hash2(node as u64, GRADIENT_STREAM))
        });
        let (err, scale) = max_error(&grid, &g, |_| true);
        eprintln!("central differences, {samples:>5} directions: max error {err:.3e} (scale {scale:.3})");
        errs.push(err / scale);
    }
    // Each 16x more directions cuts the QMC error by more than 4x (MC would give 4x).
    assert!(errs[1] < errs[0] / 4.0 && errs[2] < errs[1] / 4.0, "{errs:?}");
    // Stated error at 16384 directions: 0.5% of the largest gradient component.
    const CD_REL_ERROR: f64 = 5e-3;
    assert!(errs[2] < CD_REL_ERROR, "{errs:?}");
}

/// Estimator (b) fed the exact directional integral `f_s = C(x_s)` at the bake's QMC
/// positions (`positions` per cell): the limit of the bake's estimator as its per-sample
/// direction noise averages out. Returns the gradient array.
fn basis_direction_exact(grid: &GridSpec, positions: u32, seed: u64) -> Vec<f32> {
    let q = SphereQuadrature::exact_for_degree(4);
    let mut gacc = BasisGradientAccumulator::new(grid, 9);
    for cell in 0..grid.cell_count() {
        let (lo, hi) = grid.cell_bounds(cell);
        let h = Qmc::<5>::new(seed, cell as u64);
        for s in 0..u64::from(positions) {
            let p = h.point(s);
            let g: [f64; 3] = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * p[a]);
            let f = exact_coeffs(&q, DVec3::from_array(grid.to_world(g)));
            gacc.add_sample(
                grid.cell_corners(cell),
                lightvol_volume::grid::corner_weights([p[0], p[1], p[2]]),
                &f,
            );
        }
    }
    let vol = IrradianceVolume::zeros(grid.clone(), 9).unwrap();
    let (g, report) = gacc.finish(&vol).unwrap();
    assert_eq!(report.singular, 0);
    g.data().to_vec()
}

/// Estimator (b), in its two parts. (i) Bias: with the directions integrated
/// exactly, the estimate (a `b_i`-weighted support average of the gradient) converges to the
/// finite-difference gradient of the exact field at interior nodes like O(Δ²). (ii) Noise:
/// on a fixed grid the bake's single-direction samples converge to that limit as the samples
/// per cell grow (noise ∝ 1/(Δ √S), so finer grids need many more samples). Numbers are
/// printed with `--nocapture`.
#[test]
fn basis_gradients_converge_on_analytic_field() {
    let (mut centre, mut inner, mut all) = (Vec::new(), Vec::new(), Vec::new());
    for res in [3u32, 5, 9] {
        let grid = GridSpec::new([0.0; 3], [2.0; 3], [res; 3]).unwrap();
        let g = basis_direction_exact(&grid, 1024, 5);
        let mid = (res - 1) / 2;
        let (err_c, _) = max_error(&grid, &g, |n| grid.node_coords(n) == [mid; 3]);
        let (err_in, scale) = max_error(&grid, &g, |n| interior(&grid, n));
        let (err_all, _) = max_error(&grid, &g, |_| true);
        eprintln!(
            "basis gradients, exact directions, cell {:.3}: centre node error {err_c:.3e}, interior max {err_in:.3e}, all nodes {err_all:.3e} (scale {scale:.3})",
            2.0 / f64::from(res - 1)
        );
        centre.push(err_c);
        inner.push(err_in / scale);
        all.push(err_all);
    }
    // O(Δ²) at the centre node (the same point on every grid): halving the cell cuts the
    // error by more than 3x.
    assert!(centre[1] < centre[0] / 3.0 && centre[2] < centre[1] / 3.0, "{centre:?}");
    // O(Δ) on the boundary (one-sided supports): halving the cell about halves the error.
    assert!(all.windows(2).all(|w| (1.7..2.3).contains(&(w[0] / w[1]))), "{all:?}");
    // Stated bias at Δ = 0.25: below 1% of the largest gradient component at interior nodes.
    const BASIS_BIAS_REL: f64 = 1e-2;
    assert!(inner[2] < BASIS_BIAS_REL, "{inner:?}");

    // (ii) Δ = 0.5: the bake's estimator against its direction-exact limit (same positions).
    let grid = GridSpec::new([0.0; 3], [2.0; 3], [5; 3]).unwrap();
    let limit = basis_direction_exact(&grid, 1024, 5);
    let mut noise = Vec::new();
    for samples in [256u32, 4096, 65536] {
        let (acc, gacc) = bake_field_with_gradients(&field, &grid, 9, samples, 5).unwrap();
        let (vol, _) = acc.finalize();
        let (g, _) = gacc.finish(&vol).unwrap();
        let to_limit = g.data().iter().zip(&limit).map(|(a, b)| f64::from(a - b).abs()).fold(0.0, f64::max);
        let (err_in, scale) = max_error(&grid, g.data(), |n| interior(&grid, n));
        eprintln!(
            "basis gradients, bake samples, cell 0.5, {samples:>5}/cell: max |est - limit| {to_limit:.3e}, interior error vs exact {err_in:.3e} (scale {scale:.3})"
        );
        noise.push(to_limit);
    }
    // 16x the samples: the noise falls by more than 3x each time (MC would give 4x).
    assert!(noise[1] < noise[0] / 3.0 && noise[2] < noise[1] / 3.0, "{noise:?}");
}

/// The basis-gradient system is exact for linear fields on any 3D-spanning sample subset:
/// here samples are dropped on one side of a tilted plane (a domain-of-interest cut through
/// the supports), under a rotated, scaled placement.
#[test]
fn basis_gradients_exact_for_linear_fields_on_cut_supports() {
    let placement =
        Placement::new([[0.0, -1.2, 0.0, 1.0], [0.9, 0.0, 0.3, -2.0], [0.0, 0.0, 1.1, 0.5]]).unwrap();
    let grid = GridSpec::new([0.0; 3], [3.0, 2.0, 2.0], [4, 3, 3]).unwrap().with_placement(placement);
    let mut r = SplitMix64::new(9);
    let a: Vec<f64> = (0..12).map(|_| r.range(-1.0, 1.0)).collect();
    let gw: Vec<[f64; 3]> =
        (0..12).map(|_| [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)]).collect();
    let lin = |x: DVec3| -> Vec<f64> { (0..12).map(|m| a[m] + DVec3::from_array(gw[m]).dot(x)).collect() };
    let mut gacc = BasisGradientAccumulator::new(&grid, 4);
    let mut kept = 0;
    for cell in 0..grid.cell_count() {
        let (lo, hi) = grid.cell_bounds(cell);
        for _ in 0..64 {
            let u: [f64; 3] = std::array::from_fn(|_| r.next_f64());
            let g: [f64; 3] = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * u[a]);
            if g[0] + 0.5 * g[1] - 0.7 * g[2] > 2.2 {
                continue; // outside the "domain"
            }
            kept += 1;
            let x = DVec3::from_array(grid.to_world(g));
            gacc.add_sample(grid.cell_corners(cell), lightvol_volume::grid::corner_weights(u), &lin(x));
        }
    }
    assert!(kept > 500 && kept < 64 * grid.cell_count());
    let vol = IrradianceVolume::zeros(grid.clone(), 4).unwrap();
    let (g, report) = gacc.finish(&vol).unwrap();
    // Nodes whose whole support lies outside have no samples: singular, zero gradient.
    assert!(report.solved > 0 && report.solved + report.singular == grid.node_count());
    /// f64 solve of a well-conditioned 4x4 system, result stored as f32 (6e-8 relative).
    const LINEAR_TOL: f64 = 1e-6;
    for node in 0..grid.node_count() {
        if g.node(node).iter().all(|&v| v == 0.0) {
            continue;
        }
        for m in 0..12 {
            let got = g.gradient(node, m / 3, m % 3);
            for k in 0..3 {
                assert!((got[k] - gw[m][k]).abs() < LINEAR_TOL, "node {node} m {m}: {got:?} vs {:?}", gw[m]);
            }
        }
    }
}

/// Solid angle of the plate `[-1, 1]² × {1}` seen from `p` (below it): the rectangle formula
/// `Ω = F(x₂, y₂) − F(x₁, y₂) − F(x₂, y₁) + F(x₁, y₁)`, `F(a, b) = atan(a b / (d √(a² + b² + d²)))`.
fn plate_solid_angle(p: DVec3) -> f64 {
    let d = 1.0 - p.z;
    let f = |a: f64, b: f64| (a * b / (d * (a * a + b * b + d * d).sqrt())).atan();
    let (x1, x2, y1, y2) = (-1.0 - p.x, 1.0 - p.x, -1.0 - p.y, 1.0 - p.y);
    f(x2, y2) - f(x1, y2) - f(x2, y1) + f(x1, y1)
}

/// The exact DC coefficient under a unit sky with the black plate: `Y₀ (4π − Ω(p))`.
fn plate_dc(p: DVec3) -> f64 {
    0.5 / std::f64::consts::PI.sqrt() * (4.0 * std::f64::consts::PI - plate_solid_angle(p))
}

/// Both estimators on a scene: a uniform sky (radiance 1) and a single black, single-sided
/// occluding plate 2 m above the compared nodes. Both estimators' DC gradients against the
/// finite-difference gradient of the exact (closed-form solid angle) field, at two sample
/// counts; numbers printed with `--nocapture`. Also: the bake with gradients is
/// bit-identical across thread counts.
#[test]
fn scene_estimators_converge_and_are_deterministic() {
    // The closed form: the plate seen from 1 m straight below subtends 4 atan(1/√3) = 2π/3.
    assert!((plate_solid_angle(DVec3::ZERO) - 2.0 * std::f64::consts::PI / 3.0).abs() < 1e-14);
    let mut b = SceneBuilder::new("plate");
    let m = b.add_material(Material::diffuse("black", [0.0; 3])).unwrap();
    // Facing down (counter-clockwise seen from below): the grid sees its front face.
    b.add_quad(
        [
            DVec3::new(-1.0, -1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, 1.0),
        ],
        m,
    )
    .unwrap();
    b.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
    let scene = b.build().unwrap();
    let tracer = Tracer::new(&scene);
    let t = Transport::new(&scene, &tracer, TransportSettings::default());
    let grid = GridSpec::new([-2.0, -2.0, -1.5], [2.0, 2.0, -0.5], [9, 9, 3]).unwrap();
    let plane: Vec<usize> =
        (0..grid.node_count()).filter(|&n| grid.node_coords(n)[2] == 1 && interior(&grid, n)).collect();
    let exact: Vec<[f64; 3]> = plane
        .iter()
        .map(|&n| {
            let x = node_pos(&grid, n);
            std::array::from_fn(|a| {
                let e = DVec3::from_array(std::array::from_fn(|b| if a == b { FD_STEP } else { 0.0 }));
                (plate_dc(x + e) - plate_dc(x - e)) / (2.0 * FD_STEP)
            })
        })
        .collect();
    let rms = |g: &VolumeGradients| -> f64 {
        let s: f64 = plane
            .iter()
            .zip(&exact)
            .map(|(&n, e)| (0..3).map(|k| (g.gradient(n, 0, 1)[k] - e[k]).powi(2)).sum::<f64>())
            .sum();
        (s / plane.len() as f64).sqrt()
    };
    let scale =
        (exact.iter().map(|e| e.iter().map(|v| v * v).sum::<f64>()).sum::<f64>() / plane.len() as f64).sqrt();
    let (mut basis_err, mut cd_err) = (Vec::new(), Vec::new());
    for count in [1024u32, 8192] {
        let s = BakeSettings {
            method: Method::DoiPaper,
            samples: samples(count),
            seed: 1,
            light_sampling: false,
            ..Default::default()
        };
        let (out, gacc) = bake_with_gradients(&t, &grid, &s, &BakeControl::default()).unwrap();
        let (vol, _) = out.finish();
        let (basis, report) = gacc.finish(&vol).unwrap();
        assert_eq!(report.singular, 0);
        let cd = central_difference_gradients(&t, &grid, &s, default_offset(&grid), &vol).unwrap();
        let (eb, ec) = (rms(&basis), rms(&cd));
        let centre = grid.node_index(4, 4, 1);
        eprintln!(
            "plate, {count:>4} samples: rms DC-gradient error basis {eb:.3e}, central {ec:.3e} (rms exact {scale:.3e}); centre node exact {:.4?} basis {:.4?} central {:.4?}",
            exact[plane.iter().position(|&n| n == centre).unwrap()],
            basis.gradient(centre, 0, 1),
            cd.gradient(centre, 0, 1)
        );
        basis_err.push(eb / scale);
        cd_err.push(ec / scale);
        if count == 1024 {
            let run = |threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| bake_with_gradients(&t, &grid, &s, &BakeControl::default()).unwrap().1)
            };
            assert_eq!(run(1), gacc);
            assert_eq!(run(2), gacc);
        }
    }
    eprintln!("relative rms errors: basis {basis_err:?}, central {cd_err:?}");
    // Both converge: 8x the samples cuts the error by more than 2.5x (MC: 2.8x).
    assert!(basis_err[1] < basis_err[0] / 2.5 && cd_err[1] < cd_err[0] / 2.5, "{basis_err:?} {cd_err:?}");
    // Stated errors at 8192 samples (relative rms over the plane): basis 12%, central 40%
    // (measured 7.8% and 27%). Visibility is binary here, so a central difference flips by
    // 4π Y₀ / (N 2h) per direction that crosses the plate's edge between x − h and x + h:
    // common random numbers do not help at edges, and the small h weighs each flip 1/h.
    const PLATE_BASIS_REL: f64 = 0.12;
    const PLATE_CENTRAL_REL: f64 = 0.4;
    assert!(basis_err[1] < PLATE_BASIS_REL && cd_err[1] < PLATE_CENTRAL_REL);
    // The comparison: at equal samples (per cell for the bake, per projection for the
    // differences, which cost 6 extra projections per node) the basis estimator is closer.
    assert!(basis_err[0] < cd_err[0] && basis_err[1] < cd_err[1]);
}
