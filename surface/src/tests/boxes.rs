//! Intersecting boxes: the domain of interest of texels buried in other geometry.

use lightvol_core::samples::samples;

use super::*;

/// Box A `[-1, 1]² × [0, 1.5]` and box B `[0.3, 1.8] × [-0.5, 0.5] × [0, 1]`, which pierces
/// A's +X face; both without bottoms, on a ground plane (not baked), under a uniform sky.
/// Each box face gets its own chart in a 3 × 2 grid of the lightmap, 4 % padding (2 texels at
/// the test's density).
const BOX_A: (DVec3, DVec3) = (DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 1.5));
const BOX_B: (DVec3, DVec3) = (DVec3::new(0.3, -0.5, 0.0), DVec3::new(1.8, 0.5, 1.0));

fn box_object(b: &mut SceneBuilder, name: &str, (lo, hi): (DVec3, DVec3), material: u32) {
    let c = |x: usize, y: usize, z: usize| DVec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z]);
    // Counter-clockwise seen from outside; no bottom face.
    let faces = [
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
        [c(0, 1, 0), c(0, 0, 0), c(0, 0, 1), c(0, 1, 1)],
        [c(1, 1, 0), c(0, 1, 0), c(0, 1, 1), c(1, 1, 1)],
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
    ];
    let extent = (hi - lo).max_element();
    let (cell_w, cell_h, pad) = (1.0 / 3.0, 0.5, 0.04);
    let k = ((cell_w - 2.0 * pad) / extent).min((cell_h - 2.0 * pad) / extent);
    let (mut p, mut uv, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    for (f, q) in faces.iter().enumerate() {
        let origin = DVec2::new((f % 3) as f64 * cell_w + pad, (f / 3) as f64 * cell_h + pad);
        let (es, et) = (q[1] - q[0], q[3] - q[0]);
        let base = p.len() as u32;
        for (s, t) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            p.push(q[0] + es * s + et * t);
            uv.push(origin + DVec2::new(s * es.length() * k, t * et.length() * k));
        }
        tris.push([base, base + 1, base + 2]);
        tris.push([base, base + 2, base + 3]);
    }
    add_object(b, name, p, uv, &tris, material);
}

pub(super) fn boxes_scene() -> Scene {
    let mut b = SceneBuilder::new("boxes");
    let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
    let g = b.add_material(Material::diffuse("ground", [0.3; 3])).unwrap();
    b.add_quad(
        [
            DVec3::new(-6.0, -6.0, 0.0),
            DVec3::new(6.0, -6.0, 0.0),
            DVec3::new(6.0, 6.0, 0.0),
            DVec3::new(-6.0, 6.0, 0.0),
        ],
        g,
    )
    .unwrap();
    box_object(&mut b, "A", BOX_A, m);
    box_object(&mut b, "B", BOX_B, m);
    b.environment = Environment::UniformSky { sky: [1.0; 3], ground: None };
    b.build().unwrap()
}

fn strictly_inside((lo, hi): (DVec3, DVec3), p: DVec3) -> bool {
    const MARGIN: f64 = 1e-9;
    (0..3).all(|i| p[i] > lo[i] + MARGIN && p[i] < hi[i] - MARGIN)
}

