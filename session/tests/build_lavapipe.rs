//! Build cases on real lavapipe, run and judged as a run does: every generated indirect build is
//! recorded under the validation layer (never submitted) and the layer's VUIDs are compared with the
//! model's for the device's sizes; valid cases (valid apart from the missing
//! accelerationStructureIndirectBuild) are also built directly, and the check's rays (through every
//! built primitive plus random rays) traced at it must pass the reference tracer's judgement.

mod common;

use common::{deviation, layer_vuids, mismatches, model_vuids, status, traced, Lavapipe, DEVICE};
use harness::{Status, TraceCheck};
use model::accel::check::BuildCheck;
use model::accel::unavoidable;
use std::collections::{BTreeMap, BTreeSet};

#[test]
fn valid_builds_trace_as_the_model_says_and_the_layer_reports_the_missing_feature() {
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let mut lvp = Lavapipe::new();
    let unavoidable = unavoidable(&lvp.profile);
    let mut rays = 0;
    let mut known_deviation = 0;
    let mut kinds = BTreeSet::new();
    for seed in 0..4 {
        for case in generator::accel::generate(&lvp.profile, &lvp.rules, seed, 4)
            .into_iter()
            .filter(|c| c.name.ends_with("-valid"))
        {
            let ran = lvp.run(&case, TraceCheck::Auto);
            assert_eq!(status(&ran), &Status::Ran, "{}: {ran:?}", case.name);
            assert_eq!(
                model_vuids(&ran),
                unavoidable,
                "{}: the device's sizes keep the case valid",
                case.name
            );
            assert_eq!(
                layer_vuids(&ran),
                unavoidable,
                "{}: the layer reports exactly the missing feature",
                case.name
            );
            let t = traced(&ran);
            assert!(
                t.direct_layer_vuids.is_empty(),
                "{}: the direct build is valid: {:?}",
                case.name,
                t.direct_layer_vuids
            );
            // FIXME(lavapipe, Mesa 25.0.7): triangle geometry gets firstVertex added twice (the spec
            // adds it once), so such cases trace differently; asserted as exactly that deviation (the
            // device's hits are those of the build with firstVertex doubled) so a fixed driver or a new
            // departure shows up here. See cases/build/indexed-first-vertex-shifted-primitives.yaml.
            let wrong = mismatches(&ran);
            let deviates = !wrong.is_empty()
                && deviation(&case, &t.records)
                    .is_some_and(|d| d.contains("first-vertex-applied-twice"));
            if deviates {
                known_deviation += 1;
            } else {
                assert!(
                    wrong.is_empty(),
                    "{}: {wrong:#?}\n{}",
                    case.name,
                    case.to_yaml()
                );
            }
            rays += t.hits.len();
            let body = case.as_accel().unwrap();
            kinds.insert(format!(
                "{:?}",
                body.call.infos[0].geometries[0].data.geometry_type()
            ));
        }
    }
    assert!(rays > 100, "only {rays} rays traced");
    assert!(
        known_deviation <= 6,
        "{known_deviation} cases hit the known firstVertex deviation"
    );
    assert!(kinds.len() >= 2, "geometry kinds exercised: {kinds:?}");
}

#[test]
fn check_rays_must_hit_active_primitives_and_miss_inactive_ones() {
    let profile = session::sources::profile_for("lavapipe").unwrap();
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
    let check = BuildCheck::of(case.as_accel().unwrap()).unwrap();
    // Two rays through each active box, one where the inactive one would be, then random rays.
    let aimed: Vec<(bool, Vec<u32>)> = check.allowed[..5]
        .iter()
        .map(|a| {
            let must = a
                .committable
                .iter()
                .map(|&i| a.candidates[i].primitive.primitive)
                .collect();
            (a.miss.allowed, must)
        })
        .collect();
    assert_eq!(
        aimed,
        vec![
            (false, vec![0]),
            (false, vec![0]),
            (true, vec![]),
            (false, vec![2]),
            (false, vec![2]),
        ]
    );
    assert!(check.allowed[2].miss.required);
    assert!(check.rays.len() >= 5 + 8, "{} rays", check.rays.len());
}

