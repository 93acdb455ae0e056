//! The grid-manager files in `deploy/` kept true: every `gridlight` command line in them is
//! split as its runner splits it (shell, systemd, HTCondor, Kubernetes), its variables
//! replaced by sample values, and parsed by the real command line (`Cli::try_parse_from`);
//! the HTCondor policy expressions parse and read only attributes HTCondor documents; the
//! Kubernetes objects refer to each other consistently; the systemd unit passes
//! `systemd-analyze verify` where that exists. `tests/deploy_slurm.rs` runs the Slurm
//! script for real.

mod deploy;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use clap::Parser;
use deploy::words::{self, Vars};
use gridlight::cli::{Cli, Command as Sub};
use serde_yaml::Value;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(repo().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// Parses `words` with the real CLI; panics naming the file and line on refusal.
fn check_cli(file: &str, line: usize, words: &[String]) -> Cli {
    Cli::try_parse_from(words).unwrap_or_else(|e| {
        panic!("{file}:{line}: `{}` is refused by gridlight:\n{e}", words.join(" "))
    })
}

fn worker_args(cli: Cli) -> gridlight::cli::worker::Args {
    match cli.command {
        Sub::Worker(args) => args,
        other => panic!("expected a worker command, got {other:?}"),
    }
}

// --- Slurm ---------------------------------------------------------------------------

#[test]
fn slurm_batch_script_starts_a_valid_worker() {
    let file = "deploy/slurm/gridlight-workers.sbatch";
    let vars = words::vars(&[
        ("1", "render-host:7840"),
        ("SLURM_CPUS_PER_TASK", "4"),
        ("SLURM_JOB_USER", "alice"),
        ("SLURM_JOB_ID", "42"),
        ("SLURM_ARRAY_JOB_ID", "41"),
        ("SLURM_ARRAY_TASK_ID", "3"),
        ("HOME", "/home/alice"),
        ("MASTER", "render-host:7840"),
    ]);
    let commands =
        words::shell_commands(&read(file), &vars).unwrap_or_else(|e| panic!("{file}: {e}"));
    assert_eq!(commands.len(), 1, "{file}: one gridlight command expected: {commands:?}");
    let (line, cmd) = &commands[0];
    let args = worker_args(check_cli(file, *line, cmd));
    assert_eq!(args.master.as_deref(), Some("render-host:7840"), "the script's argument");
    assert_eq!(args.threads, Some(4), "one thread per CPU Slurm gives the task");
    assert_eq!(args.name.as_deref(), Some("slurm-41-3"));
    // The #SBATCH directives come before the first command, or sbatch ignores them.
    let text = read(file);
    let first_command = text
        .lines()
        .position(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .expect("the script runs something");
    let last_directive = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("#SBATCH"))
        .map(|(i, _)| i)
        .last()
        .expect("directives");
    assert!(last_directive < first_command, "{file}: #SBATCH after the first command");
}

#[test]
fn slurm_local_cluster_script_is_valid_bash() {
    let status = Command::new("bash")
        .args(["-n", "deploy/slurm/local-cluster.sh", "deploy/slurm/gridlight-workers.sbatch"])
        .current_dir(repo())
        .status()
        .expect("bash runs");
    assert!(status.success());
}

// --- HTCondor ------------------------------------------------------------------------

/// `NAME = VALUE` lines of an HTCondor file (`\` continues a line; `#` comments).
fn condor_definitions(text: &str) -> Vec<(usize, String, String)> {
    words::logical_lines(text)
        .into_iter()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .filter_map(|(n, l)| {
            let (k, v) = l.split_once('=')?;
            Some((n, k.trim().to_string(), v.trim().to_string()))
        })
        .collect()
}

/// Machine and job ClassAd attributes the HTCondor manual documents ("Machine ClassAd
/// Attributes", "Job ClassAd Attributes") that these files use or might.
const DOCUMENTED_ATTRIBUTES: &[&str] = &[
    "Activity",
    "Arch",
    "ClockDay",
    "ClockMin",
    "CondorLoadAvg",
    "ConsoleIdle",
    "Cpus",
    "CurrentTime",
    "Disk",
    "EnteredCurrentActivity",
    "EnteredCurrentState",
    "HasFileTransfer",
    "JobStart",
    "KeyboardIdle",
    "LoadAvg",
    "Machine",
    "Memory",
    "OpSys",
    "OpSysAndVer",
    "RemoteOwner",
    "RemoteUser",
    "State",
    "TotalCondorLoadAvg",
    "TotalCpus",
    "TotalDisk",
    "TotalLoadAvg",
    "TotalMemory",
    "ExitBySignal",
    "ExitCode",
    "NumJobStarts",
    "RequestCpus",
];

/// Startd policy expressions (HTCondor manual, "Policy Configuration for Execute Hosts").
const POLICY_KNOBS: &[&str] =
    &["START", "SUSPEND", "CONTINUE", "PREEMPT", "KILL", "WANT_SUSPEND", "WANT_VACATE"];

/// Submit description commands the HTCondor manual documents (condor_submit).
const SUBMIT_COMMANDS: &[&str] = &[
    "universe",
    "executable",
    "transfer_executable",
    "arguments",
    "transfer_input_files",
    "should_transfer_files",
    "when_to_transfer_output",
    "request_cpus",
    "request_memory",
    "request_disk",
    "requirements",
    "rank",
    "output",
    "error",
    "log",
    "environment",
    "getenv",
    "notification",
    "initialdir",
    "on_exit_remove",
    "periodic_remove",
    "periodic_release",
];

fn check_attributes(file: &str, line: usize, name: &str, expr: &str) {
    let attrs = deploy::classad::attributes(expr).unwrap_or_else(|e| {
        panic!("{file}:{line}: {name} = {expr}\nis not a ClassAd expression: {e}")
    });
    for a in attrs {
        assert!(
            DOCUMENTED_ATTRIBUTES.iter().any(|d| d.eq_ignore_ascii_case(&a)),
            "{file}:{line}: {name} reads `{a}`, which is not a documented ClassAd attribute"
        );
    }
}

#[test]
fn htcondor_policy_runs_workers_only_on_idle_desktops() {
    let file = "deploy/htcondor/idle-desktop.config";
    let defs = condor_definitions(&read(file));
    let macros: Vars = defs.iter().map(|(_, k, v)| (k.clone(), v.clone())).collect();
    for knob in ["START", "SUSPEND", "CONTINUE", "PREEMPT", "KILL"] {
        assert!(macros.contains_key(knob), "{file}: no {knob} expression");
    }
    for (line, name, value) in &defs {
        let expanded = words::condor_expand(value, &macros)
            .unwrap_or_else(|e| panic!("{file}:{line}: {name}: {e}"));
        if POLICY_KNOBS.contains(&name.as_str()) {
            check_attributes(file, *line, name, &expanded);
        }
    }
    // The owner's activity is what the policy watches.
    let start = words::condor_expand(&macros["START"], &macros).unwrap();
    let suspend = words::condor_expand(&macros["SUSPEND"], &macros).unwrap();
    for (knob, expr) in [("START", &start), ("SUSPEND", &suspend)] {
        for attr in ["KeyboardIdle", "LoadAvg"] {
            assert!(expr.contains(attr), "{file}: {knob} does not look at {attr}: {expr}");
        }
    }
}

#[test]
fn htcondor_submit_description_is_valid() {
    let file = "deploy/htcondor/gridlight-worker.sub";
    let text = read(file);
    let defs = condor_definitions(&text);
    let mut macros: Vars = defs.iter().map(|(_, k, v)| (k.clone(), v.clone())).collect();
    macros.insert("Cluster".into(), "17".into());
    macros.insert("Process".into(), "5".into());
    let get = |k: &str| macros.get(k).unwrap_or_else(|| panic!("{file}: no `{k}`"));
    assert_eq!(get("universe"), "vanilla");
    assert_eq!(
        get("transfer_executable").to_lowercase(),
        "true",
        "the binary travels with the job"
    );
    assert!(words::is_gridlight(get("executable")));
    // Every key is a documented command, or a macro of this file that something uses.
    for (line, key, _) in &defs {
        let used = text.to_lowercase().contains(&format!("$({})", key.to_lowercase()));
        assert!(
            SUBMIT_COMMANDS.contains(&key.as_str()) || key.starts_with('+') || used,
            "{file}:{line}: `{key}` is neither a submit command nor a macro used in the file"
        );
    }
    let (line, _, arguments) = defs.iter().find(|(_, k, _)| k == "arguments").expect("arguments");
    let arguments = words::condor_expand(arguments, &macros).unwrap();
    let mut cmd = vec!["gridlight".to_string()];
    cmd.extend(
        words::condor_arguments(&arguments).unwrap_or_else(|e| panic!("{file}:{line}: {e}")),
    );
    let args = worker_args(check_cli(file, *line, &cmd));
    assert_eq!(args.master.as_ref(), Some(&macros["master"]), "the `master` macro");
    // The secret file the worker reads is one the job transfers.
    let secret = args.secret_file.expect("workers prove the secret");
    assert!(get("transfer_input_files").split(',').any(|f| Path::new(f.trim()) == secret));
    let (line, _, requirements) = defs.iter().find(|(_, k, _)| k == "requirements").unwrap();
    check_attributes(file, *line, "requirements", requirements);
    let queue = text.lines().find(|l| l.trim_start().starts_with("queue")).expect("a queue line");
    let count = words::condor_expand(queue.trim_start()["queue".len()..].trim(), &macros).unwrap();
    assert!(count.parse::<u32>().is_ok(), "{file}: queue {count}");
}

// --- Kubernetes and the container ------------------------------------------------------

fn yaml_documents(rel: &str) -> Vec<Value> {
    use serde::Deserialize;
    serde_yaml::Deserializer::from_str(&read(rel))
        .map(|d| Value::deserialize(d).unwrap_or_else(|e| panic!("{rel}: {e}")))
        .filter(|v| !v.is_null())
        .collect()
}

fn find<'a>(docs: &'a [Value], kind: &str, name: &str) -> &'a Value {
    docs.iter()
        .find(|d| d["kind"] == kind && d["metadata"]["name"] == name)
        .unwrap_or_else(|| panic!("no {kind} {name}"))
}

