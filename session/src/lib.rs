//! rtconf's run session: where the model and the device meet. A run plans its specs, generates cases
//! a chunk at a time, gates them (the case's own errors, [`model::Case::runnable`], the profile's
//! limits), dispatches them to worker processes ([`harness::run_in_workers`]), judges each result
//! once ([`run::Judging`]), compares it with the observation ([`compare`](mod@compare)) against the
//! triage files, and streams `results.jsonl`; then the summary, the JUnit report and shrunk
//! regressions. A replay does the same for one case, through one worker process.
//!
//! The command line, the tests and the benches call this crate instead of copying its pieces.

pub mod baseline;
pub mod compare;
pub mod details;
pub mod detect;
pub mod error;
pub mod export;
pub(crate) mod gate;
pub mod html;
pub mod inject;
pub mod merge;
pub mod names;
pub mod outdir;
pub mod pictures;
pub mod plan;
pub mod rendered;
pub mod replay;
pub mod report;
pub mod results;
pub mod run;
pub mod select;
pub(crate) mod shrink;
pub mod sources;
pub mod stress;
pub mod triage;

pub use baseline::{Expectations, Status};
pub use compare::{compare, CaseReport, Outcome};
pub use error::SessionError;
pub use plan::Scope;
pub use replay::{replay, ReplayConfig, Replayed};
pub use run::{list, list_each, run, Progress, RunConfig, RunOutcome};
pub use select::{Selection, Shard};
pub use triage::Triage;
