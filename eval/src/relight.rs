//! Relit entries: a volume baked under one sky and relit to the comparison's, measured on
//! the plate like a fresh bake of that sky. `BASE+relit` relights with the exact sky
//! transfer ([`lightvol_volume::light_groups`]), `BASE+skyocc` with Unity APV's sky
//! occlusion ([`lightvol_sampler::sky_occlusion`]), the baseline the transfer is measured
//! against.

use std::time::Instant;

use lightvol_sampler::BakeStats;
use lightvol_sampler::method::Method;
use lightvol_scene::band_limit::irradiance_band_limit_error;
use lightvol_scene::light_groups::{LightGroups, sky_coefficients};
use lightvol_scene::transport::Transport;
use lightvol_volume::{GridSpec, GroupedVolume};

use crate::error::EvalError;
use crate::plate::Plate;
use crate::runs::{BakeContext, MethodRun, RunDetail, uniform_run};

/// Bakes `method` on `grid` under the sky `from` (the scene's other lights as they are)
/// with a sky transfer of `coeffs` coefficients (stage `name`): the whole bake split into
/// the other lights' groups and the transfer's, and the bake's statistics.
fn bake_transfer_under(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    method: Method,
    from: &lightvol_scene::Environment,
    coeffs: usize,
) -> Result<(GroupedVolume, BakeStats), EvalError> {
    let mut baked_under = ctx.transport.scene().clone();
    baked_under.environment = from.clone();
    let groups = LightGroups::with_sky_transfer(&baked_under, None, coeffs).map_err(EvalError::Relight)?;
    let transport =
        Transport::new(&baked_under, ctx.transport.tracer(), *ctx.transport.settings()).with_groups(groups);
    let settings = ctx.settings(method);
    let out = ctx
        .stage(name, |c| lightvol_sampler::bake(&transport, grid, &settings, c))
        .map_err(EvalError::at("baking"))?;
    let t0 = Instant::now();
    let (whole, _) = out.accumulator.finalize();
    let grouped = out
        .accumulator
        .finalize_grouped(&whole)
        .expect("a grouped transport")
        .map_err(|e| EvalError::Relight(e.to_string()))?;
    let mut stats = out.stats;
    stats.wall_time += t0.elapsed();
    Ok((grouped, stats))
}

/// Bakes `method` on `grid` with a sky transfer of SH order `order` (`order²` coefficients
/// of the sky's radiance) under the sky `from`
/// (the scene's other lights as they are), relights it to the scene's own sky
/// ([`lightvol_volume::GroupedVolume::sky_scales`]) and measures it on the plate (stage
/// `name`): the error a relit volume carries against a fresh bake's, beside the new sky's
/// open-sky band-limit error at that order ([`RunDetail::Relit`]). Its rays are the
/// transfer bake's.
///
/// # Errors
/// The bake's, and groups that cannot be made for the scene.
pub fn run_relit(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    method: Method,
    order: u32,
    from: &lightvol_scene::Environment,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    let coeffs = (order * order) as usize;
    let (grouped, stats) = bake_transfer_under(ctx, grid, name, method, from, coeffs)?;
    let t0 = Instant::now();
    let scales = grouped
        .sky_scales(&sky_coefficients(&ctx.transport.scene().environment, coeffs), None)
        .map_err(|e| EvalError::Relight(e.to_string()))?;
    let vol = grouped.relit(&scales).map_err(|e| EvalError::Relight(e.to_string()))?;
    let seconds = stats.wall_time.as_secs_f64() + t0.elapsed().as_secs_f64();
    let mut run = uniform_run(ctx, grid, name, plate, vol, stats.rays, seconds);
    let sky_band_limit = irradiance_band_limit_error(&ctx.transport.scene().environment, coeffs);
    run.detail = RunDetail::Relit { order, sky_band_limit };
    Ok(run)
}

/// Bakes `method` on `grid` under the sky `from` with the sky's light split from the
/// other lights', bakes Unity APV's sky occlusion with the same method
/// ([`lightvol_sampler::sky_occlusion`]: a white sky, one grey albedo, L1), and relights:
/// the other lights as baked plus the occlusion times the scene's own sky in each node's
/// shading direction ([`lightvol_sampler::sky_occlusion::relight_occlusion`]); measured on
/// the plate (stage `name`). Its rays are both bakes'.
///
/// # Errors
/// The bakes', and groups that cannot be made for the scene.
pub fn run_sky_occlusion(
    ctx: &BakeContext<'_>,
    grid: &GridSpec,
    name: &str,
    method: Method,
    from: &lightvol_scene::Environment,
    plate: &Plate,
) -> Result<MethodRun, EvalError> {
    use lightvol_sampler::sky_occlusion::{mean_albedo, occlusion_scene, relight_occlusion};
    const COEFFS: usize = 9;
    let scene = ctx.transport.scene();
    // The other lights as baked: a sky transfer's groups before the sky's, from the same
    // paths as the sky's light (which is then dropped).
    let (grouped, stats) = bake_transfer_under(ctx, grid, name, method, from, COEFFS)?;
    let occ_scene = occlusion_scene(scene, mean_albedo(scene));
    let occ_transport = Transport::new(&occ_scene, ctx.transport.tracer(), *ctx.transport.settings());
    let settings = ctx.settings(method);
    let occ = ctx
        .stage(&format!("{name} (sky occlusion)"), |c| {
            lightvol_sampler::bake(&occ_transport, grid, &settings, c)
        })
        .map_err(EvalError::at("baking the sky occlusion"))?;
    let t0 = Instant::now();
    let whole = grouped.total();
    let (base, _) = grouped.sky_transfer().expect("a sky transfer");
    let (occ_vol, _) = occ.accumulator.finalize();
    let mut data =
        relight_occlusion(occ_vol.data(), whole.coeffs(), &sky_coefficients(&scene.environment, COEFFS));
    for g in 0..base {
        for (d, &v) in data.iter_mut().zip(grouped.layer(g)) {
            *d += v;
        }
    }
    let vol = whole.with_data(data).map_err(|e| EvalError::Relight(e.to_string()))?;
    let mut rays = stats.rays;
    rays.add(&occ.stats.rays);
    let seconds =
        stats.wall_time.as_secs_f64() + occ.stats.wall_time.as_secs_f64() + t0.elapsed().as_secs_f64();
    Ok(uniform_run(ctx, grid, name, plate, vol, rays, seconds))
}
