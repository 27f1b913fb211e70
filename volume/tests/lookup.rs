//! The lookup is exact for linear fields, its weights sum to
//! one, the batched path equals the scalar path bit for bit (any thread count), and the
//! irradiance at a node equals lightvol-sh's irradiance of that node's coefficients.

use lightvol_sh::coeffs::{Sh, ShRgb};
use lightvol_sh::irradiance::irradiance_rgb;
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::{GridSpec, IrradianceVolume, Placement};

/// f64 interpolation of a linear field with exactly representable node values: only the
/// rounding of ~30 products and sums of O(10) numbers remains.
const LINEAR_F64_TOL: f64 = 1e-12;
/// The f32 path rounds the grid coordinate (relative 2^-24 of up to ~10 cell units, i.e.
/// ~1e-6 of a cell) and then sums 8 weighted values of magnitude up to ~40: a few 1e-5
/// absolute; 1e-4 leaves margin without hiding a wrong weight (which errs by O(1)).
const LINEAR_F32_TOL: f64 = 1e-4;
/// f32 SH basis evaluation and 27-term sums against f64: relative 1e-5 of the magnitude.
const F32_VS_F64_REL: f64 = 1e-5;

fn grid() -> GridSpec {
    // Cell size 0.5 on every axis: node positions are exact binary fractions.
    GridSpec::new([-2.0, 0.0, 1.0], [1.0, 2.0, 3.5], [7, 5, 6]).unwrap()
}

/// Coefficient `(j, ch)` of the linear test field at point `x`.
fn linear(j: usize, ch: usize, x: [f64; 3]) -> f64 {
    let a = (j as f64) - 4.0 + ch as f64;
    let b = [1.0 + (j % 3) as f64, -2.0 + ch as f64, (j % 5) as f64 - 1.0];
    a + b[0] * x[0] + b[1] * x[1] + b[2] * x[2]
}

fn linear_volume(coeffs: usize, spec: GridSpec) -> IrradianceVolume {
    let n = spec.node_count();
    let mut data = Vec::with_capacity(n * coeffs * 3);
    for node in 0..n {
        let [i, j, k] = spec.node_coords(node);
        let x = spec.node_position(i, j, k);
        for jj in 0..coeffs {
            for ch in 0..3 {
                data.push(linear(jj, ch, x) as f32);
            }
        }
    }
    IrradianceVolume::new(spec, coeffs, data, vec![1.0; n]).unwrap()
}

fn random_points(n: usize, seed: u64, lo: [f64; 3], hi: [f64; 3]) -> Vec<[f64; 3]> {
    let mut rng = SplitMix64::new(seed);
    (0..n).map(|_| std::array::from_fn(|a| rng.range(lo[a], hi[a]))).collect()
}

#[test]
fn lookup_is_exact_for_linear_fields() {
    for coeffs in [4, 9, 16] {
        let vol = linear_volume(coeffs, grid());
        let (lo, hi) = vol.spec().bounds();
        // Points inside and outside the box (outside clamps).
        for p in random_points(500, 17 + coeffs as u64, [-3.0, -1.0, 0.0], [2.0, 3.0, 4.5]) {
            let pc: [f64; 3] = std::array::from_fn(|a| p[a].clamp(lo[a], hi[a]));
            let reference = vol.coeffs_reference(p);
            let pf = p.map(|v| v as f32);
            let pfc: [f64; 3] = std::array::from_fn(|a| f64::from(pf[a]).clamp(lo[a], hi[a]));
            let mut fast = vec![0.0f32; coeffs * 3];
            vol.coeffs_at(pf, &mut fast);
            for j in 0..coeffs {
                for ch in 0..3 {
                    let want = linear(j, ch, pc);
                    let got = reference[3 * j + ch];
                    assert!((got - want).abs() <= LINEAR_F64_TOL * (1.0 + want.abs()), "{got} vs {want}");
                    let want32 = linear(j, ch, pfc);
                    let got32 = f64::from(fast[3 * j + ch]);
                    assert!((got32 - want32).abs() <= LINEAR_F32_TOL, "f32 {got32} vs {want32}");
                }
            }
        }
    }
}

