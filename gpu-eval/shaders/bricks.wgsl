// The brick volume's lookup (src/brick_shader.rs prepends the generated constants and the
// shared basis and corner weights, and appends a fetch and the test entry point). Every
// field comes from the export's description (lightvol-volume's io::bricks):
// world_to_units: rows of the map from the scene file's positions to base-cell units;
// normal_to_sh: rows of the rotation from the file's directions to the SH frame;
// top: xyz the base cells per axis (n - 1), w = 2^finest_level / brick_cells;
// indirection: xyz its texels per axis, w the finest level;
// atlas: x brick_cells, y the atlas's slots along z, z the coefficients per channel.
struct LightvolBricks {
    world_to_units: array<vec4<f32>, 3>,
    normal_to_sh: array<vec4<f32>, 3>,
    top: vec4<f32>,
    indirection: vec4<u32>,
    atlas: vec4<u32>,
}

// File-frame position -> base-cell units, clamped to the box.
fn lightvol_brick_units(b: LightvolBricks, p: vec3<f32>) -> vec3<f32> {
    let q = vec4<f32>(p, 1.0);
    let u = vec3<f32>(dot(b.world_to_units[0], q), dot(b.world_to_units[1], q), dot(b.world_to_units[2], q));
    return min(max(u, vec3<f32>(0.0)), b.top.xyz);
}

// Irradiance at file-frame position p for the unit file-frame normal n: the indirection
// texel names the brick (its atlas slot and level), the brick's probes are interpolated
// trilinearly (Kontkanen & Laine 2006, Eq. 2) and shaded, sum_j A_l(j) Y_j(n) c_j (Eq. 3).
fn lightvol_irradiance_bricks(b: LightvolBricks, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let u = lightvol_brick_units(b, p);
    let t = min(vec3<u32>(u * b.top.w), b.indirection.xyz - vec3<u32>(1u));
    let entry = lightvol_brick_entry(t);
    let level = entry.w;
    let brick = t / vec3<u32>(1u << (b.indirection.w - level));
    let cells = f32(b.atlas.x);
    let s = min(max(u * f32(1u << level) - vec3<f32>(brick * b.atlas.x), vec3<f32>(0.0)), vec3<f32>(cells));
    let cell = min(floor(s), vec3<f32>(cells - 1.0));
    var w = lightvol_corner_weights(s - cell);
    let c0 = vec3<u32>(cell);
    let sh_n = vec3<f32>(dot(b.normal_to_sh[0].xyz, n), dot(b.normal_to_sh[1].xyz, n), dot(b.normal_to_sh[2].xyz, n));
    var y = lightvol_sh_basis(sh_n);
    var lobe = LIGHTVOL_COSINE_LOBE;
    var e = vec3<f32>(0.0);
    for (var j = 0u; j < b.atlas.z; j++) {
        var c = vec3<f32>(0.0);
        for (var k = 0u; k < 8u; k++) {
            let d = vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
            c += w[k] * lightvol_brick_fetch(b, entry.xyz, c0 + d, j);
        }
        e += (lobe[j] * y[j]) * c;
    }
    return e;
}