fn strings(v: &Value) -> Vec<String> {
    v.as_sequence()
        .map(|s| s.iter().map(|x| x.as_str().expect("a string").to_string()).collect())
        .unwrap_or_default()
}

/// A container's command line, `$(VAR)` replaced from its `env` (Kubernetes' own syntax).
fn container_command(c: &Value) -> Vec<String> {
    let env: HashMap<String, String> = c["env"]
        .as_sequence()
        .into_iter()
        .flatten()
        .map(|e| {
            let name = e["name"].as_str().unwrap().to_string();
            let value =
                e["value"].as_str().map_or_else(|| format!("sample-{name}"), str::to_string);
            (name, value)
        })
        .collect();
    let mut words = strings(&c["command"]);
    words.extend(strings(&c["args"]));
    words
        .into_iter()
        .map(|w| env.iter().fold(w, |w, (k, v)| w.replace(&format!("$({k})"), v)))
        .collect()
}

/// The secret file a container reads must be a key of the Secret, mounted where it reads.
fn check_secret_mount(pod: &Value, container: &Value, path: &Path, secret: &Value) {
    let dir = path.parent().unwrap().to_str().unwrap();
    let key = path.file_name().unwrap().to_str().unwrap();
    let mount = container["volumeMounts"]
        .as_sequence()
        .unwrap()
        .iter()
        .find(|m| m["mountPath"] == dir)
        .unwrap_or_else(|| panic!("nothing mounted at {dir}"));
    let volume = pod["volumes"]
        .as_sequence()
        .unwrap()
        .iter()
        .find(|v| v["name"] == mount["name"])
        .expect("the mounted volume exists");
    assert_eq!(volume["secret"]["secretName"], secret["metadata"]["name"]);
    assert!(!secret["stringData"][key].is_null() || !secret["data"][key].is_null(), "no key {key}");
}

