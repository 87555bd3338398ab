//! `agentstar batch`: three synthetic captures planned as a batch, run as a Slurm job array
//! on a one-node cluster on localhost (`scripts/slurm_local.sh`) and with `batch local`, one
//! job killed midway and resumed, then the tables gathered and compared with `eval --batch`.

mod support;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};
use support::{agentstar_in, path_str as s, text};

fn json(o: &Output) -> Value {
    assert!(o.status.success(), "{}", text(o));
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(o)))
}

/// `batch local BATCH --json` (which runs the jobs that need a run): its report and each
/// job's attempts so far.
fn run_local(batch: &Path) -> (Value, Vec<u64>) {
    let v = json(&agentstar_in(&[], &["batch", "local", s(batch), "--json"]));
    let attempts = v["jobs"]
        .as_array()
        .expect("jobs")
        .iter()
        .map(|j| j["attempts"].as_u64().expect("n"))
        .collect();
    (v, attempts)
}

/// Waits (bounded) until `done` holds, polling.
fn wait_for(what: &str, limit: Duration, mut done: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !done() {
        assert!(
            t0.elapsed() < limit,
            "timed out after {limit:?} waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Three small synthetic captures (two ARCTIC-like, one HOT3D-like) and a track batch on
/// them whose jobs take a few seconds each.
fn planned_batch(dir: &Path) -> PathBuf {
    for object in ["box", "laptop", "mug"] {
        let out = dir.join("caps").join(object);
        let o = agentstar_in(
            &[],
            &[
                "synth",
                s(&out),
                "--object",
                object,
                "--frames",
                "4",
                "--size",
                "160x120",
                "--seed",
                "3",
            ],
        );
        assert!(o.status.success(), "{}", text(&o));
    }
    let batch = dir.join("b");
    let caps: Vec<PathBuf> = ["box", "laptop", "mug"]
        .iter()
        .map(|o| dir.join("caps").join(o))
        .collect();
    let mut args = vec!["batch", "plan"];
    args.extend(caps.iter().map(|c| s(c)));
    args.extend([
        "--out",
        s(&batch),
        "--job-arg=--evals",
        "--job-arg=300",
        "--job-arg=--no-temporal",
        "--cpus-per-task",
        "1",
        "--mem",
        "1G",
        "--time",
        "10",
        "--json",
    ]);
    let m = json(&agentstar_in(&[], &args));
    assert_eq!(m["format"], "agentstar-batch/v1");
    let jobs = m["jobs"].as_array().expect("jobs");
    assert_eq!(jobs.len(), 3);
    assert_eq!(jobs[1]["name"], "laptop");
    assert_eq!(jobs[1]["argv"][0], "track");
    assert_eq!(jobs[1]["resources"]["mem_mb"], 1024);
    assert!(batch.join("jobs/laptop/job.json").is_file());
    batch
}

/// The child pid of the running attempt of `job`, once its command has started.
fn running_child(batch: &Path, job: &str) -> Option<u32> {
    let text = std::fs::read_to_string(batch.join("jobs").join(job).join("record.json")).ok()?;
    let r: Value = serde_json::from_str(&text).ok()?;
    let last = r["attempts"].as_array()?.last()?;
    if !last["exit"].is_null() {
        return None;
    }
    last["child_pid"].as_u64().map(|p| p as u32)
}

fn states(env: &[(&str, &str)], batch: &Path) -> Vec<(String, String, u64)> {
    let v = json(&agentstar_in(env, &["batch", "status", s(batch), "--json"]));
    v["jobs"]
        .as_array()
        .expect("jobs")
        .iter()
        .map(|j| {
            (
                j["name"].as_str().expect("name").to_string(),
                j["state"].as_str().expect("state").to_string(),
                j["attempts"].as_u64().expect("attempts"),
            )
        })
        .collect()
}

/// `gather` prints `eval --batch BATCH/runs.json --per-sequence`'s tables, then the jobs.
fn gather_matches_eval(env: &[(&str, &str)], batch: &Path) {
    let g = agentstar_in(env, &["batch", "gather", s(batch), "--samples", "500"]);
    assert!(g.status.success(), "{}", text(&g));
    let gathered = String::from_utf8_lossy(&g.stdout).into_owned();
    let runs = batch.join("runs.json");
    let e = agentstar_in(
        env,
        &[
            "eval",
            "--batch",
            s(&runs),
            "--per-sequence",
            "--samples",
            "500",
        ],
    );
    assert!(e.status.success(), "{}", text(&e));
    let evaluated = String::from_utf8_lossy(&e.stdout).into_owned();
    assert!(
        gathered.starts_with(&evaluated),
        "gather:\n{gathered}\neval --batch:\n{evaluated}"
    );
    for table in [
        "### ARCTIC-like",
        "### HOT3D-like",
        "### Per sequence",
        "### Jobs",
    ] {
        assert!(gathered.contains(table), "{table} missing:\n{gathered}");
    }
    for job in ["box", "laptop", "mug"] {
        assert!(
            gathered.contains(&format!("| track · {job} |"))
                || gathered.contains(&format!("| {job} | track | 4 |")),
            "{job}:\n{gathered}"
        );
    }
    // Wall times come from the job records: no finished sequence shows 0.0 s.
    let per_seq: Vec<&str> = gathered
        .lines()
        .filter(|l| l.contains("| track | 4 |"))
        .collect();
    assert_eq!(per_seq.len(), 3, "{gathered}");
    for l in per_seq {
        let wall: f64 = l
            .split('|')
            .nth(4)
            .expect("cell")
            .trim()
            .parse()
            .expect("number");
        assert!(wall > 0.0, "{l}");
        // The tracker's evaluations, from the job's log (they read 0 before).
        let evals: u64 = l
            .split('|')
            .nth(6)
            .expect("cell")
            .trim()
            .parse()
            .expect("number");
        assert!(evals > 0, "{l}");
    }
    // The killed job shows its two attempts.
    assert!(
        gathered
            .lines()
            .any(|l| l.starts_with("| laptop | track | finished | 2 |")),
        "{gathered}"
    );
}

#[test]
fn a_batch_runs_locally_survives_a_killed_job_and_gathers_the_tables() {
    let dir = tempfile::tempdir().expect("tmp");
    let batch = planned_batch(dir.path());
    assert!(states(&[], &batch)
        .iter()
        .all(|(_, st, n)| st == "pending" && *n == 0));

    let mut local = Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args(["batch", "local", s(&batch), "-j", "3"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("batch local");
    let mut pid = None;
    wait_for("the laptop job to start", Duration::from_secs(120), || {
        pid = running_child(&batch, "laptop");
        pid.is_some()
    });
    let kill = Command::new("kill")
        .args(["-9", &pid.expect("pid").to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let status = local.wait().expect("wait");
    assert!(!status.success(), "a killed job makes `batch local` fail");
    let st = states(&[], &batch);
    assert_eq!(st[1], ("laptop".into(), "failed".into(), 1), "{st:?}");
    assert!(st[0].1 == "finished" && st[2].1 == "finished", "{st:?}");
    let v = json(&agentstar_in(
        &[],
        &["batch", "status", s(&batch), "--json"],
    ));
    assert_eq!(v["jobs"][1]["exit"]["signal"], 9);

    // Resuming runs only the killed job.
    let (v, attempts) = run_local(&batch);
    assert_eq!(v["summary"], "3 jobs: 3 finished");
    assert_eq!(attempts, [1, 2, 1]);
    let log = std::fs::read_to_string(batch.join("logs/laptop.log")).expect("log");
    assert_eq!(log.matches("== attempt").count(), 2, "{log}");
    // A finished job is not run again.
    let o = agentstar_in(&[], &["batch", "exec", s(&batch), "--job", "box"]);
    assert!(
        o.status.success() && text(&o).contains("already finished"),
        "{}",
        text(&o)
    );
    // The array script lists only what still needs a run: nothing.
    let o = agentstar_in(&[], &["batch", "slurm", s(&batch)]);
    assert!(
        o.status.success() && text(&o).contains("nothing to submit"),
        "{}",
        text(&o)
    );

    gather_matches_eval(&[], &batch);
}

/// The one-node cluster of `scripts/slurm_local.sh`, started if needed; its `SLURM_CONF`.
/// Only that cluster is used (never whatever Slurm the machine is configured for).
fn local_slurm() -> Option<String> {
    let required = std::env::var_os("AGENTSTAR_REQUIRE_SLURM").is_some();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/slurm_local.sh");
    let installed = Command::new("sh")
        .args([
            "-c",
            "command -v slurmctld && command -v slurmd && command -v munged && command -v sbatch",
        ])
        .output()
        .is_ok_and(|o| o.status.success());
    if !installed {
        assert!(
            !required,
            "AGENTSTAR_REQUIRE_SLURM is set but Slurm is not installed"
        );
        eprintln!("note: Slurm is not installed (scripts/slurm_local.sh install); the Slurm batch test is skipped");
        return None;
    }
    let o = Command::new("bash")
        .arg(&script)
        .arg("start")
        .output()
        .expect("slurm_local.sh");
    let conf = String::from_utf8_lossy(&o.stdout)
        .lines()
        .find_map(|l| l.strip_prefix("export SLURM_CONF=").map(str::to_string));
    match (o.status.success(), conf) {
        (true, Some(c)) => Some(c),
        _ => {
            assert!(
                !required,
                "scripts/slurm_local.sh start failed: {}",
                text(&o)
            );
            eprintln!(
                "note: the local Slurm cluster did not start ({}); the Slurm batch test is skipped",
                text(&o).trim()
            );
            None
        }
    }
}

fn queue_empty(env: &[(&str, &str)], job_id: u64) -> bool {
    let mut c = Command::new("squeue");
    c.args(["-h", "-o", "%i", "-j", &job_id.to_string()]);
    for (k, v) in env {
        c.env(k, v);
    }
    let o = c.output().expect("squeue");
    // Slurm forgets a finished job after MinJobAge; then it says the id is invalid.
    o.stdout.iter().all(u8::is_ascii_whitespace)
}

#[test]
fn a_batch_runs_as_a_slurm_array_resubmits_a_cancelled_task_and_gathers_the_tables() {
    let Some(conf) = local_slurm() else { return };
    let env = [("SLURM_CONF", conf.as_str())];
    let dir = tempfile::tempdir().expect("tmp");
    let batch = planned_batch(dir.path());

    let v = json(&agentstar_in(
        &env,
        &["batch", "slurm", s(&batch), "--submit", "--json"],
    ));
    let job_id = v["job_id"].as_u64().expect("job id");
    assert_eq!(v["tasks"], serde_json::json!([0, 1, 2]));
    let script = std::fs::read_to_string(batch.join("slurm/array-1.sbatch")).expect("script");
    assert!(
        script.contains("#SBATCH --array=0-2\n") && script.contains("#SBATCH --mem=1024M\n"),
        "{script}"
    );

    wait_for("the laptop task to start", Duration::from_secs(180), || {
        running_child(&batch, "laptop").is_some()
    });
    let o = Command::new("scancel")
        .arg(format!("{job_id}_1"))
        .env("SLURM_CONF", &conf)
        .output()
        .expect("scancel");
    assert!(o.status.success(), "{}", text(&o));
    wait_for(
        "the array to leave the queue",
        Duration::from_secs(300),
        || queue_empty(&env, job_id),
    );
    let st = states(&env, &batch);
    assert!(st[0].1 == "finished" && st[2].1 == "finished", "{st:?}");
    assert!(
        ["interrupted", "failed", "cancelled"].contains(&st[1].1.as_str()),
        "{st:?}"
    );
    let codes = std::fs::read_to_string(batch.join("slurm/exit-codes.tsv")).expect("exit codes");
    assert!(
        codes.contains(&format!("{job_id}\t0\t0\n"))
            && codes.contains(&format!("{job_id}\t2\t0\n")),
        "{codes}"
    );

    // Resubmitting runs only the cancelled task.
    let v = json(&agentstar_in(
        &env,
        &["batch", "slurm", s(&batch), "--submit", "--json"],
    ));
    let second = v["job_id"].as_u64().expect("job id");
    assert_eq!(v["tasks"], serde_json::json!([1]));
    wait_for(
        "the resubmitted task to finish",
        Duration::from_secs(300),
        || queue_empty(&env, second),
    );
    let st = states(&env, &batch);
    assert_eq!(
        st,
        [
            ("box".to_string(), "finished".to_string(), 1),
            ("laptop".to_string(), "finished".to_string(), 2),
            ("mug".to_string(), "finished".to_string(), 1)
        ]
    );
    let subs: Value = serde_json::from_str(
        &std::fs::read_to_string(batch.join("slurm/submissions.json")).expect("submissions"),
    )
    .expect("json");
    assert_eq!(subs["submissions"].as_array().map(Vec::len), Some(2));
    assert!(batch.join(format!("logs/slurm-{second}_1.log")).is_file());

    gather_matches_eval(&env, &batch);
}

/// One small synthetic capture at `dir/caps/box` (with model/ and gt.json).
fn one_capture(dir: &Path) -> PathBuf {
    let out = dir.join("caps").join("box");
    let o = agentstar_in(
        &[],
        &[
            "synth",
            s(&out),
            "--object",
            "box",
            "--frames",
            "2",
            "--size",
            "64x48",
            "--seed",
            "3",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    out
}

/// `batch plan CAPTURE --out OUT EXTRA…`: refused with exit 2, a message containing every
/// `needle`, no panic, and nothing written.
fn plan_refused(dir: &Path, capture: &Path, extra: &[&str], needles: &[&str]) {
    let out = dir.join("refused");
    let mut args = vec!["batch", "plan", s(capture), "--out", s(&out)];
    args.extend(extra);
    let o = agentstar_in(&[], &args);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{extra:?}: {t}");
    assert!(!t.contains("panicked"), "{t}");
    for n in needles {
        assert!(t.contains(n), "{extra:?}: `{n}` missing from: {t}");
    }
    assert!(!out.exists(), "{extra:?}: nothing is written");
}

#[test]
fn plan_refuses_memory_time_and_cpus_out_of_range() {
    let dir = tempfile::tempdir().expect("tmp");
    let cap = one_capture(dir.path());
    plan_refused(
        dir.path(),
        &cap,
        &["--mem", "99999999999999T"],
        &["--mem", "99999999999999T", "out of range"],
    );
    plan_refused(dir.path(), &cap, &["--mem", "1025T"], &["out of range"]);
    plan_refused(dir.path(), &cap, &["--time", "0"], &["--time 0"]);
    plan_refused(
        dir.path(),
        &cap,
        &["--cpus-per-task", "0"],
        &["--cpus-per-task 0"],
    );
    // The largest valid values are kept as given, not wrapped or raised.
    let out = dir.path().join("b");
    let v = json(&agentstar_in(
        &[],
        &[
            "batch",
            "plan",
            s(&cap),
            "--out",
            s(&out),
            "--mem",
            "1024T",
            "--time",
            "1",
            "--json",
        ],
    ));
    assert_eq!(v["jobs"][0]["resources"]["mem_mb"], 1u64 << 30);
    assert_eq!(v["jobs"][0]["resources"]["time_min"], 1);
    // `batch slurm` refuses the same values when it overrides the plan's.
    for (flag, value) in [
        ("--time", "0"),
        ("--cpus-per-task", "0"),
        ("--mem", "99999999999999T"),
    ] {
        let o = agentstar_in(&[], &["batch", "slurm", s(&out), flag, value]);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
        assert!(text(&o).contains(flag), "{}", text(&o));
    }
    assert!(!out.join("slurm/array-1.sbatch").exists());
}

#[test]
fn plan_refuses_the_same_capture_given_twice() {
    let dir = tempfile::tempdir().expect("tmp");
    let cap = one_capture(dir.path());
    let again = dir.path().join("caps").join("..").join("caps").join("box");
    plan_refused(
        dir.path(),
        &cap,
        &[s(&again)],
        &["same capture", "give each capture once"],
    );
    #[cfg(unix)]
    {
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&cap, &link).expect("symlink");
        plan_refused(dir.path(), &cap, &[s(&link)], &["same capture"]);
    }
}

#[test]
fn plan_refuses_a_scene_that_is_not_a_regular_model_file() {
    let dir = tempfile::tempdir().expect("tmp");
    let cap = one_capture(dir.path());
    let t0 = Instant::now();
    plan_refused(
        dir.path(),
        &cap,
        &["--scene", "/dev/zero", "--scale", "0.2"],
        &["--scene /dev/zero", "not a regular file"],
    );
    #[cfg(unix)]
    {
        // A script name on a device is refused before it is read.
        let link = dir.path().join("zero.rhai");
        std::os::unix::fs::symlink("/dev/zero", &link).expect("symlink");
        plan_refused(
            dir.path(),
            &cap,
            &["--scene", s(&link), "--scale", "0.2"],
            &["zero.rhai", "not a regular file"],
        );
    }
    assert!(t0.elapsed() < Duration::from_secs(60), "bounded reads");
    // A scene that does not build is refused at plan time too, not in every job.
    let bad = dir.path().join("bad.rhai");
    std::fs::write(&bad, "part(\"a\", box(1, 1);").expect("write");
    plan_refused(
        dir.path(),
        &cap,
        &["--scene", s(&bad), "--scale", "0.2"],
        &["--scene", "bad.rhai"],
    );
}

fn stderr_of(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Rows of the per-sequence table in `gather`'s output.
fn per_sequence_rows(gathered: &str) -> Vec<String> {
    gathered
        .lines()
        .filter(|l| l.contains("| track | 4 |"))
        .map(str::to_string)
        .collect()
}

#[test]
fn a_finished_job_whose_result_is_damaged_runs_again_and_gather_tables_the_rest() {
    let dir = tempfile::tempdir().expect("tmp");
    let batch = planned_batch(dir.path());
    let v = json(&agentstar_in(
        &[],
        &["batch", "local", s(&batch), "-j", "3", "--json"],
    ));
    assert_eq!(v["summary"], "3 jobs: 3 finished");
    // The finishing attempt recorded its result's size and digest.
    let record: Value = serde_json::from_str(
        &std::fs::read_to_string(batch.join("jobs/box/record.json")).expect("record"),
    )
    .expect("json");
    let outputs = &record["attempts"][0]["outputs"];
    assert_eq!(outputs[0]["path"], "jobs/box/pose.json", "{record}");
    assert_eq!(outputs[0]["sha256"].as_str().map(str::len), Some(64));

    let pose = |job: &str| batch.join("jobs").join(job).join("pose.json");
    let text_box = std::fs::read(pose("box")).expect("pose");
    std::fs::write(pose("box"), &text_box[..text_box.len() / 2]).expect("truncate");
    std::fs::write(pose("laptop"), b"").expect("empty");
    let o = agentstar_in(&[], &["batch", "status", s(&batch), "--json"]);
    let err = stderr_of(&o);
    let st = states(&[], &batch);
    assert_eq!(
        st.iter().map(|(_, s, _)| s.as_str()).collect::<Vec<_>>(),
        ["damaged", "damaged", "finished"],
        "{err}"
    );
    assert!(
        err.contains("job box: jobs/box/pose.json was changed")
            && err.contains("job laptop: jobs/laptop/pose.json was emptied")
            && err.contains("runs again"),
        "{err}"
    );

    // gather tables what it can read and names what it cannot.
    let g = agentstar_in(&[], &["batch", "gather", s(&batch), "--samples", "300"]);
    assert!(g.status.success(), "{}", text(&g));
    let gathered = String::from_utf8_lossy(&g.stdout).into_owned();
    let rows = per_sequence_rows(&gathered);
    assert_eq!(rows.len(), 1, "{gathered}");
    assert!(rows[0].contains("mug"), "{gathered}");
    assert!(
        stderr_of(&g).contains("job box: damaged; not evaluated"),
        "{}",
        text(&g)
    );
    assert!(
        gathered.contains("| box | track | damaged | 1 |"),
        "{gathered}"
    );

    // Only the damaged jobs need a run, and `batch local` reruns them.
    let o = agentstar_in(&[], &["batch", "slurm", s(&batch), "--json"]);
    assert_eq!(json(&o)["tasks"], serde_json::json!([0, 1]));
    let (v, attempts) = run_local(&batch);
    assert_eq!(v["summary"], "3 jobs: 3 finished");
    assert_eq!(attempts, [2, 2, 1]);
    assert_eq!(
        std::fs::read(batch.join("jobs/box/pose.json.damaged")).expect("kept aside"),
        &text_box[..text_box.len() / 2]
    );

    // A result swapped for another valid pose file, or deleted, is caught as well.
    std::fs::copy(pose("mug"), pose("box")).expect("swap");
    std::fs::remove_file(pose("laptop")).expect("delete");
    let o = agentstar_in(&[], &["batch", "status", s(&batch)]);
    let err = stderr_of(&o);
    assert!(
        err.contains("jobs/box/pose.json was changed")
            && err.contains("jobs/laptop/pose.json was deleted"),
        "{err}"
    );
    let o = agentstar_in(&[], &["batch", "exec", s(&batch), "--job", "box"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("running it again"), "{}", text(&o));
    let v = json(&agentstar_in(&[], &["batch", "local", s(&batch), "--json"]));
    assert_eq!(v["summary"], "3 jobs: 3 finished");

    // A run that cannot be read at all (its ground truth gone) is named; the rest are tabled.
    std::fs::remove_file(dir.path().join("caps/mug/gt.json")).expect("rm gt");
    let g = agentstar_in(
        &[],
        &["batch", "gather", s(&batch), "--samples", "300", "--json"],
    );
    let v = json(&g);
    assert_eq!(
        v["results"].as_array().map(Vec::len),
        Some(2),
        "{}",
        text(&g)
    );
    assert_eq!(v["unreadable"][0]["job"], "mug", "{v}");
    assert!(
        stderr_of(&g).contains("job mug: cannot read its run"),
        "{}",
        text(&g)
    );
    let runs: Value =
        serde_json::from_str(&std::fs::read_to_string(batch.join("runs.json")).expect("runs"))
            .expect("json");
    assert_eq!(runs.as_array().map(Vec::len), Some(2));
}
