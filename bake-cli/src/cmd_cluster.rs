//! `lightvol slurm` and `lightvol k8s`: a sharded bake as cluster jobs.
//!
//! Both write job files that run `lightvol bake ... --shard auto --shards N` once per
//! shard (the shard index comes from the scheduler's array variables, see
//! `lightvol_core::shard`) and then one `lightvol merge` of the shards' exact sums, which
//! equals the whole bake bit for bit.
//!
//! - `slurm` writes `bake.sbatch` (a job array), `merge.sbatch` and `submit.sh` into the
//!   work folder. `--submit` submits them (the merge with `--dependency=afterok:ARRAY
//!   --kill-on-invalid-dep=yes`, so a failed shard cancels it instead of leaving it pending
//!   forever) and prints the job ids; `--wait` then polls `scontrol` until the merge ends,
//!   exits with its status, and names any failed array task.
//! - `k8s` writes `bake-job.yaml` (an Indexed Job) and `merge-job.yaml`; Kubernetes has no
//!   job dependencies, so the merge is applied after `kubectl wait` (printed).
//!
//! An adaptive bake (`--adaptive`) shards level by level (`lightvol_sampler::adaptive_shard`):
//! one job array per octree level (`bake-levelL`), each reading the complete shard sets of
//! the levels below and started only after them, and a final job that assembles the levels
//! with `bake --adaptive --from-shards` instead of `merge`.
//!
//! The job files are lightvol-sampler's `cluster` (`slurm_jobs`, `k8s_jobs`); this verb
//! turns its options into a plan, writes the files, and submits and watches the Slurm jobs.

use std::path::{Path, PathBuf};
use std::process::{Command as Proc, ExitCode};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Args;

use lightvol_sampler::cluster::{
    FINAL_STATES, JobLine, JobPlan, K8sJobs, K8sOptions, SlurmJobs, SlurmOptions, check_job_value, k8s_jobs,
    parse_job_lines, slurm_jobs,
};

use crate::bake_args::BakeArgs;

/// Options the cluster verbs share, after the bake's own options.
#[derive(Debug, Args)]
pub(crate) struct JobArgs {
    /// Work folder for the job files, shard outputs and logs (default: the output's path
    /// with the extension `.slurm`; for k8s, `STEM.k8s` in the current folder).
    #[arg(long)]
    workdir: Option<PathBuf>,
    /// The lightvol executable the jobs run (default: this one).
    #[arg(long)]
    pub(crate) lightvol: Option<PathBuf>,
}

/// `lightvol slurm`.
#[derive(Debug, Args)]
pub(crate) struct SlurmArgs {
    /// The bake (scene, grid, sampling, method; `-o` is the merged volume). `--shards N` is
    /// required; `--shard` is set by the jobs.
    #[command(flatten)]
    pub(crate) bake: BakeArgs,
    /// Job files.
    #[command(flatten)]
    pub(crate) job: JobArgs,
    /// Slurm partition (`--partition`).
    #[arg(long)]
    partition: Option<String>,
    /// Time limit per shard (`--time`, e.g. `2:00:00`).
    #[arg(long)]
    pub(crate) time: Option<String>,
    /// CPUs per shard (`--cpus-per-task`; the bake uses that many threads).
    #[arg(long)]
    cpus: Option<u32>,
    /// Memory per shard (`--mem`, e.g. `4G`).
    #[arg(long)]
    mem: Option<String>,
    /// Submit the jobs with sbatch and print their ids.
    #[arg(long)]
    submit: bool,
    /// With --submit: wait for the merge and exit with its status.
    #[arg(long, requires = "submit")]
    wait: bool,
}

/// `lightvol k8s`.
#[derive(Debug, Args)]
pub(crate) struct K8sArgs {
    /// The bake, as for `slurm`. Paths must be valid inside the container.
    #[command(flatten)]
    pub(crate) bake: BakeArgs,
    /// Job files.
    #[command(flatten)]
    pub(crate) job: JobArgs,
    /// Container image with `lightvol` on its PATH.
    #[arg(long)]
    pub(crate) image: String,
    /// PersistentVolumeClaim mounted at --mount in every pod (scene, shards and output).
    #[arg(long, default_value = "lightvol-data")]
    pvc: String,
    /// Where the claim is mounted.
    #[arg(long, default_value = "/data")]
    mount: String,
    /// CPU request per shard pod.
    #[arg(long, default_value_t = 1)]
    cpus: u32,
}

