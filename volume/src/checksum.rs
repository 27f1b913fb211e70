//! Integrity checksums, so that a damaged file is an error rather than a silently
//! different volume.
//!
//! Byte-level corruption of a file either breaks its structure (caught by the format
//! checks) or changes values that still parse: a coefficient, a bound, a metadata string.
//! Every lightvol file therefore carries a 64-bit FNV-1a checksum of the volume *as it will
//! be decoded* (grid, SH order, metadata, coefficient and weight bits), and readers
//! recompute it. The checksum detects accidental damage; it is not a cryptographic
//! signature.

use crate::error::VolumeError;
use crate::volume::IrradianceVolume;

pub use lightvol_core::hash::{Fnv1a, fnv1a};

/// The checksum of everything a reader reconstructs: grid (box, resolution, placement),
/// coefficient count, metadata, the bits of every coefficient and weight, and the validity
/// mask and node reach when there are (a volume without them hashes as before they
/// existed, so older files still verify).
#[must_use]
pub fn volume_checksum(vol: &IrradianceVolume) -> u64 {
    let mut h = Fnv1a::default();
    h.write_str("lightvol-volume checksum v1");
    let spec = vol.spec();
    let (min, max) = spec.bounds();
    for v in min.iter().chain(&max) {
        h.write(&v.to_bits().to_le_bytes());
    }
    for r in spec.res() {
        h.write(&r.to_le_bytes());
    }
    match spec.placement() {
        None => h.write(&[0]),
        Some(p) => {
            h.write(&[1]);
            for v in p.to_world_matrix().iter().flatten() {
                h.write(&v.to_bits().to_le_bytes());
            }
        }
    }
    h.write(&(vol.coeffs() as u64).to_le_bytes());
    let m = vol.metadata();
    for s in [&m.method, &m.scene_hash, &m.units] {
        h.write_str(s);
    }
    for v in [m.sampling_rays, m.seed, u64::from(m.shard_index), u64::from(m.shard_count)] {
        h.write(&v.to_le_bytes());
    }
    // The typed settings record, where the file has one (files without it keep the checksum
    // they always had); serde_json writes it the same way every time (fields in declaration
    // order, shortest round-trip floats).
    if let Some(settings) = &m.settings {
        h.write_str("settings");
        h.write_str(&serde_json::to_string(settings).unwrap_or_default());
    }
    for v in vol.data().iter().chain(vol.weights()) {
        h.write(&v.to_bits().to_le_bytes());
    }
    if let Some(mask) = vol.validity() {
        h.write_str("validity");
        for &v in mask.as_slice() {
            h.write(&[u8::from(v)]);
        }
    }
    if let Some(reach) = vol.reach() {
        h.write_str("reach");
        for i in 0..reach.len() {
            for v in reach.node(i) {
                h.write(&v.to_bits().to_le_bytes());
            }
        }
    }
    h.finish()
}

/// 16 lowercase hex digits.
#[must_use]
pub fn to_hex(v: u64) -> String {
    format!("{v:016x}")
}

/// Parses 16 hex digits.
pub fn from_hex(s: &str) -> Option<u64> {
    (s.len() == 16 && s.bytes().all(|b| b.is_ascii_hexdigit()))
        .then(|| u64::from_str_radix(s, 16).ok())
        .flatten()
}

/// Compares a stored hex checksum with the recomputed one.
pub(crate) fn verify(
    format: crate::error::FileFormat,
    stored: Option<&str>,
    vol: &IrradianceVolume,
) -> Result<(), VolumeError> {
    let stored = stored.ok_or_else(|| VolumeError::malformed(format, "missing checksum"))?;
    let want =
        from_hex(stored).ok_or_else(|| VolumeError::malformed(format, format!("bad checksum {stored:?}")))?;
    let got = volume_checksum(vol);
    if got == want {
        Ok(())
    } else {
        Err(VolumeError::malformed(
            format,
            format!("checksum mismatch (stored {want:016x}, data {got:016x}): the file is damaged"),
        ))
    }
}

/// `vol` with every coefficient (and, if `weights_too`, every weight) rounded through f16:
/// what an f16 file decodes to (the validity mask and node reach kept, stored f32). Errors if a value exceeds the f16
/// range.
pub(crate) fn through_f16(
    vol: &IrradianceVolume,
    weights_too: bool,
) -> Result<IrradianceVolume, VolumeError> {
    let round = |v: f32| {
        let h = half::f16::from_f32(v);
        if h.is_finite() {
            Ok(h.to_f32())
        } else {
            Err(VolumeError::InvalidData(format!("value {v} exceeds the f16 range (65504)")))
        }
    };
    let data = vol.data().iter().map(|&v| round(v)).collect::<Result<Vec<_>, _>>()?;
    let weights = if weights_too {
        vol.weights().iter().map(|&v| round(v)).collect::<Result<Vec<_>, _>>()?
    } else {
        vol.weights().to_vec()
    };
    let mut out = IrradianceVolume::new(vol.spec().clone(), vol.coeffs(), data, weights)?
        .with_metadata(vol.metadata().clone());
    out.set_validity(vol.validity().cloned())?;
    out.set_reach(vol.reach().cloned())?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trip() {
        for v in [0, 1, u64::MAX, 0x0123_4567_89ab_cdef] {
            assert_eq!(from_hex(&to_hex(v)), Some(v));
        }
        assert_eq!(from_hex("123"), None);
        assert_eq!(from_hex("+123456789abcdef"), None);
    }

    #[test]
    fn checksum_sees_every_part() {
        let spec = crate::GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let v = IrradianceVolume::zeros(spec.clone(), 4).unwrap();
        let c = volume_checksum(&v);
        let mut w = v.clone();
        w.set_node(3, &[0.0, 0.0, 0.0, -0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
        assert_ne!(volume_checksum(&w), c, "sign of zero");
        let mut m = v.metadata().clone();
        m.seed = 1;
        assert_ne!(volume_checksum(&v.clone().with_metadata(m)), c);
        let moved =
            IrradianceVolume::zeros(spec.with_placement(crate::Placement::translation([0.0; 3]).unwrap()), 4);
        assert_ne!(volume_checksum(&moved.unwrap()), c);
        // A mask counts, and so does each of its flags.
        let all = v.clone().with_validity(crate::ValidityMask::new(vec![true; 8])).unwrap();
        assert_ne!(volume_checksum(&all), c);
        let one =
            v.clone().with_validity(crate::ValidityMask::new((0..8).map(|i| i != 5).collect())).unwrap();
        assert_ne!(volume_checksum(&one), volume_checksum(&all));
    }
}