#[test]
fn trilinear_weights_sum_to_one() {
    let spec = grid().with_placement(
        Placement::new([[0.0, 1.5, 0.0, 3.0], [-1.0, 0.0, 0.0, 0.0], [0.2, 0.0, 2.0, -1.0]]).unwrap(),
    );
    for p in random_points(2000, 5, [-10.0; 3], [10.0; 3]) {
        let (_, w) = spec.trilinear_world(p);
        let s: f64 = w.iter().sum();
        // Sum of 8 products of three numbers in [0, 1]: a few ulps.
        assert!((s - 1.0).abs() <= 8.0 * f64::EPSILON, "{s}");
        assert!(w.iter().all(|&x| x >= 0.0));
    }
}

fn random_volume(coeffs: usize, spec: GridSpec, seed: u64) -> IrradianceVolume {
    let mut rng = SplitMix64::new(seed);
    let n = spec.node_count();
    let data = (0..n * coeffs * 3).map(|_| rng.range(-1.0, 1.0) as f32).collect();
    IrradianceVolume::new(spec, coeffs, data, vec![1.0; n]).unwrap()
}

fn queries(n: usize, seed: u64, lo: [f64; 3], hi: [f64; 3]) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut rng = SplitMix64::new(seed);
    let pts = (0..n).map(|_| std::array::from_fn(|a| rng.range(lo[a], hi[a]) as f32)).collect();
    let dirs =
        (0..n).map(|_| sample_uniform_sphere([rng.next_f64(), rng.next_f64()]).map(|v| v as f32)).collect();
    (pts, dirs)
}

#[test]
fn batched_equals_scalar_bit_for_bit() {
    let placed = grid().with_placement(
        Placement::new([[0.0, 1.5, 0.0, 3.0], [-1.0, 0.0, 0.0, 0.0], [0.2, 0.0, 2.0, -1.0]]).unwrap(),
    );
    for (spec, coeffs) in [(grid(), 4), (grid(), 9), (grid(), 16), (placed, 9)] {
        let vol = random_volume(coeffs, spec, 99);
        // 5001 queries: several parallel chunks and a ragged last SIMD block; some outside.
        let (pts, dirs) = queries(5001, 3, [-4.0, -2.0, -2.0], [4.0, 4.0, 6.0]);
        let scalar_e: Vec<[f32; 3]> = pts.iter().zip(&dirs).map(|(p, n)| vol.irradiance(*p, *n)).collect();
        let scalar_l: Vec<[f32; 3]> = pts.iter().zip(&dirs).map(|(p, n)| vol.radiance(*p, *n)).collect();
        let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut e = vec![[0.0; 3]; pts.len()];
            let mut l = vec![[0.0; 3]; pts.len()];
            pool.install(|| {
                vol.irradiance_batch(&pts, &dirs, &mut e).unwrap();
                vol.radiance_batch(&pts, &dirs, &mut l).unwrap();
            });
            assert_eq!(bits(&e), bits(&scalar_e), "irradiance, {threads} threads, {coeffs} coeffs");
            assert_eq!(bits(&l), bits(&scalar_l), "radiance, {threads} threads");
        }
        let mut e = vec![[0.0; 3]; pts.len()];
        vol.irradiance_batch_serial(&pts, &dirs, &mut e).unwrap();
        assert_eq!(bits(&e), bits(&scalar_e));
        assert!(vol.irradiance_batch(&pts, &dirs[1..], &mut e).is_err());
    }
}