/// Options of the cluster verbs that the shard jobs' `bake` must not see, with whether
/// they take a value.
const JOB_ONLY: &[(&str, bool)] = &[
    ("--workdir", true),
    ("--lightvol", true),
    ("--partition", true),
    ("--time", true),
    ("--cpus", true),
    ("--mem", true),
    ("--submit", false),
    ("--wait", false),
    ("--image", true),
    ("--pvc", true),
    ("--mount", true),
    ("--shards", true),
    ("--output", true),
    ("-o", true),
];

/// The bake's own arguments from the verb's command line (`argv` without the program and
/// verb): every job-only option (`--opt V`, `--opt=V`, `-oV`) removed.
#[must_use]
fn bake_arguments(argv: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < argv.len() {
        let a = &argv[i];
        let hit = JOB_ONLY.iter().find(|(name, _)| {
            a == name
                || a.starts_with(&format!("{name}="))
                || (*name == "-o" && a.starts_with("-o") && a.len() > 2 && !a.starts_with("--"))
        });
        match hit {
            Some((name, true)) if a == name => i += 2,
            Some(_) => i += 1,
            None => {
                out.push(a.clone());
                i += 1;
            }
        }
    }
    out
}

fn absolute(p: &Path) -> anyhow::Result<PathBuf> {
    if p.is_absolute() {
        Ok(p.to_owned())
    } else {
        Ok(std::env::current_dir().context("current folder")?.join(p))
    }
}

/// The `--shards N` of a bake both verbs can split: given, positive, no `--shard` of its
/// own, and a mode that shards.
fn shard_count(bake: &BakeArgs) -> anyhow::Result<u32> {
    let Some(n) = bake.shards else { bail!("give the number of shards with --shards N") };
    if n == 0 {
        bail!("--shards must be at least 1");
    }
    if bake.shard.is_some() {
        bail!("--shard is set by the jobs (--shard auto); give only --shards N");
    }
    if let Some(b) = lightvol_sampler::method::Baseline::from_name(&bake.method) {
        bail!(
            "--method {} is not sharded (the engine baselines bake a whole uniform grid: use lightvol bake)",
            b.name()
        );
    }
    if bake.adaptive.level.is_some() || !bake.adaptive.from_shards.is_empty() {
        bail!("--level and --from-shards are set by the jobs of an adaptive bake; give only --shards N");
    }
    if !bake.adaptive.adaptive {
        // What each job's bake would refuse as a shard (an engine's --target, say), refused
        // here, before any job file is written.
        crate::bake_args::request_for_shard(bake, None, Some((0, n)))?;
    }
    Ok(n)
}

/// Checks what both verbs need and returns (shards, work folder, merged output, lightvol).
fn common(bake: &BakeArgs, job: &JobArgs, ext: &str) -> anyhow::Result<(u32, PathBuf, PathBuf, PathBuf)> {
    let n = shard_count(bake)?;
    let out = absolute(&bake.output)?;
    let work = absolute(&job.workdir.clone().unwrap_or_else(|| out.with_extension(ext)))?;
    let exe = match &job.lightvol {
        Some(p) => absolute(p)?,
        None => std::env::current_exe().context("locating the lightvol executable")?,
    };
    for (what, p) in [("the output", &out), ("the work folder", &work), ("the lightvol path", &exe)] {
        check_job_value(what, &p.to_string_lossy())?;
    }
    Ok((n, work, out, exe))
}

/// The plan of the bake `bake` in `n` shards, whose tasks pass `bake_args`.
fn plan(bake: &BakeArgs, bake_args: Vec<String>, n: u32) -> anyhow::Result<JobPlan> {
    let adaptive_max_level = if bake.adaptive.adaptive {
        Some(bake.adaptive.settings(bake.grid.coeffs())?.max_level)
    } else {
        None
    };
    Ok(JobPlan { shards: n, bake_args, adaptive_max_level })
}

