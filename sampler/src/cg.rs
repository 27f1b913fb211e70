//! Jacobi-preconditioned conjugate gradients over RGB-interleaved unknowns (`[..][rgb]`),
//! the three channels solved at once with their own steps: the solver of the engine-lookup
//! fit (`target`) and of the noise-weighted smoothing (`denoise`), whose
//! systems are symmetric positive definite and the same for every channel.

/// Relative residual at which conjugate gradients stop: node values are stored as f32
/// (relative precision 6e-8); 1e-7 leaves the solver's error below that of the rounding.
const CG_TOLERANCE: f64 = 1e-7;

/// Iteration cap: a guard against a broken input, far above the few hundred iterations
/// the regularised system needs.
const CG_MAX_ITERATIONS: usize = 2000;

/// Jacobi-preconditioned conjugate gradients on the three channels at once (interleaved
/// `[..][rgb]`, each with its own step), from zero; returns the solution and the
/// iterations of the slowest channel.
pub(crate) fn conjugate_gradient_rgb(
    apply: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    precond: &[f64],
) -> (Vec<f64>, usize) {
    let len = b.len();
    let dot3 = |u: &[f64], v: &[f64]| {
        let mut s = [0.0; 3];
        for i in 0..len {
            s[i % 3] += u[i] * v[i];
        }
        s
    };
    let b_norm = dot3(b, b).map(f64::sqrt);
    let mut x = vec![0.0; len];
    let mut r = b.to_vec();
    let mut z: Vec<f64> = r.iter().zip(precond).map(|(r, m)| r * m).collect();
    let mut p = z.clone();
    let mut rz = dot3(&r, &z);
    let mut ap = vec![0.0; len];
    let mut done = b_norm.map(|n| n == 0.0);
    let mut iterations = 0;
    while !done.iter().all(|&d| d) && iterations < CG_MAX_ITERATIONS {
        apply(&p, &mut ap);
        let pap = dot3(&p, &ap);
        let alpha: [f64; 3] =
            std::array::from_fn(|ch| if done[ch] || !(pap[ch] > 0.0) { 0.0 } else { rz[ch] / pap[ch] });
        for i in 0..len {
            x[i] += alpha[i % 3] * p[i];
            r[i] -= alpha[i % 3] * ap[i];
            z[i] = r[i] * precond[i];
        }
        let rz_new = dot3(&r, &z);
        let rr = dot3(&r, &r);
        for ch in 0..3 {
            if alpha[ch] == 0.0 || rr[ch].sqrt() <= CG_TOLERANCE * b_norm[ch] {
                done[ch] = true;
            }
        }
        let beta: [f64; 3] = std::array::from_fn(|ch| if rz[ch] > 0.0 { rz_new[ch] / rz[ch] } else { 0.0 });
        rz = rz_new;
        for i in 0..len {
            p[i] = z[i] + beta[i % 3] * p[i];
        }
        iterations += 1;
    }
    (x, iterations)
}
