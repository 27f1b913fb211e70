// Corner weights over the corners a lookup keeps: shared by the Vulkan evaluator's lookup
// kernel (lookup.wgsl) and the engine sampling code (src/engine_shader.rs).
//
// The weights w renormalised over the corners kept (Unity APV's run-time validity weights;
// the node reach's corners that see the query), as lightvol-volume's `renormalise`:
// unchanged when every corner is kept or the kept ones have no weight, else kept w / their
// sum (in corner order) and 0 elsewhere.
fn lightvol_renormalise(weights: array<f32, 8>, kept: array<bool, 8>) -> array<f32, 8> {
    // Copied into variables: WGSL compilers stricter than naga index values only by
    // constants.
    var w = weights;
    var keep = kept;
    var s = 0.0;
    var all = true;
    for (var k = 0u; k < 8u; k++) {
        if keep[k] {
            s += w[k];
        } else {
            all = false;
        }
    }
    if all || !(s > 0.0) {
        return w;
    }
    var out: array<f32, 8>;
    for (var k = 0u; k < 8u; k++) {
        out[k] = select(0.0, w[k] / s, keep[k]);
    }
    return out;
}
