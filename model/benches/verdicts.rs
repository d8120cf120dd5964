//! Verdicts per second for a typical valid `vkCmdTraceRaysIndirectKHR` call on one thread: the full
//! `validate` path (rows selected per call) beside a prepared `Judge` (rows selected once per device).

use model::{Case, DeviceProfile, RuleSet};
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

fn rate(iterations: u32, mut f: impl FnMut()) -> f64 {
    // Median of five timed batches.
    let mut rates: Vec<f64> = (0..5)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..iterations {
                f();
            }
            iterations as f64 / t.elapsed().as_secs_f64()
        })
        .collect();
    rates.sort_by(|a, b| a.total_cmp(b));
    rates[2]
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let set = vk_registry::source::load_vuids(Path::new(vk_registry::source::DEFAULT_REGISTRY_DIR))
        .expect("the installed registry (bash scripts/setup.sh)");
    let rules = RuleSet::from_vuids(&set);
    let profile_text = std::fs::read_to_string(root.join("profiles/lavapipe.json"))
        .expect("profiles/lavapipe.json");
    let profile =
        DeviceProfile::from_profiles_json("lavapipe", &profile_text).expect("a valid profile");
    let case_path = root.join("cases/hand/trace-indirect-basic.yaml");
    let case = Case::from_yaml(
        "basic",
        &std::fs::read_to_string(&case_path).expect("the basic case"),
    )
    .expect("parses");
    assert!(
        model::validate(&rules, &profile, &case).is_valid(),
        "the basic case is valid"
    );

    let full = rate(50_000, || {
        black_box(model::validate(
            black_box(&rules),
            &profile,
            black_box(&case),
        ));
    });
    let judge = rules.prepare(&profile, case.body.device(), case.command());
    let prepared = rate(200_000, || {
        black_box(judge.judge(black_box(&case.body)));
    });
    println!("rows judged per call: {}", judge.len());
    println!("validate (rows selected per call): {full:.0} verdicts/s");
    println!("prepared judge, ratio to validate: {:.2}", prepared / full);
    println!("verdicts/s: {prepared:.0}");
}
