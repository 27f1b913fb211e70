//! The names of every bake method: the grid methods ([`Method`]: Kontkanen & Laine 2006's
//! three and the two that narrow their support) and the engines' leak fixes ([`Baseline`]),
//! and what `bake --method` reads ([`BakeMethod`]). Each name parses back with `FromStr`.

use std::fmt;
use std::str::FromStr;

/// Which estimator fills the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Method {
    /// Eq. 4: directions sampled at each node.
    Point,
    /// Eq. 5-6 without the domain test.
    Prefilter,
    /// Eq. 5-6 with Algorithm 2, the paper's method (`doi-paper`): candidates uniform in each
    /// cell, those in the domain of interest averaged over each node's trilinear support.
    DoiPaper,
    /// Algorithm 2's domain test on a node's own cell: candidates uniform in the box of one
    /// cell centred on the node (half a cell each way), averaged with equal weights over
    /// those in the domain of interest. A support half as wide as Eq. 6's trilinear one.
    DoiNode,
    /// The default (`doi`): a probe per node, kept in the domain of interest. Point-sampled
    /// (Eq. 4) where the node is in the domain: it meets back faces inside its trilinear
    /// support in at most [`PROBE_NEAR_BACK_SHARE`](crate::probe::PROBE_NEAR_BACK_SHARE) of its directions (the
    /// slivers of single-sided content beside it), and back faces beyond it in at most
    /// [`PROBE_FAR_BACK_SHARE`](crate::probe::PROBE_FAR_BACK_SHARE) of its
    /// directions (a distance-limited test, so that the back of a single-sided panel seen
    /// across a room does not move the node); otherwise at the point reached through its
    /// closest back face (the relocation rule of \[Maj21\], preferring points that stay in
    /// the grid's box, up to [`PROBE_MAX_OFFSET`](crate::probe::PROBE_MAX_OFFSET) of a cell) when that point is in the
    /// domain by the same test;
    /// otherwise no samples of its own, so that the volume's fill gives it the mean of its
    /// neighbours' estimates. See [`ProbeCapture`](crate::probe::ProbeCapture). The bake also records every node's
    /// reach ([`crate::reach`]), with which the volume's lookups leave out the nodes on the
    /// far side of a wall from the query point.
    #[default]
    Doi,
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "point" => Ok(Self::Point),
            "prefilter" => Ok(Self::Prefilter),
            "doi" => Ok(Self::Doi),
            "doi-paper" => Ok(Self::DoiPaper),
            "doi-node" => Ok(Self::DoiNode),
            _ => Err(format!("unknown method '{s}' (point, prefilter, doi, doi-paper, doi-node)")),
        }
    }
}

impl Method {
    /// Every grid method, in the order help texts list them.
    pub const ALL: [Self; 5] = [Self::Point, Self::Prefilter, Self::Doi, Self::DoiPaper, Self::DoiNode];

    /// Its name, which [`FromStr`] reads.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Point => "point",
            Self::Prefilter => "prefilter",
            Self::DoiPaper => "doi-paper",
            Self::DoiNode => "doi-node",
            Self::Doi => "doi",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which engine's leak fix ([`crate::baselines`] describes each).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    /// Point sampling, invalidation, dilation; plain trilinear lookups (`point+validity`).
    Validity,
    /// Unity Adaptive Probe Volumes: virtual offset, validity, dilation, validity-weighted
    /// lookups (`point+apv`).
    Apv,
    /// Unreal volumetric lightmaps: inside voxels replaced by the mean of valid neighbours
    /// (`point+vlm`).
    Vlm,
    /// DDGI/RTXGI probe relocation (`point+ddgi`).
    Ddgi,
}

impl Baseline {
    /// Every baseline, in the order help texts list them.
    pub const ALL: [Self; 4] = [Self::Validity, Self::Apv, Self::Vlm, Self::Ddgi];

    /// Its name (in `compare --methods` and `bake --method`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Validity => "point+validity",
            Self::Apv => "point+apv",
            Self::Vlm => "point+vlm",
            Self::Ddgi => "point+ddgi",
        }
    }

    /// The baseline named `name` ([`Self::name`]), if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|b| b.name() == name)
    }

    /// Whether its volume carries a validity mask, so that its lookups are
    /// validity-weighted (only Unity APV's).
    #[must_use]
    pub fn weights_lookups(self) -> bool {
        self == Self::Apv
    }
}

/// What `lightvol bake --method` bakes: a grid method of \[KL06\] or an engine baseline
/// ([`crate::baselines`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BakeMethod {
    /// `point`, `prefilter`, `doi`, `doi-paper` or `doi-node`.
    Grid(Method),
    /// `point+validity`, `point+apv`, `point+vlm` or `point+ddgi`.
    Baseline(Baseline),
}

impl BakeMethod {
    /// Its name, which [`FromStr`] reads.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Grid(m) => m.name(),
            Self::Baseline(b) => b.name(),
        }
    }
}

/// A grid method's name or an engine baseline's ([`Baseline::name`]); an unknown name is an
/// error that lists every name.
impl FromStr for BakeMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if let Some(b) = Baseline::from_name(s) {
            return Ok(Self::Baseline(b));
        }
        s.parse::<Method>().map(Self::Grid).map_err(|_| {
            let baselines: Vec<&str> = Baseline::ALL.iter().map(|b| b.name()).collect();
            format!(
                "unknown method '{s}' (point, prefilter, doi, doi-paper, doi-node, {})",
                baselines.join(", ")
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every grid method's and baseline's name parses back to it.
    #[test]
    fn names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>().unwrap(), m);
            assert_eq!(m.name().parse::<BakeMethod>().unwrap(), BakeMethod::Grid(m));
            assert_eq!(BakeMethod::Grid(m).name(), m.name());
        }
        for b in Baseline::ALL {
            assert_eq!(Baseline::from_name(b.name()), Some(b));
            assert_eq!(b.name().parse::<BakeMethod>().unwrap(), BakeMethod::Baseline(b));
        }
    }

    /// `bake --method` names all nine when it reads none.
    #[test]
    fn unknown_names_list_every_method() {
        assert_eq!(
            "point+taylor".parse::<BakeMethod>().unwrap_err(),
            "unknown method 'point+taylor' (point, prefilter, doi, doi-paper, doi-node, point+validity, point+apv, point+vlm, point+ddgi)"
        );
        assert_eq!(
            "bogus".parse::<Method>().unwrap_err(),
            "unknown method 'bogus' (point, prefilter, doi, doi-paper, doi-node)"
        );
    }
}
