// Kernel 2a: proxy accumulation ([SGNS07] §3-5: Eq. 4 log visibility, Eq. 8
// ZH rotation, Eq. 12 and 15 averaged indirect light) for one receiver per invocation, over
// the proxies binned into the receiver's screen tile.
//
// Mirrors `lightvol_proxies::kernel::Kernel::accumulate` operation by operation: the
// sphere replacement of `lightvol_proxies::proxy::view_f32`, table interpolation linear in
// alpha^2, smooth-clamped tables pre-scaled by sqrt(4 pi / (2l + 1)) (built on the host from
// `lightvol_proxies::tables`), and the same summation order (proxies in tile-list order,
// coefficients ascending). The buffer layout is documented in src/proxy.rs.

const K_OUT: u32 = COEFFS + 29u;

struct Params {
    // x: receiver-buffer width, y: height, z: tile edge (pixels), w: tiles per row.
    dims: vec4<u32>,
    // x: table entries, y: 1 if indirect light is accumulated, z: number of tiles, w: unused.
    misc: vec4<u32>,
    // x: alpha threshold for shadows (1 / eta_shadow), y: for indirect (1 / eta_indirect).
    alphas: vec4<f32>,
    sh_a: array<vec4<f32>, 4>,
    sh_b: array<vec4<f32>, 4>,
    sh_diag: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> params: Params;
// Per receiver 8 floats: position xyz, valid (1 or 0), normal xyz, unused.
@group(0) @binding(1) var<storage, read> receivers: array<f32>;
// Per proxy 4 + 3 COEFFS floats: centre xyz, radius, exit radiance [rgb][COEFFS].
@group(0) @binding(2) var<storage, read> proxies: array<f32>;
// Tables of E entries: O^log [E][4], V [E][4], D [E][4], omega [E], in that order.
@group(0) @binding(3) var<storage, read> tables: array<f32>;
// Tile lists, CSR: offsets [tiles + 1], then proxy indices.
@group(0) @binding(4) var<storage, read> bins: array<u32>;
// Per receiver K_OUT floats: log visibility [COEFFS], indirect [rgb][9], omega, count.
@group(0) @binding(5) var<storage, read_write> accum: array<f32>;

struct View {
    ok: bool,
    dir: vec3<f32>,
    alpha: f32,
}

// `lightvol_proxies::proxy::view_f32`: direction to and alpha = r / d of the proxy, replaced
// by the sphere inside the receiver's upper half-space when it straddles the tangent plane;
// nothing for a radius that is not positive (or NaN, tested explicitly as for d below).
fn view(c0: vec3<f32>, r0: f32, p: vec3<f32>, n: vec3<f32>) -> View {
    var out = View(false, vec3<f32>(0.0, 0.0, 0.0), 0.0);
    let h = (c0.x - p.x) * n.x + (c0.y - p.y) * n.y + (c0.z - p.z) * n.z;
    if !(r0 > 0.0) || is_nan(r0) || h <= -r0 {
        return out;
    }
    var c = c0;
    var r = r0;
    if h < r0 {
        let r2 = 0.5 * (h + r0);
        let s = r2 - h;
        c = vec3<f32>(c0.x + s * n.x, c0.y + s * n.y, c0.z + s * n.z);
        r = r2;
    }
    let v = vec3<f32>(c.x - p.x, c.y - p.y, c.z - p.z);
    let d = sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    if !(d > 0.0) || is_nan(d) {
        return out;
    }
    out.ok = true;
    out.dir = vec3<f32>(v.x / d, v.y / d, v.z / d);
    out.alpha = min(r / d, 1.0);
    return out;
}

fn band(j: u32) -> u32 {
    if j == 0u {
        return 0u;
    }
    if j <= 3u {
        return 1u;
    }
    if j <= 8u {
        return 2u;
    }
    return 3u;
}

// Entry i + t (entry i + 1 - entry i) of the 4-wide table starting at word `base`.
fn lerp4(base: u32, i: u32, t: f32) -> array<f32, 4> {
    var z: array<f32, 4>;
    for (var l = 0u; l < 4u; l++) {
        let a = tables[base + 4u * i + l];
        let b = tables[base + 4u * (i + 1u) + l];
        z[l] = a + t * (b - a);
    }
    return z;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let q = gid.x + gid.y * groups.x * 64u;
    let width = params.dims.x;
    if q >= width * params.dims.y {
        return;
    }
    var log_vis: array<f32, COEFFS>;
    var indirect: array<f32, 27>;
    var omega = 0.0;
    var count = 0u;

    let rb = 8u * q;
    if receivers[rb + 3u] != 0.0 {
        let p = vec3<f32>(receivers[rb], receivers[rb + 1u], receivers[rb + 2u]);
        let n = vec3<f32>(receivers[rb + 4u], receivers[rb + 5u], receivers[rb + 6u]);
        let tile = params.dims.z;
        let x = q % width;
        let y = q / width;
        let t_index = (y / tile) * params.dims.w + x / tile;
        let entries = params.misc.x;
        let indirect_on = params.misc.y != 0u;
        let list_base = params.misc.z + 1u;
        let vis_base = 4u * entries;
        let d_base = 8u * entries;
        let omega_base = 12u * entries;
        let stride = 4u + 3u * COEFFS;
        for (var k = bins[t_index]; k < bins[t_index + 1u]; k++) {
            let pb = stride * bins[list_base + k];
            let vw = view(vec3<f32>(proxies[pb], proxies[pb + 1u], proxies[pb + 2u]), proxies[pb + 3u], p, n);
            if !vw.ok {
                continue;
            }
            let alpha = vw.alpha;
            let shadow = alpha > params.alphas.x;
            let ind = indirect_on && alpha > params.alphas.y;
            if !shadow && !ind {
                continue;
            }
            count += 1u;
            let yb = sh_basis(vw.dir, params.sh_a, params.sh_b, params.sh_diag);
            let xf = alpha * f32(entries - 1u);
            let i = min(u32(xf), entries - 2u);
            // Linear in alpha^2: t = (x^2 - i^2) / (2 i + 1).
            let t = (xf * xf - f32(i * i)) / f32(2u * i + 1u);
            if shadow {
                let z = lerp4(0u, i, t);
                for (var j = 0u; j < COEFFS; j++) {
                    log_vis[j] = log_vis[j] + z[band(j)] * yb[j];
                }
            }
            if ind {
                let v = lerp4(vis_base, i, t);
                let d = lerp4(d_base, i, t);
                let o0 = tables[omega_base + i];
                let o1 = tables[omega_base + i + 1u];
                omega = omega + (o0 + t * (o1 - o0));
                for (var c = 0u; c < 3u; c++) {
                    var kappa = 0.0;
                    for (var j = 0u; j < COEFFS; j++) {
                        kappa = kappa + d[band(j)] * yb[j] * proxies[pb + 4u + COEFFS * c + j];
                    }
                    for (var j = 0u; j < 9u; j++) {
                        indirect[9u * c + j] = indirect[9u * c + j] + kappa * v[band(j)] * yb[j];
                    }
                }
            }
        }
    }
    let ob = K_OUT * q;
    for (var j = 0u; j < COEFFS; j++) {
        accum[ob + j] = log_vis[j];
    }
    for (var j = 0u; j < 27u; j++) {
        accum[ob + COEFFS + j] = indirect[j];
    }
    accum[ob + COEFFS + 27u] = omega;
    // As f32: exact below 2^24 proxies (a bit pattern of a small u32 is a denormal f32,
    // which a driver may flush to zero).
    accum[ob + COEFFS + 28u] = f32(count);
}
