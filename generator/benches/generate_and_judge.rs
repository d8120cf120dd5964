//! Benchmark: cases generated and judged per second on one thread, valid and one-VUID-invalid mixed
//! (every spec the lavapipe profile supports), ending with the line `cases/s: N`.

use generator::{case_runner, case_strategy, executable_vuids, mutations_for, CaseSpec};
use model::CommandId;
use proptest::strategy::{Strategy, ValueTree};
use std::time::Instant;

fn main() {
    let name = std::env::args()
        .nth(1)
        .filter(|a| !a.starts_with('-'))
        .unwrap_or_else(|| "lavapipe".into());
    let profile = generator::profiles::load(&name).expect("profile loads");
    let rules = generator::registry::default_rules().expect("registry loads");
    let mut strategies = vec![];
    for command in CommandId::TRACE {
        let mut specs = vec![
            CaseSpec::valid(command),
            CaseSpec::valid(command).at_limits(),
        ];
        specs.extend(
            executable_vuids(&rules, command)
                .iter()
                .filter(|v| mutations_for(v).is_some())
                .map(|v| CaseSpec::violate(command, v)),
        );
        for spec in specs {
            if let Ok(s) = case_strategy(&profile, &name, &rules, &spec) {
                // Valid specs weigh as much as all invalid ones of a command together.
                let weight = if spec.intent == generator::SpecIntent::Valid {
                    20
                } else {
                    1
                };
                for _ in 0..weight {
                    strategies.push(s.clone());
                }
            }
        }
    }
    assert!(!strategies.is_empty(), "no spec is supported on {name}");
    let total: usize = std::env::var("RTCONF_BENCH_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50_000);
    let mut invalid_seen = 0usize;
    let start = Instant::now();
    for i in 0..total {
        let s = &strategies[i % strategies.len()];
        let mut runner = case_runner(1, i as u64);
        let case = s
            .new_tree(&mut runner)
            .expect("strategies do not reject")
            .current();
        let verdict = model::validate(&rules, &profile, &case);
        invalid_seen += !verdict.is_valid() as usize;
    }
    let secs = start.elapsed().as_secs_f64();
    println!("profile: {name}, specs: {}, cases: {total}, invalid verdicts: {invalid_seen}, seconds: {secs:.3}", strategies.len());
    println!("cases/s: {}", (total as f64 / secs) as u64);
}
