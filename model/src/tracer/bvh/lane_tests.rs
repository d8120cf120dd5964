//! The lane test against the f64 bound test it stands for, on rays planted at the padded faces,
//! edges and corners of random boxes: an f32 lane miss where the f64 test meets the box would drop
//! a node the far test keeps. Without its margin (the planted fault) the lane test does drop some.
//! Also the portable lane test against the SSE one, so that targets without SSE are covered here.

use super::{LaneBounds, LaneRay, LANE_MARGIN};
use crate::scene::Ray;
use crate::tracer::prepare::{BoundBox, RayF64};
use crate::tracer::test_support::Lcg;

/// Counts, over rays aimed at the boundary of padded boxes, the cases where the lane test with
/// `margin` misses a box the f64 test meets (unsound), and where it meets a box the f64 test
/// misses (allowed: conservative).
fn disagreements(margin: f64, cases: usize) -> (usize, usize, usize) {
    let mut rng = Lcg(0x5eed);
    let (mut unsound, mut conservative, mut decided) = (0, 0, 0);
    for _ in 0..cases {
        let scale = [1e-3, 1.0, 1e3][(rng.unit() * 3.0) as usize];
        let c = [0; 3].map(|_| rng.range(-10.0, 10.0) * scale);
        let h = [0; 3].map(|_| rng.range(0.0, 2.0) * scale);
        let b = BoundBox {
            lo: [0, 1, 2].map(|k| (c[k] - h[k]) as f32),
            hi: [0, 1, 2].map(|k| (c[k] + h[k]) as f32),
            pad_base: (rng.range(0.0, 1e-3) * scale) as f32,
            pad_slope: rng.range(0.0, 1e-5) as f32,
        };
        let origin = [0; 3].map(|_| (rng.range(-40.0, 40.0) * scale) as f32);
        let o_norm = origin
            .iter()
            .map(|&x| (x as f64) * (x as f64))
            .sum::<f64>()
            .sqrt();
        let pad = b.pad_base as f64 + b.pad_slope as f64 * o_norm;
        // A point on the padded box's boundary: a face, an edge or a corner.
        let mut target = [0; 3].map(|k| rng.range(b.lo[k] as f64 - pad, b.hi[k] as f64 + pad));
        let pinned = 1 + (rng.unit() * 3.0) as usize;
        for (k, t) in target.iter_mut().enumerate().take(pinned) {
            *t = if rng.unit() < 0.5 {
                b.lo[k] as f64 - pad
            } else {
                b.hi[k] as f64 + pad
            };
        }
        let direction = [0, 1, 2].map(|k| (target[k] - origin[k] as f64) as f32);
        if direction.contains(&0.0) {
            continue;
        }
        let tmax = if rng.unit() < 0.3 { 1.0 } else { f32::INFINITY };
        let ray = Ray::new(origin, direction, 0.0, tmax);
        let rf = RayF64::of(&ray);
        let lane_ray = LaneRay::of(&rf);
        let (lanes, fast) = LaneBounds::with_margin(&[b], margin);
        if !(lane_ray.fast && fast) {
            continue;
        }
        decided += 1;
        let f64_meets = b.entry(&rf, rf.tmax).is_some();
        let (_, hit) = lanes.entries(&lane_ray, lane_ray.tmax, 0);
        let lane_meets = hit & 1 == 1;
        if f64_meets && !lane_meets {
            unsound += 1;
        }
        if lane_meets && !f64_meets {
            conservative += 1;
        }
    }
    (unsound, conservative, decided)
}

#[test]
fn the_lane_test_never_misses_a_box_the_f64_test_meets() {
    let (unsound, conservative, decided) = disagreements(LANE_MARGIN, 200_000);
    assert!(
        decided > 150_000,
        "the lane test decided only {decided} cases"
    );
    assert_eq!(unsound, 0, "lane misses of boxes the f64 test meets");
    // The margin is small: the lane test is not "meet everything", even on rays this close.
    assert!(
        conservative < decided / 2,
        "{conservative} of {decided} grazing rays met only by the lane test"
    );
}

#[test]
fn without_its_margin_the_lane_test_misses_grazed_boxes() {
    let (unsound, _, _) = disagreements(0.0, 200_000);
    assert!(unsound > 0, "the planted fault went unnoticed");
}