#[test]
fn kubernetes_manifests_are_consistent_and_their_command_lines_valid() {
    let secret = yaml_documents("deploy/kubernetes/secret.yaml");
    let master = yaml_documents("deploy/kubernetes/master.yaml");
    let workers = yaml_documents("deploy/kubernetes/workers.yaml");
    let secret = find(&secret, "Secret", "gridlight-secret");
    let service = find(&master, "Service", "gridlight-master");
    let master = find(&master, "Deployment", "gridlight-master");
    let workers = find(&workers, "Deployment", "gridlight-workers");
    let dockerfile = read("deploy/container/Dockerfile");

    let mut master_port = None;
    for (file, deployment) in [("master.yaml", master), ("workers.yaml", workers)] {
        let pod = &deployment["spec"]["template"]["spec"];
        let labels = &deployment["spec"]["template"]["metadata"]["labels"];
        assert_eq!(&deployment["spec"]["selector"]["matchLabels"], labels, "{file}: selector");
        assert!(deployment["spec"]["replicas"].as_u64().is_some(), "{file}: replicas");
        for c in pod["containers"].as_sequence().unwrap() {
            let cmd = container_command(c);
            assert!(
                dockerfile.contains(&format!("ENTRYPOINT [\"{}\"]", cmd[0])),
                "{file}: {cmd:?}"
            );
            match check_cli(file, 0, &cmd).command {
                Sub::Master(args) => {
                    master_port = Some(args.listen.port());
                    let scene =
                        args.scene.strip_prefix("/usr/share/gridlight").expect("a built-in scene");
                    assert!(repo().join(scene).is_file(), "{file}: no {}", scene.display());
                    check_secret_mount(pod, c, &args.secret_file.expect("a secret"), secret);
                    let ports = c["ports"].as_sequence().unwrap();
                    assert!(ports
                        .iter()
                        .any(|p| p["containerPort"] == u64::from(args.listen.port())
                            && p["name"] == service["spec"]["ports"][0]["targetPort"]));
                }
                Sub::Worker(args) => {
                    let port = service["spec"]["ports"][0]["port"].as_u64().unwrap();
                    let name = service["metadata"]["name"].as_str().unwrap();
                    assert_eq!(
                        args.master,
                        Some(format!("{name}:{port}")),
                        "{file}: workers reach the Service"
                    );
                    check_secret_mount(pod, c, &args.secret_file.expect("a secret"), secret);
                }
                other => panic!("{file}: unexpected command {other:?}"),
            }
        }
    }
    assert_eq!(master_port, service["spec"]["ports"][0]["port"].as_u64().map(|p| p as u16));
    let selector = service["spec"]["selector"].as_mapping().unwrap();
    let labels = &master["spec"]["template"]["metadata"]["labels"];
    for (k, v) in selector {
        assert_eq!(&labels[k.as_str().unwrap()], v, "the Service selects the master's pods");
    }
    assert_ne!(
        &workers["spec"]["template"]["metadata"]["labels"], labels,
        "the Service must not select the workers"
    );
}

