//! Build cases with two infos (infoCount 2): the second info added to a valid case keeps it valid, and
//! each mutation between infos (the same or overlapping destinations, shared or overlapping scratch, an
//! update source that is another info's destination or under another info's scratch, a destination
//! another info's instances reference) violates exactly its VUID plus its declared co-violation.

use generator::accel::{add_second_info, generate, mutate, plan_strategy, realise};
use model::accel::unavoidable;
use model::{Case, RuleSet};

mod common;
use proptest::prelude::*;

fn rules() -> &'static RuleSet {
    common::rules()
}

fn verdict(_: &RuleSet, p: &model::DeviceProfile, c: &Case) -> Vec<String> {
    common::verdict_vuids(p, c)
}

const TWO_INFO: &[(&str, Option<&str>)] = &[
    (
        "dstAccelerationStructure-03698",
        Some("dstAccelerationStructure-03702"),
    ),
    ("dstAccelerationStructure-03702", None),
    ("dstAccelerationStructure-03703", None),
    ("scratchData-03704", None),
    ("scratchData-03705", None),
    ("pInfos-03403", Some("dstAccelerationStructure-03701")),
    ("None-03407", None),
];

#[test]
fn every_two_info_mutation_is_generated_and_judges_as_declared() {
    let r = rules();
    let p = generator::profiles::load("lavapipe").unwrap();
    let cases: Vec<Case> = (0..8).flat_map(|s| generate(&p, r, s, 8)).collect();
    for (tail, co) in TWO_INFO {
        let made: Vec<&Case> = cases.iter().filter(|c| c.name.ends_with(tail)).collect();
        assert!(!made.is_empty(), "{tail}: no plan fits");
        for c in made {
            assert_eq!(c.as_accel().unwrap().call.infos.len(), 2, "{}", c.name);
            let got = verdict(r, &p, c);
            assert_eq!(got, c.expected_vuids(), "{}:\n{}", c.name, c.to_yaml());
            let mut want: Vec<String> = unavoidable(&p);
            want.push(generator::accel::vuid(tail));
            if let Some(co) = co {
                want.push(generator::accel::vuid(co));
            }
            want.sort();
            assert_eq!(
                got, want,
                "{}: exactly the target and its co-violation",
                c.name
            );
            let back = Case::from_yaml("mem", &c.to_yaml()).unwrap();
            assert_eq!(verdict(r, &p, &back), got, "round trip of {}", c.name);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn a_second_info_keeps_a_valid_case_valid(plan in plan_strategy()) {
        let r = rules();
        let p = generator::profiles::load("lavapipe").unwrap();
        let mut c = realise(&plan, &p, "prop");
        add_second_info(c.as_accel_mut().unwrap());
        prop_assert_eq!(verdict(r, &p, &c), unavoidable(&p));
        prop_assert!(model::accel::indirect_build(&c.as_accel().unwrap().world, &c.as_accel().unwrap().call).is_ok());
    }

    #[test]
    fn two_info_mutations_never_add_undeclared_violations(plan in plan_strategy(), k in 0usize..TWO_INFO.len()) {
        let r = rules();
        let p = generator::profiles::load("lavapipe").unwrap();
        let base = realise(&plan, &p, "prop");
        if let Some(m) = mutate(&base, TWO_INFO[k].0, &p, r) {
            prop_assert_eq!(m.as_accel().unwrap().call.infos.len(), 2);
            prop_assert_eq!(verdict(r, &p, &m), m.expected_vuids());
        }
    }
}
