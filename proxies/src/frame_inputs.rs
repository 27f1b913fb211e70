//! Everything one proxy-shading frame reads (\[SGNS07\]'s per-frame passes): the
//! receiver buffer, the proxies prepared under the light, and the proxies binned into
//! screen tiles, for the default receiver scene with the character's proxies. The GPU
//! passes of lightvol-gpu and the CPU passes of [`crate::pipeline`] are timed on the same
//! inputs (`lightvol bench --gpu`, lightvol-gpu's `proxy_frame` example).

use std::time::Instant;

use crate::compare::CompareConfig;
use crate::kernel::{Kernel, KernelIndirect, PreparedProxy, prepare};
use crate::light::DistantLight;
use crate::pipeline::{TileBins, bin_proxies};
use crate::receiver_scene::{ReceiverBuffer, Scene, character};

/// The inputs of one frame of order `N`.
pub struct FrameInputs<const N: usize> {
    /// The receiver scene with its proxies.
    pub scene: Scene,
    /// Tolerances and tile size derived for the buffer.
    pub config: CompareConfig,
    /// The receivers, `size × size`.
    pub buffer: ReceiverBuffer,
    /// The scene's distant light.
    pub light: DistantLight<N>,
    /// The proxies prepared under the light.
    pub prepared: Vec<PreparedProxy<N>>,
    /// The proxies binned into tiles.
    pub bins: TileBins,
    /// Wall time of the binning (host), in seconds.
    pub bin_seconds: f64,
}

impl<const N: usize> FrameInputs<N> {
    /// The default receiver scene at `size × size` receivers, its proxies extended by the
    /// 18-sphere character (colour `(0.9, 0.4, 0)`) and truncated to `proxies`.
    #[must_use]
    pub fn benchmark(size: usize, proxies: usize) -> Self {
        let mut scene = Scene::default_scene();
        let mut list = scene.proxies.clone();
        list.extend(character([0.9, 0.4, 0.0]));
        list.truncate(proxies);
        scene.proxies = list;
        let config = CompareConfig::derived::<N>(size, size, 1.0 / 256.0);
        let buffer = ReceiverBuffer::render(&scene, size, size);
        let light = DistantLight(scene.light.sh::<N>());
        let prepared = prepare(&scene.proxies, &light);
        let eta = config.eta_shadow.max(config.eta_indirect);
        let t = Instant::now();
        let bins = bin_proxies(&scene.camera.frame(), size, size, &scene.proxies, eta, config.tile);
        let bin_seconds = t.elapsed().as_secs_f64();
        Self { scene, config, buffer, light, prepared, bins, bin_seconds }
    }

    /// The shading kernel of these tolerances (averaged indirect light).
    #[must_use]
    pub fn kernel(&self) -> Kernel<N> {
        Kernel::new(self.config.eta_shadow, self.config.eta_indirect, KernelIndirect::Averaged)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_benchmark_frame_has_the_asked_proxies_and_receivers() {
        let f = FrameInputs::<4>::benchmark(16, 20);
        assert_eq!(f.scene.proxies.len(), 20);
        assert_eq!(f.prepared.len(), 20);
        assert!((0..16 * 16).any(|i| f.buffer.valid(i)));
    }
}
