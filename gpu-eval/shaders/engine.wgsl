// The engine sampling code's lookups (src/engine_shader.rs prepends the generated constants
// and appends the corner weights, a fetch for the texel layout and the test entry point).
// One volume: world-to-grid rows, grid minimum (w: the node reach's test-point offset along
// the normal, world units), (n - 1) / (max - min), node counts and the coefficient count
// per channel (4, 9 or 16) in dims.w.
struct LightvolGrid {
    to_grid: array<vec4<f32>, 3>,
    grid_min: vec4<f32>,
    scale: vec4<f32>,
    dims: vec4<u32>,
}

// World position -> continuous node coordinates, not clamped.
fn lightvol_grid_coordinates(grid: LightvolGrid, p: vec3<f32>) -> vec3<f32> {
    let g = vec3<f32>(dot(grid.to_grid[0], vec4<f32>(p, 1.0)), dot(grid.to_grid[1], vec4<f32>(p, 1.0)),
        dot(grid.to_grid[2], vec4<f32>(p, 1.0)));
    return (g - grid.grid_min.xyz) * grid.scale.xyz;
}

// World position -> continuous node coordinates in [0, n - 1] (clamped to the box).
fn lightvol_grid_position(grid: LightvolGrid, p: vec3<f32>) -> vec3<f32> {
    let top = vec3<f32>(grid.dims.xyz) - vec3<f32>(1.0);
    return clamp(lightvol_grid_coordinates(grid, p), vec3<f32>(0.0), top);
}

// The base corner of the cell that holds continuous node coordinates u (clamped).
fn lightvol_cell(grid: LightvolGrid, u: vec3<f32>) -> vec3<f32> {
    return min(floor(u), vec3<f32>(grid.dims.xyz) - vec3<f32>(2.0));
}

// sum_j A_l(j) Y_j(n) c_j (Eq. 3) for the coefficients c_j interpolated with the corner
// weights w over the cell at c0.
fn lightvol_shade(grid: LightvolGrid, c0: vec3<u32>, w: array<f32, 8>, n: vec3<f32>) -> vec3<f32> {
    var y = lightvol_sh_basis(n);
    var lobe = LIGHTVOL_COSINE_LOBE;
    var weights = w;
    var e = vec3<f32>(0.0);
    for (var j = 0u; j < grid.dims.w; j++) {
        var c = vec3<f32>(0.0);
        for (var k = 0u; k < 8u; k++) {
            let d = vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
            c += weights[k] * lightvol_fetch(grid, c0 + d, j);
        }
        e += (lobe[j] * y[j]) * c;
    }
    return e;
}

// Irradiance at world position p for the unit world normal n (Kontkanen & Laine 2006,
// Eq. 2-3): every coefficient interpolated trilinearly, then sum_j A_l(j) Y_j(n) c_j.
fn lightvol_irradiance(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_grid_position(grid, p);
    let cell = lightvol_cell(grid, u);
    return lightvol_shade(grid, vec3<u32>(cell), lightvol_corner_weights(u - cell), n);
}

fn lightvol_node_index(grid: LightvolGrid, node: vec3<u32>) -> u32 {
    return (node.z * grid.dims.y + node.y) * grid.dims.x + node.x;
}

// Validity (a point+apv volume's mask, the sidecar's `validity` decoded): one bit per node
// in node order, node i at bit i % 32 of word i / 32, 1 = valid.
@group(0) @binding(5) var<storage, read> lightvol_validity: array<u32>;

// Unity APV's run-time validity weights at continuous node coordinates u in the cell at
// `cell`: the invalid corners left out and the others renormalised (lightvol-volume's
// validity module).
fn lightvol_valid_weights(grid: LightvolGrid, u: vec3<f32>, cell: vec3<f32>) -> array<f32, 8> {
    let c0 = vec3<u32>(cell);
    var keep: array<bool, 8>;
    for (var k = 0u; k < 8u; k++) {
        let i = lightvol_node_index(grid, c0 + vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u));
        keep[k] = ((lightvol_validity[i >> 5u] >> (i & 31u)) & 1u) == 1u;
    }
    return lightvol_renormalise(lightvol_corner_weights(u - cell), keep);
}

// lightvol_irradiance with Unity APV's run-time validity weights (lightvol_valid_weights).
fn lightvol_irradiance_valid(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_grid_position(grid, p);
    let cell = lightvol_cell(grid, u);
    return lightvol_shade(grid, vec3<u32>(cell), lightvol_valid_weights(grid, u, cell), n);
}

