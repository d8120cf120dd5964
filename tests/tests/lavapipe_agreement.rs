//! vkCmdTraceRaysIndirectKHR on the real lavapipe under the real validation layer: for every executable
//! VUID with a mutation, generated invalid cases are recorded (never submitted) and the layer's verdict
//! must agree with the model's or match the triage file; valid cases are submitted and their read-back
//! output must equal the model's expected launch.

use generator::CaseSpec;
use harness::{Driver, Executor, TraceCheck};
use model::CommandId;
use rtconf_tests::{installed_rules, profile};
use session::{CaseReport, Outcome, Triage};
use std::collections::BTreeMap;

const COMMAND: CommandId = CommandId::TraceRaysIndirect;

/// lavapipe under the validation layer, with the installed registry's rules and the triage files.
struct Lavapipe {
    rules: model::RuleSet,
    profile: model::DeviceProfile,
    triage: Triage,
    executor: Executor,
}

impl Lavapipe {
    fn new() -> Lavapipe {
        std::env::set_var("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json");
        let rules = installed_rules();
        let layer =
            harness::validation_layer().expect("the validation layer: `bash scripts/setup.sh`");
        let triage = session::sources::triage_for(&[], Some(&layer.version), &Driver::Lavapipe)
            .expect("triage files parse");
        let executor = Executor::new(Driver::Lavapipe)
            .expect("lavapipe and the validation layer: run `bash scripts/setup.sh`");
        Lavapipe {
            rules,
            profile: profile("lavapipe"),
            triage,
            executor,
        }
    }

    fn generate(
        &self,
        spec: &CaseSpec,
        count: usize,
        seed: u64,
    ) -> Result<Vec<model::Case>, generator::GenError> {
        generator::generate(&self.profile, "lavapipe", &self.rules, spec, count, seed)
    }

    /// Each case run and judged as a run does (the gate, the execution, one verdict, the comparison).
    fn run(&mut self, cases: &[model::Case]) -> Vec<CaseReport> {
        let judging = session::run::Judging {
            rules: &self.rules,
            profile: &self.profile,
            triage: &self.triage,
        };
        cases
            .iter()
            .map(|c| {
                judging
                    .run_here(&mut self.executor, c, TraceCheck::Auto)
                    .report
            })
            .collect()
    }
}

#[test]
fn the_layer_agrees_with_the_model_on_every_executable_vuid_or_the_triage_says_why() {
    let mut lvp = Lavapipe::new();
    let rows: Vec<String> = lvp
        .rules
        .rows
        .iter()
        .filter(|r| {
            r.status == model::rules::Status::Executable
                && model::rules::applies_to(&r.scope, COMMAND)
        })
        .map(|r| r.vuid.clone())
        .collect();
    let mut outcomes: BTreeMap<String, Vec<Outcome>> = BTreeMap::new();
    let mut failures = Vec::new();
    for vuid in &rows {
        let spec = CaseSpec::violate(COMMAND, vuid);
        let cases = match lvp.generate(&spec, 3, 11) {
            Ok(c) => c,
            Err(generator::GenError::Unsupported(why)) => {
                outcomes
                    .entry(vuid.clone())
                    .or_default()
                    .push(Outcome::Unsupported);
                eprintln!("{vuid}: not expressible on lavapipe: {why}");
                continue;
            }
            Err(e) => panic!("{vuid}: {e}"),
        };
        for r in lvp.run(&cases) {
            if matches!(r.outcome, Outcome::Fail | Outcome::Crash | Outcome::Timeout) {
                failures.push(format!("{}: {:?} {}", r.case, r.outcome, r.detail));
            }
            outcomes.entry(vuid.clone()).or_default().push(r.outcome);
        }
    }
    assert!(
        failures.is_empty(),
        "disagreements not in the triage file:\n{}",
        failures.join("\n")
    );
    let agreed = outcomes
        .values()
        .filter(|o| o.contains(&Outcome::Pass))
        .count();
    let exercised = outcomes
        .values()
        .filter(|o| o.iter().any(|x| *x != Outcome::Unsupported))
        .count();
    // Most rules the layer checks agree outright; the rest are written down in triage/.
    assert!(
        exercised >= 35,
        "only {exercised} VUIDs exercised: {outcomes:?}"
    );
    assert!(
        agreed >= 15,
        "only {agreed} VUIDs agreed outright: {outcomes:?}"
    );
}

#[test]
fn valid_launches_write_what_the_model_expects_and_the_layer_stays_silent() {
    let mut lvp = Lavapipe::new();
    let cases = lvp
        .generate(&CaseSpec::valid(COMMAND), 40, 3)
        .expect("valid cases");
    let reports = lvp.run(&cases);
    let bad: Vec<String> = reports
        .iter()
        .filter(|r| !matches!(r.outcome, Outcome::Pass | Outcome::Triaged))
        .map(|r| format!("{}: {:?} {}", r.case, r.outcome, r.detail))
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    let read_back = reports
        .iter()
        .filter(|r| r.output_matches == Some(true))
        .count();
    assert!(
        read_back >= 30,
        "only {read_back} of 40 valid cases compared their output"
    );
}
