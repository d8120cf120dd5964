//! Worker processes for `rtconf run`: each case runs in a child (`rtconf worker`) that reads cases as JSON
//! lines on stdin and writes results as JSON lines on stdout, so a driver crash or hang costs one case.
//! The driver comes from the environment variable [`DRIVER_ENV`] (`lavapipe`, `nvidia` or an ICD path).
//! A request is a trace case ([`WorkerRequest`], answered with a [`CaseResult`]) or a build case
//! ([`BuildRequest`], answered with a [`BuildResult`]); one pool runs either kind.

use crate::accel::{BuildObservation, BuildOptions};
use crate::execute::{execute, Executor};
use crate::observe::{CaseResult, Observation, Status};
use crate::vulkan::Driver;
use crate::vulkan::VkInstance;
use model::accel::{BuildCase, BuildRuleSet};
use model::case::Case;
use model::DeviceProfile;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Environment variable naming the driver a worker loads (default `lavapipe`).
pub const DRIVER_ENV: &str = "RTCONF_DRIVER";

/// One request on a worker's stdin.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct WorkerRequest {
    pub index: usize,
    pub case: Case,
}

/// One build case on a worker's stdin, with what the worker needs to judge it: the device profile (a
/// Vulkan Profiles JSON file) and the registry sources of the rules.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct BuildRequest {
    pub index: usize,
    /// Carried as the case's YAML: JSON has no NaN, and build cases hold NaN coordinates (inactive
    /// primitives).
    #[serde(with = "yaml_text")]
    pub build: BuildCase,
    pub profile_name: String,
    pub profile_path: PathBuf,
    pub sources: Vec<PathBuf>,
    #[serde(default)]
    pub options: BuildOptions,
}

mod yaml_text {
    use model::accel::BuildCase;
    pub fn serialize<S: serde::Serializer>(c: &BuildCase, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&c.to_yaml())
    }
    pub fn deserialize<'de, D: serde::Deserializer<'de>>(d: D) -> Result<BuildCase, D::Error> {
        let text = <String as serde::Deserialize>::deserialize(d)?;
        BuildCase::from_yaml("request", &text).map_err(serde::de::Error::custom)
    }
}

/// A build case's result on a worker's stdout.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BuildResult {
    pub index: usize,
    pub name: String,
    pub observation: BuildObservation,
    pub millis: f64,
}

/// What a worker keeps between build cases: an instance with the layer, the profile and the rules.
struct BuildContext {
    key: (PathBuf, Vec<PathBuf>),
    inst: Arc<VkInstance>,
    profile: DeviceProfile,
    rules: BuildRuleSet,
}

fn build_context(driver: &Driver, req: &BuildRequest) -> Result<BuildContext, String> {
    let text = std::fs::read_to_string(&req.profile_path)
        .map_err(|e| format!("profile {}: {e}", req.profile_path.display()))?;
    let profile =
        DeviceProfile::from_profiles_json(&req.profile_name, &text).map_err(|e| e.to_string())?;
    let set = vk_registry::source::load_union(&req.sources).map_err(|e| e.to_string())?;
    let rules = BuildRuleSet::from_vuids(&set);
    let inst = Arc::new(VkInstance::new(driver.clone(), true).map_err(|e| e.to_string())?);
    Ok(BuildContext {
        key: (req.profile_path.clone(), req.sources.clone()),
        inst,
        profile,
        rules,
    })
}

fn run_build_request(
    driver: &Driver,
    ctx: &mut Option<BuildContext>,
    req: &BuildRequest,
) -> BuildObservation {
    if ctx.as_ref().map_or(true, |c| {
        c.key != (req.profile_path.clone(), req.sources.clone())
    }) {
        *ctx = None;
        match build_context(driver, req) {
            Ok(c) => *ctx = Some(c),
            Err(e) => {
                return BuildObservation {
                    case: req.build.name.clone(),
                    status: format!("crash: {e}"),
                    ..Default::default()
                }
            }
        }
    }
    let c = ctx.as_ref().expect("made above");
    let unavoidable = generator::accel::unavoidable(&c.profile);
    crate::accel::run_case_with(
        &c.inst,
        &c.profile,
        &c.rules,
        &req.build,
        &unavoidable,
        req.options,
    )
}

