//! `lightvol lint`: geometry diagnostics that matter for domain-of-interest baking
//! (Kontkanen & Laine 2006 §7): reversed polygons seen from open space, and inconsistent
//! winding across shared edges. Exits with status 2 when suspects are found.

use std::process::ExitCode;

use clap::Args;
use lightvol_scene::diagnostics::{BackFaceSettings, back_face_report, lattice_points, winding_report};
use lightvol_scene::{DVec3, Tracer};
use serde::Serialize;

use crate::setup::{GridArgs, SceneArgs, with_threads};

/// `lightvol lint`.
#[derive(Debug, Args)]
pub(crate) struct LintArgs {
    /// Scene (lights are irrelevant here).
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// The lattice of probe points: `--bounds` and `--res`/`--spacing` as for a bake; by
    /// default the scene's own bounds (not padded: space outside a closed room sees its
    /// back faces by design) with about 16 cells along the longest axis.
    #[command(flatten)]
    pub(crate) grid: GridArgs,
    /// Probe points per grid cell.
    #[arg(long, default_value_t = 4)]
    points_per_cell: u32,
    /// Rays per probe point.
    #[arg(long, default_value_t = 128)]
    pub(crate) dirs: u32,
    /// Vertices closer than this are welded for the winding check (default: 1e-6 of the
    /// scene's extent).
    #[arg(long)]
    weld: Option<f64>,
    /// Report back-face suspects only with at least this many hits. A reversed polygon in
    /// open space is hit by a large share of the probe points around it (hundreds of hits);
    /// a handful means a few probe points squeezed into a sliver of space, such as the
    /// 0.8 mm gap between the Cornell box's light and its ceiling.
    #[arg(long, default_value_t = 50)]
    min_score: u32,
    /// Print suspects as JSON.
    #[arg(long)]
    pub(crate) json: bool,
    /// Worker threads.
    #[arg(long)]
    pub(crate) threads: Option<usize>,
}

/// One suspect triangle in the JSON output.
#[derive(Debug, Serialize)]
struct SuspectJson {
    /// Which check flagged it: `back_face` or `winding`.
    check: &'static str,
    /// Triangle index in load order.
    triangle: u32,
    /// Where to look.
    position: [f64; 3],
    /// Back-face hits, or inconsistent edges.
    score: u32,
}

/// Runs `lightvol lint`.
pub(crate) fn run(args: &LintArgs) -> anyhow::Result<ExitCode> {
    let loaded = args.scene.load()?;
    let (lo, hi) = loaded.scene.bounds();
    let mut grid_args = args.grid.clone();
    if grid_args.bounds.is_none() {
        // Shrink by a hair so that probe points never sit exactly on the outer surfaces.
        let e = (hi - lo) * 1e-4;
        // (--bounds is read in the file's frame.)
        let (a, b) = loaded.frame.box_to_file((lo + e).to_array(), (hi - e).to_array());
        grid_args.bounds = Some(format!("{},{},{},{},{},{}", a[0], a[1], a[2], b[0], b[1], b[2]));
    }
    let grid = grid_args.grid(&loaded, false)?;
    let weld = args.weld.unwrap_or(1e-6 * (hi - lo).length().max(1e-12));
    let (bf, wr) = with_threads(args.threads, || {
        let tracer = Tracer::new(&loaded.scene);
        let (a, b) = grid.bounds();
        let cells = grid.res().map(|r| r - 1);
        let points = lattice_points(DVec3::from(a), DVec3::from(b), cells, args.points_per_cell, 1);
        let bf = back_face_report(
            &tracer,
            &points,
            &BackFaceSettings { dirs: args.dirs, ..BackFaceSettings::default() },
        );
        (bf, winding_report(&loaded.scene, weld))
    })?;
    let mut all: Vec<SuspectJson> = bf
        .suspects
        .iter()
        .filter(|s| s.score >= args.min_score)
        .map(|s| SuspectJson {
            check: "back_face",
            triangle: s.triangle,
            position: s.position.to_array(),
            score: s.score,
        })
        .collect();
    all.extend(wr.suspects.iter().map(|s| SuspectJson {
        check: "winding",
        triangle: s.triangle,
        position: s.position.to_array(),
        score: s.score,
    }));
    if args.json {
        let v = serde_json::json!({
            "scene": loaded.label,
            "suspects": all,
            "inconsistent_edges": wr.inconsistent_edges,
            "boundary_edges": wr.boundary_edges,
            "non_manifold_edges": wr.non_manifold_edges,
            "probe_points": { "clean": bf.clean_points, "counted": bf.counted_points, "inside_solids": bf.solid_points },
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{}: {} triangles; probe points: {} clean, {} seeing some back faces, {} inside solids",
            loaded.label,
            loaded.scene.triangle_count(),
            bf.clean_points,
            bf.counted_points,
            bf.solid_points
        );
        println!(
            "winding: {} inconsistent shared edges, {} open (boundary) edges, {} non-manifold edges",
            wr.inconsistent_edges, wr.boundary_edges, wr.non_manifold_edges
        );
        for s in &all {
            println!(
                "suspect {:>9} triangle {:>7} at ({:.4}, {:.4}, {:.4}) score {}",
                s.check, s.triangle, s.position[0], s.position[1], s.position[2], s.score
            );
        }
        if all.is_empty() {
            println!("no suspects");
        }
    }
    Ok(if all.is_empty() { ExitCode::SUCCESS } else { ExitCode::from(2) })
}
