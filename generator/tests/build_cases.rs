//! Generated build cases judge as declared: valid plans give exactly the device's unavoidable VUIDs,
//! each mutation gives its VUID plus declared co-violations; cases round-trip through YAML.

use generator::accel::{generate, mutate, plan_strategy, realise, MUTATIONS};
use model::accel::unavoidable;
use model::{Case, RuleSet};

mod common;
use proptest::prelude::*;
use std::collections::BTreeSet;

fn rules() -> &'static RuleSet {
    common::rules()
}

fn verdict(_: &RuleSet, p: &model::DeviceProfile, c: &Case) -> Vec<String> {
    common::verdict_vuids(p, c)
}

fn lavapipe() -> model::DeviceProfile {
    generator::profiles::load("lavapipe").unwrap()
}

#[test]
fn generated_cases_judge_as_declared_and_cover_most_mutations() {
    let r = rules();
    let p = lavapipe();
    let mut covered = BTreeSet::new();
    for seed in 0..6 {
        for c in generate(&p, r, seed, 6) {
            assert_eq!(
                verdict(r, &p, &c),
                c.expected_vuids(),
                "case {}:\n{}",
                c.name,
                c.to_yaml()
            );
            if let model::Intent::Violates { vuid, .. } = &c.intent {
                covered.insert(vuid.clone());
            }
            let back = Case::from_yaml("mem", &c.to_yaml()).unwrap();
            assert_eq!(back.expected_vuids(), c.expected_vuids());
            assert_eq!(
                verdict(r, &p, &back),
                c.expected_vuids(),
                "round trip of {}",
                c.name
            );
        }
    }
    // lavapipe lacks accelerationStructureIndirectBuild: the valid cases violate exactly 03650.
    assert_eq!(unavoidable(&p).len(), 1);
    assert!(
        covered.len() >= 30,
        "only {} VUIDs covered: {covered:?}",
        covered.len()
    );
}

#[test]
fn every_mutation_fits_some_plan() {
    let p = lavapipe();
    let r = rules();
    let cases: Vec<Case> = (0..12).flat_map(|s| generate(&p, r, s, 8)).collect();
    let missing: Vec<&str> = MUTATIONS
        .iter()
        .copied()
        .filter(|t| {
            !cases
                .iter()
                .any(|c| c.expected_vuids().iter().any(|v| v.ends_with(t)) && c.name.ends_with(t))
        })
        .collect();
    // 03649 needs protectedMemory-free devices' protected command buffers; 03801 needs a count over
    // maxInstanceCount, which is fine; the rest must all appear.
    assert!(missing.len() <= 4, "mutations never applied: {missing:?}");
}

/// A device reporting a `maxInstanceCount` below the specification's 2^24-1 (a conformance finding)
/// still gets valid top-level builds that are valid on it: no more instance records than it reports.
#[test]
fn valid_builds_keep_to_a_small_instance_limit() {
    let r = rules();
    for max in [0u64, 1, 3] {
        let mut p = lavapipe();
        p.properties.insert(
            "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount".into(),
            model::profile::PropertyValue::Int(max),
        );
        let mut top_level = 0;
        for seed in 0..8 {
            for c in generate(&p, r, seed, 8)
                .iter()
                .filter(|c| c.name.ends_with("-valid"))
            {
                assert_eq!(
                    verdict(r, &p, c),
                    unavoidable(&p),
                    "{} with maxInstanceCount {max}",
                    c.name
                );
                top_level += usize::from(c.to_yaml().contains("instances"));
            }
        }
        assert!(top_level > 0, "no top-level build drawn");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn valid_plans_are_valid_apart_from_the_feature(plan in plan_strategy()) {
        let r = rules();
        let p = lavapipe();
        let c = realise(&plan, &p, "prop");
        prop_assert_eq!(verdict(r, &p, &c), unavoidable(&p));
        // and the build has a meaning
        prop_assert!(model::accel::indirect_build(&c.as_accel().unwrap().world, &c.as_accel().unwrap().call).is_ok());
    }

    #[test]
    fn a_mutation_never_adds_undeclared_violations(plan in plan_strategy(), k in 0usize..MUTATIONS.len()) {
        let r = rules();
        let p = lavapipe();
        let base = realise(&plan, &p, "prop");
        if let Some(m) = mutate(&base, MUTATIONS[k], &p, r) {
            prop_assert_eq!(verdict(r, &p, &m), m.expected_vuids());
        }
    }
}
