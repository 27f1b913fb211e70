//! Proxy shading frame time on the Vulkan device (the target: 256×256 receivers and
//! 32 proxies in under 1 ms on a real GPU), with lightvol-proxies' CPU passes measured in the
//! same run as the baseline.
//!
//! ```text
//! cargo run --release -p lightvol-gpu --example proxy_frame -- [--size S] [--proxies P] [--repeats K]
//! ```
//!
//! The upsampling pass is timed to a `2S × 2S` display.
//!
//! The default proxies scene rendered into an `S × S` receiver buffer, with `P` proxies (two
//! copies of the 18-sphere character, truncated). GPU times are timestamps around `K`
//! back-to-back dispatches of each pass (upload, binning and readback excluded); binning
//! runs on the host and is timed separately. On lavapipe the numbers are a functional check.

use std::process::ExitCode;
use std::time::Instant;

use lightvol_gpu::{GpuContext, ProxyShading};
use lightvol_proxies::frame_inputs::FrameInputs;
use lightvol_proxies::kernel::KernelIndirect;
use lightvol_proxies::pipeline::{accumulate_pass, exponentiate_pass};
use lightvol_proxies::receiver_scene::ReceiverBuffer;

const N: usize = 16;

fn arg(name: &str, default: usize) -> Result<usize, String> {
    let args: Vec<String> = std::env::args().collect();
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(i) => args
            .get(i + 1)
            .ok_or_else(|| format!("{name} needs a value"))?
            .parse()
            .map_err(|e| format!("{name}: {e}")),
    }
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("proxy_frame: {e}");
            ExitCode::FAILURE
        }
    }
}

fn ms(s: Option<f64>, repeats: u32) -> String {
    s.map_or_else(|| "n/a (no timestamps)".into(), |s| format!("{:.3} ms", s / f64::from(repeats) * 1e3))
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let size = arg("--size", 256)?.max(8);
    let count = arg("--proxies", 32)?;
    let repeats = u32::try_from(arg("--repeats", 5)?.max(1))?;
    let ctx = GpuContext::new()?;
    println!("device: {}", ctx.device_info());

    let f = FrameInputs::<N>::benchmark(size, count);
    let (scene, cfg, buffer, light, prepared, bins) =
        (&f.scene, &f.config, &f.buffer, &f.light, &f.prepared, &f.bins);
    let bin_s = f.bin_seconds;

    let gpu = ProxyShading::<N>::new(&ctx, cfg.eta_shadow, cfg.eta_indirect, KernelIndirect::Averaged)?;
    let frame = gpu.frame(buffer, bins, prepared, light)?;
    // Warm-up, then timed runs.
    gpu.run(&frame, 1)?;
    gpu.run_exponentiate(&frame, 1)?;
    let acc = gpu.run(&frame, repeats)?;
    let exp = gpu.run_exponentiate(&frame, repeats)?;
    // Upsampling to a display of twice the receiver resolution per axis (the paper's factor 2).
    let display = ReceiverBuffer::render(scene, 2 * size, 2 * size);
    let target = gpu.target(&display)?;
    gpu.run_upsample(&frame, &target, 1)?;
    let up = gpu.run_upsample(&frame, &target, repeats)?;

    let kernel = f.kernel();
    let t = Instant::now();
    let cpu_acc = accumulate_pass(&kernel, buffer, bins, prepared);
    let cpu_acc_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let cpu_inc = exponentiate_pass(&kernel, buffer, &cpu_acc, light);
    let cpu_exp_s = t.elapsed().as_secs_f64();
    let gpu_acc = gpu.read(&frame)?;
    let identical = gpu_acc.iter().zip(&cpu_acc).filter(|(g, c)| g == c).count();
    let worst_acc = gpu_acc
        .iter()
        .zip(&cpu_acc)
        .map(|(g, c)| {
            let (gv, cv) = (g.log_vis.iter().chain(&g.indirect), c.log_vis.iter().chain(&c.indirect));
            let norm: f32 = c.log_vis.iter().chain(&c.indirect).map(|v| v.abs()).sum();
            gv.zip(cv).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max) / norm.max(f32::MIN_POSITIVE)
        })
        .fold(0.0f32, f32::max);
    let inc = gpu.read_incident(&frame)?;
    let worst = inc
        .iter()
        .zip(&cpu_inc)
        .map(|(g, c)| {
            let norm: f32 = c.shadowed.iter().chain(&c.indirect).map(|v| v.abs()).sum();
            let d = g.shadowed.iter().chain(&g.indirect).zip(c.shadowed.iter().chain(&c.indirect));
            d.map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max) / norm.max(f32::MIN_POSITIVE)
        })
        .fold(0.0f32, f32::max);

    println!(
        "{size}x{size} receivers ({} valid), {} proxies, N = {N}, eta shadow {:.2} / indirect {:.2}, tile {}",
        (0..size * size).filter(|&i| buffer.valid(i)).count(),
        scene.proxies.len(),
        cfg.eta_shadow,
        cfg.eta_indirect,
        cfg.tile
    );
    println!(
        "gpu: accumulate {}, exponentiate {}, upsample to {}x{} {}; host binning {:.3} ms",
        ms(acc.gpu_seconds, repeats),
        ms(exp.gpu_seconds, repeats),
        2 * size,
        2 * size,
        ms(up.gpu_seconds, repeats),
        bin_s * 1e3
    );
    println!(
        "cpu ({} threads): accumulate {:.3} ms, exponentiate {:.3} ms",
        std::thread::available_parallelism().map_or(1, usize::from),
        cpu_acc_s * 1e3,
        cpu_exp_s * 1e3
    );
    println!(
        "agreement: {identical} of {} accumulators bit-identical, worst {worst_acc:.2e} of their norm; \
         incident worst {worst:.2e} of its norm",
        cpu_acc.len()
    );
    Ok(())
}
