//! Worker processes: each case runs in a child (`rtconf worker`) that reads [`Request`]s as JSON lines
//! on stdin and writes [`Response`]s as JSON lines on stdout, so a driver crash or hang costs one case.
//! The driver comes from the environment variable [`DRIVER_ENV`] (`lavapipe`, `nvidia` or an ICD path).
//! One request type carries a case of any command; the worker only observes.

use crate::execute::{Execution, Executor};
use crate::observe::{Observation, Status};
use crate::vk::Driver;
use model::case::Case;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Environment variable naming the driver a worker loads (default `lavapipe`).
pub const DRIVER_ENV: &str = "RTCONF_DRIVER";

/// One case on a worker's stdin and how to run it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Request {
    /// Position of the case in the batch given to the pool.
    pub index: usize,
    /// Carried as the case's CBOR, in hex: JSON has no NaN, and build cases hold NaN coordinates
    /// (inactive primitives); the case's YAML would do, but reading a rendered scene's YAML costs the
    /// worker more than running it.
    #[serde(with = "cbor_hex")]
    pub case: Case,
    #[serde(default)]
    pub execution: Execution,
}

/// A value as the runner and a worker hand it to each other inside a JSON line: its serde form in CBOR
/// (self-describing, every float kept bit for bit), as hex digits. A rendered case's scene and its
/// launch's ray records (tens of thousands of words) read several times faster so than as JSON
/// numbers.
mod cbor_hex {
    pub fn serialize<T: serde::Serialize, S: serde::Serializer>(
        v: &T,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        let mut bytes = Vec::new();
        ciborium::into_writer(v, &mut bytes).map_err(serde::ser::Error::custom)?;
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut hex = Vec::with_capacity(2 * bytes.len());
        for b in &bytes {
            hex.extend_from_slice(&[DIGITS[(b >> 4) as usize], DIGITS[(b & 15) as usize]]);
        }
        let hex = String::from_utf8(hex).expect("hex digits are ASCII");
        s.serialize_str(&hex)
    }
    pub fn deserialize<'de, T: serde::de::DeserializeOwned, D: serde::Deserializer<'de>>(
        d: D,
    ) -> Result<T, D::Error> {
        use serde::de::Error;
        let text = <std::borrow::Cow<'de, str> as serde::Deserialize>::deserialize(d)?;
        // Each byte's digit value, or 16 for a byte that is not a lowercase hex digit.
        const VALUE: [u8; 256] = {
            let mut t = [16u8; 256];
            let mut c = 0;
            while c < 10 {
                t[b'0' as usize + c] = c as u8;
                c += 1;
            }
            let mut c = 0;
            while c < 6 {
                t[b'a' as usize + c] = 10 + c as u8;
                c += 1;
            }
            t
        };
        if text.len() % 2 != 0 {
            return Err(D::Error::custom("the value's hex digits are odd in number"));
        }
        let mut bytes = Vec::with_capacity(text.len() / 2);
        for p in text.as_bytes().chunks_exact(2) {
            let (hi, lo) = (VALUE[p[0] as usize], VALUE[p[1] as usize]);
            if hi > 15 || lo > 15 {
                let c = if hi > 15 { p[0] } else { p[1] };
                return Err(D::Error::custom(format!(
                    "the value is not hex digits (byte {c:#04x})"
                )));
            }
            bytes.push(hi << 4 | lo);
        }
        ciborium::from_reader(bytes.as_slice())
            .map_err(|e| D::Error::custom(format!("the value does not read: {e}")))
    }
}

/// One case's result on a worker's stdout, as the pool reports it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Response {
    /// Position of the case in the batch given to the pool.
    pub index: usize,
    pub name: String,
    #[serde(with = "cbor_hex")]
    pub observation: Observation,
    /// Wall time of the case in the worker, in milliseconds.
    pub millis: f64,
    /// Of that, the milliseconds per phase of the execution ([`crate::timing`]); the rest is the
    /// worker's own (reading the request, the plan, destroying the case's objects).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub phases: BTreeMap<String, f64>,
}

impl Request {
    /// The response that stands for this request when its worker is lost.
    fn lost(&self, status: Status, millis: f64) -> Response {
        Response {
            index: self.index,
            name: self.case.name.clone(),
            observation: Observation::with_status(status),
            millis,
            phases: BTreeMap::new(),
        }
    }
}

