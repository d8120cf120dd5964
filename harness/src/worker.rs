//! Worker processes: each case runs in a child (`rtconf worker`) that reads [`Request`]s on stdin and
//! writes [`Response`]s on stdout, one [`frame`] each, so a driver crash or hang costs one case.
//! The driver comes from the environment variable [`DRIVER_ENV`] (`lavapipe`, `nvidia` or an ICD path).
//! One request type carries a case of any command; the worker only observes.

use crate::execute::{Affinity, Execution, Executor};
use crate::observe::{Observation, Status};
use crate::vk::Driver;
use model::case::Case;
use std::collections::BTreeMap;
use std::io::{BufReader, Read};
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
    pub case: Case,
    #[serde(default)]
    pub execution: Execution,
}

/// The messages between the runner and a worker: a text line `rtconf-frame N` and then N bytes, the
/// message's serde form in CBOR (self-describing, every float kept bit for bit — build cases hold NaN
/// coordinates, which JSON has no word for — and a rendered launch's records one byte string, which
/// [`model::bulk`] makes of them, instead of a number per word). Text lines that are not a frame's
/// header are skipped: a test harness that is the worker prints its own.
pub mod frame {
    use std::io::{BufRead, Read, Write};

    const HEADER: &[u8] = b"rtconf-frame ";

    /// Writes `value` as one frame and flushes.
    pub fn write<T: serde::Serialize>(out: &mut impl Write, value: &T) -> std::io::Result<()> {
        let mut body = Vec::new();
        ciborium::into_writer(value, &mut body).map_err(std::io::Error::other)?;
        let mut header = HEADER.to_vec();
        header.extend_from_slice(format!("{}\n", body.len()).as_bytes());
        out.write_all(&header)?;
        out.write_all(&body)?;
        out.flush()
    }

    /// The next frame's bytes, or None where the stream ends between frames. A header without a
    /// length, or a stream that ends inside a frame, is an error; the body grows as its bytes arrive,
    /// so a length that lies allocates nothing beyond what was sent.
    pub fn read(input: &mut impl BufRead) -> std::io::Result<Option<Vec<u8>>> {
        let mut line = Vec::new();
        loop {
            line.clear();
            if input.read_until(b'\n', &mut line)? == 0 {
                return Ok(None);
            }
            let Some(at) = line.windows(HEADER.len()).position(|w| w == HEADER) else {
                continue;
            };
            let digits = std::str::from_utf8(&line[at + HEADER.len()..])
                .unwrap_or("")
                .trim_end();
            let len: u64 = digits.parse().map_err(|_| {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("a frame header without a length: {digits:?}"),
                )
            })?;
            let mut body = Vec::new();
            input.take(len).read_to_end(&mut body)?;
            if body.len() as u64 != len {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    format!(
                        "the stream ended {} bytes into a {len}-byte frame",
                        body.len()
                    ),
                ));
            }
            return Ok(Some(body));
        }
    }

    /// A frame's bytes read as `T`.
    pub fn decode<T: serde::de::DeserializeOwned>(body: &[u8]) -> Result<T, String> {
        ciborium::from_reader(body).map_err(|e| e.to_string())
    }
}

/// A worker's first frame: whether it could make its executor (the instance with the validation layer
/// on its driver) and, if so, the device that instance enumerates; else the error, as text. The pool
/// that started the worker reads it where a driver check would have made an instance of its own.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Ready {
    pub executor: Result<String, String>,
}

/// One case's result on a worker's stdout, as the pool reports it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Response {
    /// Position of the case in the batch given to the pool.
    pub index: usize,
    pub name: String,
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

