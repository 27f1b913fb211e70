//! Running.

use super::*;

/// What the cases ended in, for the summary and the coverage check.
#[derive(Default)]
pub(crate) struct Outcomes {
    ok: usize,
    /// Error messages with numbers and quoted names removed, and how often each came.
    errors: BTreeMap<String, usize>,
}

impl Outcomes {
    pub(crate) fn record(&mut self, r: &Result<usize, String>) {
        match r {
            Ok(_) => self.ok += 1,
            Err(e) => {
                let e = e.strip_prefix("glTF error in fuzz: ").unwrap_or(e);
                let words: Vec<&str> = e.split(' ').filter(|w| !w.starts_with('\'')).take(7).collect();
                let shape: String = words.join(" ").chars().filter(|c| !c.is_ascii_digit()).collect();
                *self.errors.entry(shape).or_default() += 1;
            }
        }
    }

    fn summary(&self, what: &str) -> String {
        let total = self.ok + self.errors.values().sum::<usize>();
        let mut top: Vec<(&String, &usize)> = self.errors.iter().collect();
        top.sort_by(|a, b| b.1.cmp(a.1));
        let lines: Vec<String> = top.iter().take(40).map(|(e, n)| format!("  {n:4} × …{e}…")).collect();
        format!(
            "{what}: {total} runs, {} Ok, {} kinds of error:\n{}",
            self.ok,
            self.errors.len(),
            lines.join("\n")
        )
    }
}

pub(crate) fn light_is_finite(l: &PunctualLight) -> bool {
    match l {
        PunctualLight::Point { position, intensity } => {
            position.is_finite() && intensity.iter().all(|x| x.is_finite())
        }
        PunctualLight::Spot { position, axis, intensity, inner, outer } => {
            position.is_finite()
                && axis.is_finite()
                && intensity.iter().all(|x| x.is_finite())
                && inner.is_finite()
                && outer.is_finite()
        }
        PunctualLight::Directional { to_light, irradiance } => {
            to_light.is_finite() && irradiance.iter().all(|x| x.is_finite())
        }
    }
}

/// Loads `bytes` and checks the outcome: a finite scene, or one non-empty line. Returns the
/// triangle count or the message.
pub(crate) fn check(
    bytes: &[u8],
    base: &Path,
    case: &dyn Debug,
) -> Result<Result<usize, String>, TestCaseError> {
    let running = Running::start(case);
    let before = status_bytes("VmRSS:");
    reset_peak();
    let result = load_gltf_slice(bytes, Some(base), "fuzz", &LoadOptions::default());
    drop(running);
    let peak = status_bytes("VmHWM:").saturating_sub(before);
    // A scene the file really describes (an instanced mesh, a duplicated primitive) may
    // cost what its triangles cost; anything beyond that is memory the input did not back.
    let triangles = result.as_ref().map_or(0, |s| s.triangles.len() + s.report.degenerate_skipped);
    let budget = CASE_MEMORY_BUDGET + triangles * BYTES_PER_TRIANGLE;
    prop_assert!(
        peak <= budget,
        "the load held {} MiB at once (budget {} MiB for {triangles} triangles)",
        peak >> 20,
        budget >> 20
    );
    Ok(match result {
        Ok(scene) => {
            prop_assert!(
                scene.triangles.iter().all(|t| t.v.iter().all(|p| p.is_finite())),
                "a loaded scene has a non-finite vertex"
            );
            prop_assert!(
                scene.punctual.iter().all(light_is_finite),
                "a loaded light is not finite: {:?}",
                scene.punctual
            );
            prop_assert!(
                scene.cameras.iter().all(|c| c.position.is_finite()
                    && c.forward.is_finite()
                    && c.up.is_finite()
                    && c.yfov.is_finite()),
                "a loaded camera is not finite: {:?}",
                scene.cameras
            );
            Ok(scene.triangles.len())
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(!msg.trim().is_empty(), "empty error message ({e:?})");
            prop_assert!(
                !msg.contains('\n') && !msg.contains('\r'),
                "error message is not one line: {msg:?}"
            );
            Err(msg)
        }
    })
}

pub(crate) fn runner(cases: u32) -> TestRunner {
    let config = Config { cases, failure_persistence: None, max_shrink_iters: 512, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, SEED))
}

pub(crate) fn run<S: Strategy>(
    name: &str,
    cases: u32,
    strategy: S,
    test: impl Fn(S::Value, &mut Outcomes) -> TestCaseResult,
) where
    S::Value: Debug,
{
    let outcomes = RefCell::new(Outcomes::default());
    let result = runner(cases).run(&strategy, |case| test(case, &mut outcomes.borrow_mut()));
    let o = outcomes.into_inner();
    eprintln!("{}", o.summary(name));
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    // The mutations must get past the parser: some loads succeed and the errors are many.
    assert!(o.ok > 0 && o.errors.len() >= 10, "{name}: the mutations exercise too little of the loader");
}