#[test]
fn the_lane_test_misses_boxes_far_from_the_ray() {
    let b = BoundBox {
        lo: [1.0, 1.0, 1.0],
        hi: [2.0, 2.0, 2.0],
        pad_base: 1e-3,
        pad_slope: 1e-6,
    };
    let (lanes, fast) = LaneBounds::new(&[b, b, b, b]);
    assert!(fast);
    let cases = [
        // Beside the box, behind it, and short of it.
        (
            Ray::new([0.0, 5.0, 0.0], [1.0, 0.01, 1.0], 0.0, f32::INFINITY),
            false,
        ),
        (
            Ray::new([3.0, 3.0, 3.0], [1.0, 1.0, 1.0], 0.0, f32::INFINITY),
            false,
        ),
        (Ray::new([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 0.0, 0.5), false),
        (
            Ray::new([0.0, 0.0, 0.0], [1.0, 1.1, 0.9], 0.0, f32::INFINITY),
            true,
        ),
    ];
    for (ray, meets) in cases {
        let rf = RayF64::of(&ray);
        let lane_ray = LaneRay::of(&rf);
        assert!(lane_ray.fast);
        let (near, hit) = lanes.entries(&lane_ray, lane_ray.tmax, 0);
        assert_eq!(hit == 0b1111, meets, "{ray:?}");
        assert_eq!(b.entry(&rf, rf.tmax).is_some(), meets, "{ray:?}");
        if meets {
            // It enters through the face z = 1 − pad (at t ≈ 1/0.9), no later than the f64 test
            // says by more than the margin.
            let e = b.entry(&rf, rf.tmax).expect("met");
            assert!(
                (near[0] as f64 - 1.0 / 0.9).abs() < 0.01,
                "entry t {}",
                near[0]
            );
            assert!(
                (near[0] as f64 - e).abs() < 1e-5,
                "entry t {} against {e}",
                near[0]
            );
        }
    }
}

#[test]
fn the_portable_lane_test_computes_what_the_vector_one_does() {
    let mut rng = Lcg(0x1a4e);
    let mut met = [0usize; 2];
    for _ in 0..50_000 {
        let scale = [1e-3, 1.0, 1e3][(rng.unit() * 3.0) as usize];
        let boxes = [0; 4].map(|_| {
            let c = [0; 3].map(|_| rng.range(-10.0, 10.0) * scale);
            let h = [0; 3].map(|_| rng.range(0.0, 4.0) * scale);
            BoundBox {
                lo: [0, 1, 2].map(|k| (c[k] - h[k]) as f32),
                hi: [0, 1, 2].map(|k| (c[k] + h[k]) as f32),
                pad_base: (rng.range(0.0, 1e-3) * scale) as f32,
                pad_slope: rng.range(0.0, 1e-5) as f32,
            }
        });
        let origin = [0; 3].map(|_| (rng.range(-30.0, 30.0) * scale) as f32);
        // Toward a point near one of the boxes: every sign pattern of the direction (so every
        // choice of entering face) and lanes both met and missed.
        let aim = &boxes[(rng.unit() * 4.0) as usize];
        let direction = [0, 1, 2].map(|k| {
            let spread = (aim.hi[k] - aim.lo[k]) as f64;
            let target = rng.range(aim.lo[k] as f64 - spread, aim.hi[k] as f64 + spread);
            (target - origin[k] as f64) as f32
        });
        if direction.contains(&0.0) {
            continue;
        }
        // A finite tmax or none, and a cut for the lanes of triangles (any set of lanes).
        let tmax =
            [rng.range(0.0, 100.0 * scale) as f32, f32::INFINITY][(rng.unit() * 2.0) as usize];
        let ray = Ray::new(origin, direction, rng.range(0.0, 1.0) as f32, tmax);
        let lane_ray = LaneRay::of(&RayF64::of(&ray));
        let (lanes, _) = LaneBounds::new(&boxes);
        let cut = rng.range(0.0, 100.0 * scale) as f32;
        let triangles = (rng.unit() * 16.0) as u8;
        let (near, hit) = lanes.entries(&lane_ray, cut, triangles);
        let (near_portable, hit_portable) = lanes.entries_portable(&lane_ray, cut, triangles);
        assert_eq!(hit, hit_portable, "{ray:?} {boxes:?}");
        for lane in 0..4 {
            if hit >> lane & 1 == 1 {
                assert_eq!(
                    near[lane].to_bits(),
                    near_portable[lane].to_bits(),
                    "{ray:?}"
                );
            }
        }
        met[(hit != 0) as usize] += 1;
    }
    // Both outcomes were exercised.
    assert!(met[0] > 1_000 && met[1] > 1_000, "{met:?}");
}
