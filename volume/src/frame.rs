//! Source frames: grids and volumes described in the frame of the scene file a volume was
//! baked from ([`UpAxis`]).
//!
//! lightvol's internal frame is right-handed with +Z up; a file with +Y up (glTF 2.0 §3.4,
//! most OBJ exports) is rotated into it by +90° about X, `(x, y, z) → (x, −z, y)`. The
//! rotation keeps handedness and winding, and it maps heights in the file (`y`) to internal
//! heights (`z`) unchanged. Volumes record the frame of their scene ([`UpAxis::name`]), and
//! every coordinate lightvol shows or reads (command line, JSON, `info`) is in that frame.

use lightvol_sh::rotate::ShRotation;

use crate::error::VolumeError;
use crate::grid::{GridSpec, Placement};
use crate::metadata::BakeMetadata;
use crate::reach::NodeReach;
use crate::volume::IrradianceVolume;

pub use crate::up_axis::UpAxis;

/// The nodes of the internal grid `spec` described in the file frame `up`, for reports: an
/// unplaced grid becomes the axis-aligned file-frame box (bounds by [`UpAxis::box_to_file`],
/// node counts along the file's axes); a placed grid keeps its grid space and gets the
/// rotation appended to its placement.
///
/// # Errors
/// None in practice (a rotation of a valid grid is valid).
pub fn grid_in_file_frame(spec: &GridSpec, up: UpAxis) -> Result<GridSpec, VolumeError> {
    if up == UpAxis::Z {
        return Ok(spec.clone());
    }
    let (lo, hi) = spec.bounds();
    match spec.placement() {
        None => {
            let (a, b) = up.box_to_file(lo, hi);
            let res = spec.res();
            GridSpec::new(a, b, up.file_axes().map(|(axis, _)| res[axis]))
        }
        Some(p) => {
            let base = p.to_world_matrix();
            let m: [[f64; 4]; 3] = std::array::from_fn(|a| {
                let (axis, sign) = up.file_axes()[a];
                base[axis].map(|v| sign * v)
            });
            Ok(GridSpec::new(lo, hi, spec.res())?.with_placement(Placement::new(m)?))
        }
    }
}

/// `vol` (baked in the internal frame) expressed in the file frame `up`, so that world
/// positions and SH directions are the file's. An unplaced grid (the common case) is laid
/// out again along the file's axes: the rotation between the frames is a signed axis
/// permutation, so every node keeps its exact position, the result is an axis-aligned
/// file-frame grid with no placement ([`grid_in_file_frame`]'s), and a texture written
/// from it runs along the file's axes. A placed grid keeps its grid space and gets the
/// rotation appended to its placement. Every node's SH is rotated (lightvol-sh's
/// `ShRotation`, in f64, rounded once to f32), so looking the result up at `(R p, R n)`
/// gives the original at `(p, n)` to f32 rounding. The metadata records `up`; the weights,
/// the validity mask and the node reach follow their nodes (the reach's six directions are
/// permuted with the axes). For `UpAxis::Z` the volume is returned unchanged (apart from the
/// frame). [`to_internal_frame`] is the inverse.
///
/// # Errors
/// If the rotated coefficients or placement are rejected (they cannot be: a rotation keeps
/// them finite and invertible).
pub fn to_file_frame(vol: &IrradianceVolume, up: UpAxis) -> Result<IrradianceVolume, VolumeError> {
    let meta = BakeMetadata { frame: up, ..vol.metadata().clone() };
    if up == UpAxis::Z {
        return Ok(vol.clone().with_metadata(meta));
    }
    let spec = vol.spec();
    let r = glam::DMat3::from_cols_array_2d(&std::array::from_fn(|c| {
        let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
        up.to_file(e)
    }));
    match spec.placement() {
        None => permute_axes(vol, up.file_axes(), r, meta),
        Some(p) => {
            let base = p.to_world_matrix();
            // file row a = sign · internal row `axis`.
            let m: [[f64; 4]; 3] = std::array::from_fn(|a| {
                let (axis, sign) = up.file_axes()[a];
                base[axis].map(|v| sign * v)
            });
            let placed = GridSpec::new(spec.bounds().0, spec.bounds().1, spec.res())?
                .with_placement(Placement::new(m)?);
            rotate_nodes(vol, placed, r, meta, |node| node, |reach| reach)
        }
    }
}