/// The worker loop: first a [`Ready`] frame, then one [`Response`] per [`Request`] frame on stdin.
/// Returns the exit code.
pub fn worker_main() -> i32 {
    let driver = Driver::parse(&std::env::var(DRIVER_ENV).unwrap_or_else(|_| "lavapipe".into()));
    // Made before the first request arrives: the instance (and the layer's start-up) overlaps the
    // runner's reading of the registry and drawing of the first cases.
    let first = Executor::new(driver.clone());
    let ready = Ready {
        executor: match &first {
            Ok(e) => Ok(e.running_on().device),
            // Said as the driver check says it: naming the manifest and its library.
            Err(e) => Err(match crate::driver_check::check_manifest(&driver) {
                Ok((manifest, library)) => {
                    crate::driver_check::instance_failure(&manifest, &library, e.clone())
                        .to_string()
                }
                Err(bad) => bad.to_string(),
            }),
        },
    };
    let mut executor: Option<Result<Executor, crate::HarnessError>> = Some(first);
    let mut stdin = std::io::stdin().lock();
    let mut stdout = std::io::stdout().lock();
    if frame::write(&mut stdout, &ready).is_err() {
        return 4;
    }
    loop {
        let body = match frame::read(&mut stdin) {
            Ok(Some(body)) => body,
            Ok(None) => {
                // Every answer is out, and the runner waits for this process to end: it ends without
                // tearing down its devices and instance, which the process's exit releases (the
                // teardown, every device's objects destroyed under the layer, costs lavapipe about
                // 50 ms; the driver's shader cache is written as pipelines are made, not then). The
                // layer's records of the modules it passed are written first (`vk::validated`).
                if let Some(Ok(e)) = executor.as_mut() {
                    e.save_validated();
                }
                std::mem::forget(executor);
                return 0;
            }
            Err(_) => return 2,
        };
        let started = Instant::now();
        let _ = crate::timing::take();
        let (index, name, observation) = match frame::decode::<Request>(&body) {
            Err(e) => {
                /// The part of a request that still reads when the rest does not.
                #[derive(serde::Deserialize)]
                struct Index {
                    index: usize,
                }
                let index = frame::decode::<Index>(&body).map_or(usize::MAX, |i| i.index);
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
        if frame::write(&mut stdout, &response).is_err() {
            return 4;
        }
    }
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
    /// The worker's responses, read and decoded on a thread of their own.
    responses: Receiver<Response>,
    /// Its [`Ready`] frame, the first it writes.
    ready: Receiver<Ready>,
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
        let (tx, responses) = mpsc::channel();
        let (ready_tx, ready) = mpsc::channel();
        std::thread::spawn(move || {
            let mut stdout = BufReader::with_capacity(1 << 16, stdout);
            // A frame that does not read as a response or as the worker's readiness is neither (it is
            // skipped, as text is).
            while let Ok(Some(body)) = frame::read(&mut stdout) {
                if let Ok(r) = frame::decode::<Response>(&body) {
                    if tx.send(r).is_err() {
                        break;
                    }
                } else if let Ok(r) = frame::decode::<Ready>(&body) {
                    let _ = ready_tx.send(r);
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
            responses,
            ready,
            stderr,
        })
    }

    /// [`Worker::spawn`], its failure said as a case's crash says it.
    fn start(cmd: &WorkerCommand) -> Result<Worker, String> {
        Worker::spawn(cmd)
            .map_err(|e| format!("cannot start worker {}: {e}", cmd.program.display()))
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

    /// Closes the worker's stdin (it exits once it has read the end): the process, and when that
    /// was.
    fn close(self) -> (Child, Instant) {
        let Worker { child, stdin, .. } = self;
        drop(stdin);
        (child, Instant::now())
    }
}

/// Waits for a worker whose stdin closed at `closed` to exit, killing it once `grace` has passed
/// since; whether it had to be killed.
fn exit_or_kill(mut child: Child, closed: Instant, grace: Duration) -> bool {
    while closed.elapsed() < grace {
        match child.try_wait() {
            Ok(Some(_)) | Err(_) => return false,
            Ok(None) => std::thread::sleep(Duration::from_millis(1)),
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    true
}

/// Workers that have given every answer and whose stdin is closed, still exiting: a worker's exit
/// releases what its driver made (on lavapipe tens of milliseconds of the kernel freeing its
/// memory), which the caller need not wait for before its own last work (a run's summary and
/// report). Each is reaped when this is dropped, killed if it still runs `EXIT_GRACE` after its
/// stdin closed.
#[must_use = "dropping it waits for the workers to exit"]
#[derive(Default)]
pub struct ExitingWorkers {
    closing: Vec<(Child, Instant)>,
}

impl ExitingWorkers {
    /// Waits for every worker to exit (killing any past its grace); how many had to be killed.
    pub fn reap(mut self) -> usize {
        self.reap_all()
    }

    fn reap_all(&mut self) -> usize {
        self.closing
            .drain(..)
            .map(|(child, closed)| exit_or_kill(child, closed, EXIT_GRACE) as usize)
            .sum()
    }
}

impl Drop for ExitingWorkers {
    fn drop(&mut self) {
        self.reap_all();
    }
}

/// How long a worker whose stdin has closed may take to exit before it is killed.
const EXIT_GRACE: Duration = Duration::from_secs(10);

enum Outcome {
    Done(Response),
    /// The worker is gone or hung; the case's result says which.
    Lost(Response),
}

fn run_one(w: &mut Worker, req: &Request, timeout: Duration) -> Outcome {
    let started = Instant::now();
    let lost =
        |status: Status| Outcome::Lost(req.lost(status, started.elapsed().as_secs_f64() * 1000.0));
    if frame::write(&mut w.stdin, req).is_err() {
        return lost(Status::Crash {
            message: format!(
                "the worker exited before taking the case; stderr: {}",
                w.stderr_tail()
            ),
        });
    }
    loop {
        let left = timeout.saturating_sub(started.elapsed());
        match w.responses.recv_timeout(left) {
            Ok(r) if r.index == req.index => return Outcome::Done(r),
            // An earlier case's answer that came after its timeout.
            Ok(_) => continue,
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
    // Reaped at once: the caller's next step may start workers of its own.
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
    )
    .reap();
}

/// Worker processes started ahead of the stream they will run, so that each loads its driver and the
/// layer while the runner is still reading the registry and drawing the first cases. The first one's
/// [`Ready`] frame answers for the instance a driver check would make ([`StartedWorkers::ready`]).
/// Workers never handed to a stream are killed when this is dropped.
pub struct StartedWorkers {
    cmd: WorkerCommand,
    /// One per job; `Err` where the process could not be started (each job of such a slot says so).
    workers: Vec<Result<Worker, String>>,
}

impl StartedWorkers {
    /// Starts `jobs` (at least one) `cmd` processes.
    pub fn start(cmd: &WorkerCommand, jobs: usize) -> StartedWorkers {
        StartedWorkers {
            cmd: cmd.clone(),
            workers: (0..jobs.max(1)).map(|_| Worker::start(cmd)).collect(),
        }
    }

    /// Whether the first worker made its executor (an instance of its driver under the validation
    /// layer): the device it enumerates, or what went wrong — the worker's own words, or that it
    /// could not start, exited before it was ready, or was not ready within `timeout`.
    pub fn ready(&self, timeout: Duration) -> Result<String, String> {
        let w = match self.workers.first() {
            Some(Ok(w)) => w,
            Some(Err(e)) => return Err(e.clone()),
            None => return Err("no worker was started".into()),
        };
        match w.ready.recv_timeout(timeout) {
            Ok(r) => r.executor,
            Err(RecvTimeoutError::Timeout) => Err(format!(
                "the worker did not make its instance within {:.1} s",
                timeout.as_secs_f64()
            )),
            Err(RecvTimeoutError::Disconnected) => Err(format!(
                "the worker exited before it made its instance: {}",
                w.stderr_tail()
            )),
        }
    }
}

impl Drop for StartedWorkers {
    fn drop(&mut self) {
        for w in self.workers.drain(..).flatten() {
            w.stop();
        }
    }
}

/// Runs a stream of jobs on `jobs` worker processes started at once (each makes its instance while
/// the first jobs are still being drawn) and kept for the whole stream: `source` is drawn from by
/// whichever worker is free, so a producer that generates jobs while earlier ones run keeps every
/// worker busy. `prepare` is applied to each job by the thread that drew it, before it runs (work the
/// producer need not do alone, such as the gate); `request` says what a job runs (None: nothing —
/// the job passes straight to `on_result`, in its turn). `on_result` gets each job back with its response, in completion order,
/// on the calling thread. A worker that crashes or hangs is replaced and its job reported `crash` or
/// `timeout`. Returns once every job is answered, with the workers told to exit and still exiting
/// ([`ExitingWorkers`]: reaped when dropped).
pub fn run_stream<J: Send>(
    cmd: &WorkerCommand,
    jobs: usize,
    timeout: Duration,
    source: impl Iterator<Item = J> + Send,
    prepare: impl Fn(J) -> J + Sync,
    request: impl Fn(&J) -> Option<&Request> + Sync,
    on_result: impl FnMut(J, Option<Response>),
) -> ExitingWorkers {
    run_stream_on(
        StartedWorkers::start(cmd, jobs),
        timeout,
        source,
        prepare,
        request,
        |_| None,
        on_result,
    )
}

/// How many drawn jobs, per worker, a free worker looks through for one whose device or pipeline it
/// already has ([`Lookahead`]), up to [`LOOKAHEAD_MAX`] in all. On lavapipe with two workers, 64 made
/// fewer devices and views than 16 or 4 (the invalid selection of `run_end_to_end`: device phase 0.15–0.19 s
/// against 0.17–0.21 and 0.22–0.23 s, one worker alone 0.14 s).
const LOOKAHEAD_PER_WORKER: usize = 32;

/// The most drawn jobs held back at once (each a whole case).
const LOOKAHEAD_MAX: usize = 256;

/// The jobs drawn from a stream and not yet taken, and which worker took each device and pipeline
/// key ([`Affinity`]) first. A free worker takes, within the first `window` jobs, one of a
/// pipeline it has run, else one of a device it has and a pipeline no worker has, else one of a
/// device no worker has, else the oldest job (no worker waits while there is work). So each worker
/// makes its own share of the devices, their first views of a format and the pipelines, instead of
/// every worker making them all; the jobs run in another order, and their results come back in
/// completion order as before.
struct Lookahead<J> {
    /// How many drawn jobs a free worker looks through ([`LOOKAHEAD_PER_WORKER`] per worker, at most
    /// [`LOOKAHEAD_MAX`]).
    window: usize,
    queue: std::collections::VecDeque<(J, Option<Affinity>)>,
    devices: std::collections::HashMap<u64, usize>,
    pipelines: std::collections::HashMap<u64, usize>,
    exhausted: bool,
}

impl<J> Lookahead<J> {
    fn new(window: usize) -> Lookahead<J> {
        Lookahead {
            window,
            queue: Default::default(),
            devices: Default::default(),
            pipelines: Default::default(),
            exhausted: false,
        }
    }

    /// How well a job suits `worker`: 3 a job without a key or of a pipeline it ran, 2 of its
    /// device and a pipeline nobody ran, 1 of a device nobody has, 0 another worker's.
    fn suits(&self, worker: usize, key: &Option<Affinity>) -> u8 {
        let Some(k) = key else { return 3 };
        match (self.pipelines.get(&k.pipeline), self.devices.get(&k.device)) {
            (Some(&w), _) if w == worker => 3,
            (None, Some(&w)) if w == worker => 2,
            (None, None) => 1,
            _ => 0,
        }
    }

    /// The next job for `worker`, drawing from `source` as needed (see [`Lookahead`]); None once
    /// the source and the queue are empty.
    fn take(
        &mut self,
        worker: usize,
        source: &mut dyn Iterator<Item = J>,
        affinity: &dyn Fn(&J) -> Option<Affinity>,
    ) -> Option<J> {
        loop {
            let best = (0..self.queue.len())
                .map(|i| (self.suits(worker, &self.queue[i].1), i))
                .fold(None, |best: Option<(u8, usize)>, (score, i)| match best {
                    Some((b, _)) if b >= score => best,
                    _ => Some((score, i)),
                });
            let settled = match best {
                Some((3, _)) => true,
                // A worker that has nothing yet has nothing to look further for.
                Some((score, _)) => {
                    score >= 2
                        || self.exhausted
                        || self.queue.len() >= self.window
                        || (score == 1 && !self.devices.values().any(|&w| w == worker))
                }
                None => self.exhausted,
            };
            if settled {
                let (_, at) = best?;
                let (job, key) = self.queue.remove(at).expect("an index of the queue");
                if let Some(k) = key {
                    self.devices.entry(k.device).or_insert(worker);
                    self.pipelines.entry(k.pipeline).or_insert(worker);
                }
                return Some(job);
            }
            match source.next() {
                Some(job) => {
                    let key = affinity(&job);
                    self.queue.push_back((job, key));
                }
                None => self.exhausted = true,
            }
        }
    }
}

/// [`run_stream`] on workers already started, one job slot each; `affinity` keys the jobs whose
/// device or pipeline a worker keeps for later jobs (`Lookahead`: such jobs go to one worker
/// where that costs no worker a wait).
pub fn run_stream_on<J: Send>(
    mut started: StartedWorkers,
    timeout: Duration,
    source: impl Iterator<Item = J> + Send,
    prepare: impl Fn(J) -> J + Sync,
    request: impl Fn(&J) -> Option<&Request> + Sync,
    affinity: impl Fn(&J) -> Option<Affinity> + Sync,
    mut on_result: impl FnMut(J, Option<Response>),
) -> ExitingWorkers {
    let slots: Vec<Result<Worker, String>> = started.workers.drain(..).collect();
    let window = (LOOKAHEAD_PER_WORKER * slots.len()).min(LOOKAHEAD_MAX);
    let source = Mutex::new((source, Lookahead::new(window)));
    let (tx, rx) = mpsc::channel::<(J, Option<Response>)>();
    let cmd = &started.cmd;
    // A worker whose every job is done is told so at once, and reaped by the caller.
    let exiting = Mutex::new(ExitingWorkers::default());
    std::thread::scope(|s| {
        for (number, slot) in slots.into_iter().enumerate() {
            let tx = tx.clone();
            let (source, prepare, request, affinity) = (&source, &prepare, &request, &affinity);
            let exiting = &exiting;
            s.spawn(move || {
                let mut worker: Option<Worker> = slot.ok();
                loop {
                    let next = {
                        let mut guard = source.lock().unwrap_or_else(|e| e.into_inner());
                        let (source, lookahead) = &mut *guard;
                        lookahead.take(number, source, affinity)
                    };
                    let Some(job) = next else { break };
                    let job = prepare(job);
                    let Some(req) = request(&job) else {
                        let _ = tx.send((job, None));
                        continue;
                    };
                    if worker.is_none() {
                        match Worker::start(cmd) {
                            Ok(w) => worker = Some(w),
                            Err(message) => {
                                let status = Status::Crash { message };
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
                    let closed = w.close();
                    exiting
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .closing
                        .push(closed);
                }
            });
        }
        drop(tx);
        for (job, r) in rx {
            on_result(job, r);
        }
    });
    exiting.into_inner().unwrap_or_else(|e| e.into_inner())
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

    /// Jobs `(number, device, pipeline)`; a job numbered 0 has no key.
    fn keyed(jobs: &[(u32, u64, u64)]) -> Vec<(u32, Option<Affinity>)> {
        jobs.iter()
            .map(|&(n, device, pipeline)| (n, (n != 0).then_some(Affinity { device, pipeline })))
            .collect()
    }

    #[test]
    fn a_worker_takes_its_own_pipelines_and_devices_first_and_never_waits_for_them() {
        // Two devices; pipelines 10 and 11 on device 1, 20 on device 2.
        let jobs = keyed(&[
            (1, 1, 10),
            (2, 2, 20),
            (3, 1, 11),
            (4, 2, 20),
            (5, 1, 10),
            (6, 1, 11),
            (7, 2, 20),
            (0, 0, 0),
            (8, 1, 10),
            (9, 1, 10),
            (10, 1, 10),
        ]);
        let keys: BTreeMap<u32, Option<Affinity>> = jobs.iter().copied().collect();
        let mut source = jobs.into_iter().map(|(n, _)| n);
        let affinity = |n: &u32| keys[n];
        let mut ahead = Lookahead::new(16);
        let mut took: Vec<(usize, u32)> = Vec::new();
        // Workers 0 and 1 free in turn.
        for turn in 0.. {
            let w = turn % 2;
            match ahead.take(w, &mut source, &affinity) {
                Some(n) => took.push((w, n)),
                None => break,
            }
        }
        let mut all: Vec<u32> = took.iter().map(|&(_, n)| n).collect();
        all.sort();
        // Every job once: no worker was refused one while any was left.
        assert_eq!(all, (0..=10).collect::<Vec<u32>>(), "{took:?}");
        let worker_of = |n: u32| took.iter().find(|t| t.1 == n).unwrap().0;
        // Worker 0 took the first job (device 1, pipeline 10): the other jobs of that pipeline
        // and of device 1 follow it; worker 1 took device 2's first and keeps it.
        assert_eq!(worker_of(1), 0);
        assert_eq!(worker_of(2), 1);
        for n in [3, 5, 6, 8] {
            assert_eq!(worker_of(n), 0, "job {n}: {took:?}");
        }
        for n in [4, 7] {
            assert_eq!(worker_of(n), 1, "job {n}: {took:?}");
        }
        // The keyless job went to the first worker free for it; at the end, with nothing of its
        // own left, worker 1 took one of worker 0's rather than wait.
        assert_eq!(worker_of(0), 1);
        assert_eq!(worker_of(9), 1, "{took:?}");
        assert_eq!(worker_of(10), 0, "{took:?}");
    }

    #[test]
    fn a_response_reads_back_from_its_frame_with_text_around_it() {
        let r = response((0..1000u32).map(|i| i.wrapping_mul(0x0101_0101)).collect());
        let mut stream = b"running 1 test\n".to_vec();
        frame::write(&mut stream, &r).unwrap();
        stream.extend_from_slice(b"\ntest worker_entry ... ok\n");
        frame::write(&mut stream, &response(vec![])).unwrap();
        let mut input = stream.as_slice();
        let first = frame::read(&mut input).unwrap().expect("a frame");
        assert_eq!(frame::decode::<Response>(&first).unwrap(), r);
        let second = frame::read(&mut input).unwrap().expect("a frame");
        assert_eq!(
            frame::decode::<Response>(&second).unwrap(),
            response(vec![])
        );
        assert!(frame::read(&mut input).unwrap().is_none());
    }

    #[test]
    fn a_cut_frame_or_a_header_without_a_length_is_an_error() {
        let mut stream = Vec::new();
        frame::write(&mut stream, &response(vec![7, 8])).unwrap();
        let cut = &stream[..stream.len() - 3];
        let e = frame::read(&mut &cut[..]).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::UnexpectedEof);
        assert!(e.to_string().contains("bytes into a"), "{e}");
        // A length far beyond what was sent allocates only what arrives, then says so.
        let lie = b"rtconf-frame 18446744073709551615\nabc";
        let e = frame::read(&mut &lie[..]).unwrap_err();
        assert!(e.to_string().contains("ended 3 bytes into"), "{e}");
        let e = frame::read(&mut &b"rtconf-frame twelve\n"[..]).unwrap_err();
        assert!(e.to_string().contains("without a length"), "{e}");
    }

    fn shell(script: &str) -> WorkerCommand {
        WorkerCommand {
            program: "sh".into(),
            args: vec!["-c".into(), script.into()],
            env: Vec::new(),
        }
    }

    #[test]
    fn a_worker_that_exits_when_its_stdin_closes_is_not_killed() {
        let w = Worker::spawn(&shell("cat > /dev/null")).expect("sh starts");
        let started = Instant::now();
        let (child, closed) = w.close();
        assert!(!exit_or_kill(child, closed, Duration::from_secs(20)));
        assert!(started.elapsed() < Duration::from_secs(10));
    }

    #[test]
    fn a_worker_that_outlives_its_stdin_is_killed_after_the_grace() {
        // Ignores the end of its input and keeps running, as a driver's hung teardown would.
        let w =
            Worker::spawn(&shell("cat > /dev/null; while :; do sleep 1; done")).expect("sh starts");
        let started = Instant::now();
        let (child, closed) = w.close();
        assert!(exit_or_kill(child, closed, Duration::from_millis(300)));
        let took = started.elapsed();
        assert!(
            took >= Duration::from_millis(300) && took < Duration::from_secs(10),
            "{took:?}"
        );
    }

    #[test]
    fn a_stream_returns_while_its_workers_exit_and_they_are_reaped_after() {
        // A worker that takes half a second to exit once its input ends, as a driver's teardown
        // does; the stream has nothing for it.
        let cmd = shell("cat > /dev/null; sleep 0.5");
        let started = Instant::now();
        let exiting = run_stream(
            &cmd,
            1,
            Duration::from_secs(20),
            std::iter::empty::<()>(),
            |j| j,
            |_: &()| None,
            |_, _| {},
        );
        let returned = started.elapsed();
        assert!(returned < Duration::from_millis(400), "{returned:?}");
        assert_eq!(exiting.reap(), 0, "an exiting worker is not killed");
        let reaped = started.elapsed();
        assert!(reaped >= Duration::from_millis(500), "{reaped:?}");
    }

    #[test]
    fn a_started_worker_that_is_never_ready_is_said_to_be_so() {
        // One that exits without a word, and one that never answers.
        let gone = StartedWorkers::start(&shell("echo the loader is missing >&2; exit 3"), 1);
        let e = gone.ready(Duration::from_secs(20)).unwrap_err();
        assert!(e.contains("exited before it made its instance"), "{e}");
        let mute = StartedWorkers::start(&shell("sleep 30"), 2);
        let started = Instant::now();
        let e = mute.ready(Duration::from_millis(200)).unwrap_err();
        assert!(e.contains("did not make its instance within 0.2 s"), "{e}");
        drop(mute);
        // Dropped unused, the mute workers are killed, not waited for.
        assert!(started.elapsed() < Duration::from_secs(10));
    }

    #[test]
    fn a_ready_frame_reads_as_readiness_and_never_as_a_response() {
        let mut stream = Vec::new();
        let ready = Ready {
            executor: Ok("llvmpipe".into()),
        };
        frame::write(&mut stream, &ready).unwrap();
        let body = frame::read(&mut stream.as_slice()).unwrap().unwrap();
        assert!(frame::decode::<Response>(&body).is_err());
        assert_eq!(frame::decode::<Ready>(&body).unwrap(), ready);
    }

    #[test]
    fn a_frame_that_is_not_the_expected_message_is_an_error_naming_it() {
        let mut stream = Vec::new();
        frame::write(&mut stream, &"just a string").unwrap();
        let body = frame::read(&mut stream.as_slice()).unwrap().unwrap();
        assert!(frame::decode::<Response>(&body).is_err());
    }
}