// Node reach (a doi volume's, the sidecar's `reach` decoded): six f32 per node in node
// order, +x, -x, +y, -y, +z, -z, each the free distance along that grid axis in cells,
// capped at 1.
@group(0) @binding(6) var<storage, read> lightvol_reach: array<f32>;

// The node reach's weights for a query at p with normal n, u its continuous node
// coordinates in the cell at `cell`: a corner is left out when the test point
// p + n grid_min.w lies beyond its reach on an axis whose cell edge both end nodes see
// blocked (their reaches along it sum to at most LIGHTVOL_REACH_EDGE), and the others are
// renormalised (lightvol-volume's reach module).
fn lightvol_reach_weights(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>, u: vec3<f32>, cell: vec3<f32>)
    -> array<f32, 8> {
    let c0 = vec3<u32>(cell);
    let f = lightvol_grid_coordinates(grid, p + n * grid.grid_min.w) - cell;
    var keep: array<bool, 8>;
    for (var k = 0u; k < 8u; k++) {
        let d = vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
        let here_node = 6u * lightvol_node_index(grid, c0 + d);
        var sees = true;
        for (var a = 0u; a < 3u; a++) {
            let s = select(f[a], 1.0 - f[a], d[a] == 1u);
            var across = d;
            across[a] = 1u - d[a];
            let here = lightvol_reach[here_node + 2u * a + d[a]];
            let there = lightvol_reach[6u * lightvol_node_index(grid, c0 + across) + 2u * a + 1u - d[a]];
            sees = sees && (s <= here || here + there > LIGHTVOL_REACH_EDGE);
        }
        keep[k] = sees;
    }
    return lightvol_renormalise(lightvol_corner_weights(u - cell), keep);
}

// lightvol_irradiance with the node reach (lightvol_reach_weights).
fn lightvol_irradiance_reach(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_grid_position(grid, p);
    let cell = lightvol_cell(grid, u);
    return lightvol_shade(grid, vec3<u32>(cell), lightvol_reach_weights(grid, p, n, u, cell), n);
}

// Light groups (a volume baked with light groups, a sky transfer or lighting scenarios): the
// relit volume is sum_g s_g c_g over the groups' coefficients c_g with one RGB scale s_g per
// group, in group order (w unused; the array's length is the group count). For a sky
// transfer's groups sky.shJJ the scales are the new sky's SH radiance coefficients l_j; for
// scenarios, the blend weights. Every lookup is linear in the coefficients, so this is the
// lookup of the relit volume.
@group(0) @binding(9) var<storage, read> lightvol_group_scales: array<vec4<f32>>;

// lightvol_shade over the relit coefficients sum_g s_g c_g.
fn lightvol_shade_groups(grid: LightvolGrid, c0: vec3<u32>, w: array<f32, 8>, n: vec3<f32>) -> vec3<f32> {
    var y = lightvol_sh_basis(n);
    var lobe = LIGHTVOL_COSINE_LOBE;
    var weights = w;
    let groups = arrayLength(&lightvol_group_scales);
    var e = vec3<f32>(0.0);
    for (var j = 0u; j < grid.dims.w; j++) {
        var c = vec3<f32>(0.0);
        for (var g = 0u; g < groups; g++) {
            var cg = vec3<f32>(0.0);
            for (var k = 0u; k < 8u; k++) {
                let d = vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
                cg += weights[k] * lightvol_fetch_group(grid, c0 + d, j, g, groups);
            }
            c += lightvol_group_scales[g].xyz * cg;
        }
        e += (lobe[j] * y[j]) * c;
    }
    return e;
}

// lightvol_irradiance of the relit volume (the group scales above).
fn lightvol_irradiance_groups(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_grid_position(grid, p);
    let cell = lightvol_cell(grid, u);
    return lightvol_shade_groups(grid, vec3<u32>(cell), lightvol_corner_weights(u - cell), n);
}

// lightvol_irradiance_valid of the relit volume (groups share the whole bake's validity).
fn lightvol_irradiance_groups_valid(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_grid_position(grid, p);
    let cell = lightvol_cell(grid, u);
    return lightvol_shade_groups(grid, vec3<u32>(cell), lightvol_valid_weights(grid, u, cell), n);
}

// lightvol_irradiance_reach of the relit volume (groups share the whole bake's reach).
fn lightvol_irradiance_groups_reach(grid: LightvolGrid, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_grid_position(grid, p);
    let cell = lightvol_cell(grid, u);
    return lightvol_shade_groups(grid, vec3<u32>(cell), lightvol_reach_weights(grid, p, n, u, cell), n);
}