/// The inverse of [`to_file_frame`]: a volume whose data is in the file frame `up` (as the
/// engine exports store it) back in lightvol's internal frame, as the native file stores
/// it. An axis-aligned file-frame grid becomes the axis-aligned internal grid (nodes
/// permuted back, exactly); a placed grid gets the inverse rotation prepended to its
/// placement's world side. The metadata's frame (the scene's) is kept.
///
/// # Errors
/// As [`to_file_frame`].
pub fn to_internal_frame(vol: &IrradianceVolume, up: UpAxis) -> Result<IrradianceVolume, VolumeError> {
    if up == UpAxis::Z {
        return Ok(vol.clone());
    }
    let meta = vol.metadata().clone();
    let spec = vol.spec();
    // internal = Rᵀ file.
    let r = glam::DMat3::from_cols_array_2d(&std::array::from_fn(|c| {
        let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
        up.to_world(e)
    }));
    let file_axes = up.file_axes();
    match spec.placement() {
        None => {
            // internal axis b is file axis a with file_axes[a].0 == b, same sign.
            let axes: [(usize, f64); 3] = std::array::from_fn(|b| {
                let a = (0..3).find(|&a| file_axes[a].0 == b).expect("a permutation");
                (a, file_axes[a].1)
            });
            permute_axes(vol, axes, r, meta)
        }
        Some(p) => {
            let m = p.to_world_matrix();
            // internal row `axis` = sign · file row a.
            let mut base = [[0.0; 4]; 3];
            for (a, (axis, sign)) in file_axes.into_iter().enumerate() {
                base[axis] = m[a].map(|v| sign * v);
            }
            let placed = GridSpec::new(spec.bounds().0, spec.bounds().1, spec.res())?
                .with_placement(Placement::new(base)?);
            rotate_nodes(vol, placed, r, meta, |node| node, |reach| reach)
        }
    }
}

/// `vol`'s unplaced grid along new axes: new axis `a` is old axis `axes[a].0`, reversed where
/// `axes[a].1` is negative (a signed permutation, the rotation `r` of directions).
fn permute_axes(
    vol: &IrradianceVolume,
    axes: [(usize, f64); 3],
    r: glam::DMat3,
    meta: BakeMetadata,
) -> Result<IrradianceVolume, VolumeError> {
    let spec = vol.spec();
    let (lo, hi) = spec.bounds();
    let res = spec.res();
    let (a, b) = (
        std::array::from_fn::<f64, 3, _>(|i| axes[i].1 * [lo, hi][usize::from(axes[i].1 < 0.0)][axes[i].0]),
        std::array::from_fn::<f64, 3, _>(|i| axes[i].1 * [hi, lo][usize::from(axes[i].1 < 0.0)][axes[i].0]),
    );
    let new_res: [u32; 3] = std::array::from_fn(|i| res[axes[i].0]);
    let new_spec = GridSpec::new(a, b, new_res)?;
    let new_dims = new_spec.clone();
    let old_of_new = |node: usize| {
        let q = new_dims.node_coords(node);
        let mut c = [0u32; 3];
        for (i, &(axis, sign)) in axes.iter().enumerate() {
            c[axis] = if sign < 0.0 { res[axis] - 1 - q[i] } else { q[i] };
        }
        spec.node_index(c[0], c[1], c[2])
    };
    // Reach directions +x,-x,+y,-y,+z,-z: new direction (i, s) is old (axis, s·sign).
    let reach_map = |old: [f32; 6]| -> [f32; 6] {
        std::array::from_fn(|d| {
            let (i, negative) = (d / 2, d % 2 == 1);
            let (axis, sign) = axes[i];
            old[2 * axis + usize::from(negative != (sign < 0.0))]
        })
    };
    rotate_nodes(vol, new_spec, r, meta, old_of_new, reach_map)
}

