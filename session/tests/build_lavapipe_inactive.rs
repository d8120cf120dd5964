//! The inactive-triangle deviation of lavapipe (Mesa 25.0.7), probed with rays away from the model's
//! centroids: geometry 0 of `cases/build/lavapipe-unexplained-rays.yaml` holds the triangles of
//! firstVertex applied twice, geometry 1 loses primitive 0 next to its inactive (NaN) triangle, and
//! `model::accel::check::deviation` names both cases after the CPU cast.

mod common;

use common::{committed, deviation, mismatches, status, traced, Lavapipe};
use harness::{Status, TraceCheck};
use model::accel::check::INACTIVE_TRIANGLE_DROPS;

#[test]
fn lavapipe_drops_a_primitive_beside_an_inactive_triangle() {
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
    let named = deviation(&unexplained, &traced(&ran).hits).unwrap();
    assert!(
        named
            .split('|')
            .any(|n| n == format!("first-vertex-applied-twice+{INACTIVE_TRIANGLE_DROPS}")),
        "{named}"
    );

    let clean = committed("build/lavapipe-inactive-triangle-drops-primitive.yaml");
    let ran = lvp.run(&clean, TraceCheck::Auto);
    assert_eq!(status(&ran), &Status::Ran);
    assert_eq!(mismatches(&ran).len(), 1, "{:?}", mismatches(&ran));
    let hits = traced(&ran).hits.clone();
    assert_eq!(
        deviation(&clean, &hits).as_deref(),
        Some(INACTIVE_TRIANGLE_DROPS)
    );
    // A device that hits a primitive the cast does not is no deviation, dropped primitives or not.
    let mut wrong = hits;
    let k = wrong.iter().position(|h| h.is_some()).unwrap();
    wrong[k] = Some((0, 7, 7));
    assert_eq!(deviation(&clean, &wrong), None);
}
