//! `lightvol gpu-info` and the GPU part of `lightvol bench --gpu` (lightvol-gpu, Vulkan).

use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use lightvol_gpu::lookup::Quantity;
use lightvol_gpu::{DEVICE_ENV, GpuContext, ProxyShading, VolumeLookup, gpu_info, select_device};
use lightvol_proxies::frame_inputs::FrameInputs;
use lightvol_proxies::kernel::KernelIndirect;
use lightvol_proxies::pipeline::{accumulate_pass, exponentiate_pass};
use lightvol_proxies::receiver_scene::ReceiverBuffer;
use lightvol_volume::IrradianceVolume;
use serde_json::{Value, json};

/// `lightvol gpu-info`.
#[derive(Debug, Args)]
pub(crate) struct GpuInfoArgs {
    /// Print JSON.
    #[arg(long)]
    pub(crate) json: bool,
}

/// Runs `lightvol gpu-info`.
pub(crate) fn run_info(args: &GpuInfoArgs) -> anyhow::Result<ExitCode> {
    let devices = gpu_info().context("listing Vulkan devices")?;
    let selector = std::env::var(DEVICE_ENV).ok();
    let selected = select_device(&devices, selector.as_deref()).ok();
    if args.json {
        let list: Vec<String> = devices.iter().map(ToString::to_string).collect();
        println!("{}", serde_json::to_string_pretty(&json!({ "devices": list, "selected": selected }))?);
    } else {
        if devices.is_empty() {
            println!("no Vulkan devices");
        }
        for (i, d) in devices.iter().enumerate() {
            println!("{d}{}", if selected == Some(i) { "  (selected)" } else { "" });
        }
        println!("select with {DEVICE_ENV}=<index or name substring>");
    }
    Ok(if selected.is_some() { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}

/// GPU lookups per second on `vol` (device timestamps, upload excluded) for the given
/// queries, with the CPU batched lookup on all cores measured in the same run.
fn lookups(
    ctx: &GpuContext,
    vol: &IrradianceVolume,
    pts: &[[f32; 3]],
    nrm: &[[f32; 3]],
) -> anyhow::Result<Value> {
    let lookup = VolumeLookup::new(ctx, vol)?;
    let mut batch = lookup.batch(pts, nrm)?;
    lookup.run(&mut batch, Quantity::Irradiance, 1)?;
    let repeats = 5;
    let stats = lookup.run(&mut batch, Quantity::Irradiance, repeats)?;
    let gpu_out = batch.read()?;
    let mut cpu_out = vec![[0.0f32; 3]; pts.len()];
    let t = Instant::now();
    vol.irradiance_batch(pts, nrm, &mut cpu_out)?;
    let cpu_rate = pts.len() as f64 / t.elapsed().as_secs_f64();
    let identical = gpu_out.iter().zip(&cpu_out).filter(|(g, c)| g == c).count();
    let gpu_rate = stats.gpu_seconds.map(|s| pts.len() as f64 * f64::from(repeats) / s);
    Ok(json!({
        "gpu_lookups_per_second": gpu_rate,
        "gpu_wall_seconds": stats.wall_seconds,
        "cpu_lookups_per_second": cpu_rate,
        "gpu_over_cpu": gpu_rate.map(|g| g / cpu_rate),
        "bit_identical_to_cpu": identical,
        "queries": pts.len(),
    }))
}

/// Proxy shading frame times for 256×256 receivers and 32 proxies (order 4), GPU passes
/// against the CPU reference passes of lightvol-proxies in the same run.
fn proxy_frame(ctx: &GpuContext) -> anyhow::Result<Value> {
    const N: usize = 16;
    let size = 256;
    let f = FrameInputs::<N>::benchmark(size, 32);
    let (cfg, buffer, light, prepared, bins) = (&f.config, &f.buffer, &f.light, &f.prepared, &f.bins);
    let gpu = ProxyShading::<N>::new(ctx, cfg.eta_shadow, cfg.eta_indirect, KernelIndirect::Averaged)?;
    let frame = gpu.frame(buffer, bins, prepared, light)?;
    gpu.run(&frame, 1)?;
    gpu.run_exponentiate(&frame, 1)?;
    let repeats = 3;
    let acc = gpu.run(&frame, repeats)?;
    let exp = gpu.run_exponentiate(&frame, repeats)?;
    let display = ReceiverBuffer::render(&f.scene, 2 * size, 2 * size);
    let target = gpu.target(&display)?;
    gpu.run_upsample(&frame, &target, 1)?;
    let up = gpu.run_upsample(&frame, &target, repeats)?;
    let per = |s: Option<f64>| s.map(|s| s / f64::from(repeats) * 1e3);
    let kernel = f.kernel();
    let t = Instant::now();
    let cpu_acc = accumulate_pass(&kernel, buffer, bins, prepared);
    let cpu_acc_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let _ = exponentiate_pass(&kernel, buffer, &cpu_acc, light);
    let cpu_exp_ms = t.elapsed().as_secs_f64() * 1e3;
    Ok(json!({
        "receivers": [size, size],
        "proxies": f.scene.proxies.len(),
        "gpu_ms": { "accumulate": per(acc.gpu_seconds), "exponentiate": per(exp.gpu_seconds), "upsample_2x": per(up.gpu_seconds) },
        "cpu_ms": { "accumulate": cpu_acc_ms, "exponentiate": cpu_exp_ms },
    }))
}

/// The `gpu` section of `lightvol bench --gpu`.
pub(crate) fn bench_section(
    vol: &IrradianceVolume,
    coherent: &[[f32; 3]],
    random: &[[f32; 3]],
    normals: &[[f32; 3]],
) -> anyhow::Result<Value> {
    let ctx = GpuContext::new().context("opening the Vulkan device")?;
    let device = ctx.device_info().to_string();
    let software = device.to_lowercase().contains("llvmpipe") || device.to_lowercase().contains("lavapipe");
    Ok(json!({
        "device": device,
        "note": if software { "software rasterizer (lavapipe): a functional check, not a performance figure" } else { "hardware device" },
        "lookups_coherent": lookups(&ctx, vol, coherent, normals)?,
        "lookups_random": lookups(&ctx, vol, random, normals)?,
        "proxy_frame": proxy_frame(&ctx)?,
    }))
}
