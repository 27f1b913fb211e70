// What every lightvol sampling source shares (src/engine_shader.rs and src/brick_shader.rs
// prepend the generated constants): lightvol-sh's basis and the trilinear corner weights.

// Real orthonormal SH, 4 bands, flat index l (l + 1) + m, no Condon-Shortley phase:
// Q_l^m = a(l, m) z Q_{l-1}^m + b(l, m) Q_{l-2}^m, Q_m^m = diag[m],
// Y_{l,+-m} = Q_l^m (Re | Im)(x + i y)^m.
fn lightvol_sh_basis(n: vec3<f32>) -> array<f32, 16> {
    var sh_a = LIGHTVOL_SH_A;
    var sh_b = LIGHTVOL_SH_B;
    var sh_diag = LIGHTVOL_SH_DIAG;
    var y: array<f32, 16>;
    var c = 1.0;
    var s = 0.0;
    for (var m = 0u; m < 4u; m++) {
        if m > 0u {
            let cn = n.x * c - n.y * s;
            let sn = n.x * s + n.y * c;
            c = cn;
            s = sn;
        }
        var q_prev2 = 0.0;
        var q_prev = sh_diag[m];
        for (var l = m; l < 4u; l++) {
            var q = q_prev;
            if l > m {
                let idx = l * (l + 1u) + m;
                q = sh_a[idx] * n.z * q_prev + sh_b[idx] * q_prev2;
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

// Trilinear corner weights (Kontkanen & Laine 2006, Eq. 2) at fraction f of the cell,
// corner k = dx + 2 dy + 4 dz.
fn lightvol_corner_weights(f: vec3<f32>) -> array<f32, 8> {
    var w: array<f32, 8>;
    for (var k = 0u; k < 8u; k++) {
        let d = vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
        let t = select(vec3<f32>(1.0) - f, f, d == vec3<u32>(1u));
        w[k] = t.x * t.y * t.z;
    }
    return w;
}

