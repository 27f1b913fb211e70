//! Lighting scenarios: one scene's geometry baked under several lightings (a sun at noon and
//! at dusk, the lamps on and off) into one file, which an engine blends by weight
//! (lightvol-volume's `light_groups`, scenario groups). Unlike light groups, each scenario
//! is a bake of its own: its paths follow its own lights. The geometry, grid, method,
//! samples and seed are shared, so every scenario classifies, relocates, fills and reaches
//! its nodes the same way (none of those reads the light), and a blend of two is a blend of
//! the same nodes.

use lightvol_core::progress::BakeControl;
use lightvol_scene::{Scene, Tracer, Transport, UpAxis};
use lightvol_volume::Accumulator;
use lightvol_volume::accumulator::GroupLabels;
use lightvol_volume::light_groups::SCENARIO_PREFIX;
use lightvol_volume::{GridSpec, GroupedVolume};

use crate::request::{BakeRequest, Provenance, UniformBake, UniformBakeError, bake_uniform};
use crate::scene_setup::{LightOverrides, SetupError, apply_lights};

/// One lighting scenario: its name and the lights it sets on the scene.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The name (`scenario.NAME` in the file).
    pub name: String,
    /// The lights, applied over the scene's own as the bake options apply them.
    pub lights: LightOverrides,
}

/// Why a scenario bake failed.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// A scenario's lights could not be applied (an unreadable map).
    #[error("scenario '{0}'")]
    Lights(String, #[source] Box<SetupError>),
    /// A scenario's bake failed.
    #[error("scenario '{0}'")]
    Bake(String, #[source] Box<UniformBakeError>),
    /// The scenarios' volumes could not be put together.
    #[error("putting the scenarios together")]
    Volume(#[source] Box<lightvol_volume::VolumeError>),
    /// Fewer than two scenarios, or a name twice.
    #[error("{0}")]
    Names(String),
}

/// Bakes `request` on `scene` (traced by `tracer`, built from its geometry; the file frame
/// `frame`) once per scenario, each with its lights applied over the scene's, and returns
/// the scenarios as one grouped volume (the first scenario's bake as the whole) with each
/// scenario's bake. The scene's lights are restored afterwards.
///
/// # Errors
/// [`ScenarioError`].
pub fn bake_scenarios(
    scene: &mut Scene,
    tracer: &Tracer,
    frame: UpAxis,
    grid: &GridSpec,
    request: &BakeRequest,
    scenarios: &[Scenario],
    control: &BakeControl<'_>,
) -> Result<(GroupedVolume, Vec<UniformBake>), ScenarioError> {
    if scenarios.len() < 2 {
        return Err(ScenarioError::Names(
            "lighting scenarios need at least two (--scenario NAME=... twice)".into(),
        ));
    }
    for (i, s) in scenarios.iter().enumerate() {
        if s.name.is_empty() || scenarios[..i].iter().any(|t| t.name == s.name) {
            return Err(ScenarioError::Names(format!("scenario name {:?} is empty or given twice", s.name)));
        }
    }
    let saved = (scene.environment.clone(), scene.sun, scene.punctual.clone());
    let result = (|| {
        let mut bakes = Vec::with_capacity(scenarios.len());
        for s in scenarios {
            (scene.environment, scene.sun, scene.punctual) = saved.clone();
            apply_lights(scene, frame, &s.lights)
                .map_err(|e| ScenarioError::Lights(s.name.clone(), Box::new(e)))?;
            let transport = Transport::new(scene, tracer, request.transport);
            let key = request.key(scene, grid);
            let bake =
                bake_uniform(&transport, scene, grid, request, Provenance { frame, key: &key }, control)
                    .map_err(|e| ScenarioError::Bake(s.name.clone(), Box::new(e)))?;
            bakes.push(bake);
        }
        let names = scenarios.iter().map(|s| format!("{SCENARIO_PREFIX}{}", s.name)).collect();
        let layers = bakes.iter().map(|b| b.volume.data().to_vec()).collect();
        let grouped = GroupedVolume::new(bakes[0].volume.clone(), names, layers)
            .map_err(|e| ScenarioError::Volume(Box::new(e)))?;
        Ok((grouped, bakes))
    })();
    (scene.environment, scene.sun, scene.punctual) = saved;
    result
}

/// The scenarios' exact sums as one accumulator, for a shard's `.lvacc` file: the first
/// scenario's bake with one light group per scenario (`scenario.NAME`) whose numerator is
/// that scenario's ([`Accumulator::set_group_from`]). `merge` adds the shards' files and
/// writes the grouped file, whose scenarios are then, bit for bit, the unsharded bake's:
/// every scenario shares the first's denominators (the light moves no sample), and a group
/// finalizes exactly as its own bake does.
///
/// # Errors
/// [`ScenarioError::Volume`] when a scenario's sums do not fit the first's.
pub fn scenario_accumulator(
    scenarios: &[Scenario],
    bakes: &[UniformBake],
) -> Result<Accumulator, ScenarioError> {
    let first = bakes.first().ok_or_else(|| ScenarioError::Names("no scenario was baked".into()))?;
    let mut acc = first.output.accumulator.clone();
    acc.enable_groups(GroupLabels {
        names: scenarios.iter().map(|s| format!("{SCENARIO_PREFIX}{}", s.name)).collect(),
        sky: None,
    });
    for (g, b) in bakes.iter().enumerate() {
        acc.set_group_from(g, &b.output.accumulator).map_err(|e| ScenarioError::Volume(Box::new(e)))?;
    }
    Ok(acc)
}
