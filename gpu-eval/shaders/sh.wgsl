// Shared helpers, prepended (after the COEFFS / BANDS constants) to every kernel by build.rs.

// NaN test on the bits: Vulkan lets drivers assume floats are never NaN (no
// SignedZeroInfNanPreserve), so `x != x` or `!(x >= 0)` may be folded away; integer
// operations may not.
fn is_nan(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) > 0x7f800000u;
}

fn flat4(a: array<vec4<f32>, 4>, j: u32) -> f32 {
    return a[j / 4u][j % 4u];
}

// Real orthonormal SH (no Condon-Shortley phase, +z polar axis) at unit vector n, flat
// index l (l + 1) + m: lightvol-sh's normalised recurrence
//   Q_l^m = a(l, m) z Q_{l-1}^m + b(l, m) Q_{l-2}^m,  Q_m^m = diag[m],
//   Y_{l,+-m} = Q_l^m (Re | Im)(x + i y)^m,
// with a, b at flat index l (l + 1) + m (computed on the host: `ShRecurrence`). Its twin is
// `lightvol_sh_basis` of the generated engine code (`src/engine_shader.rs`), which carries the
// same constants as literals because engines bind no lightvol uniforms; the device tests hold
// both against the CPU lookups (`tests/lookup.rs`, `tests/engine_shader.rs`).
fn sh_basis(n: vec3<f32>, sh_a: array<vec4<f32>, 4>, sh_b: array<vec4<f32>, 4>, sh_diag: vec4<f32>) -> array<f32, COEFFS> {
    var y: array<f32, COEFFS>;
    var c = 1.0;
    var s = 0.0;
    for (var m = 0u; m < BANDS; m++) {
        if m > 0u {
            // Re and Im of (x + i y)^m.
            let cn = n.x * c - n.y * s;
            let sn = n.x * s + n.y * c;
            c = cn;
            s = sn;
        }
        var q_prev2 = 0.0;
        var q_prev = sh_diag[m];
        for (var l = m; l < BANDS; l++) {
            var q = q_prev;
            if l > m {
                let idx = l * (l + 1u) + m;
                q = flat4(sh_a, idx) * n.z * q_prev + flat4(sh_b, idx) * q_prev2;
                q_prev2 = q_prev;
                q_prev = q;
            }
            let base = l * (l + 1u);
            if m == 0u {
                y[base] = q;
            } else {
                y[base + m] = q * c;
                y[base - m] = q * s;
            }
        }
    }
    return y;
}

