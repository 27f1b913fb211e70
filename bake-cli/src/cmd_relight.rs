//! `lightvol relight`: a volume baked with light groups, its groups scaled and summed
//! (lightvol-volume's `light_groups`), and with a sky transfer relit by a new sky, written
//! as a plain volume.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use lightvol_volume::io::exr::{ExrOptions, write_exr};
use lightvol_volume::io::groups::read_grouped_exr;

/// `lightvol relight`.
#[derive(Debug, Args)]
pub(crate) struct RelightArgs {
    /// A volume baked with `--light-groups`.
    pub(crate) volume: PathBuf,
    /// Scales per group, `NAME=S` or `NAME=R,G,B`, separated by `;` (groups not named keep
    /// 1): for example `sun=0;lamps=1,0.8,0.6` turns the sun off and warms the lamps.
    #[arg(long, value_name = "NAME=S;...", default_value = "")]
    pub(crate) scale: String,
    /// A new uniform sky for a volume baked with --sky-transfer: radiance `R,G,B` over the
    /// upper hemisphere and `:R,G,B` below the horizon (default black), as `bake --sky` and
    /// `--ground` give it.
    #[arg(long, value_name = "R,G,B[:R,G,B]", conflicts_with = "env")]
    pub(crate) sky: Option<String>,
    /// A new sky from a latitude-longitude EXR environment map (as `bake --env` reads it),
    /// projected to the volume's sky transfer order; the projection's band-limit error (the
    /// open sky's irradiance against the projection's) is printed.
    #[arg(long, value_name = "FILE.exr")]
    pub(crate) env: Option<PathBuf>,
    /// For a file of lighting scenarios: their blend, `NAME=W;NAME=W` (scenarios not named
    /// weigh 0), for example `noon=0.25;dusk=0.75`.
    #[arg(long, value_name = "NAME=W;...", conflicts_with_all = ["scale", "sky", "env"])]
    pub(crate) blend: Option<String>,
    /// Write this group alone instead (its scale, if given, applies).
    #[arg(long, value_name = "NAME", conflicts_with = "list")]
    pub(crate) group: Option<String>,
    /// List the groups and exit.
    #[arg(long)]
    pub(crate) list: bool,
    /// Output volume (native EXR, without groups).
    #[arg(short, long, required_unless_present = "list")]
    pub(crate) output: Option<PathBuf>,
}

/// Parses `R,G,B[:R,G,B]`: sky and ground radiance.
fn uniform_sky(spec: &str) -> anyhow::Result<lightvol_scene::Environment> {
    let rgb = |t: &str| -> anyhow::Result<[f64; 3]> {
        let v: Vec<f64> = t
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| anyhow::anyhow!("--sky: '{t}' is not R,G,B"))?;
        match v[..] {
            [r, g, b] if v.iter().all(|c| c.is_finite() && *c >= 0.0) => Ok([r, g, b]),
            _ => anyhow::bail!("--sky: '{t}' is not three finite radiances >= 0"),
        }
    };
    let (sky, ground) = match spec.split_once(':') {
        Some((s, g)) => (rgb(s)?, Some(rgb(g)?)),
        None => (rgb(spec)?, None),
    };
    Ok(lightvol_scene::Environment::UniformSky { sky, ground })
}

/// Runs `lightvol relight`.
pub(crate) fn run(args: &RelightArgs) -> anyhow::Result<ExitCode> {
    let path = &args.volume;
    let grouped = read_grouped_exr(path).with_context(|| format!("reading {}", path.display()))?;
    if args.list {
        for n in grouped.names() {
            println!("{n}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    let mut scales = match &args.blend {
        Some(b) => grouped.parse_blend(b).context("--blend")?,
        None => grouped.parse_scales(&args.scale).context("--scale")?,
    };
    if let Some(name) = &args.group {
        let g = grouped.find(name).ok_or_else(|| {
            anyhow::anyhow!(
                "--group: no light group {name:?} (the volume has {})",
                grouped.names().join(", ")
            )
        })?;
        for (i, s) in scales.iter_mut().enumerate() {
            if i != g {
                *s = [0.0; 3];
            }
        }
    }
    let sky = match (&args.sky, &args.env) {
        (Some(spec), _) => Some(uniform_sky(spec)?),
        (None, Some(path)) => Some(lightvol_scene::Environment::Map(
            lightvol_scene::envmap::EnvMap::from_exr(path)
                .with_context(|| format!("reading {}", path.display()))?,
        )),
        (None, None) => None,
    };
    if let Some(env) = sky {
        let (_, n) = grouped.sky_transfer().ok_or_else(|| {
            anyhow::anyhow!(
                "{} has no sky transfer: bake it with --sky-transfer 2, 3 or 4 to relight its sky",
                path.display()
            )
        })?;
        let coeffs = lightvol_scene::light_groups::sky_coefficients(&env, n);
        scales = grouped.sky_scales(&coeffs, Some(&scales)).context("--sky")?;
        let order = (n as f64).sqrt().round();
        let loss = lightvol_scene::band_limit::irradiance_band_limit_error(&env, n);
        eprintln!(
            "the new sky at SH order {order}: its open-sky irradiance is off by {:.2}% (relative RMS over \
             normals); points that see part of the sky can see more of it",
            100.0 * loss
        );
    }
    let relit = grouped.relit(&scales).context("relighting")?;
    let out = args.output.as_ref().expect("clap requires --output without --list");
    write_exr(out, &relit, &ExrOptions::default()).with_context(|| format!("writing {}", out.display()))?;
    eprintln!("wrote {}", out.display());
    Ok(ExitCode::SUCCESS)
}
