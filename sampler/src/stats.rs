//! Bake statistics: rays by kind, domain classification counts, fill, timing.

use std::time::Duration;

use lightvol_scene::stats::RayCounts;

/// Everything a bake reports besides the volume.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BakeStats {
    /// Rays by kind.
    pub rays: RayCounts,
    /// Cells processed (or nodes, for point sampling).
    pub units: u64,
    /// Cells in which at least one back-face point was found (Algorithm 2).
    pub cells_with_back_faces: u64,
    /// Candidate samples generated.
    pub candidates: u64,
    /// Samples kept (accumulated).
    pub samples_kept: u64,
    /// Candidates rejected as outside the domain of interest.
    pub samples_rejected: u64,
    /// Back-face points found.
    pub back_face_points: u64,
    /// Nodes that received no weight (filled by lightvol-volume, see `fill_report`).
    pub zero_weight_nodes: u64,
    /// How lightvol-volume filled zero-weight nodes (its `FillReport`, formatted).
    pub fill_report: String,
    /// Samples per unit summed over the units: the bake's samples times its units, or with
    /// a noise target ([`crate::noise`]) each unit's final round.
    pub final_samples: u64,
    /// Units that reached the noise target's cap before its error target.
    pub capped_units: u64,
    /// Rays of `doi`'s node reach ([`crate::reach`]), also counted among the query rays: a
    /// cost per node that does not grow with the samples.
    pub reach_rays: u64,
    /// Wall time of the sampling (excluding BVH build).
    pub wall_time: Duration,
    /// BVH build time.
    pub bvh_build_time: Duration,
}

/// Million rays per second: `rays` traced in `seconds` (0 when no time passed).
#[must_use]
pub fn mrays_per_second(rays: &RayCounts, seconds: f64) -> f64 {
    if seconds > 0.0 { rays.total() as f64 / seconds / 1e6 } else { 0.0 }
}

impl BakeStats {
    /// Million rays per second over the sampling wall time.
    #[must_use]
    pub fn mrays_per_second(&self) -> f64 {
        mrays_per_second(&self.rays, self.wall_time.as_secs_f64())
    }

    /// Adds the counters of another (disjoint) part of the bake; times are not added.
    pub fn add_counts(&mut self, o: &Self) {
        self.rays.add(&o.rays);
        self.units += o.units;
        self.cells_with_back_faces += o.cells_with_back_faces;
        self.candidates += o.candidates;
        self.samples_kept += o.samples_kept;
        self.samples_rejected += o.samples_rejected;
        self.back_face_points += o.back_face_points;
        self.final_samples += o.final_samples;
        self.capped_units += o.capped_units;
        self.reach_rays += o.reach_rays;
    }
}

impl std::fmt::Display for BakeStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = &self.rays;
        writeln!(
            f,
            "rays: {} total ({} sampling, {} query, {} bounce, {} shadow)",
            r.total(),
            r.sampling,
            r.query,
            r.bounce,
            r.shadow
        )?;
        writeln!(
            f,
            "units: {}, with back faces: {}, back-face points: {}",
            self.units, self.cells_with_back_faces, self.back_face_points
        )?;
        writeln!(
            f,
            "samples: {} candidates, {} kept, {} rejected",
            self.candidates, self.samples_kept, self.samples_rejected
        )?;
        writeln!(f, "zero-weight nodes: {} ({})", self.zero_weight_nodes, self.fill_report)?;
        write!(
            f,
            "wall time: {:.3} s (BVH {:.3} s), {:.2} Mrays/s",
            self.wall_time.as_secs_f64(),
            self.bvh_build_time.as_secs_f64(),
            self.mrays_per_second()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn throughput_is_rays_over_time() {
        let rays = RayCounts { sampling: 1_000_000, query: 500_000, bounce: 1_000_000, shadow: 500_000 };
        assert_eq!(mrays_per_second(&rays, 1.5), 2.0);
        assert_eq!(mrays_per_second(&rays, 0.0), 0.0);
        let stats = BakeStats { rays, wall_time: Duration::from_millis(750), ..BakeStats::default() };
        assert_eq!(stats.mrays_per_second(), 4.0);
    }
}
