//! The inactive-triangle deviation of lavapipe (Mesa 25.0.7), probed with rays away from the model's
//! centroids: geometry 0 of `cases/build/lavapipe-unexplained-rays.yaml` holds the triangles of
//! firstVertex applied twice, geometry 1 loses primitive 0 next to its inactive (NaN) triangle, and
//! `model::accel::check::deviation` names both cases after judging the records against each deviation's
//! structure. Its AABB twin: an active box
//! before an inactive one (minimum X NaN) is lost, `cases/build/lavapipe-inactive-aabb-drops-box.yaml`.
//! And a geometry hidden whole beside an exact fit that is a coincidence
//! (`cases/build/lavapipe-first-vertex-twice-hidden-geometry.yaml`).

mod common;

use common::{committed, deviation, mismatches, status, traced, Lavapipe};
use harness::{Status, TraceCheck};
use model::accel::check::{INACTIVE_AABB_DROPS, INACTIVE_TRIANGLE_DROPS};
use model::tracer::record::RayRecord as R;
use session::Outcome;

#[test]
fn lavapipe_drops_a_primitive_beside_an_inactive_triangle() {
    let _one = common::DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let unexplained = committed("build/lavapipe-unexplained-rays.yaml");
    let mut lvp = Lavapipe::new();
    {
        // The centroids of geometry 0's primitives 0-2 with indices + 2 x firstVertex (vertices 5,6,4;
        // 8,9,7; 11,12,10), then geometry 1's primitive 0 where the model puts it.
        let origins = [
            [2.0, -1.0 / 6.0, -1.0],
            [5.0, -1.0 / 6.0, -1.0],
            [8.0, -1.0 / 6.0, -1.0],
            [0.0, 2.5 + 1.0 / 3.0, -1.0],
        ];
        let hits = lvp
            .executor
            .probe_rays(&unexplained, &origins, TraceCheck::Auto)
            .unwrap();
        // FIXME(lavapipe, Mesa 25.0.7): a fixed driver misses the first three and hits (0, 1, 0).
        assert_eq!(
            hits,
            vec![Some((0, 0, 0)), Some((0, 0, 1)), Some((0, 0, 2)), None]
        );
    }

    let ran = lvp.run(&unexplained, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    let named = deviation(&unexplained, &traced(&ran).records).unwrap();
    assert!(
        named
            .split('|')
            .any(|n| n == format!("first-vertex-applied-twice+{INACTIVE_TRIANGLE_DROPS}")),
        "{named}"
    );

    let clean = committed("build/lavapipe-inactive-triangle-drops-primitive.yaml");
    let ran = lvp.run(&clean, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    assert!(!mismatches(&ran).is_empty());
    let records = traced(&ran).records.clone();
    assert_eq!(
        deviation(&clean, &records).as_deref(),
        Some(INACTIVE_TRIANGLE_DROPS)
    );
    // A device that hits a primitive the model does not have is no deviation, dropped primitives or not.
    let mut wrong = records;
    let k = traced(&ran).hits.iter().position(|h| h.is_some()).unwrap();
    wrong[k * R::WORDS + R::GEOMETRY_INDEX] = 7;
    wrong[k * R::WORDS + R::PRIMITIVE_ID] = 7;
    assert_eq!(deviation(&clean, &wrong), None);
}

#[test]
fn lavapipe_loses_an_active_box_before_an_inactive_one() {
    let _one = common::DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let (mut lvp, case, ran) = ran_committed("build/lavapipe-inactive-aabb-drops-box.yaml");
    // FIXME(lavapipe, Mesa 25.0.7): a fixed driver hits box 0 with the rays through it and the case
    // passes.
    assert!(traced(&ran).hits.iter().all(|h| h.is_none()));
    assert!(!mismatches(&ran).is_empty());
    assert_triaged_as_aabb_drops(&case, &ran);
    // A device that hits the inactive box is no deviation.
    let mut wrong = traced(&ran).records.clone();
    wrong[R::OUTCOME] = R::HIT;
    wrong[R::GROUP] = 3;
    wrong[R::PRIMITIVE_ID] = 1;
    wrong[R::T] = 2.0f32.to_bits();
    assert_eq!(deviation(&case, &wrong), None);

    // The inactive box first: lavapipe builds it as the model does.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/build/lavapipe-inactive-aabb-drops-box.yaml");
    let text = std::fs::read_to_string(path).unwrap();
    let (first, second) = (
        "    - !floats\n      offset: 0\n",
        "    - !floats\n      offset: 32\n",
    );
    assert_eq!(text.matches(first).count(), 1);
    assert_eq!(text.matches(second).count(), 1);
    let swapped = text
        .replace(first, "@FIRST@")
        .replace(second, first)
        .replace("@FIRST@", second);
    let swapped = model::Case::from_yaml("swapped", &swapped).unwrap();
    let ran = lvp.run(&swapped, TraceCheck::Auto);
    assert_eq!(ran.report.outcome, Outcome::Pass, "{}", ran.report.detail);
    let hits = &traced(&ran).hits;
    assert!(hits.contains(&Some((0, 0, 1))) && !hits.contains(&Some((0, 0, 0))));
}

#[test]
fn which_boxes_lavapipe_loses_beside_an_inactive_one_depends_on_the_ray() {
    let _one = common::DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let (_, case, ran) = ran_committed("build/lavapipe-inactive-aabb-ray-dependent.yaml");
    let hits = &traced(&ran).hits;
    // FIXME(lavapipe, Mesa 25.0.7): a fixed driver runs box 3's intersection shader for check ray 6
    // (which enters the box and its sphere) as it does for ray 5, and the case passes.
    assert_eq!(hits[5], Some((0, 0, 3)));
    assert_eq!(hits[6], None);
    let failing = mismatches(&ran);
    assert!(
        failing.iter().any(|m| m.starts_with("ray 6 from")),
        "{failing:?}"
    );
    assert!(
        !failing.iter().any(|m| m.starts_with("ray 5 from")),
        "{failing:?}"
    );
    // No one set of dropped boxes explains ray 5's hit and ray 6's miss; ray by ray they are.
    assert_triaged_as_aabb_drops(&case, &ran);
    let records = traced(&ran).records.clone();
    // Ray by ray still fails a hit the model does not allow: ray 5's hit moved to a box it never
    // enters, or to the inactive box.
    for primitive in [0, 1] {
        let mut wrong = records.clone();
        wrong[5 * R::WORDS + R::PRIMITIVE_ID] = primitive;
        assert_eq!(
            deviation(&case, &wrong),
            None,
            "ray 5 hitting box {primitive}"
        );
    }
}

/// A committed build case run on lavapipe with its check traced (it must run), with the executor
/// for more runs.
fn ran_committed(path: &str) -> (Lavapipe, model::Case, session::run::Ran) {
    let case = committed(path);
    let mut lvp = Lavapipe::new();
    let ran = lvp.run(&case, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran, "{path}");
    (lvp, case, ran)
}

/// The model names the records' deviation inactive-aabb-drops-primitives, and the run triaged it.
fn assert_triaged_as_aabb_drops(case: &model::Case, ran: &session::run::Ran) {
    assert_eq!(
        deviation(case, &traced(ran).records).as_deref(),
        Some(INACTIVE_AABB_DROPS)
    );
    assert_eq!(
        ran.report.outcome,
        Outcome::Triaged,
        "{}",
        ran.report.detail
    );
}

/// An exact fit by another deviation can be a coincidence. In
/// `cases/build/lavapipe-first-vertex-twice-hidden-geometry.yaml` the inactive triangle of geometry 1
/// hides all of geometry 0 from lavapipe's rays, and ignoring geometry 0's firstVertex would move it
/// away from every check ray: both fit, both are named, and the inactive-triangle entry triages the case
/// by its alternative. With geometry 0's own NaN vertex made finite only the drops fit.
#[test]
fn a_geometry_hidden_by_an_inactive_triangle_is_named_beside_a_coincidental_exact_fit() {
    let _one = common::DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let path = "build/lavapipe-first-vertex-twice-hidden-geometry.yaml";
    let (mut lvp, case, ran) = ran_committed(path);
    assert_eq!(
        deviation(&case, &traced(&ran).records),
        Some(format!(
            "indexed-first-vertex-ignored|first-vertex-applied-twice+{INACTIVE_TRIANGLE_DROPS}"
        ))
    );
    assert_eq!(
        ran.report.outcome,
        Outcome::Triaged,
        "{}",
        ran.report.detail
    );
    let entries: Vec<&str> = ran.report.triage.iter().map(|m| m.entry.as_str()).collect();
    assert!(
        entries.iter().any(|e| e.contains(INACTIVE_TRIANGLE_DROPS)),
        "{entries:?}"
    );
    // Geometry 0 is hidden whole: straight rays through the centroid of its primitive 1 where the model
    // puts it (vertices 6, 7, 5) and where firstVertex applied twice puts it (8, 9, 7) both miss.
    let origins = [[3.0, -1.0 / 6.0, -5.0], [5.0, -1.0 / 6.0, -5.0]];
    let hits = lvp
        .executor
        .probe_rays(&case, &origins, TraceCheck::Auto)
        .unwrap();
    // FIXME(lavapipe, Mesa 25.0.7): a fixed driver hits geometry 0 at the second origin.
    assert_eq!(hits, vec![None, None]);

    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases")
        .join(path);
    let text = std::fs::read_to_string(&file).unwrap();
    let nan = "      offset: 32\n      values: [.nan, -0.5, 0.0]";
    assert!(text.contains(nan));
    let finite = text.replace(nan, "      offset: 32\n      values: [0.0, -0.5, 0.0]");
    let finite = model::Case::from_yaml(path, &finite).unwrap();
    let ran = lvp.run(&finite, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    assert_eq!(
        deviation(&finite, &traced(&ran).records),
        Some(format!(
            "first-vertex-applied-twice+{INACTIVE_TRIANGLE_DROPS}"
        ))
    );
}
