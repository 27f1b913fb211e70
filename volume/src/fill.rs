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
    /// Coefficients that were not finite after division (e.g. a NaN radiance sample) and
    /// were set to zero.
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
    let mut acc = vec![0.0f64; k];
    loop {
        let mut updates: Vec<(usize, f64, Vec<f64>)> = Vec::new();
        for node in 0..n {
            if source[node].is_some() {
                continue;
            }
            let [i, j, kk] = spec.node_coords(node);
            acc.iter_mut().for_each(|a| *a = 0.0);
            let (mut wsum, mut src_wsum, mut src_count) = (0.0f64, 0.0f64, 0usize);
            for dz in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        if dx == 0 && dy == 0 && dz == 0 {
                            continue;
                        }
                        let (x, y, z) = (i64::from(i) + dx, i64::from(j) + dy, i64::from(kk) + dz);
                        if x < 0
                            || y < 0
                            || z < 0
                            || x >= res[0].into()
                            || y >= res[1].into()
                            || z >= res[2].into()
                        {
                            continue;
                        }
                        let nb = spec.node_index(x as u32, y as u32, z as u32);
                        let Some(sw) = source[nb] else { continue };
                        let d2 = (dx as f64 * cell[0]).powi(2)
                            + (dy as f64 * cell[1]).powi(2)
                            + (dz as f64 * cell[2]).powi(2);
                        let w = sw / d2;
                        for (a, v) in acc.iter_mut().zip(&values[nb * k..(nb + 1) * k]) {
                            *a += w * v;
                        }
                        wsum += w;
                        src_wsum += sw;
                        src_count += 1;
                    }
                }
            }
            if src_count > 0 {
                updates.push((node, src_wsum / src_count as f64, acc.iter().map(|a| a / wsum).collect()));
            }
        }
        if updates.is_empty() {
            break;
        }
        report.passes += 1;
        for (node, sw, vals) in updates {
            values[node * k..(node + 1) * k].copy_from_slice(&vals);
            source[node] = Some(sw);
            report.filled += 1;
        }
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
