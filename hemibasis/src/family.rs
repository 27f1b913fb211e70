//! The families of bases by name: [`BasisFamily`], [`by_name`] and [`by_family`] (the bases
//! of \[Ish11\] §1.8 that the enabled cargo features compile), and [`LIGHTMAP_BASES`], the sizes
//! of \[Ish11\] Table 3.1 that lightvol bakes and compares.

use crate::basis::HemiBasis;
use crate::sh_basis::ShBasis;

/// The basis called `name` (as in [`HemiBasis::name`]) with `count` coefficients, if that
/// basis is compiled in and has such a size: `sh` (squares), `hl2` (3), `hsh` and
/// `makhotkin` (squares), `zernike` (triangular numbers), `hbasis`/`hbasis_mod` (4, 6).
#[must_use]
pub fn by_name(name: &str, count: usize) -> Option<Box<dyn HemiBasis>> {
    name.parse::<BasisFamily>().ok().and_then(|f| by_family(f, count))
}

/// A family of bases, by the name [`by_name`] takes (`sh`, `hl2`, `hsh`, `makhotkin`,
/// `zernike`, `hbasis`, `hbasis_mod`); every family exists whichever cargo features are on,
/// [`by_family`] builds only the enabled ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BasisFamily {
    /// Real spherical harmonics (\[Ish11\] §1.8.1).
    Sh,
    /// Half-Life 2's three-vector basis (§1.8.2).
    Hl2,
    /// Hemispherical harmonics (§1.8.3).
    Hsh,
    /// Makhotkin's hemispherical basis (§1.8.4).
    Makhotkin,
    /// Hemispherical Zernike polynomials (§1.8.5).
    Zernike,
    /// The H-basis (§1.8.6).
    HBasis,
    /// The modified H-basis (§1.8.7).
    HBasisMod,
}

impl BasisFamily {
    /// Every family, in the order above.
    pub const ALL: [Self; 7] =
        [Self::Sh, Self::Hl2, Self::Hsh, Self::Makhotkin, Self::Zernike, Self::HBasis, Self::HBasisMod];

    /// The name [`by_name`] takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Sh => "sh",
            Self::Hl2 => "hl2",
            Self::Hsh => "hsh",
            Self::Makhotkin => "makhotkin",
            Self::Zernike => "zernike",
            Self::HBasis => "hbasis",
            Self::HBasisMod => "hbasis_mod",
        }
    }
}

impl std::fmt::Display for BasisFamily {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for BasisFamily {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|f| f.name() == s).ok_or_else(|| format!("unknown basis family {s:?}"))
    }
}

/// The lightmap bases lightvol bakes and compares, as `(family, coefficients)`: each
/// family at the sizes of \[Ish11\] Table 3.1 (about 4 and about 9 coefficients; the
/// H-bases at 4 and 6, Zernike at 3 and 6, Half-Life 2 at its 3). [`by_family`] builds them
/// all when every cargo feature is on.
pub const LIGHTMAP_BASES: [(BasisFamily, usize); 13] = [
    (BasisFamily::Sh, 4),
    (BasisFamily::Sh, 9),
    (BasisFamily::Hl2, 3),
    (BasisFamily::Hsh, 4),
    (BasisFamily::Hsh, 9),
    (BasisFamily::Makhotkin, 4),
    (BasisFamily::Makhotkin, 9),
    (BasisFamily::Zernike, 3),
    (BasisFamily::Zernike, 6),
    (BasisFamily::HBasis, 4),
    (BasisFamily::HBasis, 6),
    (BasisFamily::HBasisMod, 4),
    (BasisFamily::HBasisMod, 6),
];

/// The basis of `family` with `count` coefficients, `None` for a size the family does not
/// have or a family whose cargo feature is off.
#[must_use]
pub fn by_family(family: BasisFamily, count: usize) -> Option<Box<dyn HemiBasis>> {
    let bands = count.isqrt();
    let square = bands * bands == count && bands > 0;
    match family {
        BasisFamily::Sh if square && bands <= 16 => Some(Box::new(ShBasis::new(bands))),
        #[cfg(feature = "hl2")]
        BasisFamily::Hl2 if count == 3 => Some(Box::new(crate::hl2::Hl2)),
        #[cfg(feature = "hsh")]
        BasisFamily::Hsh if square && bands <= 12 => Some(Box::new(crate::hsh::Hsh::new(bands))),
        #[cfg(feature = "makhotkin")]
        BasisFamily::Makhotkin if square && bands <= 10 => {
            Some(Box::new(crate::makhotkin::Makhotkin::new(bands)))
        }
        #[cfg(feature = "zernike")]
        BasisFamily::Zernike => {
            crate::zernike::Zernike::with_count(count).map(|z| Box::new(z) as Box<dyn HemiBasis>)
        }
        #[cfg(feature = "hbasis")]
        BasisFamily::HBasis => crate::hbasis::HBasis::new(count).map(|b| Box::new(b) as Box<dyn HemiBasis>),
        #[cfg(feature = "hbasis")]
        BasisFamily::HBasisMod => {
            crate::hbasis::HBasis::modified(count).map(|b| Box::new(b) as Box<dyn HemiBasis>)
        }
        _ => None,
    }
}
