//! Filling nodes that received no samples.
//!
//! A node whose trilinear support never met the domain of interest (Kontkanen & Laine 2006
//! §5: e.g. a node deep inside a wall) has a zero denominator in Eq. 6 and no estimate. It
//! still takes part in run-time interpolation whenever a query point lies in one of its
//! cells, so it needs a value that does not drag its neighbours toward black (the
//! "darkness leaking from the wall" of the paper's §1).
//!
//! The fill is a deterministic dilation, in passes:
//!
//! 1. *Known* nodes are those with an estimate (weight > 0).
//! 2. In each pass, every unknown node with at least one known node among its 26
//!    neighbours gets the weighted average of those neighbours' coefficients, with weight
//!    `w_nb / d²`: `w_nb` is the neighbour's domain weight (for a node filled in an earlier
//!    pass, the mean domain weight of the nodes it was filled from) and `d` its grid-space
//!    distance. All fills of a pass read only values known before the pass (Jacobi
//!    order), so the result does not depend on traversal order or thread count.
//! 3. Nodes filled in a pass become known for the next; passes repeat until no unknown
//!    node has a known neighbour.
//!
//! If no node at all has an estimate, every node stays zero and is counted as unreachable.
//! Filled nodes keep weight 0 in the volume so that engines and tools can still tell them
//! apart (the KTX2/DDS exports put validity in alpha).

use crate::grid::GridSpec;

/// What [`crate::Accumulator::finalize`] did to nodes without an estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FillReport {
    /// Nodes that had zero weight and were filled from neighbours.
    pub filled: usize,
    /// Zero-weight nodes that could not be filled (only when no node has an estimate);
    /// they are left at zero.
    pub unreachable: usize,
    /// Dilation passes run (the largest neighbour-hop distance of a filled node).
    pub passes: u32,
    /// Non-finite values met by `finalize` and set to zero before the fill: coefficients
    /// (e.g. from a NaN radiance sample) plus non-finite denominators (node then treated
    /// as empty) and non-finite weights (weight then 1).
    pub non_finite_zeroed: usize,
}