#[test]
fn scalar_f32_path_matches_algorithm_1_reference() {
    for coeffs in [4, 9, 16] {
        let vol = random_volume(coeffs, grid(), 7);
        let (pts, dirs) = queries(1000, 8, [-2.5, -0.5, 0.5], [1.5, 2.5, 4.0]);
        for (p, n) in pts.iter().zip(&dirs) {
            let pd = p.map(f64::from);
            let nd = n.map(f64::from);
            for (fast, slow) in [
                (vol.irradiance(*p, *n), vol.irradiance_reference(pd, nd)),
                (vol.radiance(*p, *n), vol.radiance_reference(pd, nd)),
            ] {
                // Coefficients are O(1) and there are up to 16 of them times basis values
                // O(1): the magnitude scale is ~10.
                for ch in 0..3 {
                    assert!(
                        (f64::from(fast[ch]) - slow[ch]).abs() <= F32_VS_F64_REL * 10.0 * (coeffs as f64),
                        "{fast:?} vs {slow:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn non_finite_queries_clamp_instead_of_panicking() {
    let vol = random_volume(9, grid(), 3);
    let (lo, _) = vol.spec().bounds();
    let lo32 = lo.map(|v| v as f32);
    // NaN coordinates are treated as the box minimum on that axis, infinities clamp.
    let at_min = vol.irradiance(lo32, [0.0, 0.0, 1.0]);
    assert_eq!(vol.irradiance([f32::NAN, lo32[1], lo32[2]], [0.0, 0.0, 1.0]), at_min);
    assert_eq!(vol.irradiance([f32::NEG_INFINITY, lo32[1], f32::NAN], [0.0, 0.0, 1.0]), at_min);
    let e = vol.irradiance([f32::INFINITY; 3], [1.0, 0.0, 0.0]);
    assert!(e.iter().all(|v| v.is_finite()));
}

#[test]
fn radiance_at_a_node_is_the_sh_expansion() {
    let vol = random_volume(16, grid(), 8);
    let spec = vol.spec().clone();
    let node = spec.node_index(3, 2, 1);
    let x = spec.node_position_world(3, 2, 1);
    let sh: ShRgb<f64, 16> = vol.node_sh::<16>(node).unwrap().cast();
    assert!(vol.node_sh::<9>(node).is_err());
    // Interpolated SH at the node equals the node's SH (weight 1 there, exactly).
    assert_eq!(vol.sh_at::<16>(x.map(|v| v as f32)).unwrap(), vol.node_sh::<16>(node).unwrap());
    let mut rng = SplitMix64::new(2);
    for _ in 0..50 {
        let d = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        let want = sh.eval(d);
        let got = vol.radiance_reference(x, d);
        let fast = vol.radiance(x.map(|v| v as f32), d.map(|v| v as f32));
        for ch in 0..3 {
            assert!((got[ch] - want[ch]).abs() <= 1e-13);
            assert!((f64::from(fast[ch]) - want[ch]).abs() <= F32_VS_F64_REL * 16.0);
        }
    }
}

#[test]
fn irradiance_at_a_node_agrees_with_lightvol_sh() {
    let vol = random_volume(9, grid(), 21);
    let spec = vol.spec().clone();
    let mut rng = SplitMix64::new(4);
    for node in [0, 17, 100, spec.node_count() - 1] {
        let [i, j, k] = spec.node_coords(node);
        let x = spec.node_position_world(i, j, k);
        let sh: ShRgb<f64, 9> = ShRgb(std::array::from_fn(|ch| {
            Sh(std::array::from_fn(|c| f64::from(vol.coeff_rgb(node, c)[ch])))
        }));
        for _ in 0..50 {
            let n = sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let want = irradiance_rgb(&sh, n);
            let slow = vol.irradiance_reference(x, n);
            let fast = vol.irradiance(x.map(|v| v as f32), n.map(|v| v as f32));
            for ch in 0..3 {
                // The reference at a node has one weight 1 and seven 0: only summation
                // order differs from lightvol-sh.
                assert!((slow[ch] - want[ch]).abs() <= 1e-13, "{} vs {}", slow[ch], want[ch]);
                assert!(
                    (f64::from(fast[ch]) - want[ch]).abs() <= F32_VS_F64_REL * 10.0,
                    "{fast:?} vs {want:?}"
                );
            }
        }
    }
}
