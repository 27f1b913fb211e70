//! # Cluster jobs: a sharded bake as Slurm job arrays or Kubernetes Indexed Jobs
//!
//! A bake split into `N` shards ([`lightvol_core::shard`]) runs as one job array whose tasks each
//! call `lightvol bake ... --shard auto --shards N` (the shard index comes from the
//! scheduler's array variables), then one `lightvol merge` of the shards' exact sums, which
//! equals the whole bake bit for bit. An adaptive bake shards level by level
//! ([`crate::adaptive_shard`]): one array per octree level, each reading the complete shard
//! sets of the levels below and started only after them, and a final `bake --adaptive
//! --from-shards` that assembles the levels.
//!
//! [`slurm_jobs`] writes that plan as `sbatch` scripts and a `submit.sh` that chains them
//! with `--dependency=afterok:ID --kill-on-invalid-dep=yes` (a failed shard cancels what
//! depends on it instead of leaving it pending forever). [`k8s_jobs`] writes Indexed Jobs,
//! applied one after another (Kubernetes has no job dependencies). [`parse_job_lines`]
//! reads `scontrol -o show job`, and [`FINAL_STATES`] are the states after which a job
//! never runs again.
//!
//! Nothing here runs a scheduler or touches the file system: the caller writes the files
//! and submits them. Every value written into a script is checked ([`check_job_value`]) or
//! shell-quoted ([`sh_quote`]).

use std::path::Path;

use lightvol_volume::io::accumulator::ACC_EXTENSION;

use crate::adaptive_shard::LEVEL_EXTENSION;

/// A value that job files cannot carry.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ClusterError {
    /// A control character, `%` (a Slurm file-name pattern) or `\` in a value.
    #[error(
        "{what} {value:?} contains a control character, '%' or '\\', which job files cannot carry safely"
    )]
    UnsafeValue {
        /// What the value is.
        what: String,
        /// The value.
        value: String,
    },
}

/// POSIX shell single-quoting (words of only safe characters are left as they are).
#[must_use]
pub fn sh_quote(s: &str) -> String {
    if !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_./=:,+@%".contains(&b)) {
        return s.to_owned();
    }
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// Refuses a value written into an `#SBATCH` line or a job's shell command that could end
/// the line or mean something else to Slurm (control characters, `%` patterns, `\`).
///
/// # Errors
/// [`ClusterError::UnsafeValue`] naming `what`.
pub fn check_job_value(what: &str, v: &str) -> Result<(), ClusterError> {
    if v.chars().any(|c| c.is_control() || c == '%' || c == '\\') {
        return Err(ClusterError::UnsafeValue { what: what.to_owned(), value: v.to_owned() });
    }
    Ok(())
}

/// A sharded bake to run as jobs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JobPlan {
    /// Shards (array tasks per stage), at least 1.
    pub shards: u32,
    /// The bake's own `lightvol bake` arguments (unquoted; no shard, output or job
    /// options), passed to every task.
    pub bake_args: Vec<String>,
    /// `Some(max_level)` for an adaptive bake sharded level by level, `None` for a uniform
    /// bake and a merge.
    pub adaptive_max_level: Option<u32>,
}

impl JobPlan {
    /// The tasks' bake arguments, shell-quoted, with `--quiet` added (no progress bars in
    /// their logs) unless given.
    #[must_use]
    pub fn words(&self) -> String {
        let quiet = (!self.bake_args.iter().any(|a| a == "--quiet")).then(|| "--quiet".to_owned());
        let words: Vec<String> = self.bake_args.iter().map(|a| sh_quote(a)).chain(quiet).collect();
        words.join(" ")
    }
}

/// One job array of a plan.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stage {
    /// File stem and job name suffix: `bake`, or `bake-levelL`.
    pub name: String,
    /// What follows the bake's arguments in each task's command.
    pub tail: String,
}

