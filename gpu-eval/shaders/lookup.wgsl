// Kernel 1: irradiance-volume lookup (Kontkanen & Laine 2006, Eq. 1-3 and Algorithm 1).
//
// One invocation per query: locate the cell of the world-space point, form the 8 trilinear
// weights b_i(x) (Table 1), interpolate the 3*COEFFS coefficients of the 8 corner nodes
// (Eq. 2), then shade: out = sum_j f_j Y_j(n) L_j(x) with f_j = A_l(j) for irradiance
// (Eq. 3) or 1 for radiance.
//
// The arithmetic mirrors lightvol-volume's f32 scalar path (`lookup.rs`) operation by
// operation and in the same order: clamping, cell index, weights (gx*gy)*gz, corner-by-corner
// accumulation, j-ascending shading. The SH basis is the normalised three-term recurrence of
// lightvol-sh (`eval_recurrence`), with its constants computed on the host in f64 and
// rounded once to f32, as in lightvol-sh's generated code. A Vulkan driver may still fuse
// a*b+c into an FMA, so agreement is to f32 rounding, not bit-exact.
//
// COEFFS (4, 9 or 16) and BANDS (2, 3 or 4) are prepended by build.rs, one SPIR-V module
// per value, together with shaders/sh.wgsl (`sh_basis`, `flat4`, `is_nan`) and
// shaders/weights.wgsl (`lightvol_renormalise`). The buffer
// layouts are documented in src/lookup.rs and README.md.

const K: u32 = 3u * COEFFS;