/// Texels *near the intersection* are those whose footprint has both visible and
/// buried points (a 4 × 4 grid of footprint points, classified analytically: a point of box A
/// strictly inside box B is buried, and vice versa — ground truth independent of the bake's
/// ray-based classification), and the wholly buried texels beside them (4-neighbours), which
/// bilinear filtering blends into the visible surface. Such a texel *leaks dark* when its
/// irradiance at the normal is below half the path-traced irradiance (256 samples) at the
/// centroid of the visible grid points of the straddling texel. With the domain-of-interest
/// treatment no such texel leaks; without it both kinds do.
#[test]
fn intersecting_boxes_do_not_leak_dark_with_domain_of_interest() {
    const DARK: f64 = 0.5;
    let scene = boxes_scene();
    let tracer = Tracer::new(&scene);
    let t = Transport::new(&scene, &tracer, TransportSettings { bounces: 1, ..TransportSettings::default() });
    let geo = SurfaceGeometry::new(&scene, UvSet::Lightmap).unwrap();
    let base = SurfaceSettings { samples: samples(64), texels_per_unit: 8.0, ..settings("sh9") };
    let fixed = bake_surface(&t, &base, &BakeControl::default()).unwrap();
    let kept = bake_surface(
        &t,
        &SurfaceSettings { invalid: InvalidTexels::Keep, ..base.clone() },
        &BakeControl::default(),
    )
    .unwrap();
    let r = &fixed.report;
    println!("fixed: {r:?}\nkept: {:?}", kept.report);
    assert!(r.invalid_texels > 0 && r.moved > 0 && r.dilated > 0, "{r:?}");
    // Faces buried whole (B's -X face inside A) have no valid texel to dilate from.
    assert_eq!(r.invalid_texels, r.moved + r.dilated + r.unfilled);
    assert!(kept.report.invalid_texels > 0);
    assert_eq!((kept.report.moved, kept.report.dilated), (0, 0));
    // Per-object counters in the maps sum to the report; the maps carry the lighting.
    for bake in [&fixed, &kept] {
        let sum = bake.maps.iter().fold(InvalidCounts::default(), |a, m| InvalidCounts {
            invalid_texels: a.invalid_texels + m.invalid.invalid_texels,
            moved: a.moved + m.invalid.moved,
            dilated: a.dilated + m.invalid.dilated,
            unfilled: a.unfilled + m.invalid.unfilled,
        });
        let r = &bake.report;
        assert_eq!(
            sum,
            InvalidCounts {
                invalid_texels: r.invalid_texels,
                moved: r.moved,
                dilated: r.dilated,
                unfilled: r.unfilled
            }
        );
        for m in &bake.maps {
            assert!(m.invalid.invalid_texels > 0, "{}: {:?}", m.object, m.invalid);
            assert_eq!(
                m.lighting,
                lighting_fingerprint(
                    &scene,
                    &TransportSettings { bounces: 1, ..TransportSettings::default() }
                )
            );
            assert!(m.lighting.ends_with("; bounces=1+roulette"), "{}", m.lighting);
        }
    }
    for m in &fixed.maps {
        let c = m.invalid;
        assert_eq!(c.invalid_texels, c.moved + c.dilated + c.unfilled, "{}", m.object);
    }

    let sh9 = lightvol_hemibasis::ShBasis::new(3);
    let (mut mixed, mut adjacent) = (0, 0);
    let (mut leaks_fixed, mut leaks_kept) = (Vec::new(), Vec::new());
    for (o, obj) in geo.objects().iter().enumerate() {
        let other = if obj.name == "A" { BOX_B } else { BOX_A };
        let (w, h) = (fixed.maps[o].width, fixed.maps[o].height);
        // Per texel: visible grid points (triangle, position) and the number of buried ones.
        let mut cls: Vec<(Vec<(u32, DVec3)>, u32)> = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let mut visible = Vec::new();
                let mut buried = 0;
                for j in 0..4 {
                    for i in 0..4 {
                        let uv = DVec2::new(
                            (f64::from(x) + (f64::from(i) + 0.5) / 4.0) / f64::from(w),
                            (f64::from(y) + (f64::from(j) + 0.5) / 4.0) / f64::from(h),
                        );
                        let Some((tri, bary)) = locate(&geo, &obj.triangles, uv) else { continue };
                        let p = scene.triangles[tri as usize].point(bary[0], bary[1]);
                        if strictly_inside(other, p) {
                            buried += 1;
                        } else {
                            visible.push((tri, p));
                        }
                    }
                }
                cls.push((visible, buried));
            }
        }
        let is_mixed = |t: usize| cls[t].1 > 0 && !cls[t].0.is_empty();
        // Reference: path-traced irradiance at the centroid of the visible points of the
        // texel itself (straddling) or of its first straddling 4-neighbour (a buried texel next
        // to the intersection, which bilinear filtering blends into that neighbour's visible
        // part). The visible points lie on one face: the charts are faces.
        let reference_at = |texel: usize| -> f64 {
            let visible = &cls[texel].0;
            let tri = visible[0].0;
            let c = visible.iter().map(|v| v.1).sum::<DVec3>() / visible.len() as f64;
            let bary = bary_of(&scene.triangles[tri as usize].v, c);
            reference_surface_irradiance(
                &t,
                &geo,
                tri,
                bary,
                [0.0, 0.0, 1.0],
                Quantity::Irradiance,
                samples(256),
                5,
                texel as u64,
            )
            .0[1]
        };
        for y in 0..h {
            for x in 0..w {
                let texel = (y * w + x) as usize;
                let source = if is_mixed(texel) {
                    mixed += 1;
                    texel
                } else if cls[texel].1 > 0 {
                    let nb = [
                        (x > 0).then(|| texel - 1),
                        (x + 1 < w).then(|| texel + 1),
                        (y > 0).then(|| texel - w as usize),
                        (y + 1 < h).then(|| texel + w as usize),
                    ];
                    let Some(n) = nb.into_iter().flatten().find(|&n| is_mixed(n)) else { continue };
                    adjacent += 1;
                    n
                } else {
                    continue;
                };
                let reference = reference_at(source);
                let at = |m: &CoefficientMap| {
                    let c: Vec<f64> = m.texel(x, y).iter().map(|v| f64::from(v[1])).collect();
                    sh9.reconstruct_f64(&c, [0.0, 0.0, 1.0])
                };
                let (ef, ek) = (at(&fixed.maps[o]), at(&kept.maps[o]));
                let buried_whole = texel != source;
                if ef < DARK * reference {
                    leaks_fixed.push((obj.name.clone(), x, y, buried_whole, ef, reference));
                }
                if ek < DARK * reference {
                    leaks_kept.push((obj.name.clone(), x, y, buried_whole, ek, reference));
                }
            }
        }
    }
    let count =
        |l: &[(String, u32, u32, bool, f64, f64)], whole: bool| l.iter().filter(|v| v.3 == whole).count();
    println!(
        "{mixed} texels straddle the intersection, {adjacent} buried texels border them; dark leaks \
         (straddling, buried): fixed ({}, {}), kept ({}, {})",
        count(&leaks_fixed, false),
        count(&leaks_fixed, true),
        count(&leaks_kept, false),
        count(&leaks_kept, true)
    );
    assert!(mixed >= 20 && adjacent >= 20, "{mixed} {adjacent}");
    assert!(leaks_fixed.is_empty(), "{leaks_fixed:?}");
    assert!(count(&leaks_kept, false) >= 5 && count(&leaks_kept, true) >= 5, "{leaks_kept:?}");
}

/// The triangle of `tris` whose lightmap UV triangle contains `uv`, with barycentrics.
fn locate(geo: &SurfaceGeometry, tris: &[u32], uv: DVec2) -> Option<(u32, [f64; 2])> {
    tris.iter().find_map(|&tri| {
        let t = geo.triangle(tri)?.uv;
        let (d1, d2, r) = (t[1] - t[0], t[2] - t[0], uv - t[0]);
        let det = d1.perp_dot(d2);
        let (u, v) = (r.perp_dot(d2) / det, d1.perp_dot(r) / det);
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some((tri, [u, v]))
    })
}

/// Barycentrics `(u, v)` of a point in the plane of triangle `v`.
fn bary_of(v: &[DVec3; 3], p: DVec3) -> [f64; 2] {
    let (e1, e2, r) = (v[1] - v[0], v[2] - v[0], p - v[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (r.dot(e1), r.dot(e2));
    let det = d11 * d22 - d12 * d12;
    [(r1 * d22 - r2 * d12) / det, (r2 * d11 - r1 * d12) / det]
}