/// The job arrays of `plan`, in dependency order, and the final command's words after the
/// lightvol executable. `shards` is the shell-quoted shard folder, `index` the shell text of
/// the task index, `out` the shell-quoted merged volume.
#[must_use]
pub fn stages(plan: &JobPlan, shards: &str, index: &str, out: &str) -> (Vec<Stage>, String) {
    let n = plan.shards;
    let Some(max_level) = plan.adaptive_max_level else {
        let st = Stage {
            name: "bake".into(),
            tail: format!("--shard auto --shards {n} -o {shards}/shard-{index}.exr"),
        };
        return (vec![st], format!("merge {shards}/*.{ACC_EXTENSION} -o {out}"));
    };
    let mut inputs = vec![format!("{shards}/level0-*.{ACC_EXTENSION}")];
    let mut out_stages = Vec::new();
    for level in 0..=max_level {
        let mut tail = format!("--shard auto --shards {n}");
        if level > 0 {
            tail += &format!(" --level {level} --from-shards {}", inputs.join(" "));
            inputs.push(format!("{shards}/level{level}-*.{LEVEL_EXTENSION}"));
        }
        tail += &format!(" -o {shards}/level{level}-{index}.exr");
        out_stages.push(Stage { name: format!("bake-level{level}"), tail });
    }
    (out_stages, format!("bake {} --from-shards {} -o {out}", plan.words(), inputs.join(" ")))
}

/// Slurm resources of every task.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SlurmOptions {
    /// `--partition`.
    pub partition: Option<String>,
    /// `--time` per task, e.g. `2:00:00`.
    pub time: Option<String>,
    /// `--cpus-per-task` (the bake uses that many threads).
    pub cpus: Option<u32>,
    /// `--mem` per task, e.g. `4G`.
    pub mem: Option<String>,
}

/// A plan's Slurm job files.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlurmJobs {
    /// The plan's job arrays, in submission order.
    pub stages: Vec<Stage>,
    /// `(file name, text)`: one `STAGE.sbatch` per stage, `merge.sbatch` and `submit.sh`, to
    /// be written into the work folder and made executable.
    pub files: Vec<(String, String)>,
}