/// The worker loop: one [`Request`] per stdin line, one [`Response`] per stdout line. Returns the exit
/// code.
pub fn worker_main() -> i32 {
    let driver = Driver::parse(&std::env::var(DRIVER_ENV).unwrap_or_else(|_| "lavapipe".into()));
    // Made before the first request arrives: the instance (and the layer's start-up) overlaps the
    // runner's drawing of the first cases.
    let mut executor: Option<Result<Executor, crate::HarnessError>> =
        Some(Executor::new(driver.clone()));
    let stdin = std::io::stdin();
    let mut stdout = std::io::stdout();
    for line in stdin.lock().lines() {
        let Ok(line) = line else { return 2 };
        if line.trim().is_empty() {
            continue;
        }
        let started = Instant::now();
        let _ = crate::timing::take();
        let (index, name, observation) = match serde_json::from_str::<Request>(&line) {
            Err(e) => {
                let index = serde_json::from_str::<serde_json::Value>(&line)
                    .ok()
                    .and_then(|v| v.get("index").and_then(|i| i.as_u64()))
                    .map_or(usize::MAX, |i| i as usize);
                let obs = Observation::crash(format!("worker could not read its request: {e}"));
                (index, String::new(), obs)
            }
            Ok(req) => {
                inject_fault(&req.case.name);
                let ctx = executor.get_or_insert_with(|| Executor::new(driver.clone()));
                let obs = match ctx {
                    Ok(ctx) => ctx.execute(&req.case, &req.execution),
                    Err(e) => Observation::crash(e.to_string()),
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
        let response = Response {
            index,
            name,
            observation,
            millis: started.elapsed().as_secs_f64() * 1000.0,
            phases: crate::timing::take(),
        };
        let Ok(text) = serde_json::to_string(&response) else {
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

/// Environment variable that turns on fault injection for the pool's and the runner's own tests: a case
/// named `fault-abort…` aborts the worker, one named `fault-hang…` never answers, and one named
/// `fault-flaky…` aborts the worker and runs normally by turns (across the workers of one runner).
pub const FAULTS_ENV: &str = "RTCONF_WORKER_FAULTS";

fn inject_fault(name: &str) {
    if std::env::var_os(FAULTS_ENV).is_none() {
        return;
    }
    if name.starts_with("fault-abort") {
        std::process::abort();
    }
    if name.starts_with("fault-flaky") {
        // The turn is a marker file of the runner (the workers' parent) and the case: absent, the
        // worker makes it and dies; present, it removes it and runs the case.
        let marker = std::env::temp_dir().join(format!(
            "rtconf-fault-flaky-{}-{}",
            std::os::unix::process::parent_id(),
            name.replace('/', "_")
        ));
        if std::fs::remove_file(&marker).is_err() {
            let _ = std::fs::write(&marker, b"");
            std::process::abort();
        }
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

enum Outcome {
    Done(Response),
    /// The worker is gone or hung; the case's result says which.
    Lost(Response),
}

fn run_one(w: &mut Worker, req: &Request, timeout: Duration) -> Outcome {
    let started = Instant::now();
    let lost =
        |status: Status| Outcome::Lost(req.lost(status, started.elapsed().as_secs_f64() * 1000.0));
    let Ok(text) = serde_json::to_string(req) else {
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
                return match serde_json::from_str::<Response>(&line[start..]) {
                    Ok(r) if r.index == req.index => Outcome::Done(r),
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

/// Runs `requests` on `jobs` worker processes (`current_exe() worker`), `timeout` per case; a worker that
/// crashes or hangs is replaced and its case reported `crash` or `timeout`. Responses arrive in
/// completion order; each request's `index` comes back in its response.
pub fn run_in_workers(
    requests: &[Request],
    jobs: usize,
    timeout: Duration,
    mut on_result: impl FnMut(Response),
) {
    match WorkerCommand::current_exe() {
        Ok(cmd) => run_in_workers_with(&cmd, requests, jobs, timeout, on_result),
        Err(e) => {
            for req in requests {
                on_result(req.lost(
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
    requests: &[Request],
    jobs: usize,
    timeout: Duration,
    mut on_result: impl FnMut(Response),
) {
    if requests.is_empty() {
        return;
    }
    let workers = jobs.max(1).min(requests.len());
    run_stream(
        cmd,
        workers,
        timeout,
        requests.iter(),
        |r| r,
        |r: &&Request| Some(*r),
        |_, r| {
            if let Some(r) = r {
                on_result(r)
            }
        },
    );
}

/// Runs a stream of jobs on `jobs` worker processes started at once (each makes its instance while
/// the first jobs are still being drawn) and kept for the whole stream: `source` is drawn from by
/// whichever worker is free, so a producer that generates jobs while earlier ones run keeps every
/// worker busy. `prepare` is applied to each job by the thread that drew it, before it runs (work the
/// producer need not do alone, such as the gate); `request` says what a job runs (None: nothing —
/// the job passes straight to `on_result`, in its turn). `on_result` gets each job back with its response, in completion order,
/// on the calling thread. A worker that crashes or hangs is replaced and its job reported `crash` or
/// `timeout`.
pub fn run_stream<J: Send>(
    cmd: &WorkerCommand,
    jobs: usize,
    timeout: Duration,
    source: impl Iterator<Item = J> + Send,
    prepare: impl Fn(J) -> J + Sync,
    request: impl Fn(&J) -> Option<&Request> + Sync,
    mut on_result: impl FnMut(J, Option<Response>),
) {
    let source = Mutex::new(source);
    let (tx, rx) = mpsc::channel::<(J, Option<Response>)>();
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1) {
            let tx = tx.clone();
            let (source, prepare, request) = (&source, &prepare, &request);
            s.spawn(move || {
                let mut worker: Option<Worker> = Worker::spawn(cmd).ok();
                loop {
                    let next = source.lock().unwrap_or_else(|e| e.into_inner()).next();
                    let Some(job) = next else { break };
                    let job = prepare(job);
                    let Some(req) = request(&job) else {
                        let _ = tx.send((job, None));
                        continue;
                    };
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
                                let lost = req.lost(status, 0.0);
                                let _ = tx.send((job, Some(lost)));
                                continue;
                            }
                        }
                    }
                    let w = worker.as_mut().expect("spawned above");
                    let response = match run_one(w, req, timeout) {
                        Outcome::Done(r) => r,
                        Outcome::Lost(r) => {
                            if let Some(w) = worker.take() {
                                w.stop();
                            }
                            r
                        }
                    };
                    let _ = tx.send((job, Some(response)));
                }
                if let Some(w) = worker.take() {
                    drop(w.stdin);
                    let mut child = w.child;
                    let _ = child.wait();
                }
            });
        }
        drop(tx);
        for (job, r) in rx {
            on_result(job, r);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn response(words: Vec<u32>) -> Response {
        let mut observation = Observation::with_status(Status::Ran);
        observation.output = Some(crate::observe::Output::Words(words));
        Response {
            index: 3,
            name: "c".into(),
            observation,
            millis: 1.5,
            phases: BTreeMap::new(),
        }
    }

    #[test]
    fn a_response_reads_back_from_its_json_line() {
        let r = response((0..1000u32).map(|i| i.wrapping_mul(0x0101_0101)).collect());
        let line = serde_json::to_string(&r).unwrap();
        assert!(!line.contains('\n'));
        let back: Response = serde_json::from_str(&line).unwrap();
        assert_eq!(back, r);
    }

    #[test]
    fn digits_that_are_not_hex_are_an_error_naming_the_byte() {
        let line = serde_json::to_string(&response(vec![7, 8])).unwrap();
        let (head, tail) = line.split_once("\"observation\":\"").unwrap();
        // The observation's first digit replaced by `g`, then the whole value one digit short.
        let bad = format!("{head}\"observation\":\"g{}", &tail[1..]);
        let e = serde_json::from_str::<Response>(&bad).unwrap_err();
        assert!(e.to_string().contains("not hex digits (byte 0x67)"), "{e}");
        let odd = format!("{head}\"observation\":\"{}", &tail[1..]);
        let e = serde_json::from_str::<Response>(&odd).unwrap_err();
        assert!(e.to_string().contains("odd in number"), "{e}");
    }
}
