//! `lightvol layout SCENE.glb|gltf --tiles NXxNZ [--pitch P] -o DIR`: one glTF scene repeated
//! on a grid of tiles in the file's horizontal plane, written as a new glTF that shares the
//! source's binary data, so that the loader instances every mesh (lightvol-scene's
//! `layout::write_grid_layout`): large worlds to bake and stream from one room.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;

/// `lightvol layout`.
#[derive(Debug, Args)]
pub(crate) struct LayoutArgs {
    /// The glTF (or GLB) scene to repeat.
    scene: PathBuf,
    /// Tiles along the file's x and z axes, `NXxNZ` (e.g. `8x8`).
    #[arg(long, value_name = "NXxNZ")]
    tiles: String,
    /// Distance between neighbouring tiles, in the file's units.
    #[arg(long, default_value_t = 10.0)]
    pitch: f64,
    /// Folder to write `STEM_NXxNZ.gltf` (and its `.bin`) into.
    #[arg(short, long)]
    output: PathBuf,
}

/// Parses `NXxNZ` (two whole numbers of at least 1).
fn parse_tiles(s: &str) -> anyhow::Result<[u32; 2]> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let [a, b] = parts[..] else { bail!("--tiles: expected NXxNZ, e.g. 8x8, got '{s}'") };
    let n = |t: &str| -> anyhow::Result<u32> {
        match t.trim().parse::<u32>() {
            Ok(v) if v >= 1 => Ok(v),
            _ => bail!("--tiles: '{t}' is not a whole number of at least 1"),
        }
    };
    Ok([n(a)?, n(b)?])
}

/// Runs `lightvol layout`.
pub(crate) fn run(args: &LayoutArgs) -> anyhow::Result<ExitCode> {
    let tiles = parse_tiles(&args.tiles)?;
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let path = lightvol_scene::layout::write_grid_layout(&args.scene, &args.output, tiles, args.pitch)
        .with_context(|| format!("writing the layout of {}", args.scene.display()))?;
    eprintln!("wrote {} ({} x {} tiles, {} apart)", path.display(), tiles[0], tiles[1], args.pitch);
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_parse() {
        assert_eq!(parse_tiles("8x8").unwrap(), [8, 8]);
        assert_eq!(parse_tiles("3X2").unwrap(), [3, 2]);
        for bad in ["8", "0x2", "ax2", "2x2x2"] {
            assert!(parse_tiles(bad).is_err(), "{bad}");
        }
    }
}
