//! How a run's cases go to the workers and their results to the judge: a stream drawn by whichever
//! worker is free while the cases are still being generated and gated (so generation, the gate, the
//! workers and the judge overlap, and the workers stay up for the whole run), then the cases to record
//! again and the failing cases to retry.

use super::{Judging, Progress, Sink};
use crate::compare::{CaseReport, Outcome};
use crate::details::CaseDetails;
use crate::inject::CaseInjection;
use crate::report::{GATE_PHASE, JUDGE_PHASE};
use harness::{Execution, Request, Response};
use model::Case;
use std::time::Duration;

/// A case on its way to a worker: the case as judged, what an injection did with it, and the request
/// the worker runs (under `--inject`, a perturbed copy).
pub(super) struct Job {
    case: Case,
    note: Option<CaseInjection>,
    request: Request,
    /// How long the gate took over the case (for a valid case, mostly the reference tracer's
    /// expected outcomes of its launch): the report's `gate` phase.
    gate_millis: f64,
}

/// What the run's producer hands the dispatch, in the plan's order.
pub(super) enum Drawn {
    /// A case not gated yet (the thread that draws it gates it, [`Dispatch::drawn`]), with the index
    /// its job will carry.
    Ungated(Case, usize),
    /// A case for the workers.
    Run(Box<Job>),
    /// A case the gate kept from the driver, with its report: written in its turn, never run.
    Gated {
        case: Case,
        report: Box<CaseReport>,
        details: CaseDetails,
    },
}

/// How a run's cases go to the workers and their results to the judge.
pub(super) struct Dispatch<'a> {
    pub(super) jobs: usize,
    pub(super) timeout: Duration,
    /// Times a failing, crashing or timed-out case is run again (stopping once its outcome changes).
    pub(super) retries: usize,
    pub(super) judging: &'a Judging<'a>,
    pub(super) progress: &'a dyn Progress,
    /// The injection and its seed: each request carries the perturbed copy, the judge the case.
    pub(super) inject: Option<(crate::inject::Injection, u64)>,
}

/// A case held back from `results.jsonl` to be run again: its first report and details, and the
/// outcome of every attempt so far.
struct Retried {
    job: Job,
    report: CaseReport,
    details: CaseDetails,
    attempts: Vec<Outcome>,
    /// What the first attempt observed (its pictures go beside the case's file).
    observation: harness::Observation,
}

/// What the stream leaves for after it: cases to record again with validation stopping at the
/// unavoidable VUIDs, and failing cases held for their retries.
#[derive(Default)]
struct Later {
    revalidate: Vec<Job>,
    held: Vec<Retried>,
}