struct Params {
    // Rows of the world-to-grid affine map (the identity when the volume is not placed).
    to_grid: array<vec4<f32>, 3>,
    // xyz: grid-space box minimum; w: the node reach's test-point offset along the normal.
    grid_min: vec4<f32>,
    // xyz: (n - 1) / (max - min), grid units to cell units; w: the reach's edge limit.
    scale: vec4<f32>,
    // xyz: n - 1 as f32 (the clamp limit in cell units).
    cells: vec4<f32>,
    // xyz: n - 2, the largest cell index; w: flags, 1 validity mask, 2 node reach,
    // 4 irradiance (the reach is tested at the point moved along the normal).
    max_cell: vec4<u32>,
    // x: nx, y: nx * ny, z: 1 if placed (apply to_grid), else 0, w: number of queries.
    dims: vec4<u32>,
    // f_j for j = 4 i + c at factor[i][c]: A_l(j) (irradiance) or 1 (radiance).
    factor: array<vec4<f32>, 4>,
    // Recurrence constants a(l, m), b(l, m) at flat index l (l + 1) + m, m >= 0.
    sh_a: array<vec4<f32>, 4>,
    sh_b: array<vec4<f32>, 4>,
    // Q_m^m for m = 0..3.
    sh_diag: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> params: Params;
// [node][coeff][rgb], f32, exactly lightvol-volume's `IrradianceVolume::data()`.
@group(0) @binding(1) var<storage, read> coeffs: array<f32>;
// Tightly packed xyz triples (no padding): query q is at 3q .. 3q + 2.
@group(0) @binding(2) var<storage, read> points: array<f32>;
@group(0) @binding(3) var<storage, read> dirs: array<f32>;
// Tightly packed RGB triples.
@group(0) @binding(4) var<storage, read_write> result: array<f32>;
// The validity mask: node i is bit i % 32 of word i / 32, 1 = valid (flag 1).
@group(0) @binding(5) var<storage, read> validity: array<u32>;
// The node reach: six f32 per node, +x, -x, +y, -y, +z, -z, in cells (flag 2).
@group(0) @binding(6) var<storage, read> reach: array<f32>;

// World to grid space: m[r][0] p0 + m[r][1] p1 + m[r][2] p2 + m[r][3], left to right,
// only for a placed volume (like the CPU: an identity product would turn one NaN or
// infinite coordinate into NaN on every axis, 0 * inf = NaN).
fn to_grid_space(p: vec3<f32>) -> array<f32, 3> {
    var g = array<f32, 3>(p.x, p.y, p.z);
    if params.dims.z != 0u {
        for (var r = 0u; r < 3u; r++) {
            let m = params.to_grid[r];
            g[r] = m.x * p.x + m.y * p.y + m.z * p.z + m.w;
        }
    }
    return g;
}

struct AxisPos {
    cell: u32,
    frac: f32,
}

fn locate_axis(x: f32, lo: f32, scale: f32, cells: f32, max_cell: u32) -> AxisPos {
    var u = (x - lo) * scale;
    // Below the box, and NaN, map to 0 (the CPU path's `max(0.0)` drops NaN the same way).
    if is_nan(u) || u < 0.0 {
        u = 0.0;
    }
    u = min(u, cells);
    let i = min(u32(u), max_cell);
    return AxisPos(i, u - f32(i));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    // 2D dispatch for batches beyond 65535 workgroups along x.
    let q = gid.x + gid.y * groups.x * 64u;
    if q >= params.dims.w {
        return;
    }
    let p = vec3<f32>(points[3u * q], points[3u * q + 1u], points[3u * q + 2u]);
    let n = vec3<f32>(dirs[3u * q], dirs[3u * q + 1u], dirs[3u * q + 2u]);

    let g = to_grid_space(p);
    let ax = locate_axis(g[0], params.grid_min.x, params.scale.x, params.cells.x, params.max_cell.x);
    let ay = locate_axis(g[1], params.grid_min.y, params.scale.y, params.cells.y, params.max_cell.y);
    let az = locate_axis(g[2], params.grid_min.z, params.scale.z, params.cells.z, params.max_cell.z);
    let nx = params.dims.x;
    let nxy = params.dims.y;
    let base = ax.cell + nx * ay.cell + nxy * az.cell;

    // Trilinear weights, corner c = dx + 2 dy + 4 dz (Kontkanen & Laine Table 1).
    let fx = ax.frac;
    let fy = ay.frac;
    let fz = az.frac;
    let gx = 1.0 - fx;
    let gy = 1.0 - fy;
    let gz = 1.0 - fz;
    var w = array<f32, 8>(
        gx * gy * gz, fx * gy * gz, gx * fy * gz, fx * fy * gz,
        gx * gy * fz, fx * gy * fz, gx * fy * fz, fx * fy * fz,
    );
    var offset = array<u32, 8>(0u, 1u, nx, nx + 1u, nxy, nxy + 1u, nxy + nx, nxy + nx + 1u);

    // Unity APV's validity weights, then the node reach (lightvol-volume's `validity` and
    // `reach`, in the CPU lookup's order and f32 arithmetic).
    let flags = params.max_cell.w;
    if (flags & 1u) != 0u {
        var keep: array<bool, 8>;
        for (var c = 0u; c < 8u; c++) {
            let i = base + offset[c];
            keep[c] = ((validity[i >> 5u] >> (i & 31u)) & 1u) == 1u;
        }
        w = lightvol_renormalise(w, keep);
    }
    if (flags & 2u) != 0u {
        var t = p;
        if (flags & 4u) != 0u {
            t = p + n * params.grid_min.w;
        }
        let gt = to_grid_space(t);
        let cell = array<u32, 3>(ax.cell, ay.cell, az.cell);
        var f: array<f32, 3>;
        for (var a = 0u; a < 3u; a++) {
            f[a] = (gt[a] - params.grid_min[a]) * params.scale[a] - f32(cell[a]);
        }
        var keep: array<bool, 8>;
        for (var c = 0u; c < 8u; c++) {
            var sees = true;
            for (var a = 0u; a < 3u; a++) {
                let d = (c >> a) & 1u;
                let s = select(f[a], 1.0 - f[a], d == 1u);
                let here = reach[6u * (base + offset[c]) + 2u * a + d];
                let there = reach[6u * (base + offset[c ^ (1u << a)]) + 2u * a + 1u - d];
                sees = sees && (s <= here || here + there > params.scale.w);
            }
            keep[c] = sees;
        }
        w = lightvol_renormalise(w, keep);
    }

    // Eq. 2: L_j(x) = sum_i c_ij b_i(x), corner by corner.
    var acc: array<f32, K>;
    let s0 = base * K;
    for (var k = 0u; k < K; k++) {
        acc[k] = w[0] * coeffs[s0 + k];
    }
    for (var c = 1u; c < 8u; c++) {
        let sc = (base + offset[c]) * K;
        for (var k = 0u; k < K; k++) {
            acc[k] = acc[k] + w[c] * coeffs[sc + k];
        }
    }

    // Eq. 3: sum_j f_j Y_j(n) L_j(x), j ascending.
    let y = sh_basis(n, params.sh_a, params.sh_b, params.sh_diag);
    var o = vec3<f32>(0.0, 0.0, 0.0);
    for (var j = 0u; j < COEFFS; j++) {
        let t = flat4(params.factor, j) * y[j];
        o.x = o.x + t * acc[3u * j];
        o.y = o.y + t * acc[3u * j + 1u];
        o.z = o.z + t * acc[3u * j + 2u];
    }
    result[3u * q] = o.x;
    result[3u * q + 1u] = o.y;
    result[3u * q + 2u] = o.z;
}
