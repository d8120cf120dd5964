//! Exercises the vkCmdTraceRaysNV paths until a profile with VK_NV_ray_tracing is committed: a profile
//! derived from a captured one, with its KHR ray tracing properties also filed under the NV struct
//! (no number is typed here). Valid cases must be valid and each NV mutation must hit its VUID.

mod common;

use generator::{executable_vuids, generate, mutations_for, CaseSpec, GenError};
use model::profile::PropertyValue;
use model::CommandId;
use std::collections::BTreeSet;

fn derived_nv_profile() -> (String, model::DeviceProfile) {
    let (_, mut p) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let khr = "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::";
    let copy = |p: &mut model::DeviceProfile, from: &str, to: &str| {
        let v: PropertyValue = p
            .properties
            .get(&format!("{khr}{from}"))
            .cloned()
            .expect("captured KHR property");
        p.properties
            .insert(format!("VkPhysicalDeviceRayTracingPropertiesNV::{to}"), v);
    };
    for (from, to) in [
        ("shaderGroupHandleSize", "shaderGroupHandleSize"),
        ("shaderGroupBaseAlignment", "shaderGroupBaseAlignment"),
        ("maxShaderGroupStride", "maxShaderGroupStride"),
        ("maxRayRecursionDepth", "maxRecursionDepth"),
    ] {
        copy(&mut p, from, to);
    }
    p.extensions.insert("VK_NV_ray_tracing".into());
    p.name = "lavapipe-as-nv".into();
    ("lavapipe-as-nv".into(), p)
}

#[test]
fn nv_valid_and_invalid_cases_on_a_derived_profile() {
    let (name, profile) = derived_nv_profile();
    let n = common::per_spec() / 2;
    for spec in [
        CaseSpec::valid(CommandId::TraceRaysNv),
        CaseSpec::valid(CommandId::TraceRaysNv).at_limits(),
    ] {
        for case in generate(&profile, &name, common::rules(), &spec, n, 5).unwrap() {
            let v = common::judge(&profile, &case);
            assert!(
                v.is_valid(),
                "{}: {:?}\n{}",
                case.name,
                v.violations,
                case.to_yaml()
            );
        }
    }
    let mut generated = 0;
    for vuid in executable_vuids(common::rules(), CommandId::TraceRaysNv) {
        assert!(mutations_for(&vuid).is_some(), "{vuid}");
        let cases = match generate(
            &profile,
            &name,
            common::rules(),
            &CaseSpec::violate(CommandId::TraceRaysNv, &vuid),
            n,
            5,
        ) {
            Ok(c) => c,
            Err(GenError::Unsupported(_)) => continue,
            Err(e) => panic!("{vuid}: {e}"),
        };
        generated += 1;
        let good = cases
            .iter()
            .filter(|c| {
                let got: BTreeSet<String> = common::judge(&profile, c)
                    .vuids()
                    .into_iter()
                    .map(String::from)
                    .collect();
                let expected: BTreeSet<String> = c.expected_vuids().into_iter().collect();
                got.contains(&vuid) && got.is_subset(&expected)
            })
            .count();
        assert!(
            good * 100 >= cases.len() * 95,
            "{vuid}: {good}/{}\n{}",
            cases.len(),
            cases[0].to_yaml()
        );
    }
    assert!(generated >= 25, "{generated}");
}