/// The volume on `spec` whose node `i` is `vol`'s node `old_of(i)` with its SH rotated by
/// `r`, its weight, validity and (mapped by `reach_of`) reach carried along.
fn rotate_nodes(
    vol: &IrradianceVolume,
    spec: GridSpec,
    r: glam::DMat3,
    meta: BakeMetadata,
    old_of: impl Fn(usize) -> usize,
    reach_of: impl Fn([f32; 6]) -> [f32; 6],
) -> Result<IrradianceVolume, VolumeError> {
    let rot = ShRotation::from_mat3(vol.bands(), r);
    let coeffs = vol.coeffs();
    let count = spec.node_count();
    let mut data = Vec::with_capacity(vol.data().len());
    let mut weights = Vec::with_capacity(count);
    let mut ch = vec![0.0f64; coeffs];
    for node in 0..count {
        let old = old_of(node);
        let c = vol.node(old);
        weights.push(vol.weights()[old]);
        let start = data.len();
        data.resize(start + 3 * coeffs, 0.0f32);
        for k in 0..3 {
            for (j, v) in ch.iter_mut().enumerate() {
                *v = f64::from(c[3 * j + k]);
            }
            rot.apply_in_place(&mut ch);
            for (j, v) in ch.iter().enumerate() {
                data[start + 3 * j + k] = *v as f32;
            }
        }
    }
    let mut out = IrradianceVolume::new(spec, coeffs, data, weights)?.with_metadata(meta);
    out.set_validity(
        vol.validity()
            .map(|m| crate::validity::ValidityMask::new((0..count).map(|i| m.is_valid(old_of(i))).collect())),
    )?;
    out.set_reach(
        vol.reach()
            .map(|r| NodeReach::new((0..count).map(|i| reach_of(r.node(old_of(i)))).collect()))
            .transpose()?,
    )?;
    Ok(out)
}

/// A grid as users see it in reports: nodes per axis and the corners along the scene file's
/// axes, with the frame they are in, so that bounds and resolution given back to a bake
/// give the same grid.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FileGrid {
    /// Nodes per axis, along the scene file's axes.
    pub res: [u32; 3],
    /// Min and max corners in the scene file's frame.
    pub bounds: [[f64; 3]; 2],
    /// The frame of `res` and `bounds`.
    pub frame: UpAxis,
}

impl FileGrid {
    /// Describes an (unplaced) internal grid in the scene file's frame `frame`
    /// ([`grid_in_file_frame`]; a placed grid is described as it is).
    #[must_use]
    pub fn of(spec: &GridSpec, frame: UpAxis) -> Self {
        let f = grid_in_file_frame(spec, frame).unwrap_or_else(|_| spec.clone());
        let (a, b) = f.bounds();
        Self { res: f.res(), bounds: [a, b], frame }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    }