/// Runs `lightvol slurm`; `argv` is the verb's command line after `slurm`.
pub(crate) fn run_slurm(args: &SlurmArgs, argv: &[String]) -> anyhow::Result<ExitCode> {
    let (n, work, out, exe) = common(&args.bake, &args.job, "slurm")?;
    // The scene and lights must load here, so that a typo fails now, not on the cluster.
    args.bake.scene.load_quiet().context("checking the scene before writing jobs")?;
    let bake_args = bake_arguments(argv);
    for a in &bake_args {
        check_job_value("the bake option", a)?;
    }
    for v in [&args.partition, &args.time, &args.mem].into_iter().flatten() {
        check_job_value("the Slurm option", v)?;
    }
    // Jobs run where this command ran, so relative paths in the bake options keep meaning
    // what they mean here.
    let cwd = std::env::current_dir().context("current folder")?;
    check_job_value("the current folder", &cwd.to_string_lossy())?;
    let plan = plan(&args.bake, bake_args, n)?;
    let slurm = SlurmOptions {
        partition: args.partition.clone(),
        time: args.time.clone(),
        cpus: args.cpus,
        mem: args.mem.clone(),
    };
    let SlurmJobs { stages, files } = slurm_jobs(&plan, &slurm, &out, &work, &exe, &cwd)?;
    for d in ["shards", "logs"] {
        std::fs::create_dir_all(work.join(d)).with_context(|| format!("creating {}", work.display()))?;
    }
    for (name, body) in &files {
        let p = work.join(name);
        crate::imaging::write_atomic(&p, body.as_bytes())
            .with_context(|| format!("writing {}", p.display()))?;
        make_executable(&p)?;
    }
    eprintln!(
        "wrote {}/{{{}}} ({n} shards → {})",
        work.display(),
        files.iter().map(|f| f.0.as_str()).collect::<Vec<_>>().join(","),
        out.display()
    );
    if !args.submit {
        println!("{}", work.join("submit.sh").display());
        return Ok(ExitCode::SUCCESS);
    }
    let mut bake_ids: Vec<String> = Vec::new();
    for st in &stages {
        let file = work.join(format!("{}.sbatch", st.name));
        let id = match bake_ids.last() {
            None => sbatch(&[s(&file)])?,
            Some(p) => {
                sbatch(&[&format!("--dependency=afterok:{p}"), "--kill-on-invalid-dep=yes", s(&file)])?
            }
        };
        bake_ids.push(id);
    }
    let last_id = bake_ids.last().expect("at least one stage").clone();
    let merge_id = sbatch(&[
        &format!("--dependency=afterok:{last_id}"),
        "--kill-on-invalid-dep=yes",
        s(&work.join("merge.sbatch")),
    ])?;
    if bake_ids.len() == 1 {
        println!("bake array {last_id}, merge {merge_id}");
    } else {
        let list: Vec<String> =
            stages.iter().zip(&bake_ids).map(|(st, id)| format!("{} array {id}", st.name)).collect();
        println!("{}, merge {merge_id}", list.join(", "));
    }
    if !args.wait {
        return Ok(ExitCode::SUCCESS);
    }
    let state = wait_for(&merge_id)?;
    if state.state == "COMPLETED" && state.exit_code.starts_with("0:") {
        eprintln!("merge {merge_id} completed: {}", out.display());
        return Ok(ExitCode::SUCCESS);
    }
    let mut lines = Vec::new();
    for (st, id) in stages.iter().zip(&bake_ids) {
        // A multi-level bake names the array each task belongs to.
        let prefix = if stages.len() > 1 { format!("{} ", st.name) } else { String::new() };
        lines.extend(job_lines(id)?.into_iter().map(|j| (prefix.clone(), j)));
    }
    let failed: Vec<String> = lines
        .into_iter()
        .filter(|(_, j)| j.state != "COMPLETED" && FINAL_STATES.contains(&j.state.as_str()))
        .map(|(prefix, j)| {
            format!(
                "{prefix}array task {} ({}) {} exit {}",
                j.task.as_deref().unwrap_or("?"),
                j.id,
                j.state,
                j.exit_code
            )
        })
        .collect();
    let logs = work.join("logs");
    if failed.is_empty() {
        bail!("merge {merge_id} ended {} (exit {}); see {}", state.state, state.exit_code, logs.display());
    }
    bail!(
        "{}; merge {merge_id} {} ({}); logs in {}",
        failed.join(", "),
        state.state,
        state.reason,
        logs.display()
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap_or_default()
}

#[cfg(unix)]
fn make_executable(p: &Path) -> anyhow::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(0o755))
        .with_context(|| format!("chmod {}", p.display()))
}

#[cfg(not(unix))]
fn make_executable(_: &Path) -> anyhow::Result<()> {
    Ok(())
}