/// Fills the nodes with `weights[node] == 0` in `values` (`[node][k]`, `k` floats per
/// node) by the dilation described in the module docs.
pub fn fill_empty_nodes(spec: &GridSpec, k: usize, values: &mut [f64], weights: &[f64]) -> FillReport {
    let n = spec.node_count();
    debug_assert_eq!(values.len(), n * k);
    // Source weight of each known node; None = unknown.
    let mut source: Vec<Option<f64>> = weights.iter().map(|&w| (w > 0.0).then_some(w)).collect();
    let mut report = FillReport::default();
    let unknown_at_start = source.iter().filter(|s| s.is_none()).count();
    if unknown_at_start == 0 {
        return report;
    }
    if unknown_at_start == n {
        report.unreachable = n;
        return report;
    }
    let cell = spec.cell_size();
    let res = spec.res();
    // The 26 neighbour offsets in a fixed order (the summation order of every fill) with
    // their inverse squared grid-space distances.
    let mut offsets: Vec<([i64; 3], f64)> = Vec::with_capacity(26);
    for dz in -1i64..=1 {
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                if dx != 0 || dy != 0 || dz != 0 {
                    let d2 = (dx as f64 * cell[0]).powi(2)
                        + (dy as f64 * cell[1]).powi(2)
                        + (dz as f64 * cell[2]).powi(2);
                    offsets.push(([dx, dy, dz], 1.0 / d2));
                }
            }
        }
    }
    let neighbours = |node: usize| {
        let c = spec.node_coords(node).map(i64::from);
        offsets.iter().filter_map(move |&(d, inv_d2)| {
            let p = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
            let inside = (0..3).all(|a| p[a] >= 0 && p[a] < i64::from(res[a]));
            inside.then(|| (spec.node_index(p[0] as u32, p[1] as u32, p[2] as u32), inv_d2))
        })
    };
    // Only unknown nodes next to a known one can be filled in a pass (the frontier), so a
    // pass costs O(frontier), not O(grid); the total work is O(nodes · 26 · k).
    let mut in_frontier = vec![false; n];
    let mut frontier: Vec<usize> = Vec::new();
    for node in 0..n {
        if source[node].is_none() && neighbours(node).any(|(nb, _)| source[nb].is_some()) {
            in_frontier[node] = true;
            frontier.push(node);
        }
    }
    let mut acc = vec![0.0f64; k];
    while !frontier.is_empty() {
        // Jacobi order: every fill of the pass reads only values known before it.
        let mut updates: Vec<(usize, f64, Vec<f64>)> = Vec::with_capacity(frontier.len());
        for &node in &frontier {
            acc.iter_mut().for_each(|a| *a = 0.0);
            let (mut wsum, mut src_wsum, mut src_count) = (0.0f64, 0.0f64, 0usize);
            for (nb, inv_d2) in neighbours(node) {
                let Some(sw) = source[nb] else { continue };
                let w = sw * inv_d2;
                for (a, v) in acc.iter_mut().zip(&values[nb * k..(nb + 1) * k]) {
                    *a += w * v;
                }
                wsum += w;
                src_wsum += sw;
                src_count += 1;
            }
            debug_assert!(src_count > 0, "frontier nodes have a known neighbour");
            updates.push((node, src_wsum / src_count as f64, acc.iter().map(|a| a / wsum).collect()));
        }
        report.passes += 1;
        for (node, sw, vals) in updates {
            values[node * k..(node + 1) * k].copy_from_slice(&vals);
            source[node] = Some(sw);
            report.filled += 1;
        }
        let mut next = Vec::new();
        for &node in &frontier {
            for (nb, _) in neighbours(node) {
                if source[nb].is_none() && !in_frontier[nb] {
                    in_frontier[nb] = true;
                    next.push(nb);
                }
            }
        }
        next.sort_unstable();
        frontier = next;
    }
    report.unreachable = source.iter().filter(|s| s.is_none()).count();
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_by_inverse_square_distance() {
        // 3x2x2 grid with cell size (1, 2, 1); node 0 = (0,0,0) known value 1 weight 1,
        // node 2 = (2,0,0) known value 4 weight 0.5. Node 1 = (1,0,0) has both at d² = 1.
        let spec = GridSpec::new([0.0; 3], [2.0, 2.0, 1.0], [3, 2, 2]).unwrap();
        let n = spec.node_count();
        let mut values = vec![0.0; n];
        let mut weights = vec![0.0; n];
        values[0] = 1.0;
        weights[0] = 1.0;
        values[2] = 4.0;
        weights[2] = 0.5;
        let r = fill_empty_nodes(&spec, 1, &mut values, &weights);
        assert_eq!(r.filled, n - 2);
        assert_eq!(r.unreachable, 0);
        // Node 1 sees nodes 0 and 2 at d²=1, plus nothing else known in pass 1.
        let want = (1.0 * 1.0 + 0.5 * 4.0) / (1.0 + 0.5);
        assert!((values[1] - want).abs() < 1e-15);
        assert_eq!(r.passes, 1);
    }

    #[test]
    fn all_empty_is_unreachable() {
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let mut values = vec![0.0; 8 * 3];
        let r = fill_empty_nodes(&spec, 3, &mut values, &[0.0; 8]);
        assert_eq!(r.unreachable, 8);
        assert_eq!(r.filled, 0);
        assert!(values.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn large_empty_region_fills_one_hop_per_pass() {
        // 48³ grid with a single known plane x = 0: 47 passes, each touching only the next
        // plane (the frontier), so this is fast; equality with the brute-force dilation is
        // checked on a smaller grid below.
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [48, 48, 48]).unwrap();
        let n = spec.node_count();
        let mut values = vec![0.0; n];
        let mut weights = vec![0.0; n];
        for node in 0..n {
            let [i, j, k] = spec.node_coords(node);
            if i == 0 {
                values[node] = f64::from(j + 2 * k);
                weights[node] = 1.0;
            }
        }
        let r = fill_empty_nodes(&spec, 1, &mut values, &weights);
        assert_eq!(r.passes, 47);
        assert_eq!(r.filled, n - 48 * 48);
        // Along +x the plane's values spread; a node deep inside the grid averages its
        // neighbours, so it stays within the range of the plane.
        assert!(values.iter().all(|&v| (0.0..=141.0).contains(&v)));
    }

    #[test]
    fn frontier_fill_equals_brute_force_jacobi() {
        let spec = GridSpec::new([0.0; 3], [2.0, 1.0, 1.5], [7, 5, 6]).unwrap();
        let n = spec.node_count();
        let mut rng = lightvol_sh::lowdisc::SplitMix64::new(4);
        let weights: Vec<f64> =
            (0..n).map(|_| if rng.next_f64() < 0.1 { rng.range(0.1, 1.0) } else { 0.0 }).collect();
        let start: Vec<f64> = (0..2 * n).map(|_| rng.range(-1.0, 1.0)).collect();
        let mut fast = start.clone();
        fill_empty_nodes(&spec, 2, &mut fast, &weights);
        // Brute force: every pass visits every unknown node, 26 neighbours in the same order.
        let mut slow = start;
        let mut src: Vec<Option<f64>> = weights.iter().map(|&w| (w > 0.0).then_some(w)).collect();
        let cell = spec.cell_size();
        loop {
            let mut upd = Vec::new();
            for node in 0..n {
                if src[node].is_some() {
                    continue;
                }
                let c = spec.node_coords(node).map(i64::from);
                let (mut acc, mut ws, mut sws, mut cnt) = ([0.0; 2], 0.0, 0.0, 0);
                for dz in -1i64..=1 {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let p = [c[0] + dx, c[1] + dy, c[2] + dz];
                            if (dx, dy, dz) == (0, 0, 0)
                                || (0..3).any(|a| p[a] < 0 || p[a] >= i64::from(spec.res()[a]))
                            {
                                continue;
                            }
                            let nb = spec.node_index(p[0] as u32, p[1] as u32, p[2] as u32);
                            if let Some(sw) = src[nb] {
                                let d2 = (dx as f64 * cell[0]).powi(2)
                                    + (dy as f64 * cell[1]).powi(2)
                                    + (dz as f64 * cell[2]).powi(2);
                                let w = sw * (1.0 / d2);
                                acc[0] += w * slow[2 * nb];
                                acc[1] += w * slow[2 * nb + 1];
                                ws += w;
                                sws += sw;
                                cnt += 1;
                            }
                        }
                    }
                }
                if cnt > 0 {
                    upd.push((node, sws / f64::from(cnt), [acc[0] / ws, acc[1] / ws]));
                }
            }
            if upd.is_empty() {
                break;
            }
            for (node, sw, v) in upd {
                slow[2 * node..2 * node + 2].copy_from_slice(&v);
                src[node] = Some(sw);
            }
        }
        assert_eq!(fast, slow);
    }

    #[test]
    fn far_nodes_need_several_passes() {
        let spec = GridSpec::new([0.0; 3], [1.0; 3], [6, 2, 2]).unwrap();
        let n = spec.node_count();
        let mut values = vec![0.0; n];
        let mut weights = vec![0.0; n];
        values[0] = 3.0;
        weights[0] = 1.0;
        let r = fill_empty_nodes(&spec, 1, &mut values, &weights);
        assert_eq!(r.passes, 5);
        assert_eq!(r.filled, n - 1);
        // A single source propagates its value: each fill is a convex combination of equal
        // values, exact up to one rounding of the sum and one of the division per pass.
        const CONVEX_TOL: f64 = 3.0 * 32.0 * f64::EPSILON;
        assert!(values.iter().all(|&v| (v - 3.0).abs() < CONVEX_TOL));
    }
}