    /// Y-up: the file's +Y is internal +Z; the map is a rotation (x × y = z is kept); the
    /// inverse undoes it; `file_axes` is the same map written per axis; names round-trip.
    #[test]
    fn frames_are_rotations_with_their_inverses() {
        assert_eq!(UpAxis::Y.to_world([0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        for up in [UpAxis::Y, UpAxis::Z] {
            let e = |i: usize| -> [f64; 3] { std::array::from_fn(|j| f64::from(u8::from(i == j))) };
            assert_eq!(cross(up.to_world(e(0)), up.to_world(e(1))), up.to_world(e(2)));
            let p = [1.5, -2.0, 3.25];
            assert_eq!(up.to_file(up.to_world(p)), p);
            assert_eq!(up.to_world(up.to_file(p)), p);
            let q = up.to_file(p);
            for (a, (axis, sign)) in up.file_axes().into_iter().enumerate() {
                assert_eq!(q[a], sign * p[axis]);
            }
            assert_eq!(UpAxis::parse(up.name()), Some(up));
            let (lo, hi) = up.box_to_file([-1.0, -2.0, 0.0], [1.0, 3.0, 4.0]);
            assert!((0..3).all(|a| lo[a] < hi[a]));
            assert_eq!(up.box_to_world(lo, hi), ([-1.0, -2.0, 0.0], [1.0, 3.0, 4.0]));
            let json = serde_json::to_string(&up).unwrap();
            assert_eq!(json, format!("\"{}\"", up.name()));
        }
    }

    /// A random volume with a validity mask and a node reach expressed in the Y-up frame:
    /// laid out along the file's axes, its lookup at the rotated point and normal is the
    /// original's (the mask and the reach leave out the same corners), to f32 rounding of
    /// the rotated coefficients; the inverse gives the original grid, mask and reach back.
    #[test]
    fn file_frame_volume_is_the_same_field() {
        let spec = GridSpec::new([-1.0, 0.0, 0.5], [2.0, 3.0, 2.0], [4, 3, 5]).unwrap();
        let coeffs = 9;
        let n = spec.node_count();
        let mut state = 0x1234_5678_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let data: Vec<f32> = (0..n * coeffs * 3).map(|_| (next() * 2.0 - 0.5) as f32).collect();
        // A validity mask and a node reach (multiples of an eighth of a cell) that the
        // new layout must carry with their nodes and directions.
        let valid = (0..n).map(|_| next() < 0.7).collect();
        let reach = (0..n)
            .map(|_| {
                std::array::from_fn(|_| if next() < 0.5 { 1.0 } else { (next() * 8.0).floor() as f32 / 8.0 })
            })
            .collect();
        let vol = IrradianceVolume::new(spec, coeffs, data, vec![1.0; n])
            .unwrap()
            .with_validity(crate::ValidityMask::new(valid))
            .unwrap()
            .with_reach(NodeReach::new(reach).unwrap())
            .unwrap();
        let file = to_file_frame(&vol, UpAxis::Y).unwrap();
        assert_eq!(file.metadata().frame, UpAxis::Y);
        // Laid out along the file's axes: axis-aligned, file res (x, z, y) of the internal.
        assert!(file.spec().placement().is_none());
        assert_eq!(file.spec().res(), [4, 5, 3]);
        assert_eq!(file.spec().bounds(), ([-1.0, 0.5, -3.0], [2.0, 2.0, 0.0]));
        assert_eq!(file.validity().unwrap().invalid_count(), vol.validity().unwrap().invalid_count());
        let back = to_internal_frame(&file, UpAxis::Y).unwrap();
        assert_eq!(back.spec(), vol.spec());
        assert_eq!(back.validity(), vol.validity());
        assert_eq!(back.reach(), vol.reach());
        assert_eq!(back.weights(), vol.weights());
        for (a, b) in back.data().iter().zip(vol.data()) {
            // Two f32 roundings of rotated coefficients of size ≤ 1.5.
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
        // Rotated coefficients rounded to f32: 2^-24 relative each, over 9 coefficients of
        // size ≤ 1.5 times the irradiance factors (≤ π): below 1e-5 in all.
        const TOL: f64 = 1e-5;
        for _ in 0..500 {
            let p = [next() * 3.0 - 1.0, next() * 3.0, 0.5 + next() * 1.5];
            let nn = [next() - 0.5, next() - 0.5, next() - 0.5];
            let l = (nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]).sqrt();
            let nn = nn.map(|v| v / l);
            let e0 = vol.irradiance_reference(p, nn);
            let e1 = file.irradiance_reference(UpAxis::Y.to_file(p), UpAxis::Y.to_file(nn));
            let e2 = back.irradiance_reference(p, nn);
            for c in 0..3 {
                assert!((e0[c] - e1[c]).abs() < TOL, "{e0:?} vs {e1:?}");
                assert!((e0[c] - e2[c]).abs() < TOL, "{e0:?} vs {e2:?}");
            }
        }
    }
}
