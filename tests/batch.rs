//! `rmvp batch` against a real one-node Slurm (Debian 12's slurmctld, slurmd and munge, started
//! here without systemd and stopped by PID), and the same plan run `--local`.
//!
//! A 4-task array (the spot fixture and a damaged copy of it, x the full model and the
//! photometric-only ablation, 20 iterations each): one task preempted by SIGUSR2 requeues
//! itself and finishes bit for bit like an uninterrupted run; the damaged copy's tasks fail,
//! are listed by status and gather while the others complete, and are resubmitted alone once
//! the copy is repaired; the local run gives the same table. Needs root (the daemons).

use rmvp_pipeline::batch::gather::BatchTable;
use rmvp_testkit::fixture;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::time::{Duration, Instant};

/// A one-node Slurm cluster in a temporary folder (its own slurm.conf through `SLURM_CONF`).
struct Cluster {
    dir: tempfile::TempDir,
    conf: PathBuf,
    /// munged's pid file when this test started it.
    munged: Option<PathBuf>,
}

fn run(command: &mut Command) -> Output {
    command.output().unwrap_or_else(|e| panic!("{command:?}: {e}"))
}

fn kill(pid_file: &Path) {
    if let Ok(pid) = std::fs::read_to_string(pid_file) {
        let _ = Command::new("kill").arg(pid.trim()).status();
    }
}

impl Cluster {
    fn start() -> Self {
        let uid = String::from_utf8(run(Command::new("id").arg("-u")).stdout).unwrap();
        assert_eq!(uid.trim(), "0", "the Slurm test starts slurmctld, slurmd and munged: run it as root (./run test)");
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for sub in ["state", "spool", "log"] {
            std::fs::create_dir_all(root.join(sub)).unwrap();
        }
        let cpus = std::thread::available_parallelism().map_or(2, |n| n.get());
        let conf = root.join("slurm.conf");
        let p = |name: &str| root.join(name).display().to_string();
        std::fs::write(
            &conf,
            format!(
                "ClusterName=rmvptest\nSlurmctldHost=localhost\n\
                 NodeName=localhost NodeHostname=localhost CPUs={cpus} RealMemory=2000 State=UNKNOWN\n\
                 PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n\
                 SlurmUser=root\nProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n\
                 JobAcctGatherType=jobacct_gather/none\nSchedulerType=sched/backfill\n\
                 SelectType=select/cons_tres\nSelectTypeParameters=CR_Core_Memory\nDefMemPerCPU=400\n\
                 MinJobAge=600\nReturnToService=2\nAuthInfo=cred_expire=10\n\
                 AccountingStorageType=accounting_storage/none\n\
                 SlurmctldPidFile={}\nSlurmdPidFile={}\nSlurmdSpoolDir={}\nStateSaveLocation={}\n\
                 SlurmctldLogFile={}\nSlurmdLogFile={}\n",
                p("slurmctld.pid"),
                p("slurmd.pid"),
                p("spool"),
                p("state"),
                p("log/slurmctld.log"),
                p("log/slurmd.log"),
            ),
        )
        .unwrap();
        // munged runs as its own user (as root it refuses); one already running is shared.
        let munge_pid = Path::new("/run/munge/munged.pid");
        let alive =
            std::fs::read_to_string(munge_pid).is_ok_and(|pid| Path::new(&format!("/proc/{}", pid.trim())).exists());
        let mut cluster = Cluster { conf, munged: None, dir };
        if !alive {
            assert!(run(Command::new("install").args(["-d", "-o", "munge", "-g", "munge", "/run/munge"]))
                .status
                .success());
            let out = run(Command::new("su").args(["-s", "/bin/sh", "munge", "-c", "/usr/sbin/munged"]));
            assert!(out.status.success(), "munged: {}", String::from_utf8_lossy(&out.stderr));
            cluster.munged = Some(munge_pid.to_path_buf());
        }
        let conf = cluster.conf.display().to_string();
        for daemon in
            [vec!["/usr/sbin/slurmctld", "-f", &conf], vec!["/usr/sbin/slurmd", "-f", &conf, "-N", "localhost"]]
        {
            let out = run(Command::new(daemon[0]).args(&daemon[1..]));
            assert!(out.status.success(), "{}: {}", daemon[0], String::from_utf8_lossy(&out.stderr));
        }
        cluster.wait_for("the node to be idle", 30, || {
            let out = cluster.command("sinfo").args(["-h", "-o", "%T"]).output().unwrap();
            String::from_utf8_lossy(&out.stdout).contains("idle")
        });
        cluster
    }

