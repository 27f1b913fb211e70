//! `lightvol slurm` and `lightvol k8s`: a sharded bake as cluster jobs.
//!
//! Both write job files that run `lightvol bake ... --shard auto --shards N` once per
//! shard (the shard index comes from the scheduler's array variables, see
//! `lightvol_sampler::shard`) and then one `lightvol merge` of the shards' exact sums, which
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

use std::path::{Path, PathBuf};
use std::process::{Command as Proc, ExitCode};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::Args;

use crate::bake_args::BakeArgs;

/// Options the cluster verbs share, after the bake's own options.
#[derive(Debug, Args)]
pub(crate) struct JobArgs {
    /// Work folder for the job files, shard outputs and logs (default: the output's path
    /// with the extension `.slurm`; for k8s, `STEM.k8s` in the current folder).
    #[arg(long)]
    pub(crate) workdir: Option<PathBuf>,
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
    pub(crate) partition: Option<String>,
    /// Time limit per shard (`--time`, e.g. `2:00:00`).
    #[arg(long)]
    pub(crate) time: Option<String>,
    /// CPUs per shard (`--cpus-per-task`; the bake uses that many threads).
    #[arg(long)]
    pub(crate) cpus: Option<u32>,
    /// Memory per shard (`--mem`, e.g. `4G`).
    #[arg(long)]
    pub(crate) mem: Option<String>,
    /// Submit the jobs with sbatch and print their ids.
    #[arg(long)]
    pub(crate) submit: bool,
    /// With --submit: wait for the merge and exit with its status.
    #[arg(long, requires = "submit")]
    pub(crate) wait: bool,
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
    pub(crate) pvc: String,
    /// Where the claim is mounted.
    #[arg(long, default_value = "/data")]
    pub(crate) mount: String,
    /// CPU request per shard pod.
    #[arg(long, default_value_t = 1)]
    pub(crate) cpus: u32,
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
pub(crate) fn bake_arguments(argv: &[String]) -> Vec<String> {
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

/// POSIX shell single-quoting.
#[must_use]
pub(crate) fn sh_quote(s: &str) -> String {
    if !s.is_empty() && s.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_./=:,+@%".contains(&b)) {
        return s.to_owned();
    }
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// Refuses a value written into an `#SBATCH` line or a job's shell command that could end
/// the line or mean something else to Slurm (control characters, `%` patterns, `\`).
fn check_job_value(what: &str, v: &str) -> anyhow::Result<()> {
    if v.chars().any(|c| c.is_control() || c == '%' || c == '\\') {
        bail!("{what} {v:?} contains a control character, '%' or '\\', which job files cannot carry safely");
    }
    Ok(())
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
    if let Some(b) = lightvol_sampler::baselines::Baseline::from_name(&bake.method) {
        bail!(
            "--method {} is not sharded (the engine baselines bake a whole uniform grid: use lightvol bake)",
            b.name()
        );
    }
    if bake.adaptive.level.is_some() || !bake.adaptive.from_shards.is_empty() {
        bail!("--level and --from-shards are set by the jobs of an adaptive bake; give only --shards N");
    }
    Ok(n)
}

/// One job array of a sharded bake: its file stem and what follows the bake's options.
struct Stage {
    name: String,
    tail: String,
}

/// The job arrays of a sharded bake, in dependency order, and the final command's words
/// after the lightvol executable. A uniform bake is one array and a `merge`; an adaptive
/// bake is one array per level (each reading the levels below) and an assembling `bake`.
/// `shards` is the shell-quoted shard folder, `index` the shell text of the task index.
fn stages(
    bake: &BakeArgs,
    words: &str,
    n: u32,
    shards: &str,
    index: &str,
    out: &str,
) -> anyhow::Result<(Vec<Stage>, String)> {
    if !bake.adaptive.adaptive {
        let st = Stage {
            name: "bake".into(),
            tail: format!("--shard auto --shards {n} -o {shards}/shard-{index}.exr"),
        };
        return Ok((vec![st], format!("merge {shards}/*.lvacc -o {out}")));
    }
    let max_level = bake.adaptive.settings(bake.grid.coeffs())?.max_level;
    let mut inputs = vec![format!("{shards}/level0-*.lvacc")];
    let mut out_stages = Vec::new();
    for level in 0..=max_level {
        let mut tail = format!("--shard auto --shards {n}");
        if level > 0 {
            tail += &format!(" --level {level} --from-shards {}", inputs.join(" "));
            inputs.push(format!("{shards}/level{level}-*.lvref"));
        }
        tail += &format!(" -o {shards}/level{level}-{index}.exr");
        out_stages.push(Stage { name: format!("bake-level{level}"), tail });
    }
    Ok((out_stages, format!("bake {words} --from-shards {} -o {out}", inputs.join(" "))))
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

/// Runs `lightvol slurm`; `argv` is the verb's command line after `slurm`.
pub(crate) fn run_slurm(args: &SlurmArgs, argv: &[String]) -> anyhow::Result<ExitCode> {
    let (n, work, out, exe) = common(&args.bake, &args.job, "slurm")?;
    // The scene and lights must load here, so that a typo fails now, not on the cluster.
    args.bake.scene.load_quiet().context("checking the scene before writing jobs")?;
    let bake = bake_arguments(argv);
    for a in &bake {
        check_job_value("the bake option", a)?;
    }
    for v in [&args.partition, &args.time, &args.mem].into_iter().flatten() {
        check_job_value("the Slurm option", v)?;
    }
    // Jobs run where this command ran, so relative paths in the bake options keep meaning
    // what they mean here.
    let cwd = std::env::current_dir().context("current folder")?;
    check_job_value("the current folder", &cwd.to_string_lossy())?;
    let q = |p: &Path| sh_quote(&p.to_string_lossy());
    let mut head = vec![
        "#!/bin/bash".to_owned(),
        "#SBATCH --job-name=lightvol-bake".to_owned(),
        format!("#SBATCH --array=0-{}", n - 1),
        format!("#SBATCH --output={}", q(&work.join("logs/bake-%A_%a.log"))),
        format!("#SBATCH --chdir={}", q(&cwd)),
    ];
    if let Some(c) = args.cpus {
        head.push(format!("#SBATCH --cpus-per-task={c}"));
    }
    for (k, v) in [("partition", &args.partition), ("time", &args.time), ("mem", &args.mem)] {
        if let Some(v) = v {
            head.push(format!("#SBATCH --{k}={}", sh_quote(v)));
        }
    }
    let words: Vec<String> = bake.iter().map(|a| sh_quote(a)).chain(quiet(&bake)).collect();
    let words = words.join(" ");
    let (stages, last) =
        stages(&args.bake, &words, n, &q(&work.join("shards")), "\"$SLURM_ARRAY_TASK_ID\"", &q(&out))?;
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
                q(&exe),
                st.tail
            ),
        ));
    }
    let mut mhead = vec![
        "#!/bin/bash".to_owned(),
        "#SBATCH --job-name=lightvol-merge".to_owned(),
        format!("#SBATCH --output={}", q(&work.join("logs/merge-%j.log"))),
        format!("#SBATCH --chdir={}", q(&cwd)),
    ];
    if let Some(c) = args.cpus.filter(|_| args.bake.adaptive.adaptive) {
        // The assembly replays the heuristics: it uses the shards' CPUs.
        mhead.push(format!("#SBATCH --cpus-per-task={c}"));
    }
    for (k, v) in [("partition", &args.partition), ("time", &args.time), ("mem", &args.mem)] {
        if let Some(v) = v {
            mhead.push(format!("#SBATCH --{k}={}", sh_quote(v)));
        }
    }
    files.push((
        "merge.sbatch".into(),
        format!(
            "{}\n# Written by `lightvol slurm`: {} (refuses an incomplete set).\nset -euo pipefail\nexec {} {last}\n",
            mhead.join("\n"),
            if args.bake.adaptive.adaptive {
                "assembles the levels' exact sums into the octree volume"
            } else {
                "merges the shards' exact sums"
            },
            q(&exe),
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
    for d in ["shards", "logs"] {
        std::fs::create_dir_all(work.join(d)).with_context(|| format!("creating {}", work.display()))?;
    }
    files.push(("submit.sh".into(), submit));
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
        .filter(|(_, j)| j.state != "COMPLETED" && FINAL.contains(&j.state.as_str()))
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

/// `--quiet` for the shard jobs (no progress bars in their logs), unless already given.
fn quiet(bake: &[String]) -> Option<String> {
    (!bake.iter().any(|a| a == "--quiet")).then(|| "--quiet".to_owned())
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

/// One job (or array task) as `scontrol -o show job` prints it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct JobLine {
    /// `JobId`.
    pub(crate) id: String,
    /// `ArrayTaskId`, for array tasks.
    pub(crate) task: Option<String>,
    /// `JobState`.
    pub(crate) state: String,
    /// `ExitCode` (`code:signal`).
    pub(crate) exit_code: String,
    /// `Reason`.
    pub(crate) reason: String,
}

/// Parses `scontrol -o show job` output (one job per line, `Key=Value` fields).
#[must_use]
pub(crate) fn parse_job_lines(text: &str) -> Vec<JobLine> {
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

fn job_lines(id: &str) -> anyhow::Result<Vec<JobLine>> {
    let o = Proc::new("scontrol").args(["-o", "show", "job", id]).output().context("running scontrol")?;
    if !o.status.success() {
        bail!("scontrol show job {id}: {}", String::from_utf8_lossy(&o.stderr).trim());
    }
    Ok(parse_job_lines(&String::from_utf8_lossy(&o.stdout)))
}

/// Job states after which a job never runs again.
const FINAL: &[&str] = &[
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
                    && FINAL.contains(&j.state.as_str())
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
    let raw = bake_arguments(argv);
    let words: Vec<String> = raw.iter().map(|a| sh_quote(a)).chain(quiet(&raw)).collect();
    let words = words.join(" ");
    let shards = sh_quote(&format!("{mount}/shards"));
    let (stages, last) =
        stages(&args.bake, &words, n, &shards, "\"$JOB_COMPLETION_INDEX\"", &sh_quote(&out))?;
    let volume = serde_json::json!([{"name": "data", "persistentVolumeClaim": {"claimName": args.pvc}}]);
    let mounts = serde_json::json!([{"name": "data", "mountPath": args.mount}]);
    let job = |name: &str, cmd: &str, indexed: bool| {
        let mut spec = serde_json::json!({
            "backoffLimit": 0,
            "template": {"spec": {
                "restartPolicy": "Never",
                "containers": [{"name": name, "image": args.image, "command": ["sh", "-c", cmd],
                    "resources": {"requests": {"cpu": args.cpus.to_string()}},
                    "env": [{"name": "RAYON_NUM_THREADS", "value": args.cpus.to_string()}],
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
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    // Kubernetes has no job dependencies: each job is applied after the one before completes.
    let mut files: Vec<(String, serde_json::Value)> = stages
        .iter()
        .map(|st| {
            let cmd = format!("mkdir -p {shards} && exec lightvol bake {words} {}", st.tail);
            (format!("{}-job.yaml", st.name), job(&st.name, &cmd, true))
        })
        .collect();
    files.push(("merge-job.yaml".into(), job("merge", &format!("exec lightvol {last}"), false)));
    let steps: Vec<String> = stages
        .iter()
        .zip(&files)
        .map(|(st, (file, _))| {
            format!(
                "kubectl apply -f {0}/{file} && kubectl wait --for=condition=complete --timeout=24h job/lightvol-{1}",
                work.display(),
                st.name
            )
        })
        .chain(std::iter::once(format!("kubectl apply -f {}/merge-job.yaml", work.display())))
        .collect();
    // JSON is YAML (YAML 1.2 is a superset), and kubectl reads either.
    let header = format!(
        "# Written by `lightvol k8s`. Apply each job after the one before completes, the merge last:\n{}",
        steps.iter().map(|l| format!("#   {l}\n")).collect::<String>()
    );
    for (file, j) in &files {
        let p = work.join(file);
        let body = format!("{header}{}\n", serde_json::to_string_pretty(j).expect("plain data"));
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

    #[test]
    fn shell_quoting() {
        assert_eq!(sh_quote("a/b.exr"), "a/b.exr");
        assert_eq!(sh_quote("it's here"), r"'it'\''s here'");
        assert_eq!(sh_quote(""), "''");
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
