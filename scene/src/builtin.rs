//! Built-in scenes that need no files (the embedded default for demos and tests), each
//! with a recommended grid, lights and evaluation plate heights.
//!
//! - [`city`]: ground and 16 buildings under a sky with a soft sun (Kontkanen & Laine 2006
//!   Fig. 6a-b in spirit: many grid nodes fall inside buildings).
//! - [`interior`]: a closed room with thick walls, a window, a bed of thin bars and a table,
//!   lit by sun and sky through the window (Fig. 6c).
//! - [`maze`]: thick maze walls on a ground plane (Fig. 2, left).
//!
//! All solids are closed boxes with outward normals (bottoms omitted where they stand on
//! the ground), so their insides are outside the domain of interest. Units: metres, +Z up.

use glam::DVec3;
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_volume::GridSpec;

use crate::builder::SceneBuilder;
use crate::lights::{Environment, Sun};
use crate::material::Material;
use crate::scene::Scene;

/// A built-in scene with its recommended bake setup.
#[derive(Clone, Debug)]
pub struct BuiltinScene {
    /// The scene (lights included).
    pub scene: Scene,
    /// Recommended grid.
    pub grid: GridSpec,
    /// Heights (z) of horizontal evaluation plates.
    pub plate_heights: Vec<f64>,
    /// What it shows.
    pub description: &'static str,
}

/// Names accepted by [`builtin`].
pub const BUILTIN_NAMES: [&str; 3] = ["city", "interior", "maze"];

/// A built-in scene by name.
#[must_use]
pub fn builtin(name: &str) -> Option<BuiltinScene> {
    match name {
        "city" => Some(city()),
        "interior" => Some(interior()),
        "maze" => Some(maze()),
        _ => None,
    }
}

fn grid(min: [f64; 3], max: [f64; 3], res: [u32; 3]) -> GridSpec {
    // The built-in bounds are valid by construction (finite, non-empty, res >= 2).
    GridSpec::new(min, max, res).expect("built-in grid is valid")
}

fn ground(b: &mut SceneBuilder, half: f64, albedo: [f64; 3]) -> u32 {
    let m = b.add_material(Material::diffuse("ground", albedo)).expect("finite");
    b.add_quad(
        [
            DVec3::new(-half, -half, 0.0),
            DVec3::new(half, -half, 0.0),
            DVec3::new(half, half, 0.0),
            DVec3::new(-half, half, 0.0),
        ],
        m,
    )
    .expect("valid quad");
    m
}

impl BuiltinScene {
    /// A `res[0] × res[1]` lattice of points (cell centres) over the grid's horizontal
    /// extent at height `z`, row-major with x fastest: an evaluation plate (Kontkanen &
    /// Laine 2006 Fig. 6). Mask it with the domain-of-interest test (lightvol-sampler's
    /// `domain::classify_points`).
    #[must_use]
    pub fn plate(&self, z: f64, res: [u32; 2]) -> Vec<DVec3> {
        let (lo, hi) = self.grid.bounds();
        let mut out = Vec::with_capacity(res[0] as usize * res[1] as usize);
        for j in 0..res[1] {
            for i in 0..res[0] {
                let fx = (f64::from(i) + 0.5) / f64::from(res[0]);
                let fy = (f64::from(j) + 0.5) / f64::from(res[1]);
                out.push(DVec3::new(lo[0] + fx * (hi[0] - lo[0]), lo[1] + fy * (hi[1] - lo[1]), z));
            }
        }
        out
    }
}

/// The footprints and heights of the city's buildings: `(min, max)` boxes.
#[must_use]
pub fn city_buildings() -> Vec<(DVec3, DVec3)> {
    let mut rng = SplitMix64::new(0xc17e);
    let mut out = Vec::new();
    for bx in 0..4 {
        for by in 0..4 {
            // Blocks on a 14 m pitch with 4-5 m streets; sizes vary so that grid nodes on
            // a 4 m pitch land inside most buildings.
            let cx = -21.0 + 14.0 * f64::from(bx) + rng.range(-1.0, 1.0);
            let cy = -21.0 + 14.0 * f64::from(by) + rng.range(-1.0, 1.0);
            let hx = rng.range(3.5, 5.0);
            let hy = rng.range(3.5, 5.0);
            let h = rng.range(6.0, 18.0);
            out.push((DVec3::new(cx - hx, cy - hy, 0.0), DVec3::new(cx + hx, cy + hy, h)));
        }
    }
    out
}

