//! How a comparison reads what each entry baked: through one engine's lookup for every
//! entry ([`ReadAs::Engine`], [`lightvol_volume::engine_lookup`]), or each entry through
//! the lookup of the engine it belongs to ([`ReadAs::Native`]): Unity APV's fix through
//! APV's lookup, the other engines' fixes through plain trilinear interpolation, a bake
//! fitted for an engine (`BASE+ENGINE`) through that engine's, lightvol's own methods
//! through lightvol's lookups.
//!
//! A comparison may read every entry several ways (`compare --lookup`, repeatable): the
//! first way keeps the entries' names, each further one adds the runs `NAME@WAY`, measured
//! on the same plate and views from the same bakes.

use lightvol_volume::EngineLookup;

use crate::baked::RunVolume;
use crate::entries::Entry;
use crate::plate::Plate;
use crate::runs::MethodRun;
use lightvol_sampler::method::Baseline;

/// One way of reading every entry (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReadAs {
    /// Every entry through this engine's lookup (uniform grids only but for lightvol's).
    Engine(EngineLookup),
    /// Each entry through its own engine's lookup.
    Native,
}

impl Default for ReadAs {
    fn default() -> Self {
        Self::Engine(EngineLookup::Lightvol)
    }
}

impl ReadAs {
    /// The name `--lookup` takes: an engine lookup's ([`EngineLookup::name`]) or `native`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Engine(l) => l.name(),
            Self::Native => "native",
        }
    }

    /// The lookup that reads `entry` this way (`None`: the entry's own reading, lightvol's).
    #[must_use]
    pub fn lookup_for(self, entry: Entry) -> Option<EngineLookup> {
        match (self, entry) {
            (_, Entry::Bound(l)) => Some(l),
            (Self::Engine(EngineLookup::Lightvol), Entry::Targeted(..)) => Some(EngineLookup::Lightvol),
            (Self::Engine(EngineLookup::Lightvol), _) => None,
            (Self::Engine(l), _) => Some(l),
            (Self::Native, Entry::Baseline(Baseline::Apv)) => Some(EngineLookup::Apv),
            (Self::Native, Entry::Baseline(_)) => Some(EngineLookup::Trilinear),
            (Self::Native, Entry::Targeted(_, l)) => Some(l),
            (Self::Native, _) => None,
        }
    }

    /// Whether this way reads `entry` through an engine lookup that needs a uniform grid
    /// (gradient, octree and brick entries can be read only their own way).
    #[must_use]
    pub fn needs_grid(self, entry: Entry) -> bool {
        matches!(entry, Entry::Gradient(..) | Entry::Adaptive(_) | Entry::Bricks(_))
            && self.lookup_for(entry).is_some()
    }
}

impl std::fmt::Display for ReadAs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ReadAs {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "native" {
            return Ok(Self::Native);
        }
        s.parse::<EngineLookup>().map(Self::Engine).map_err(|e| format!("{e}, or native"))
    }
}

/// `run` (of `entry`) read `way`: a uniform grid's plate estimate (normal up, viewed from
/// above) and metrics by [`IrradianceVolume::engine_irradiance`](lightvol_volume::IrradianceVolume::engine_irradiance),
/// its views through the same lookup; an entry read its own way is left as it is.
#[must_use]
pub fn read_as(run: MethodRun, entry: Entry, way: ReadAs, plate: &Plate) -> MethodRun {
    let Some(lookup) = way.lookup_for(entry) else { return run };
    let Some(vol) = run.volume.uniform().cloned() else { return run };
    if matches!(run.volume, RunVolume::Engine(_, l) if l == lookup) {
        return run;
    }
    let estimate = plate.engine_estimate(&vol, lookup);
    MethodRun { metrics: plate.metrics(&estimate), estimate, volume: RunVolume::Engine(vol, lookup), ..run }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_sampler::method::Method;

    /// Names round-trip; `native` reads each engine's fix through its own engine's lookup.
    #[test]
    fn names_and_native_lookups() {
        for l in EngineLookup::ALL {
            let w = ReadAs::Engine(l);
            assert_eq!(w.name().parse::<ReadAs>(), Ok(w));
        }
        assert_eq!("native".parse::<ReadAs>(), Ok(ReadAs::Native));
        assert!("unity".parse::<ReadAs>().unwrap_err().ends_with("apv), or native"));
        let n = ReadAs::Native;
        assert_eq!(n.lookup_for(Entry::Baseline(Baseline::Apv)), Some(EngineLookup::Apv));
        assert_eq!(n.lookup_for(Entry::Baseline(Baseline::Ddgi)), Some(EngineLookup::Trilinear));
        assert_eq!(n.lookup_for(Entry::Baseline(Baseline::Vlm)), Some(EngineLookup::Trilinear));
        assert_eq!(n.lookup_for(Entry::Targeted(Method::Doi, EngineLookup::Bevy)), Some(EngineLookup::Bevy));
        assert_eq!(n.lookup_for(Entry::Uniform(Method::Doi)), None);
        // A bound is read through its own lookup, whichever way the others are read.
        for w in [ReadAs::Native, ReadAs::default(), ReadAs::Engine(EngineLookup::Bevy)] {
            assert_eq!(w.lookup_for(Entry::Bound(EngineLookup::Three)), Some(EngineLookup::Three));
        }
        assert!(!n.needs_grid(Entry::Adaptive(2)));
        assert!(ReadAs::Engine(EngineLookup::Three).needs_grid(Entry::Adaptive(2)));
        assert!(!ReadAs::default().needs_grid(Entry::Adaptive(2)));
    }
}