// --- systemd ----------------------------------------------------------------------------

#[test]
fn systemd_unit_runs_an_idle_priority_worker() {
    let file = "deploy/systemd/gridlight-worker.service";
    let text = read(file);
    let entries: Vec<(usize, String, String)> = words::logical_lines(&text)
        .into_iter()
        .filter(|(_, l)| !l.starts_with('#') && !l.starts_with('['))
        .filter_map(|(n, l)| l.split_once('=').map(|(k, v)| (n, k.to_string(), v.to_string())))
        .collect();
    for (key, value) in [("CPUSchedulingPolicy", "idle"), ("Nice", "19"), ("Restart", "on-failure")]
    {
        assert_eq!(unit_values(&entries, key), [value], "{file}: {key}");
    }
    let vars: Vars = unit_values(&entries, "Environment")
        .into_iter()
        .filter_map(|v| v.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let (line, _, exec) = entries.iter().find(|(_, k, _)| k == "ExecStart").expect("ExecStart");
    let cmd = words::systemd_exec(exec, &vars).unwrap_or_else(|e| panic!("{file}:{line}: {e}"));
    let args = worker_args(check_cli(file, *line, &cmd));
    assert_eq!(args.master.as_ref(), Some(&vars["GRIDLIGHT_MASTER"]));
    assert_eq!(args.when_idle, Some(true), "{file}: office desktops run --when-idle");
    verify_unit(file, &text, &cmd[0]);
}

/// The values of every `key=` line of a unit.
fn unit_values<'a>(entries: &'a [(usize, String, String)], key: &str) -> Vec<&'a str> {
    entries.iter().filter(|(_, k, _)| k == key).map(|(_, _, v)| v.as_str()).collect()
}

/// `systemd-analyze verify` on the unit with the real binary in place of the installed one
/// (verify checks that the executable exists); any complaint fails.
fn verify_unit(file: &str, text: &str, installed: &str) {
    let dir = tempfile::tempdir().unwrap();
    let unit = dir.path().join("gridlight-worker.service");
    std::fs::write(&unit, text.replace(installed, env!("CARGO_BIN_EXE_gridlight"))).unwrap();
    let out = match Command::new("systemd-analyze").arg("verify").arg(&unit).output() {
        Ok(out) => out,
        Err(e) => {
            let why = format!("systemd-analyze not runnable ({e})");
            let test = format!("systemd-analyze verify of {file}");
            // Not installed fails under CI=true (`.ci/run` installs systemd).
            let missing = match e.kind() {
                std::io::ErrorKind::NotFound => gridlight::testing::Missing::Tool,
                _ => gridlight::testing::Missing::System,
            };
            gridlight::testing::skip(&test, missing, why);
            return;
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stderr.trim().is_empty(),
        "systemd-analyze verify {file}:\n{stderr}"
    );
}