/// Ground and 16 box buildings, a blue-ish uniform sky and a soft sun (3° radius) at 40°
/// elevation. Grid: 4 m spacing over the town, from 1 m below the ground to 22 m.
#[must_use]
pub fn city() -> BuiltinScene {
    let mut b = SceneBuilder::new("city");
    ground(&mut b, 100.0, [0.35, 0.33, 0.3]);
    let palette = [[0.7, 0.65, 0.55], [0.55, 0.6, 0.7], [0.75, 0.5, 0.4], [0.6, 0.6, 0.6]];
    let mats: Vec<u32> = palette
        .iter()
        .enumerate()
        .map(|(i, &c)| b.add_material(Material::diffuse(&format!("facade{i}"), c)).expect("finite"))
        .collect();
    for (i, (lo, hi)) in city_buildings().into_iter().enumerate() {
        b.add_box(lo, hi, mats[i % mats.len()], true, true).expect("valid box");
    }
    b.environment = Environment::UniformSky { sky: [0.55, 0.65, 0.85], ground: None };
    b.sun = Some(Sun::from_angles(40.0, 35.0, [3.0, 2.85, 2.6], 3f64.to_radians()));
    BuiltinScene {
        scene: b.build().expect("non-empty"),
        grid: grid([-30.0, -30.0, -1.0], [30.0, 30.0, 23.0], [16, 16, 7]),
        plate_heights: vec![1.0, 6.0],
        description: "ground and 16 buildings, sky and soft sun (Kontkanen & Laine 2006 Fig. 6a-b)",
    }
}

/// Room interior `[0, 6] × [0, 5] × [0, 3]` m; walls, floor and ceiling are 0.3 m thick
/// boxes; a 1.6 × 1.2 m window in the +Y wall; a bed of 0.05 m bars and a table.
#[must_use]
pub fn interior() -> BuiltinScene {
    let (w, d, h, t) = (6.0, 5.0, 3.0, 0.3);
    let mut b = SceneBuilder::new("interior");
    let wall = b.add_material(Material::diffuse("plaster", [0.75, 0.72, 0.68])).expect("finite");
    let floor = b.add_material(Material::diffuse("wood", [0.5, 0.35, 0.22])).expect("finite");
    let bed = b.add_material(Material::diffuse("bed", [0.7, 0.3, 0.25])).expect("finite");
    let table = b.add_material(Material::diffuse("table", [0.45, 0.4, 0.35])).expect("finite");
    let v = DVec3::new;
    let solid = |b: &mut SceneBuilder, lo: DVec3, hi: DVec3, m: u32| {
        b.add_box(lo, hi, m, true, false).expect("valid box")
    };
    // Floor and ceiling slabs, then walls; the +Y wall is built around the window.
    solid(&mut b, v(-t, -t, -t), v(w + t, d + t, 0.0), floor);
    solid(&mut b, v(-t, -t, h), v(w + t, d + t, h + t), wall);
    solid(&mut b, v(-t, -t, 0.0), v(0.0, d + t, h), wall);
    solid(&mut b, v(w, -t, 0.0), v(w + t, d + t, h), wall);
    solid(&mut b, v(0.0, -t, 0.0), v(w, 0.0, h), wall);
    let (wx0, wx1, wz0, wz1) = (2.2, 3.8, 0.9, 2.1);
    solid(&mut b, v(0.0, d, 0.0), v(wx0, d + t, h), wall);
    solid(&mut b, v(wx1, d, 0.0), v(w, d + t, h), wall);
    solid(&mut b, v(wx0, d, 0.0), v(wx1, d + t, wz0), wall);
    solid(&mut b, v(wx0, d, wz1), v(wx1, d + t, h), wall);
    // Bed: 2 m × 1.4 m, 9 bars 0.05 m thick at 0.45 m, on two rails and four legs.
    let (bx0, by0) = (0.4, 0.5);
    for k in 0..9 {
        let x = bx0 + 0.1 + f64::from(k) * 0.22;
        solid(&mut b, v(x, by0, 0.45), v(x + 0.05, by0 + 1.4, 0.5), bed);
    }
    for y in [by0, by0 + 1.35] {
        solid(&mut b, v(bx0, y, 0.4), v(bx0 + 2.0, y + 0.05, 0.45), bed);
    }
    for (x, y) in [(bx0, by0), (bx0 + 1.95, by0), (bx0, by0 + 1.35), (bx0 + 1.95, by0 + 1.35)] {
        solid(&mut b, v(x, y, 0.0), v(x + 0.05, y + 0.05, 0.4), bed);
    }
    // Table: 1.2 × 0.8 m top at 0.75 m on four legs.
    let (tx0, ty0) = (3.8, 2.6);
    solid(&mut b, v(tx0, ty0, 0.72), v(tx0 + 1.2, ty0 + 0.8, 0.77), table);
    for (x, y) in [(tx0, ty0), (tx0 + 1.14, ty0), (tx0, ty0 + 0.74), (tx0 + 1.14, ty0 + 0.74)] {
        solid(&mut b, v(x + 0.02, y + 0.02, 0.0), v(x + 0.06, y + 0.06, 0.72), table);
    }
    b.environment = Environment::UniformSky { sky: [0.5, 0.6, 0.8], ground: Some([0.2, 0.18, 0.15]) };
    // Sun shining in through the +Y window, 30° up.
    b.sun = Some(Sun::from_angles(30.0, 100.0, [4.0, 3.8, 3.4], 1f64.to_radians()));
    BuiltinScene {
        scene: b.build().expect("non-empty"),
        // The outer node layers sit *inside* the 0.3 m walls, floor and ceiling (at 0.15 m
        // depth), as grid nodes do in real rooms: point sampling then reads darkness from
        // inside the solids (Kontkanen & Laine 2006 Fig. 6c), which domain-of-interest
        // sampling avoids. A few nodes of the +Y layer fall in the window opening. Spacing
        // about 0.3 m (0.30 × 0.29 × 0.275): coarser grids cannot hold the sun patch under
        // the window at all, and its blur then dominates every method's error.
        grid: grid([-0.15, -0.15, -0.15], [6.15, 5.15, 3.15], [22, 19, 13]),
        plate_heights: vec![0.6, 1.2],
        description: "closed room, thick walls, window, bed of thin bars, table; sun and sky (Fig. 6c)",
    }
}