/// The Slurm files of `plan` for the merged volume `out`, with job files, shard outputs and
/// logs under `work`, run by the executable `exe` in the folder `cwd` (so that relative
/// paths in the bake's arguments keep their meaning). All paths should be absolute.
///
/// # Errors
/// [`ClusterError::UnsafeValue`] for a path, bake argument or Slurm option that a job file
/// cannot carry.
pub fn slurm_jobs(
    plan: &JobPlan,
    slurm: &SlurmOptions,
    out: &Path,
    work: &Path,
    exe: &Path,
    cwd: &Path,
) -> Result<SlurmJobs, ClusterError> {
    for (what, p) in [("the output", out), ("the work folder", work), ("the lightvol path", exe)] {
        check_job_value(what, &p.to_string_lossy())?;
    }
    for a in &plan.bake_args {
        check_job_value("the bake option", a)?;
    }
    for v in [&slurm.partition, &slurm.time, &slurm.mem].into_iter().flatten() {
        check_job_value("the Slurm option", v)?;
    }
    check_job_value("the current folder", &cwd.to_string_lossy())?;
    let q = |p: &Path| sh_quote(&p.to_string_lossy());
    let n = plan.shards;
    let mut head = vec![
        "#!/bin/bash".to_owned(),
        "#SBATCH --job-name=lightvol-bake".to_owned(),
        format!("#SBATCH --array=0-{}", n.saturating_sub(1)),
        format!("#SBATCH --output={}", q(&work.join("logs/bake-%A_%a.log"))),
        format!("#SBATCH --chdir={}", q(cwd)),
    ];
    if let Some(c) = slurm.cpus {
        head.push(format!("#SBATCH --cpus-per-task={c}"));
    }
    for (k, v) in [("partition", &slurm.partition), ("time", &slurm.time), ("mem", &slurm.mem)] {
        if let Some(v) = v {
            head.push(format!("#SBATCH --{k}={}", sh_quote(v)));
        }
    }
    let words = plan.words();
    let (stages, last) = stages(plan, &q(&work.join("shards")), "\"$SLURM_ARRAY_TASK_ID\"", &q(out));
    let mut files: Vec<(String, String)> = Vec::new();
    for st in &stages {
        let mut h = head.clone();
        h[1] = format!("#SBATCH --job-name=lightvol-{}", st.name);
        h[3] = format!("#SBATCH --output={}", q(&work.join(format!("logs/{}-%A_%a.log", st.name))));
        files.push((
            format!("{}.sbatch", st.name),
            format!(
                "{}\n# Written by `lightvol slurm`: one array task per shard. `--shard auto` maps the task's\n# SLURM_ARRAY_TASK_ID (with _MIN/_MAX/_STEP) to a dense shard index.\nset -euo pipefail\nexec {} bake {words} {}\n",
                h.join("\n"),
                q(exe),
                st.tail
            ),
        ));
    }
    let adaptive = plan.adaptive_max_level.is_some();
    let mut mhead = vec![
        "#!/bin/bash".to_owned(),
        "#SBATCH --job-name=lightvol-merge".to_owned(),
        format!("#SBATCH --output={}", q(&work.join("logs/merge-%j.log"))),
        format!("#SBATCH --chdir={}", q(cwd)),
    ];
    if let Some(c) = slurm.cpus.filter(|_| adaptive) {
        // The assembly replays the heuristics: it uses the shards' CPUs.
        mhead.push(format!("#SBATCH --cpus-per-task={c}"));
    }
    for (k, v) in [("partition", &slurm.partition), ("time", &slurm.time), ("mem", &slurm.mem)] {
        if let Some(v) = v {
            mhead.push(format!("#SBATCH --{k}={}", sh_quote(v)));
        }
    }
    files.push((
        "merge.sbatch".into(),
        format!(
            "{}\n# Written by `lightvol slurm`: {} (refuses an incomplete set).\nset -euo pipefail\nexec {} {last}\n",
            mhead.join("\n"),
            if adaptive {
                "assembles the levels' exact sums into the octree volume"
            } else {
                "merges the shards' exact sums"
            },
            q(exe),
        ),
    ));
    let mut submit = String::from(
        "#!/bin/bash\n# Written by `lightvol slurm`: submits the shard arrays in order, each running only if\n# every task of the one before succeeded (and cancelled if one failed), then the merge.\nset -euo pipefail\n",
    );
    let mut prev: Option<String> = None;
    let mut names: Vec<String> = stages.iter().map(|st| st.name.clone()).collect();
    names.push("merge".into());
    for (i, name) in names.iter().enumerate() {
        let var = format!("job{i}");
        let dep = prev.as_ref().map_or_else(String::new, |p| {
            format!("--dependency=afterok:\"${p}\" --kill-on-invalid-dep=yes ")
        });
        submit += &format!(
            "{var}=$(sbatch --parsable {dep}{})\n{var}=${{{var}%%;*}}\necho \"{name} ${var}\"\n",
            q(&work.join(format!("{name}.sbatch")))
        );
        prev = Some(var);
    }
    files.push(("submit.sh".into(), submit));
    Ok(SlurmJobs { stages, files })
}

/// Kubernetes resources of every pod.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct K8sOptions {
    /// Container image with `lightvol` on its PATH.
    pub image: String,
    /// PersistentVolumeClaim mounted in every pod (scene, shards and output).
    pub pvc: String,
    /// Where the claim is mounted (absolute; a trailing `/` is ignored).
    pub mount: String,
    /// CPU request per pod (and the bake's threads).
    pub cpus: u32,
}

/// A plan's Kubernetes job files.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct K8sJobs {
    /// `(file name, text)`: one `STAGE-job.yaml` per stage and `merge-job.yaml`.
    pub files: Vec<(String, String)>,
    /// The shell commands that apply them in order, each after the one before completed.
    pub steps: Vec<String>,
}

