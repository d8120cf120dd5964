//! Meta-tests of the case format as the generator uses it: the YAML round trip of generated cases is
//! exact, a malformed case reports its line and problem, and shrinking writes a replayable minimal case.

mod common;

use generator::{case_strategy, generate, shrink_failure, CaseSpec};
use model::Case;
use model::CommandId;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

fn lavapipe() -> (String, model::DeviceProfile) {
    common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap()
}

#[test]
fn yaml_round_trip_of_generated_cases_is_exact() {
    let (name, profile) = lavapipe();
    let specs = [
        CaseSpec::valid(CommandId::TraceRaysIndirect),
        CaseSpec::valid(CommandId::TraceRays).at_limits(),
        CaseSpec::violate(
            CommandId::TraceRaysIndirect,
            "VUID-vkCmdTraceRaysIndirectKHR-pHitShaderBindingTable-04736",
        ),
        CaseSpec::violate(
            CommandId::TraceRays,
            "VUID-VkStridedDeviceAddressRegionKHR-size-04631",
        ),
    ];
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: 64,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &[3; 32]),
    );
    for spec in specs {
        let strategy = case_strategy(&profile, &name, common::rules(), &spec).unwrap();
        runner
            .run(&strategy, |case| {
                let yaml = case.to_yaml();
                let back = Case::from_yaml("generated.yaml", &yaml)
                    .map_err(|e| TestCaseError::fail(e.to_string()))?;
                prop_assert_eq!(&back, &case);
                prop_assert_eq!(back.to_yaml(), yaml);
                Ok(())
            })
            .unwrap();
    }
}

#[test]
fn malformed_case_yaml_reports_line_and_problem() {
    let (name, profile) = lavapipe();
    let case = &generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::valid(CommandId::TraceRaysIndirect),
        1,
        1,
    )
    .unwrap()[0];
    let yaml = case.to_yaml();
    // A misspelt field on a known line.
    let line = yaml
        .lines()
        .position(|l| l.trim_start().starts_with("max_recursion_depth"))
        .unwrap()
        + 1;
    let broken = yaml.replace("max_recursion_depth", "max_recursion_dept");
    let err = Case::from_yaml("broken.yaml", &broken).unwrap_err();
    assert_eq!(err.location.map(|(l, _)| l), Some(line), "{err}");
    assert!(err.problem.contains("max_recursion_dept"), "{err}");
    assert!(
        err.to_string().starts_with(&format!("broken.yaml:{line}:")),
        "{err}"
    );
    // An unknown usage flag names the flag.
    let broken = yaml.replacen("INDIRECT_BUFFER_BIT", "INDIRECT_BUFER_BIT", 1);
    let err = Case::from_yaml("flags.yaml", &broken).unwrap_err();
    assert!(
        err.location.is_some() && err.problem.contains("INDIRECT_BUFER_BIT"),
        "{err}"
    );
}

#[test]
fn shrinking_finds_a_minimal_failing_case_and_writes_it() {
    let (name, profile) = lavapipe();
    let dir = std::env::temp_dir().join(format!("rtconf-shrink-{}", std::process::id()));
    // "Fails" whenever the launch traces a ray: the minimum keeps exactly one ray and drops the rest.
    let fails = |c: &Case| !c.as_trace().unwrap().world.launch.rays.is_empty();
    let spec = CaseSpec::valid(CommandId::TraceRaysIndirect);
    let index = (0..50)
        .find(|&i| {
            let c = &generate(&profile, &name, common::rules(), &spec, i + 1, 21).unwrap()[i];
            c.as_trace().unwrap().world.launch.rays.len() >= 2
        })
        .expect("some case traces two rays");
    let shrunk = shrink_failure(
        &profile,
        &name,
        common::rules(),
        &spec,
        21,
        index,
        &dir,
        fails,
    )
    .unwrap()
    .expect("it fails");
    assert_eq!(
        shrunk.case.as_trace().unwrap().world.launch.rays.len(),
        1,
        "{}",
        shrunk.case.to_yaml()
    );
    assert!(
        shrunk
            .case
            .as_trace()
            .unwrap()
            .world
            .launch
            .scene
            .instances
            .is_empty(),
        "{}",
        shrunk.case.to_yaml()
    );
    let text = std::fs::read_to_string(&shrunk.path).unwrap();
    let back = Case::from_yaml(&shrunk.path.display().to_string(), &text).unwrap();
    assert_eq!(back, shrunk.case);
    assert_eq!(back.seed.as_deref(), Some(format!("21/{index}").as_str()));
    assert!(
        common::judge(&profile, &back).is_valid(),
        "shrinking keeps validity by construction"
    );
    std::fs::remove_dir_all(&dir).unwrap();
    // A case that does not fail is not written.
    assert!(
        shrink_failure(&profile, &name, common::rules(), &spec, 21, 0, &dir, |_| {
            false
        })
        .unwrap()
        .is_none()
    );
}