    /// A Slurm command (or rmvp) talking to this cluster.
    fn command(&self, program: &str) -> Command {
        let mut command = Command::new(program);
        command.env("SLURM_CONF", &self.conf);
        command
    }

    fn rmvp(&self, args: &[&str]) -> Output {
        run(self.command(env!("CARGO_BIN_EXE_rmvp")).args(args))
    }

    fn rmvp_ok(&self, args: &[&str]) -> String {
        let out = self.rmvp(args);
        assert!(out.status.success(), "rmvp {args:?}:\n{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    }

    /// Slurm's state of a job (`squeue -t all`: finished jobs stay `MinJobAge` seconds).
    fn job_state(&self, job: &str) -> String {
        let out = run(self.command("squeue").args(["-h", "-t", "all", "-o", "%T", "-j", job]));
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    }

    /// Poll `done` every quarter second; past `seconds`, fail with the controller's log.
    fn wait_for(&self, what: &str, seconds: u64, mut done: impl FnMut() -> bool) {
        let start = Instant::now();
        while !done() {
            if start.elapsed() > Duration::from_secs(seconds) {
                let log = std::fs::read_to_string(self.dir.path().join("log/slurmctld.log")).unwrap_or_default();
                let tail: Vec<&str> = log.lines().rev().take(30).collect();
                panic!(
                    "waited {seconds} s for {what}; slurmctld.log ends:\n{}",
                    tail.into_iter().rev().collect::<Vec<_>>().join("\n")
                );
            }
            std::thread::sleep(Duration::from_millis(250));
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        kill(&self.dir.path().join("slurmd.pid"));
        kill(&self.dir.path().join("slurmctld.pid"));
        if let Some(pid) = &self.munged {
            kill(pid);
        }
        // Let the daemons release their ports before another test starts a cluster.
        std::thread::sleep(Duration::from_millis(500));
    }
}

fn table(dir: &Path) -> BatchTable {
    serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap()
}

const PLAN: &str = r#"# two datasets x two variants x one seed: a 4-task array
datasets = ["SPOT", "broken"]

[evaluation]
max_samples = 20000

[[variant]]
name = "full"
options = { iters = 20, checkpoint_every = 5, mesh_res = 64, mesh_only = true }

[[variant]]
name = "photometric"
options = { no_geometric = true, iters = 20, checkpoint_every = 5, mesh_res = 64, mesh_only = true }
"#;

#[test]
fn a_slurm_array_preempted_failed_resubmitted_gathered_as_locally() {
    let tmp = tempfile::tempdir().unwrap();
    let work = tmp.path();
    let spot = fixture("spot_nersp");
    // A damaged copy: the plan accepts it (a scene folder with its ground truth); its tasks
    // fail when they read it.
    let broken = work.join("broken");
    rmvp_testkit::copy_tree(&spot, &broken);
    let damaged = broken.join("s1/0002.npy");
    let good = std::fs::read(&damaged).unwrap();
    std::fs::write(&damaged, &good[..good.len() / 2]).unwrap();
    let plan = work.join("batch.toml");
    std::fs::write(&plan, PLAN.replace("SPOT", spot.to_str().unwrap())).unwrap();
    let (plan_s, slurm_dir, local_dir) = (plan.to_str().unwrap(), work.join("slurm"), work.join("local"));
    let slurm_s = slurm_dir.to_str().unwrap();

    // Bad plans are refused before anything is written or submitted, naming the line.
    let bad = work.join("bad.toml");
    let good_plan = PLAN.replace("SPOT", spot.to_str().unwrap());
    let bad_plan = good_plan.replace("{ iters = 20, checkpoint", "{ iter = 20, checkpoint");
    assert_ne!(bad_plan, good_plan, "the plan has no option to misspell");
    std::fs::write(&bad, bad_plan).unwrap();
    let no_slurm = Command::new(env!("CARGO_BIN_EXE_rmvp"))
        .args(["batch", "run", bad.to_str().unwrap(), "-o", slurm_s, "--slurm"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&no_slurm.stderr);
    assert!(
        !no_slurm.status.success() && stderr.contains("line 9") && stderr.contains("unknown field `iter`"),
        "{stderr}"
    );
    assert!(!slurm_dir.exists());
    // Without Slurm's commands: a clear error and the way to run locally.
    let no_slurm = Command::new(env!("CARGO_BIN_EXE_rmvp"))
        .env("PATH", "/nonexistent")
        .args(["batch", "run", plan_s, "-o", work.join("nowhere").to_str().unwrap(), "--slurm"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&no_slurm.stderr);
    assert!(!no_slurm.status.success(), "{stderr}");
    assert!(stderr.contains("sbatch: not found") && stderr.contains("--local"), "{stderr}");

    let cluster = Cluster::start();
    let listing = cluster.rmvp_ok(&["batch", "plan", plan_s]);
    assert!(listing.starts_with("4 tasks: 2 datasets x 2 variants x 1 seeds"), "{listing}");
    let out =
        cluster.rmvp_ok(&["batch", "run", plan_s, "-o", slurm_s, "--slurm", "--cpus-per-task", "1", "--mem", "300M"]);
    assert!(out.contains("submitted 4 of 4 task(s)"), "{out}");
    let submission: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(slurm_dir.join("submission.json")).unwrap()).unwrap();
    let array = submission["arrays"][0]["job_id"].as_str().unwrap().to_string();
    let gather_job = submission["arrays"][0]["gather_job_id"].as_str().unwrap().to_string();
    let script = std::fs::read_to_string(slurm_dir.join("batch.sbatch")).unwrap();
    for line in
        ["#SBATCH --array=0-3", "#SBATCH --requeue", "#SBATCH --signal=B:USR2@120", "#SBATCH --open-mode=append"]
    {
        assert!(script.contains(line), "{line} not in\n{script}");
    }

    // Preempt task 0 part-way through its training, as Slurm's warning before a time limit does.
    let task0 = slurm_dir.join("tasks/spot_nersp-full-s0");
    let log0 = slurm_dir.join(format!("logs/{array}_0.log"));
    let lines = |path: &Path| std::fs::read_to_string(path).map_or(0, |t| t.lines().count());
    cluster.wait_for("task 0 to train 3 iterations", 120, || lines(&task0.join("log.jsonl")) >= 3);
    // Slurm 22.05 answers a signal to an array task whose siblings are pending with "Job can not
    // be altered now" although it delivered it, and scancel then retries, signalling the
    // requeued run again: it is stopped once the task has requeued itself.
    let mut scancel: Child =
        cluster.command("scancel").args(["--batch", "--signal=USR2", &format!("{array}_0")]).spawn().unwrap();
    cluster.wait_for("task 0 to requeue itself", 60, || {
        std::fs::read_to_string(&log0).is_ok_and(|log| log.contains("requeued"))
    });
    let _ = scancel.kill();
    let _ = scancel.wait();

    cluster.wait_for("the gather job", 300, || cluster.job_state(&gather_job) == "COMPLETED");
    let log = std::fs::read_to_string(&log0).unwrap();
    assert!(log.contains("checkpointed at iteration") && log.contains("task 0 (spot_nersp-full-s0): done"), "{log}");
    // The task's log shows its training's progress as plain lines.
    assert!(log.lines().any(|l| l.starts_with("spot_nersp-full-s0: ") && l.contains("/20 (")), "{log}");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(task0.join("result.json")).unwrap()).unwrap();
    assert!(result["sessions"].as_u64().unwrap() >= 2, "{result}");

    // The damaged dataset's tasks failed, named in status and gather; the others completed.
    let status = cluster.rmvp_ok(&["batch", "status", slurm_s]);
    assert!(status.contains("2 done, 2 failed"), "{status}");
    assert!(status.contains("0002.npy"), "the failure names the damaged file:\n{status}");
    let first = table(&slurm_dir);
    assert_eq!(first.open.iter().map(|t| t.index).collect::<Vec<_>>(), [2, 3]);
    assert!(first.open.iter().all(|t| t.state == "failed" && t.detail.contains("s1/0002.npy")));
    assert_eq!(first.rows.iter().map(|r| r.seeds).collect::<Vec<_>>(), [1, 1, 0, 0]);

    // Repaired, the failed tasks alone are submitted again.
    std::fs::write(&damaged, &good).unwrap();
    let out = cluster.rmvp_ok(&["batch", "resubmit", slurm_s]);
    assert!(out.contains("resubmitted 2 task(s)"), "{out}");
    let submission: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(slurm_dir.join("submission.json")).unwrap()).unwrap();
    assert_eq!(submission["arrays"][1]["indices"], serde_json::json!([2, 3]));
    let regather = submission["arrays"][1]["gather_job_id"].as_str().unwrap().to_string();
    cluster.wait_for("the second gather job", 300, || cluster.job_state(&regather) == "COMPLETED");
    let slurm_table = table(&slurm_dir);
    assert!(slurm_table.open.is_empty(), "{:?}", slurm_table.open);
    assert!(std::fs::metadata(slurm_dir.join("results.png")).unwrap().len() > 1000);

    // The same plan here, one thread per task as on the cluster: the same table, and the
    // preempted task's state and mesh identical to its uninterrupted run.
    let out = cluster.rmvp_ok(&[
        "--threads",
        "2",
        "batch",
        "run",
        plan_s,
        "-o",
        local_dir.to_str().unwrap(),
        "--local",
        "--jobs",
        "2",
    ]);
    assert!(out.contains("4 finished, 0 already complete, 0 failed"), "{out}");
    let local_table = table(&local_dir);
    let figures = |t: &BatchTable| {
        t.rows
            .iter()
            .map(|r| (r.dataset.clone(), r.variant.clone(), r.seeds, r.chamfer, r.fscore, r.normal_mae_deg))
            .collect::<Vec<_>>()
    };
    assert_eq!(figures(&slurm_table), figures(&local_table));
    for file in ["checkpoint.bin", "mesh.ply"] {
        let local = std::fs::read(local_dir.join("tasks/spot_nersp-full-s0").join(file)).unwrap();
        assert!(std::fs::read(task0.join(file)).unwrap() == local, "{file} differs after preemption");
    }
    // The batch's page lists each task, linking to the task's own page.
    let page = std::fs::read_to_string(local_dir.join("report.html")).unwrap();
    assert_eq!(local_table.results.len(), 4);
    for result in &local_table.results {
        let link = format!("tasks/{}/report.html", result.task.id);
        assert!(page.contains(&link) && local_dir.join(&link).is_file(), "{link}");
    }
    // `rmvp report` writes it again, as `batch gather` does.
    std::fs::remove_file(local_dir.join("report.html")).unwrap();
    let written = cluster.rmvp_ok(&["report", local_dir.to_str().unwrap()]);
    assert!(
        written.trim().ends_with("report.html")
            && std::fs::read_to_string(local_dir.join("report.html")).unwrap() == page
    );
    // Re-running a complete plan does nothing.
    let out = cluster.rmvp_ok(&["batch", "run", plan_s, "-o", local_dir.to_str().unwrap(), "--local"]);
    assert!(out.contains("0 finished, 4 already complete"), "{out}");
}