/// The Kubernetes Indexed Jobs of `plan` for the merged volume `out` (a path inside the
/// pods, under the mount), whose files are to be written into `work` (named in the apply
/// steps). The files are JSON, which is YAML 1.2 and which kubectl reads.
///
/// # Errors
/// [`ClusterError::UnsafeValue`] for a mount or output that a job file cannot carry.
pub fn k8s_jobs(plan: &JobPlan, k8s: &K8sOptions, out: &str, work: &Path) -> Result<K8sJobs, ClusterError> {
    let mount = k8s.mount.trim_end_matches('/');
    check_job_value("--mount", mount)?;
    check_job_value("the output", out)?;
    let n = plan.shards;
    let words = plan.words();
    let shards = sh_quote(&format!("{mount}/shards"));
    let (stages, last) = stages(plan, &shards, "\"$JOB_COMPLETION_INDEX\"", &sh_quote(out));
    let volume = serde_json::json!([{"name": "data", "persistentVolumeClaim": {"claimName": k8s.pvc}}]);
    let mounts = serde_json::json!([{"name": "data", "mountPath": k8s.mount}]);
    let job = |name: &str, cmd: &str, indexed: bool| {
        let mut spec = serde_json::json!({
            "backoffLimit": 0,
            "template": {"spec": {
                "restartPolicy": "Never",
                "containers": [{"name": name, "image": k8s.image, "command": ["sh", "-c", cmd],
                    "resources": {"requests": {"cpu": k8s.cpus.to_string()}},
                    "env": [{"name": "RAYON_NUM_THREADS", "value": k8s.cpus.to_string()}],
                    "volumeMounts": mounts}],
                "volumes": volume}}
        });
        if indexed {
            spec["completions"] = n.into();
            spec["parallelism"] = n.into();
            spec["completionMode"] = "Indexed".into();
        }
        serde_json::json!({"apiVersion": "batch/v1", "kind": "Job", "metadata": {"name": format!("lightvol-{name}")}, "spec": spec})
    };
    let mut jobs: Vec<(String, serde_json::Value)> = stages
        .iter()
        .map(|st| {
            let cmd = format!("mkdir -p {shards} && exec lightvol bake {words} {}", st.tail);
            (format!("{}-job.yaml", st.name), job(&st.name, &cmd, true))
        })
        .collect();
    jobs.push(("merge-job.yaml".into(), job("merge", &format!("exec lightvol {last}"), false)));
    let steps: Vec<String> = stages
        .iter()
        .zip(&jobs)
        .map(|(st, (file, _))| {
            format!(
                "kubectl apply -f {0}/{file} && kubectl wait --for=condition=complete --timeout=24h job/lightvol-{1}",
                work.display(),
                st.name
            )
        })
        .chain(std::iter::once(format!("kubectl apply -f {}/merge-job.yaml", work.display())))
        .collect();
    let header = format!(
        "# Written by `lightvol k8s`. Apply each job after the one before completes, the merge last:\n{}",
        steps.iter().map(|l| format!("#   {l}\n")).collect::<String>()
    );
    let files = jobs
        .into_iter()
        .map(|(file, j)| {
            // Serialising plain JSON values cannot fail.
            let body = format!("{header}{}\n", serde_json::to_string_pretty(&j).unwrap_or_default());
            (file, body)
        })
        .collect();
    Ok(K8sJobs { files, steps })
}

/// One job (or array task) as `scontrol -o show job` prints it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JobLine {
    /// `JobId`.
    pub id: String,
    /// `ArrayTaskId`, for array tasks.
    pub task: Option<String>,
    /// `JobState`.
    pub state: String,
    /// `ExitCode` (`code:signal`).
    pub exit_code: String,
    /// `Reason`.
    pub reason: String,
}

/// Parses `scontrol -o show job` output (one job per line, `Key=Value` fields).
#[must_use]
pub fn parse_job_lines(text: &str) -> Vec<JobLine> {
    text.lines()
        .filter(|l| l.contains("JobId="))
        .map(|l| {
            let field = |k: &str| {
                l.split_whitespace().find_map(|f| f.strip_prefix(&format!("{k}="))).map(str::to_owned)
            };
            JobLine {
                id: field("JobId").unwrap_or_default(),
                task: field("ArrayTaskId"),
                state: field("JobState").unwrap_or_default(),
                exit_code: field("ExitCode").unwrap_or_default(),
                reason: field("Reason").unwrap_or_default(),
            }
        })
        .collect()
}

