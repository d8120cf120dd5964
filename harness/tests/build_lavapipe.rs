//! Build cases on real lavapipe: every generated indirect build is recorded under the validation layer
//! (never submitted) and the layer's VUIDs are compared with the model's for the device's sizes; valid
//! cases (valid apart from the missing accelerationStructureIndirectBuild) run as the equivalent direct
//! build and one traced ray per built primitive must agree with the model's primitive list.

use harness::accel::{expected_rays, run_case};
use harness::vulkan::VkInstance;
use harness::Driver;
use model::accel::BuildRuleSet;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

/// One Vulkan instance at a time: the tests share lavapipe and the layer in one process.
static DEVICE: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn setup() -> (Arc<VkInstance>, model::DeviceProfile, BuildRuleSet) {
    let inst = Arc::new(
        VkInstance::new(Driver::Lavapipe, true)
            .expect("lavapipe and the layer are installed by scripts/setup.sh"),
    );
    let profile = generator::profiles::load("lavapipe").unwrap();
    let set = vk_registry::source::load_vuids(std::path::Path::new("/usr/share/vulkan/registry"))
        .unwrap();
    let rules = BuildRuleSet::from_vuids(&set);
    generator::accel::use_rules(rules.clone());
    (inst, profile, rules)
}

#[test]
fn valid_builds_trace_as_the_model_says_and_the_layer_reports_the_missing_feature() {
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let (inst, profile, rules) = setup();
    let unavoidable = generator::accel::unavoidable(&profile);
    let mut traced = 0;
    let mut known_deviation = 0;
    let mut kinds = BTreeSet::new();
    for seed in 0..4 {
        for case in generator::accel::generate(&profile, seed, 4)
            .into_iter()
            .filter(|c| c.name.ends_with("-valid"))
        {
            let obs = run_case(&inst, &profile, &rules, &case, &unavoidable);
            assert_eq!(obs.status, "ran", "{}: {obs:?}", case.name);
            assert_eq!(
                obs.model_vuids, unavoidable,
                "{}: the device's sizes keep the case valid",
                case.name
            );
            assert_eq!(
                obs.layer_vuids, unavoidable,
                "{}: the layer reports exactly the missing feature",
                case.name
            );
            assert!(
                obs.direct_layer_vuids.is_empty(),
                "{}: the direct build is valid: {:?}",
                case.name,
                obs.direct_layer_vuids
            );
            // FIXME(lavapipe, Mesa 25.0.7): triangle geometry gets firstVertex added twice (the spec
            // adds it once), so such cases trace differently; asserted as exactly that deviation (the
            // device's hits are those of the build with firstVertex doubled) so a fixed driver or a new
            // departure shows up here. See cases/build/indexed-first-vertex-shifted-primitives.yaml.
            let deviates = !obs.ray_mismatches.is_empty()
                && harness::accel::deviation(&case, &obs)
                    .is_some_and(|d| d.contains("first-vertex-applied-twice"));
            if deviates {
                known_deviation += 1;
            } else {
                assert!(
                    obs.ray_mismatches.is_empty(),
                    "{}: {:#?}\n{}",
                    case.name,
                    obs.ray_mismatches,
                    case.to_yaml()
                );
            }
            traced += obs.rays;
            kinds.insert(format!(
                "{:?}",
                case.call.infos[0].geometries[0].data.geometry_type()
            ));
        }
    }
    assert!(traced > 20, "only {traced} rays traced");
    assert!(
        known_deviation <= 6,
        "{known_deviation} cases hit the known firstVertex deviation"
    );
    assert!(kinds.len() >= 2, "geometry kinds exercised: {kinds:?}");
}

#[test]
fn expected_rays_hit_active_primitives_and_miss_inactive_ones() {
    let profile = generator::profiles::load("lavapipe").unwrap();
    let plan = generator::accel::BuildPlan {
        kind: generator::accel::Kind::Aabbs,
        geometries: vec![generator::accel::GeometryPlan {
            count: 3,
            slack: 0,
            offset_units: 1,
            first_vertex: 0,
            transform_units: 0,
            inactive: Some(1),
        }],
        stride_extra: 0,
        address_units: 0,
    };
    let case = generator::accel::realise(&plan, &profile, "aabbs");
    let prims = model::accel::indirect_build(&case.world, &case.call)
        .unwrap()
        .remove(0);
    let rays = expected_rays(&prims, false);
    assert_eq!(
        rays.iter().map(|r| r.hit).collect::<Vec<_>>(),
        vec![Some((0, 0, 0)), None, Some((0, 0, 2))]
    );
}

/// Invalid cases: the layer's VUIDs against the model's, per target VUID (printed as the agreement table).
#[test]
fn invalid_builds_under_the_layer_agree_with_the_model_or_are_known_layer_gaps() {
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let (inst, profile, rules) = setup();
    let unavoidable = generator::accel::unavoidable(&profile);
    let mut table: BTreeMap<String, (usize, usize, BTreeSet<String>)> = BTreeMap::new();
    for case in generator::accel::generate(&profile, 7, 3)
        .into_iter()
        .filter(|c| !c.name.ends_with("-valid"))
    {
        let obs = run_case(&inst, &profile, &rules, &case, &unavoidable);
        let model::Intent::Violates { vuid, .. } = &case.intent else {
            continue;
        };
        let e = table.entry(vuid.clone()).or_default();
        if obs.status != "ran" {
            // Command buffer states and unbound/scattered memory are not realised: recorded as such.
            e.2.insert(obs.status.clone());
            continue;
        }
        e.0 += 1;
        if obs.layer_vuids == obs.model_vuids {
            e.1 += 1;
        } else {
            let extra: Vec<_> = obs
                .layer_vuids
                .iter()
                .filter(|v| !obs.model_vuids.contains(v))
                .collect();
            let missing: Vec<_> = obs
                .model_vuids
                .iter()
                .filter(|v| !obs.layer_vuids.contains(v))
                .collect();
            e.2.insert(format!("layer extra {extra:?} missing {missing:?}"));
        }
        // The layer reports the feature VUID on every recorded case: the declared co-violation.
        assert!(
            obs.layer_vuids.iter().any(|v| unavoidable.contains(v)) || case.call.infos.is_empty(),
            "{}: {obs:?}",
            case.name
        );
    }
    for (v, (ran, agree, notes)) in &table {
        println!("{v}\tran {ran}\tagree {agree}\t{notes:?}");
    }
    assert!(table.len() >= 20, "{} VUIDs exercised", table.len());
}
