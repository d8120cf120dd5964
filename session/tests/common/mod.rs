//! What the session's lavapipe tests share: the installed registry's rules, the lavapipe profile, the
//! triage files a run uses, and one executor, so each test runs and judges cases exactly as a run does.

#![allow(dead_code)] // each test binary uses its own part

use harness::observe::{Status, TracedBuild};
use harness::{Driver, Executor, TraceCheck};
use model::{Case, DeviceProfile, RuleSet};
use session::run::{Judging, Ran};
use session::Triage;

/// One Vulkan instance at a time: tests of one binary share lavapipe and the layer in one process.
pub static DEVICE: std::sync::Mutex<()> = std::sync::Mutex::new(());

pub struct Lavapipe {
    pub rules: RuleSet,
    pub profile: DeviceProfile,
    pub triage: Triage,
    pub executor: Executor,
}

impl Lavapipe {
    pub fn new() -> Lavapipe {
        let layer = harness::validation_layer().expect("the validation layer (scripts/setup.sh)");
        let set = session::sources::registry_for_layer(&[], Some(&layer))
            .expect("the registry of the layer's version");
        let driver = Driver::Lavapipe;
        Lavapipe {
            rules: RuleSet::from_vuids(&set),
            profile: session::sources::profile_for("lavapipe").expect("profiles/lavapipe.json"),
            triage: session::sources::triage_for(&[], Some(&layer.version), &driver)
                .expect("the triage files"),
            executor: Executor::new(driver)
                .expect("lavapipe and the layer are installed by scripts/setup.sh"),
        }
    }

    /// Runs and judges one case in this process, as a run does (the gate first).
    pub fn run(&mut self, case: &Case, check: TraceCheck) -> Ran {
        let judging = Judging::new(&self.rules, &self.profile, &self.triage);
        judging.run_here(&mut self.executor, case, check)
    }
}

/// A committed case by path under `cases/`.
pub fn committed(path: &str) -> Case {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases")
        .join(path);
    session::replay::read_case(&p).expect("a committed case")
}

/// The status of a case that ran.
pub fn status(ran: &Ran) -> &Status {
    &ran.observation
        .as_ref()
        .expect("the case was runnable")
        .status
}

/// The model's VUIDs for the case as it ran, sorted.
pub fn model_vuids(ran: &Ran) -> Vec<String> {
    ran.verdict.vuids().into_iter().map(String::from).collect()
}

/// The layer's VUIDs for the case's call.
pub fn layer_vuids(ran: &Ran) -> Vec<String> {
    ran.observation
        .as_ref()
        .map(|o| o.layer_vuids.clone())
        .unwrap_or_default()
}

/// The traced check of a build run as valid.
pub fn traced(ran: &Ran) -> &TracedBuild {
    ran.observation
        .as_ref()
        .and_then(|o| o.traced())
        .unwrap_or_else(|| panic!("{}: no traced check: {:?}", ran.case.name, ran.observation))
}

/// The check rays whose record the reference tracer fails.
pub fn mismatches(ran: &Ran) -> Vec<String> {
    let body = ran.case.as_accel().expect("a build case");
    session::compare::ray_mismatches(body, &traced(ran).records)
}

/// The deviation the model names for a build case's records.
pub fn deviation(case: &Case, records: &[u32]) -> Option<String> {
    model::accel::check::deviation(case.as_accel().expect("a build case"), records)
}

/// The reason of a case the device cannot run (its profile confirms what it lacks).
pub fn unsupported(ran: &Ran) -> String {
    match status(ran) {
        Status::Unsupported { reason, .. } => reason.clone(),
        other => panic!("{}: not unsupported: {other:?}", ran.case.name),
    }
}

/// The reason of a case the harness does not realise.
pub fn not_realised(ran: &Ran) -> String {
    match status(ran) {
        Status::NotRealised { reason } => reason.clone(),
        other => panic!("{}: not `not realised`: {other:?}", ran.case.name),
    }
}

impl Lavapipe {
    /// What the device does with a case, unjudged: the gate, then the execution a run gives it.
    pub fn observe(&mut self, case: &Case) -> harness::Observation {
        case.runnable(&self.profile)
            .unwrap_or_else(|e| panic!("{}: {e}", case.name));
        let exec = harness::Execution::for_case(case, &self.profile);
        self.executor.execute(case, &exec)
    }
}

/// The trace body of a case.
pub fn body(case: &Case) -> &model::TraceBody {
    case.as_trace().expect("a trace case")
}

/// The world of a trace case, to edit.
pub fn world(case: &mut Case) -> &mut model::World {
    &mut case.as_trace_mut().expect("a trace case").world
}

/// Records as a device that builds the model's structure writes them: each ray's required hit at the
/// exact t and barycentrics, or a miss.
pub fn model_records(check: &model::accel::check::BuildCheck) -> Vec<u32> {
    use model::tracer::record::RayRecord;
    check
        .allowed
        .iter()
        .flat_map(|a| {
            let hit = a
                .committable
                .iter()
                .map(|&i| &a.candidates[i])
                .filter(|c| c.presence == model::tracer::Presence::Required)
                .min_by(|x, y| x.t_hull().lo.total_cmp(&y.t_hull().lo));
            let r = match hit {
                Some(c) => RayRecord::hit_on(c, &c.reports[0]),
                _ => RayRecord::miss(a.miss_shader.group),
            };
            let mut w = r.to_words();
            w[RayRecord::INTERSECTION_COUNT] = a.intersection.min;
            w
        })
        .collect()
}