/// Slurm job states after which a job never runs again.
pub const FINAL_STATES: &[&str] = &[
    "COMPLETED",
    "FAILED",
    "CANCELLED",
    "TIMEOUT",
    "OUT_OF_MEMORY",
    "NODE_FAIL",
    "PREEMPTED",
    "BOOT_FAIL",
    "DEADLINE",
];

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(adaptive: Option<u32>) -> JobPlan {
        JobPlan {
            shards: 3,
            bake_args: vec!["builtin:city".into(), "--note".into(), "a b".into()],
            adaptive_max_level: adaptive,
        }
    }

    #[test]
    fn shell_quoting() {
        assert_eq!(sh_quote("a/b.exr"), "a/b.exr");
        assert_eq!(sh_quote("it's here"), r"'it'\''s here'");
        assert_eq!(sh_quote(""), "''");
    }

    #[test]
    fn unsafe_values_are_refused() {
        for v in ["a\nb", "50%", r"c:\x"] {
            assert!(check_job_value("x", v).is_err(), "{v:?}");
        }
        assert_eq!(check_job_value("x", "/a b/c"), Ok(()));
    }

    #[test]
    fn a_uniform_plan_is_one_array_and_a_merge() {
        let (st, last) = stages(&plan(None), "S", "$I", "O");
        assert_eq!(
            st,
            vec![Stage { name: "bake".into(), tail: "--shard auto --shards 3 -o S/shard-$I.exr".into() }]
        );
        assert_eq!(last, "merge S/*.lvacc -o O");
        assert_eq!(plan(None).words(), "builtin:city --note 'a b' --quiet");
    }

    #[test]
    fn an_adaptive_plan_reads_every_level_below() {
        let (st, last) = stages(&plan(Some(2)), "S", "$I", "O");
        assert_eq!(st.len(), 3);
        assert_eq!(st[0].tail, "--shard auto --shards 3 -o S/level0-$I.exr");
        assert_eq!(
            st[2].tail,
            "--shard auto --shards 3 --level 2 --from-shards S/level0-*.lvacc S/level1-*.lvref -o S/level2-$I.exr"
        );
        assert!(
            last.ends_with("--from-shards S/level0-*.lvacc S/level1-*.lvref S/level2-*.lvref -o O"),
            "{last}"
        );
    }

    #[test]
    fn slurm_scripts_chain_the_stages() {
        let p = Path::new;
        let jobs = slurm_jobs(
            &plan(Some(1)),
            &SlurmOptions::default(),
            p("/o/v.exr"),
            p("/w"),
            p("/bin/lightvol"),
            p("/c"),
        )
        .unwrap();
        let names: Vec<&str> = jobs.files.iter().map(|f| f.0.as_str()).collect();
        assert_eq!(names, ["bake-level0.sbatch", "bake-level1.sbatch", "merge.sbatch", "submit.sh"]);
        assert!(jobs.files[0].1.contains("#SBATCH --array=0-2\n"));
        let submit = &jobs.files[3].1;
        assert_eq!(submit.matches("--dependency=afterok:").count(), 2, "{submit}");
        let bad =
            slurm_jobs(&plan(None), &SlurmOptions::default(), p("/o/v%j.exr"), p("/w"), p("/l"), p("/c"));
        assert!(matches!(bad, Err(ClusterError::UnsafeValue { .. })));
    }

    #[test]
    fn scontrol_lines_parse() {
        let t = "JobId=12 ArrayJobId=11 ArrayTaskId=1 JobName=lightvol-bake JobState=FAILED Reason=NonZeroExitCode Dependency=(null) ExitCode=1:0\nJobId=13 JobName=m JobState=CANCELLED Reason=DependencyNeverSatisfied ExitCode=0:0\n";
        let j = parse_job_lines(t);
        assert_eq!(j.len(), 2);
        assert_eq!(j[0].task.as_deref(), Some("1"));
        assert_eq!((j[0].state.as_str(), j[0].exit_code.as_str()), ("FAILED", "1:0"));
        assert_eq!(j[1].reason, "DependencyNeverSatisfied");
    }
}
