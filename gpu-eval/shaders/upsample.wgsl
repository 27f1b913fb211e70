// Kernel 2c: bilateral upsampling of the receivers' incident radiance to display resolution
// ([SGNS07] §4.2, Eq. 11), one invocation per display pixel, reading
// kernel 2b's output on the device.
//
// Mirrors `lightvol_proxies::upsample::bilateral_upsample` with K = 27 values
// `O * L + I` per coarse receiver: 2x2 coarse taps with bilinear weights times
// (N_p . N_i)^32 times eps / (eps + |z_p - z_i|), eps = DEPTH_EPS_REL z_p, normalised.
// Pixels whose weights all vanish are flagged (word 27 = 1) for the host's fallback.

struct Params {
    // x, y: coarse width, height; z, w: display width, height.
    dims: vec4<u32>,
    // x: coarse/display width ratio, y: height ratio, z: DEPTH_EPS_REL, w: WEIGHT_FLOOR.
    consts: vec4<f32>,
    // x: f32::MIN_POSITIVE (guards the floor test when no tap has bilinear weight).
    extra: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> params: Params;
// Coarse geometry, 4 floats per receiver: normal xyz, eye depth (infinite: no receiver).
@group(0) @binding(1) var<storage, read> coarse: array<f32>;
// Kernel 2b's output, 54 floats per receiver: shadowed [27], indirect [27].
@group(0) @binding(2) var<storage, read> incident: array<f32>;
// Display geometry, 4 floats per pixel, as binding 1.
@group(0) @binding(3) var<storage, read> fine: array<f32>;
// Output, 28 floats per display pixel: 27 values, fallback flag.
@group(0) @binding(4) var<storage, read_write> result: array<f32>;

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    let cw = params.dims.x;
    let ch = params.dims.y;
    let fw = params.dims.z;
    if i >= fw * params.dims.w {
        return;
    }
    let ob = 28u * i;
    for (var k = 0u; k < 28u; k++) {
        result[ob + k] = 0.0;
    }
    let zp = fine[4u * i + 3u];
    if !finite(zp) {
        return;
    }
    let np = vec3<f32>(fine[4u * i], fine[4u * i + 1u], fine[4u * i + 2u]);
    let x = i % fw;
    let y = i / fw;
    let cx = clamp((f32(x) + 0.5) * params.consts.x - 0.5, 0.0, f32(cw - 1u));
    let cy = clamp((f32(y) + 0.5) * params.consts.y - 0.5, 0.0, f32(ch - 1u));
    let x0 = u32(floor(cx));
    let y0 = u32(floor(cy));
    let x1 = min(x0 + 1u, cw - 1u);
    let y1 = min(y0 + 1u, ch - 1u);
    let fx = cx - f32(x0);
    let fy = cy - f32(y0);
    let eps = params.consts.z * zp;
    var tx = array<u32, 4>(x0, x1, x0, x1);
    var ty = array<u32, 4>(y0, y0, y1, y1);
    var tw = array<f32, 4>((1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy);
    var acc: array<f32, 27>;
    var wsum = 0.0;
    var bsum = 0.0;
    for (var t = 0u; t < 4u; t++) {
        let j = ty[t] * cw + tx[t];
        let zi = coarse[4u * j + 3u];
        if !finite(zi) {
            continue;
        }
        let c = max(np.x * coarse[4u * j] + np.y * coarse[4u * j + 1u] + np.z * coarse[4u * j + 2u], 0.0);
        // c^32 by five squarings.
        let c2 = c * c;
        let c4 = c2 * c2;
        let c8 = c4 * c4;
        let c16 = c8 * c8;
        let c32 = c16 * c16;
        let w = tw[t] * c32 * eps / (eps + abs(zp - zi));
        bsum = bsum + tw[t];
        wsum = wsum + w;
        for (var k = 0u; k < 27u; k++) {
            acc[k] = acc[k] + w * (incident[54u * j + k] + incident[54u * j + 27u + k]);
        }
    }
    if wsum <= params.consts.w * max(bsum, params.extra.x) || wsum == 0.0 {
        result[ob + 27u] = 1.0;
        return;
    }
    for (var k = 0u; k < 27u; k++) {
        result[ob + k] = acc[k] / wsum;
    }
}