impl Dispatch<'_> {
    /// A case as the workers get it: kept from the driver by the gate (with its report), or a job
    /// whose `index` tells its response apart on its worker.
    pub(super) fn drawn(&self, case: Case, index: usize, judging: &Judging) -> Drawn {
        let gating = std::time::Instant::now();
        let gated = crate::gate::gate(&case, judging);
        let gate_millis = gating.elapsed().as_secs_f64() * 1000.0;
        match gated {
            Some(mut report) => {
                report.phases.insert(GATE_PHASE.into(), gate_millis);
                Drawn::Gated {
                    details: CaseDetails {
                        violations: judging.verdict(&case.body).violations,
                        layer_messages: vec![],
                    },
                    case,
                    report: Box::new(report),
                }
            }
            None => Drawn::Run(Box::new(self.job(case, index, gate_millis))),
        }
    }

    fn job(&self, case: Case, index: usize, gate_millis: f64) -> Job {
        let (run, note) = crate::inject::executed(self.inject.as_ref(), &case, self.judging);
        Job {
            request: Request {
                index,
                execution: Execution::for_case(&run, self.judging.profile),
                case: run,
            },
            case,
            note,
            gate_millis,
        }
    }

    /// Runs a stream of drawn cases on one set of workers kept for the whole stream — `started`
    /// where the run started them ahead, else `jobs` started here —, judging and writing each result
    /// as it arrives (a gated case is written in its turn); then the cases to record again and the
    /// retries. The stream's workers are returned still exiting, for the caller to reap after its
    /// own last work.
    pub(super) fn run_stream(
        &self,
        drawn: impl Iterator<Item = Drawn> + Send,
        sink: &mut Sink,
        started: Option<harness::StartedWorkers>,
    ) -> harness::ExitingWorkers {
        let mut later = Later::default();
        let started = match started {
            Some(s) => s,
            None => match harness::WorkerCommand::current_exe() {
                Ok(cmd) => harness::StartedWorkers::start(&cmd, self.jobs),
                Err(e) => {
                    let why = format!("cannot find the rtconf executable to start workers: {e}");
                    for d in drawn {
                        self.settle_without_workers(d, sink, &mut later, &why);
                    }
                    self.finish(later, sink);
                    return harness::ExitingWorkers::default();
                }
            },
        };
        let exiting = harness::run_stream_on(
            started,
            self.timeout,
            drawn,
            |d| match d {
                Drawn::Ungated(case, index) => self.drawn(case, index, self.judging),
                d => d,
            },
            |d: &Drawn| match d {
                Drawn::Run(job) => Some(&job.request),
                Drawn::Gated { .. } | Drawn::Ungated(..) => None,
            },
            |d: &Drawn| match d {
                Drawn::Ungated(case, _) => harness::Executor::affinity(case),
                Drawn::Run(job) => harness::Executor::affinity(&job.request.case),
                Drawn::Gated { .. } => None,
            },
            |d, resp| match (d, resp) {
                (
                    Drawn::Gated {
                        case,
                        report,
                        details,
                    },
                    _,
                ) => self.write(sink, &case, &report, &details, vec![], None),
                (Drawn::Run(job), Some(resp)) => self.take(*job, &resp, sink, &mut later),
                (Drawn::Run(job), None) => {
                    let lost = Response {
                        index: job.request.index,
                        name: job.case.name.clone(),
                        observation: harness::Observation::crash("the worker gave no result"),
                        millis: 0.0,
                        phases: Default::default(),
                    };
                    self.take(*job, &lost, sink, &mut later)
                }
                // `prepare` gates every case; one left ungated is gated here and not run.
                (d @ Drawn::Ungated(..), _) => {
                    self.settle_without_workers(d, sink, &mut later, "no worker ran the case")
                }
            },
        );
        self.finish(later, sink);
        exiting
    }

    /// A drawn case no worker ran: written if gated, else a crash with `why`.
    fn settle_without_workers(&self, d: Drawn, sink: &mut Sink, later: &mut Later, why: &str) {
        match d {
            Drawn::Gated {
                case,
                report,
                details,
            } => self.write(sink, &case, &report, &details, vec![], None),
            Drawn::Run(job) => {
                let lost = Response {
                    index: job.request.index,
                    name: job.case.name.clone(),
                    observation: harness::Observation::crash(why),
                    millis: 0.0,
                    phases: Default::default(),
                };
                self.take(*job, &lost, sink, later);
            }
            Drawn::Ungated(case, index) => {
                let gated = self.drawn(case, index, self.judging);
                self.settle_without_workers(gated, sink, later, why)
            }
        }
    }

    fn write(
        &self,
        sink: &mut Sink,
        case: &Case,
        report: &CaseReport,
        details: &CaseDetails,
        attempts: Vec<Outcome>,
        observation: Option<&harness::Observation>,
    ) {
        sink.write(case, report, details, attempts, observation);
        self.progress.advance(1);
    }

    /// One response: judged and written, or kept for later — recorded again when it killed its worker
    /// with validation continuing past the unavoidable VUIDs (a layer whose later checks crash on the
    /// call, as 1.3.239's core checks do for an update without a source), held for its retries when
    /// it failed.
    fn take(&self, job: Job, resp: &Response, sink: &mut Sink, later: &mut Later) {
        if matches!(resp.observation.status, harness::Status::Crash { .. })
            && !job.request.execution.continue_past.is_empty()
        {
            later.revalidate.push(job);
            return;
        }
        let (report, details) = self.judged(&job, resp);
        if self.retries > 0 && report.outcome.is_unexpected() {
            later.held.push(Retried {
                job,
                attempts: vec![report.outcome],
                report,
                details,
                observation: resp.observation.clone(),
            });
            return;
        }
        let seen = Some(&resp.observation);
        self.write(sink, &job.case, &report, &details, vec![], seen);
    }

    /// The cases to record again (validation stopping at the first unavoidable VUID; the report says
    /// so), then the retries of the held cases (each stops once its outcome changes), then the held
    /// cases written with every attempt's outcome.
    fn finish(&self, later: Later, sink: &mut Sink) {
        let Later {
            revalidate,
            mut held,
        } = later;
        if !revalidate.is_empty() {
            let requests: Vec<Request> = revalidate
                .iter()
                .enumerate()
                .map(|(index, job)| Request {
                    index,
                    case: job.request.case.clone(),
                    execution: Execution {
                        continue_past: vec![],
                        ..job.request.execution.clone()
                    },
                })
                .collect();
            harness::run_in_workers(&requests, self.jobs, self.timeout, |resp| {
                let job = &revalidate[resp.index.min(revalidate.len() - 1)];
                let (mut report, details) = self.judged(job, &resp);
                let note = format!(
                    "recorded with the layer's validation continuing past {} the worker died (the layer's \
                     later checks or the driver's recording of the call), so it was recorded again with \
                     validation stopping there",
                    self.judging.profile_unavoidable().join(", ")
                );
                report.detail = if report.detail.is_empty() {
                    note
                } else {
                    format!("{note}; {}", report.detail)
                };
                let seen = Some(&resp.observation);
                self.write(sink, &job.case, &report, &details, vec![], seen);
            });
        }
        for _ in 0..self.retries {
            // Run again the cases whose outcome has not changed yet.
            let again: Vec<Request> = held
                .iter()
                .enumerate()
                .filter(|(_, h)| h.attempts.iter().all(|o| *o == h.attempts[0]))
                .map(|(k, h)| Request {
                    index: k,
                    ..h.job.request.clone()
                })
                .collect();
            if again.is_empty() {
                break;
            }
            harness::run_in_workers(&again, self.jobs, self.timeout, |resp| {
                let Some(h) = held.get_mut(resp.index) else {
                    return;
                };
                let (report, _) = self.judged(&h.job, &resp);
                h.attempts.push(report.outcome);
            });
        }
        for h in held {
            self.write(
                sink,
                &h.job.case,
                &h.report,
                &h.details,
                h.attempts,
                Some(&h.observation),
            );
        }
    }

    /// The report of one response to `job` and what the run keeps of it (its case as judged, with
    /// what an injection did with it), with the runner's phases beside the worker's: the gate's and
    /// the judge's.
    fn judged(&self, job: &Job, resp: &Response) -> (CaseReport, CaseDetails) {
        let judging = std::time::Instant::now();
        let (mut report, verdict) = self.judging.judge_with_verdict(&job.case, resp);
        report.injection = job.note.clone();
        report.phases = resp.phases.clone();
        report.phases.insert(GATE_PHASE.into(), job.gate_millis);
        report
            .phases
            .insert(JUDGE_PHASE.into(), judging.elapsed().as_secs_f64() * 1000.0);
        let details = CaseDetails {
            violations: verdict.violations,
            layer_messages: resp.observation.layer_messages.clone(),
        };
        (report, details)
    }
}