/// The worker loop: one JSON request per stdin line, one [`CaseResult`] per stdout line. Returns the exit code.
pub fn worker_main() -> i32 {
    let driver = Driver::parse(&std::env::var(DRIVER_ENV).unwrap_or_else(|_| "lavapipe".into()));
    let mut executor: Option<Result<Executor, String>> = None;
    let mut builds: Option<BuildContext> = None;
    let stdin = std::io::stdin();
    let mut stdout = std::io::stdout();
    for line in stdin.lock().lines() {
        let Ok(line) = line else { return 2 };
        if line.trim().is_empty() {
            continue;
        }
        let started = Instant::now();
        // Trace requests are parsed once, as before; only a line naming a build case is looked into.
        let value: Option<serde_json::Value> = if line.contains("\"build\"") {
            serde_json::from_str(&line).ok()
        } else {
            None
        };
        if let Some(v) = value.as_ref().filter(|v| v.get("build").is_some()) {
            let result = match serde_json::from_value::<BuildRequest>(v.clone()) {
                Ok(req) => {
                    inject_fault(&req.build.name);
                    let observation = run_build_request(&driver, &mut builds, &req);
                    BuildResult {
                        index: req.index,
                        name: req.build.name.clone(),
                        observation,
                        millis: started.elapsed().as_secs_f64() * 1000.0,
                    }
                }
                Err(e) => {
                    let index = v
                        .get("index")
                        .and_then(|i| i.as_u64())
                        .map_or(usize::MAX, |i| i as usize);
                    let observation = BuildObservation {
                        status: format!("crash: worker could not read its build request: {e}"),
                        ..Default::default()
                    };
                    BuildResult {
                        index,
                        name: String::new(),
                        observation,
                        millis: 0.0,
                    }
                }
            };
            let Ok(text) = serde_json::to_string(&result) else {
                return 3;
            };
            if writeln!(stdout, "{text}")
                .and_then(|_| stdout.flush())
                .is_err()
            {
                return 4;
            }
            continue;
        }
        let (index, name, observation) = match serde_json::from_str::<WorkerRequest>(&line) {
            Err(e) => (
                usize::MAX,
                String::new(),
                Observation::crash(format!("worker could not read its request: {e}")),
            ),
            Ok(req) => {
                inject_fault(&req.case.name);
                let ctx = executor.get_or_insert_with(|| {
                    Executor::new(driver.clone()).map_err(|e| e.to_string())
                });
                let obs = match ctx {
                    Ok(ctx) => execute(&req.case, ctx),
                    Err(e) => Observation::crash(e.clone()),
                };
                // A lost device stays lost: start the next case on a fresh instance and device rather
                // than let every later case of this worker hang or fail for it.
                if matches!(&obs.status, Status::Crash { message } if message.contains("DEVICE_LOST"))
                {
                    executor = None;
                }
                (req.index, req.case.name, obs)
            }
        };
        let result = CaseResult {
            index,
            name,
            observation,
            millis: started.elapsed().as_secs_f64() * 1000.0,
        };
        let Ok(text) = serde_json::to_string(&result) else {
            return 3;
        };
        if writeln!(stdout, "{text}")
            .and_then(|_| stdout.flush())
            .is_err()
        {
            return 4;
        }
    }
    0
}

/// Environment variable that turns on fault injection for the pool's own tests: a case named
/// `fault-abort…` aborts the worker and one named `fault-hang…` never answers.
pub const FAULTS_ENV: &str = "RTCONF_WORKER_FAULTS";

fn inject_fault(name: &str) {
    if std::env::var_os(FAULTS_ENV).is_none() {
        return;
    }
    if name.starts_with("fault-abort") {
        std::process::abort();
    }
    if name.starts_with("fault-hang") {
        loop {
            std::thread::sleep(Duration::from_secs(3600));
        }
    }
}

/// How to start a worker process.
#[derive(Debug, Clone)]
pub struct WorkerCommand {
    pub program: PathBuf,
    pub args: Vec<String>,
    pub env: Vec<(String, String)>,
}

impl WorkerCommand {
    /// `current_exe() worker`, the `rtconf worker` subcommand.
    pub fn current_exe() -> std::io::Result<WorkerCommand> {
        Ok(WorkerCommand {
            program: std::env::current_exe()?,
            args: vec!["worker".into()],
            env: Vec::new(),
        })
    }
}