/// Invalid cases: the layer's VUIDs against the model's, per target VUID (printed as the agreement table).
#[test]
fn invalid_builds_under_the_layer_agree_with_the_model_or_are_known_layer_gaps() {
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let mut lvp = Lavapipe::new();
    let unavoidable = unavoidable(&lvp.profile);
    let mut table: BTreeMap<String, (usize, usize, BTreeSet<String>)> = BTreeMap::new();
    for case in generator::accel::generate(&lvp.profile, &lvp.rules, 7, 3)
        .into_iter()
        .filter(|c| !c.name.ends_with("-valid"))
        // Validated past 03650 in this process, an update without a source crashes the 1.3.239 layer's
        // core checks (triage/layer-1.3.239.yaml, pInfos-04630); a run records it in a worker and again
        // with validation stopping at 03650 (session/tests/build_states.rs covers the states).
        .filter(|c| !c.name.ends_with("-pInfos-04630"))
    {
        let ran = lvp.run(&case, TraceCheck::Auto);
        let model::Intent::Violates { vuid, .. } = &case.intent else {
            continue;
        };
        let e = table.entry(vuid.clone()).or_default();
        if status(&ran) != &Status::Ran {
            // Command buffer states and memory the device rules out: recorded as such.
            e.2.insert(format!("{:?}", status(&ran)));
            continue;
        }
        e.0 += 1;
        let (model, layer) = (model_vuids(&ran), layer_vuids(&ran));
        if layer == model {
            e.1 += 1;
        } else {
            let extra: Vec<_> = layer.iter().filter(|v| !model.contains(v)).collect();
            let missing: Vec<_> = model.iter().filter(|v| !layer.contains(v)).collect();
            e.2.insert(format!("layer extra {extra:?} missing {missing:?}"));
        }
        // The layer reports the feature VUID on every recorded case: the declared co-violation.
        assert!(
            layer.iter().any(|v| unavoidable.contains(v))
                || case.as_accel().unwrap().call.infos.is_empty(),
            "{}: {ran:?}",
            case.name
        );
    }
    for (v, (ran, agree, notes)) in &table {
        println!("{v}\tran {ran}\tagree {agree}\t{notes:?}");
    }
    assert!(table.len() >= 20, "{} VUIDs exercised", table.len());
}

/// lavapipe weights a geometry transform's translation by the fourth component of a four-component
/// vertex (`cases/build/lavapipe-fourth-component-weights-translation.yaml`, where primitiveOffsets
/// off the vertices read that component from other bytes, and firstVertex is applied twice too):
/// the model names the deviation exactly and the run triages it. Without the geometry transforms both
/// readings of the fourth component agree, and only the firstVertex deviation is left to name. Beside
/// an inactive triangle (`cases/build/lavapipe-fourth-component-beside-inactive.yaml`) the same reading
/// with the dropped primitives explains the records.
#[test]
fn lavapipe_weights_the_translation_by_a_vertex_fourth_component() {
    use model::accel::check::FOURTH_COMPONENT_WEIGHTS_TRANSLATION as WEIGHTS;
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let path = "build/lavapipe-fourth-component-weights-translation.yaml";
    let case = common::committed(path);
    let mut lvp = Lavapipe::new();
    let ran = lvp.run(&case, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    assert!(!mismatches(&ran).is_empty());
    assert_eq!(
        deviation(&case, &traced(&ran).records),
        Some(format!("first-vertex-applied-twice+{WEIGHTS}"))
    );
    assert_triaged_by(&ran, WEIGHTS);

    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases")
        .join(path);
    let text = std::fs::read_to_string(file).unwrap();
    let transforms =
        regex::Regex::new(r"transform_data:\n          buffer: input\n          offset: \d+")
            .unwrap();
    assert_eq!(transforms.find_iter(&text).count(), 3);
    let untransformed = transforms.replace_all(&text, "transform_data: 0");
    let plain = model::Case::from_yaml(path, &untransformed).unwrap();
    let ran = lvp.run(&plain, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    assert_eq!(
        deviation(&plain, &traced(&ran).records).as_deref(),
        Some("first-vertex-applied-twice")
    );

    // Beside an inactive triangle (its X NaN), that reading places the inactive vertex with its NaN
    // kept to X, and the drops next to it explain the rest.
    let beside = common::committed("build/lavapipe-fourth-component-beside-inactive.yaml");
    let ran = lvp.run(&beside, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    assert_eq!(
        deviation(&beside, &traced(&ran).records),
        Some(format!(
            "first-vertex-applied-twice+{WEIGHTS}+{}",
            model::accel::check::INACTIVE_TRIANGLE_DROPS
        ))
    );
    assert_triaged_by(&ran, WEIGHTS);
}

/// The run triaged the case by an entry whose pattern names `name`.
fn assert_triaged_by(ran: &session::run::Ran, name: &str) {
    assert_eq!(
        ran.report.outcome,
        session::Outcome::Triaged,
        "{}",
        ran.report.detail
    );
    assert!(
        ran.report.triage.iter().any(|m| m.entry.contains(name)),
        "{:?}",
        ran.report.triage
    );
}