/// The maze's wall segments: `(min, max)` boxes.
#[must_use]
pub fn maze_walls() -> Vec<(DVec3, DVec3)> {
    // A 6 × 6 perfect maze by seeded depth-first search; cells 3 m, walls 0.4 m thick,
    // 2.5 m high.
    const N: usize = 6;
    let (cell, th, hgt) = (3.0, 0.4, 2.5);
    let mut rng = SplitMix64::new(0x3a2e);
    // open_e[x][y]: no wall between (x, y) and (x+1, y); open_n: between (x, y) and (x, y+1).
    let mut open_e = [[false; N]; N];
    let mut open_n = [[false; N]; N];
    let mut seen = [[false; N]; N];
    let mut stack = vec![(0usize, 0usize)];
    seen[0][0] = true;
    while let Some(&(x, y)) = stack.last() {
        let mut nbrs = Vec::new();
        if x + 1 < N && !seen[x + 1][y] {
            nbrs.push((x + 1, y));
        }
        if x > 0 && !seen[x - 1][y] {
            nbrs.push((x - 1, y));
        }
        if y + 1 < N && !seen[x][y + 1] {
            nbrs.push((x, y + 1));
        }
        if y > 0 && !seen[x][y - 1] {
            nbrs.push((x, y - 1));
        }
        if nbrs.is_empty() {
            stack.pop();
            continue;
        }
        let (nx, ny) = nbrs[(rng.next_u64() % nbrs.len() as u64) as usize];
        match (nx as i64 - x as i64, ny as i64 - y as i64) {
            (1, 0) => open_e[x][y] = true,
            (-1, 0) => open_e[nx][ny] = true,
            (0, 1) => open_n[x][y] = true,
            _ => open_n[nx][ny] = true,
        }
        seen[nx][ny] = true;
        stack.push((nx, ny));
    }
    let o = -(N as f64) * cell / 2.0;
    let mut walls = Vec::new();
    let seg = |x0: f64, y0: f64, x1: f64, y1: f64| {
        (DVec3::new(x0 - th / 2.0, y0 - th / 2.0, 0.0), DVec3::new(x1 + th / 2.0, y1 + th / 2.0, hgt))
    };
    let total = N as f64 * cell;
    // Outer walls, with an entrance at the south-west and an exit at the north-east.
    walls.push(seg(o + cell, o, o + total, o));
    walls.push(seg(o, o + total, o + total - cell, o + total));
    walls.push(seg(o, o, o, o + total));
    walls.push(seg(o + total, o, o + total, o + total));
    for x in 0..N {
        for y in 0..N {
            let (cx, cy) = (o + x as f64 * cell, o + y as f64 * cell);
            if x + 1 < N && !open_e[x][y] {
                walls.push(seg(cx + cell, cy, cx + cell, cy + cell));
            }
            if y + 1 < N && !open_n[x][y] {
                walls.push(seg(cx, cy + cell, cx + cell, cy + cell));
            }
        }
    }
    walls
}

/// A maze (Fig. 2, left) on a ground plane under sky and sun. Grid: 2 m spacing.
#[must_use]
pub fn maze() -> BuiltinScene {
    let mut b = SceneBuilder::new("maze");
    ground(&mut b, 60.0, [0.4, 0.38, 0.33]);
    let m = b.add_material(Material::diffuse("hedge", [0.3, 0.5, 0.3])).expect("finite");
    for (lo, hi) in maze_walls() {
        b.add_box(lo, hi, m, true, true).expect("valid box");
    }
    b.environment = Environment::UniformSky { sky: [0.55, 0.65, 0.85], ground: None };
    b.sun = Some(Sun::from_angles(50.0, -60.0, [3.0, 2.9, 2.7], 2f64.to_radians()));
    BuiltinScene {
        scene: b.build().expect("non-empty"),
        grid: grid([-10.0, -10.0, -0.5], [10.0, 10.0, 3.5], [11, 11, 3]),
        plate_heights: vec![1.0],
        description: "thick maze walls on a ground plane (Kontkanen & Laine 2006 Fig. 2, left)",
    }
}
