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

/// `vol` (baked in the internal frame) expressed in the file frame `up`: the same grid in
/// grid space, its placement followed by the rotation into the file's axes (so world
/// positions are file positions), and every node's SH rotated by it (so SH directions are
/// file directions; lightvol-sh's `ShRotation`, in f64, rounded once to f32). Looking the
/// result up at `(R p, R n)` gives the original at `(p, n)` to f32 rounding. The metadata
/// records `up`; the weights, the validity mask and the node reach (in grid axes, which the
/// rotation leaves alone) are kept. For `UpAxis::Z` the volume is
/// returned unchanged (apart from the frame).
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
    let base = spec.placement().map_or_else(
        || [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
        Placement::to_world_matrix,
    );
    // file row a = sign · internal row `axis`.
    let m: [[f64; 4]; 3] = std::array::from_fn(|a| {
        let (axis, sign) = up.file_axes()[a];
        base[axis].map(|v| sign * v)
    });
    let placed =
        GridSpec::new(spec.bounds().0, spec.bounds().1, spec.res())?.with_placement(Placement::new(m)?);
    let r = glam::DMat3::from_cols_array_2d(&std::array::from_fn(|c| {
        let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
        up.to_file(e)
    }));
    let rot = ShRotation::from_mat3(vol.bands(), r);
    let coeffs = vol.coeffs();
    let mut data = Vec::with_capacity(vol.data().len());
    let mut ch = vec![0.0f64; coeffs];
    for node in 0..spec.node_count() {
        let c = vol.node(node);
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
    let mut out = IrradianceVolume::new(placed, coeffs, data, vol.weights().to_vec())?.with_metadata(meta);
    out.set_validity(vol.validity().cloned())?;
    out.set_reach(vol.reach().cloned())?;
    Ok(out)
}

/// A grid as users see it in reports: nodes per axis and the corners along the scene file's
/// axes, with the frame they are in, so that bounds and resolution given back to a bake
/// give the same grid.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
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

    /// A random volume expressed in the Y-up frame: its lookup at the rotated point and
    /// normal is the original's, to f32 rounding of the rotated coefficients.
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
        let vol = IrradianceVolume::new(spec, coeffs, data, vec![1.0; n]).unwrap();
        let file = to_file_frame(&vol, UpAxis::Y).unwrap();
        assert_eq!(file.metadata().frame, UpAxis::Y);
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
            for c in 0..3 {
                assert!((e0[c] - e1[c]).abs() < TOL, "{e0:?} vs {e1:?}");
            }
        }
    }
}