/// Submits with `sbatch --parsable`, returning the job id.
fn sbatch(args: &[&str]) -> anyhow::Result<String> {
    let o = Proc::new("sbatch")
        .arg("--parsable")
        .args(args)
        .output()
        .context("running sbatch (is Slurm installed and SLURM_CONF set?)")?;
    if !o.status.success() {
        bail!("sbatch {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr).trim());
    }
    let id = String::from_utf8_lossy(&o.stdout).trim().split(';').next().unwrap_or("").to_owned();
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        bail!("sbatch printed no job id ({:?})", String::from_utf8_lossy(&o.stdout));
    }
    Ok(id)
}

fn job_lines(id: &str) -> anyhow::Result<Vec<JobLine>> {
    let o = Proc::new("scontrol").args(["-o", "show", "job", id]).output().context("running scontrol")?;
    if !o.status.success() {
        bail!("scontrol show job {id}: {}", String::from_utf8_lossy(&o.stderr).trim());
    }
    Ok(parse_job_lines(&String::from_utf8_lossy(&o.stdout)))
}

/// Consecutive failed `scontrol` calls `--wait` tolerates (a busy controller times out).
const SCONTROL_RETRIES: u32 = 20;

/// Polls `scontrol` twice a second (`sbatch --wait` backs off to 32 s) until job `id` ends.
fn wait_for(id: &str) -> anyhow::Result<JobLine> {
    let start = Instant::now();
    let mut failures = 0;
    loop {
        match job_lines(id) {
            Ok(lines) => {
                failures = 0;
                if let Some(j) = lines.into_iter().next()
                    && FINAL_STATES.contains(&j.state.as_str())
                {
                    return Ok(j);
                }
            }
            Err(e) => {
                failures += 1;
                if failures > SCONTROL_RETRIES {
                    return Err(e.context(format!("{SCONTROL_RETRIES} scontrol calls in a row failed")));
                }
            }
        }
        if start.elapsed() > Duration::from_secs(7 * 24 * 3600) {
            bail!("gave up waiting for job {id} after a week");
        }
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// Runs `lightvol k8s`.
pub(crate) fn run_k8s(args: &K8sArgs, argv: &[String]) -> anyhow::Result<ExitCode> {
    let n = shard_count(&args.bake)?;
    if args.job.lightvol.is_some() {
        bail!("--lightvol is for slurm; the k8s jobs run the image's lightvol");
    }
    let mount = args.mount.trim_end_matches('/');
    if !mount.starts_with('/') {
        bail!("--mount must be an absolute path inside the pods, got {:?}", args.mount);
    }
    check_job_value("--mount", mount)?;
    let out = args.bake.output.to_string_lossy().into_owned();
    if !(out.starts_with(&format!("{mount}/"))) {
        bail!(
            "-o {out}: the merged volume must be an absolute path under --mount {mount} (the pods keep nothing else)"
        );
    }
    check_job_value("the output", &out)?;
    // The job files are written here; `-o` names a path inside the pods.
    let stem = args
        .bake
        .output
        .file_stem()
        .map_or_else(|| "lightvol".to_owned(), |s| s.to_string_lossy().into_owned());
    let work = absolute(&args.job.workdir.clone().unwrap_or_else(|| PathBuf::from(format!("{stem}.k8s"))))?;
    let plan = plan(&args.bake, bake_arguments(argv), n)?;
    let k8s = K8sOptions {
        image: args.image.clone(),
        pvc: args.pvc.clone(),
        mount: args.mount.clone(),
        cpus: args.cpus,
    };
    let K8sJobs { files, steps } = k8s_jobs(&plan, &k8s, &out, &work)?;
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    for (file, body) in &files {
        let p = work.join(file);
        crate::imaging::write_atomic(&p, body.as_bytes())
            .with_context(|| format!("writing {}", p.display()))?;
    }
    println!("{}", work.display());
    eprintln!(
        "wrote {}/{{{}}}; run: {}",
        work.display(),
        files.iter().map(|f| f.0.as_str()).collect::<Vec<_>>().join(","),
        steps.join(" && ")
    );
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(s: &[&str]) -> Vec<String> {
        s.iter().map(|x| (*x).to_owned()).collect()
    }

    #[test]
    fn job_only_options_are_removed_in_every_spelling() {
        let argv = v(&[
            "builtin:city",
            "--shards",
            "4",
            "--samples",
            "8",
            "-o",
            "v.exr",
            "--partition=gpu",
            "--submit",
            "--wait",
            "--time",
            "1:00",
            "-ox.exr",
            "--output=y.exr",
            "--res",
            "4,4,4",
        ]);
        assert_eq!(bake_arguments(&argv), v(&["builtin:city", "--samples", "8", "--res", "4,4,4"]));
    }
}
