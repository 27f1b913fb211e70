// Kernel 2b: the exponentiation pass ([SGNS07] §4: Eq. 9 SHEXP by HYB,
// [Ren06]; Eq. 12 indirect normalisation) for one receiver per invocation, reading
// the accumulators kernel 2a wrote.
//
// Mirrors `lightvol_proxies::kernel::Kernel::finish` and `Kernel::exp_hyb` operation by
// operation, except the OL coefficients (a, b): lightvol-sh keeps its OL table private, so
// the host samples `OlTable::coefficients` on a uniform grid over the norms HYB feeds it
// ([0, HYB_NORM_THRESHOLD]) and the shader interpolates linearly. The buffer layout is
// documented in src/proxy.rs.

const K_ACC: u32 = COEFFS + 29u;

struct Params {
    // x: receivers, y: squaring-schedule entries, z: product-schedule entries, w: OL samples.
    dims: vec4<u32>,
    // x: smallest f32 above HYB_NORM_THRESHOLD, y: OL sample spacing, z: sqrt(4 pi), w: unused.
    consts: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> params: Params;
// Per receiver 8 floats (kernel 2a's binding 1): only `valid` (word 3) is read.
@group(0) @binding(1) var<storage, read> receivers: array<f32>;
// Kernel 2a's output: per receiver log visibility [COEFFS], indirect [27], omega, count.
@group(0) @binding(2) var<storage, read> accum: array<f32>;
// Per receiver light L(p) [rgb][COEFFS].
@group(0) @binding(3) var<storage, read> light: array<f32>;
// Gaunt schedules, 4 words per entry (i, j, k, value bits): squaring entries (i <= j,
// value doubled off the diagonal), then product entries with k < 9.
@group(0) @binding(4) var<storage, read> schedule: array<u32>;
// OL coefficients (a sqrt(4 pi), b) at norms s * spacing, s = 0 .. samples - 1.
@group(0) @binding(5) var<storage, read> ol: array<f32>;
// Per receiver 54 floats: shadowed O * L [rgb][9], indirect xi I [rgb][9].
@group(0) @binding(6) var<storage, read_write> incident: array<f32>;

fn entry_value(e: u32) -> f32 {
    return bitcast<f32>(schedule[4u * e + 3u]);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let q = gid.x + gid.y * groups.x * 64u;
    if q >= params.dims.x {
        return;
    }
    let ob = 54u * q;
    for (var j = 0u; j < 54u; j++) {
        incident[ob + j] = 0.0;
    }
    if receivers[8u * q + 3u] == 0.0 {
        return;
    }
    let ab = K_ACC * q;
    let lb = 3u * COEFFS * q;
    if accum[ab + COEFFS + 28u] == 0.0 {
        // No proxy: the unshadowed light, bands 0-2.
        for (var c = 0u; c < 3u; c++) {
            for (var j = 0u; j < 9u; j++) {
                incident[ob + 9u * c + j] = light[lb + COEFFS * c + j];
            }
        }
        return;
    }
    let sqrt4pi = params.consts.z;

    // HYB: scale the non-DC part below the threshold, OL, square back up.
    var hat: array<f32, COEFFS>;
    var norm2 = 0.0;
    for (var j = 1u; j < COEFFS; j++) {
        hat[j] = accum[ab + j];
        norm2 = norm2 + hat[j] * hat[j];
    }
    let norm = sqrt(norm2);
    var k = 0u;
    while norm / f32(1u << k) >= params.consts.x && k < 30u {
        k += 1u;
    }
    let s = 1.0 / f32(1u << k);
    let xo = (norm * s) / params.consts.y;
    let io = min(u32(xo), params.dims.w - 2u);
    let to = clamp(xo - f32(io), 0.0, 1.0);
    let a4 = ol[2u * io] + to * (ol[2u * io + 2u] - ol[2u * io]);
    let b = ol[2u * io + 1u] + to * (ol[2u * io + 3u] - ol[2u * io + 1u]);
    var g: array<f32, COEFFS>;
    for (var j = 1u; j < COEFFS; j++) {
        g[j] = hat[j] * s * b;
    }
    g[0] = a4;
    for (var r = 0u; r < k; r++) {
        var h: array<f32, COEFFS>;
        for (var e = 0u; e < params.dims.y; e++) {
            let i = schedule[4u * e];
            let jj = schedule[4u * e + 1u];
            let kk = schedule[4u * e + 2u];
            h[kk] = h[kk] + entry_value(e) * g[i] * g[jj];
        }
        g = h;
    }
    let dc = exp(accum[ab] / sqrt4pi);
    var o: array<f32, COEFFS>;
    for (var j = 0u; j < COEFFS; j++) {
        o[j] = g[j] * dc;
    }

    // Product matrix of O restricted to output bands 0-2: M_kj = sum_i G_ijk O_i.
    var m: array<f32, 144>;
    for (var e = 0u; e < params.dims.z; e++) {
        let x = params.dims.y + e;
        let i = schedule[4u * x];
        let jj = schedule[4u * x + 1u];
        let kk = schedule[4u * x + 2u];
        m[COEFFS * kk + jj] = m[COEFFS * kk + jj] + entry_value(x) * o[i];
    }
    for (var c = 0u; c < 3u; c++) {
        for (var kk = 0u; kk < 9u; kk++) {
            var sum = 0.0;
            for (var j = 0u; j < COEFFS; j++) {
                sum = sum + m[COEFFS * kk + j] * light[lb + COEFFS * c + j];
            }
            incident[ob + 9u * c + kk] = sum;
        }
    }
    let omega = accum[ab + COEFFS + 27u];
    if omega > 0.0 {
        let xi = (sqrt4pi - o[0]) / (omega / sqrt4pi);
        for (var j = 0u; j < 27u; j++) {
            incident[ob + 27u + j] = xi * accum[ab + COEFFS + j];
        }
    }
}