struct Worker {
    child: Child,
    stdin: ChildStdin,
    lines: Receiver<String>,
    stderr: Arc<Mutex<Vec<u8>>>,
}

impl Worker {
    fn spawn(cmd: &WorkerCommand) -> std::io::Result<Worker> {
        let mut child = Command::new(&cmd.program)
            .args(&cmd.args)
            .envs(cmd.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()?;
        let stdin = child
            .stdin
            .take()
            .ok_or_else(|| std::io::Error::other("worker has no stdin"))?;
        let stdout = child
            .stdout
            .take()
            .ok_or_else(|| std::io::Error::other("worker has no stdout"))?;
        let mut err = child
            .stderr
            .take()
            .ok_or_else(|| std::io::Error::other("worker has no stderr"))?;
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let keep = stderr.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                let mut k = keep.lock().unwrap_or_else(|e| e.into_inner());
                k.extend_from_slice(&buf[..n]);
                let len = k.len();
                if len > 8192 {
                    k.drain(..len - 8192);
                }
            }
        });
        Ok(Worker {
            child,
            stdin,
            lines,
            stderr,
        })
    }

    fn stderr_tail(&self) -> String {
        let k = self.stderr.lock().unwrap_or_else(|e| e.into_inner());
        let text = String::from_utf8_lossy(&k).into_owned();
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(5)..].join("\n")
    }

    fn stop(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One item of work for the pool: how it is asked of a worker and what stands for its result when the
/// worker is lost.
pub trait PoolJob: Sync {
    type Result: Send + serde::de::DeserializeOwned;
    fn name(&self) -> &str;
    fn request(&self, index: usize) -> serde_json::Result<String>;
    fn lost(&self, index: usize, status: Status, millis: f64) -> Self::Result;
    fn result_index(r: &Self::Result) -> usize;
}

impl PoolJob for Case {
    type Result = CaseResult;
    fn name(&self) -> &str {
        &self.name
    }
    fn request(&self, index: usize) -> serde_json::Result<String> {
        serde_json::to_string(&WorkerRequest {
            index,
            case: self.clone(),
        })
    }
    fn lost(&self, index: usize, status: Status, millis: f64) -> CaseResult {
        CaseResult {
            index,
            name: self.name.clone(),
            observation: Observation::with_status(status),
            millis,
        }
    }
    fn result_index(r: &CaseResult) -> usize {
        r.index
    }
}

impl PoolJob for BuildRequest {
    type Result = BuildResult;
    fn name(&self) -> &str {
        &self.build.name
    }
    fn request(&self, index: usize) -> serde_json::Result<String> {
        serde_json::to_string(&BuildRequest {
            index,
            ..self.clone()
        })
    }
    fn lost(&self, index: usize, status: Status, millis: f64) -> BuildResult {
        let status = match status {
            Status::Ran => "ran".into(),
            Status::Unsupported { reason } => format!("unsupported: {reason}"),
            Status::Crash { message } => format!("crash: {message}"),
            Status::Timeout { seconds } => format!("timeout: after {seconds:.1} s"),
        };
        BuildResult {
            index,
            name: self.build.name.clone(),
            observation: BuildObservation {
                case: self.build.name.clone(),
                status,
                ..Default::default()
            },
            millis,
        }
    }
    fn result_index(r: &BuildResult) -> usize {
        r.index
    }
}

enum Outcome<R> {
    Done(R),
    /// The worker is gone or hung; the case's result says which.
    Lost(R),
}

fn run_one<J: PoolJob>(
    w: &mut Worker,
    index: usize,
    job: &J,
    timeout: Duration,
) -> Outcome<J::Result> {
    let started = Instant::now();
    let lost = |status: Status| {
        Outcome::Lost(job.lost(index, status, started.elapsed().as_secs_f64() * 1000.0))
    };
    let Ok(text) = job.request(index) else {
        return lost(Status::Crash {
            message: "the case could not be serialised".into(),
        });
    };
    if writeln!(w.stdin, "{text}")
        .and_then(|_| w.stdin.flush())
        .is_err()
    {
        return lost(Status::Crash {
            message: format!(
                "the worker exited before taking the case; stderr: {}",
                w.stderr_tail()
            ),
        });
    }
    loop {
        let left = timeout.saturating_sub(started.elapsed());
        match w.lines.recv_timeout(left) {
            // Other output (a test harness's own text) is not a result; a result may follow it on a line.
            Ok(line) => {
                let Some(start) = line.find('{') else {
                    continue;
                };
                return match serde_json::from_str::<J::Result>(&line[start..]) {
                    Ok(r) if J::result_index(&r) == index => Outcome::Done(r),
                    Ok(_) | Err(_) => continue,
                };
            }
            Err(RecvTimeoutError::Timeout) => {
                return lost(Status::Timeout {
                    seconds: timeout.as_secs_f64(),
                })
            }
            Err(RecvTimeoutError::Disconnected) => {
                let code = w
                    .child
                    .wait()
                    .map(|s| s.to_string())
                    .unwrap_or_else(|e| e.to_string());
                std::thread::sleep(Duration::from_millis(20));
                return lost(Status::Crash {
                    message: format!("the worker died ({code}); stderr: {}", w.stderr_tail()),
                });
            }
        }
    }
}

/// Runs `cases` on `jobs` worker processes (`current_exe() worker`), `timeout` per case; a worker that crashes
/// or hangs is replaced and its case reported `crash` or `timeout`. Results arrive in completion order.
pub fn run_in_workers(
    cases: &[Case],
    jobs: usize,
    timeout: Duration,
    on_result: impl FnMut(CaseResult),
) {
    run_pool(cases, jobs, timeout, on_result)
}

/// [`run_in_workers`] for build cases.
pub fn run_builds_in_workers(
    requests: &[BuildRequest],
    jobs: usize,
    timeout: Duration,
    on_result: impl FnMut(BuildResult),
) {
    run_pool(requests, jobs, timeout, on_result)
}

fn run_pool<J: PoolJob>(
    items: &[J],
    jobs: usize,
    timeout: Duration,
    on_result: impl FnMut(J::Result),
) {
    match WorkerCommand::current_exe() {
        Ok(cmd) => run_pool_with(&cmd, items, jobs, timeout, on_result),
        Err(e) => {
            let mut on_result = on_result;
            for (index, item) in items.iter().enumerate() {
                on_result(item.lost(
                    index,
                    Status::Crash {
                        message: format!("cannot find the rtconf executable to start workers: {e}"),
                    },
                    0.0,
                ));
            }
        }
    }
}

/// [`run_in_workers`] with an explicit worker command.
pub fn run_in_workers_with(
    cmd: &WorkerCommand,
    cases: &[Case],
    jobs: usize,
    timeout: Duration,
    on_result: impl FnMut(CaseResult),
) {
    run_pool_with(cmd, cases, jobs, timeout, on_result)
}

/// The pool over any kind of job, with an explicit worker command.
pub fn run_pool_with<J: PoolJob>(
    cmd: &WorkerCommand,
    items: &[J],
    jobs: usize,
    timeout: Duration,
    mut on_result: impl FnMut(J::Result),
) {
    let queue: Arc<Mutex<VecDeque<usize>>> = Arc::new(Mutex::new((0..items.len()).collect()));
    let (tx, rx) = mpsc::channel::<J::Result>();
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1).min(items.len().max(1)) {
            let queue = queue.clone();
            let tx = tx.clone();
            s.spawn(move || {
                let mut worker: Option<Worker> = None;
                loop {
                    let Some(index) = queue.lock().unwrap_or_else(|e| e.into_inner()).pop_front()
                    else {
                        break;
                    };
                    let item = &items[index];
                    if worker.is_none() {
                        match Worker::spawn(cmd) {
                            Ok(w) => worker = Some(w),
                            Err(e) => {
                                let status = Status::Crash {
                                    message: format!(
                                        "cannot start worker {}: {e}",
                                        cmd.program.display()
                                    ),
                                };
                                let _ = tx.send(item.lost(index, status, 0.0));
                                continue;
                            }
                        }
                    }
                    let w = worker.as_mut().expect("spawned above");
                    match run_one(w, index, item, timeout) {
                        Outcome::Done(r) => {
                            let _ = tx.send(r);
                        }
                        Outcome::Lost(r) => {
                            if let Some(w) = worker.take() {
                                w.stop();
                            }
                            let _ = tx.send(r);
                        }
                    }
                }
                if let Some(w) = worker.take() {
                    drop(w.stdin);
                    let mut child = w.child;
                    let _ = child.wait();
                }
            });
        }
        drop(tx);
        for r in rx {
            on_result(r);
        }
    });
}
