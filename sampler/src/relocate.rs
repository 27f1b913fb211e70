//! Moving a probe out of geometry through its closest back face: \[Maj21\]'s relocation, the
//! rule DDGI/RTXGI ships (`point+ddgi`, [`crate::baselines`]) and the one `doi` uses for a
//! node outside the domain of interest ([`crate::probe`]), with their constants.

use glam::DVec3;
use lightvol_volume::GridSpec;

/// DDGI/RTXGI: a probe with a larger back-face fraction is relocated (NVIDIA RTXGI,
/// `probeBackfaceThreshold`, default 0.25 of the fixed rays).
pub const DDGI_BACKFACE_THRESHOLD: f64 = 0.25;
/// DDGI/RTXGI: the largest relocation per axis, times the node spacing on that axis
/// (NVIDIA RTXGI's probe relocation keeps offsets below 45% of the probe spacing).
pub const DDGI_MAX_OFFSET: f64 = 0.45;

/// World node spacing of `grid` along each axis.
#[must_use]
pub fn spacing(grid: &GridSpec) -> [f64; 3] {
    let o = DVec3::from_array(grid.node_position_world(0, 0, 0));
    [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
        .map(|d| (DVec3::from_array(grid.node_position_world(d[0], d[1], d[2])) - o).length())
}

/// DDGI's move of a probe at `x` through the back face it meets at distance `t` along `d`:
/// 1% of the smallest spacing beyond it, each axis of the offset clamped to
/// [`DDGI_MAX_OFFSET`] × `spacing`.
#[must_use]
pub fn relocate_through(x: DVec3, d: DVec3, t: f64, spacing: [f64; 3]) -> DVec3 {
    relocate_within(x, d, t, spacing, DDGI_MAX_OFFSET)
}

/// [`relocate_through`] with the per-axis clamp `max_offset` × `spacing` instead of
/// [`DDGI_MAX_OFFSET`].
#[must_use]
pub fn relocate_within(x: DVec3, d: DVec3, t: f64, spacing: [f64; 3], max_offset: f64) -> DVec3 {
    let bias = 0.01 * spacing.iter().copied().fold(f64::INFINITY, f64::min);
    let off = d * (t + bias);
    let lim = DVec3::from_array(spacing) * max_offset;
    x + off.clamp(-lim, lim)
}
