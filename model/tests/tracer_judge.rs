//! Planted faults: records doctored the way a broken driver would write them must be caught, and
//! the true records (written by hand from the scene's geometry) must pass.

mod tracer_common;

use model::scene::build;
use model::scene::{BottomLevel, Ray, RayFlags, Scene, SceneInstance, Transform3x4};
use model::tracer::judge::{judge, RayVerdict};
use model::tracer::record::{RayRecord, RecordOutcome, SeenCandidate};
use model::tracer::summary::Summary;
use model::tracer::{AllowedOutcomes, AnyHitRule, HitShaders, Precision};
use tracer_common::*;

#[allow(clippy::too_many_arguments)]
fn hit(
    instance: u32,
    geometry: u32,
    primitive: u32,
    kind: u32,
    t: f32,
    b: f32,
    c: f32,
    group: u32,
) -> RayRecord {
    RayRecord {
        outcome: RecordOutcome::Hit,
        group: Some(group),
        instance_id: instance,
        custom_index: 0,
        geometry_index: geometry,
        primitive_id: primitive,
        hit_kind: kind,
        t,
        barycentrics: [b, c],
        any_hit_count: 0,
        intersection_count: 0,
        seen: Vec::new(),
    }
}

fn verdict(allowed: &AllowedOutcomes, r: &RayRecord) -> RayVerdict {
    // Round-trip through the words the harness reads back.
    assert_eq!(
        &RayRecord::from_words(&r.to_words()).expect("well-formed"),
        r
    );
    words_verdict(allowed, r)
}

/// The verdict on a record as read back from its words, without comparing the two (a record holding
/// a NaN equals no record).
fn words_verdict(allowed: &AllowedOutcomes, r: &RayRecord) -> RayVerdict {
    let back = RayRecord::from_words(&r.to_words()).expect("well-formed");
    judge(allowed, &back).verdict
}

fn is_fail(v: &RayVerdict) -> bool {
    matches!(v, RayVerdict::Fail(_))
}

/// The unit triangle hit at (0.25, 0.25) from z = 1: t = 1, b = c = 0.25, front (0xFE).
fn centre() -> (Scene, Ray, RayRecord) {
    (
        one_instance(unit_triangle()),
        down(0.25, 0.25),
        hit(0, 0, 0, 0xFE, 1.0, 0.25, 0.25, 0),
    )
}

#[test]
fn the_true_record_passes() {
    let (scene, ray, rec) = centre();
    let out = trace(&scene, &ray);
    let j = judge(&out, &rec);
    assert_eq!(j.verdict, RayVerdict::Pass);
    assert_eq!(j.t_error_ulps, Some(0.0));
    assert!(j.t_bound.unwrap() > 0.0);
    // A t one f32 ulp off still passes, and its error is measured as one ulp.
    let mut off = rec.clone();
    off.t = f32::from_bits(1.0f32.to_bits() + 1);
    let j = judge(&out, &off);
    assert_eq!(j.verdict, RayVerdict::Pass);
    assert_eq!(j.t_error_ulps, Some(1.0));
}

/// Barycentric errors are counted in ULPs of the larger of the exact value and 1/2: next to an edge
/// (an exact coordinate of 1e-30) an error of 2^-24 is one such ULP, where ULPs of the value itself
/// would make it about 1e22; at 1/2 and above they are the value's own ULPs.
#[test]
fn barycentric_ulps_are_counted_at_the_scale_of_the_coordinates() {
    let scene = one_instance(unit_triangle());
    let half_ulp = 2f32.powi(-24);
    for (x, y, b, c, ulps) in [
        (0.5f32, 1e-30f32, 0.5f32, half_ulp, 1.0),
        (0.75, 0.125, 0.75 + 2.0 * 2f32.powi(-24), 0.125, 2.0),
        (0.25, 0.25, 0.25 + half_ulp, 0.25, 1.0),
    ] {
        let ray = down(x, y);
        let out = trace(&scene, &ray);
        let j = judge(&out, &hit(0, 0, 0, 0xFE, 1.0, b, c, 0));
        let seen = j
            .bary_error_ulps
            .expect("a triangle hit measures its barycentrics");
        assert!(
            (seen - ulps).abs() < 1e-3,
            "ray at ({x}, {y}), record ({b}, {c}): {seen} ulps, expected {ulps}"
        );
    }
}

/// The t error is counted in ULPs of the larger of |t_exact| and the ray's reach to the triangle's
/// farthest vertex (in t): a ray starting 2^-20 above the unit triangle has t_exact = 2^-20 but
/// reaches its far vertices at t = 0.75, so an error of 2^-24 is one ULP there, not the 2^19 ULPs of
/// 2^-20 itself; from z = 1 (reach 1 = t_exact) the ULPs are t's own.
#[test]
fn t_ulps_are_counted_at_the_scale_of_the_rays_reach() {
    let scene = one_instance(unit_triangle());
    let near = 2f32.powi(-20);
    for (z, t, ulps) in [
        (near, near + 2f32.powi(-24), 1.0),
        (near, near + 2f32.powi(-22), 4.0),
        (1.0, f32::from_bits(1.0f32.to_bits() + 2), 2.0),
    ] {
        let ray = Ray::new([0.25, 0.25, z], [0.0, 0.0, -1.0], 0.0, f32::INFINITY);
        let out = trace(&scene, &ray);
        let j = judge(&out, &hit(0, 0, 0, 0xFE, t, 0.25, 0.25, 0));
        let seen = j.t_error_ulps.expect("a hit measures its t");
        assert!(
            (seen - ulps).abs() < 1e-3,
            "ray from z = {z}, t = {t}: {seen} ulps, expected {ulps}"
        );
    }
}

#[test]
fn a_hit_turned_into_a_miss_fails() {
    let (scene, ray, _) = centre();
    let out = trace(&scene, &ray);
    assert!(is_fail(&verdict(&out, &RayRecord::miss(MISS_GROUP))));
}

#[test]
fn a_launch_that_did_not_run_fails() {
    let (scene, ray, _) = centre();
    let out = trace(&scene, &ray);
    let r = RayRecord::from_words(&RayRecord::PREFILL).unwrap();
    assert!(is_fail(&judge(&out, &r).verdict));
}

#[test]
fn swapped_primitive_or_instance_ids_fail() {
    // Two instances of a two-triangle strip: instance 1 shifted by x + 4.
    let bl = BottomLevel {
        geometries: vec![tri_geometry(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [2.0, 0.0, 0.0],
                [3.0, 0.0, 0.0],
                [2.0, 1.0, 0.0],
            ],
            true,
        )],
    };
    let scene = Scene {
        bottom_levels: vec![bl],
        instances: vec![
            SceneInstance::of(0),
            instance_with(Transform3x4::translation([4.0, 0.0, 0.0])),
        ],
    };
    let out = trace(&scene, &down(2.25, 0.25));
    // Instance 0, primitive 1: b = c = 0.25, t = 1; group 10·0 + 0.
    let good = hit(0, 0, 1, 0xFE, 1.0, 0.25, 0.25, 0);
    assert_eq!(verdict(&out, &good), RayVerdict::Pass);
    let mut wrong_prim = good.clone();
    wrong_prim.primitive_id = 0;
    assert!(is_fail(&verdict(&out, &wrong_prim)));
    let mut wrong_instance = good.clone();
    wrong_instance.instance_id = 1;
    wrong_instance.group = Some(10);
    assert!(is_fail(&verdict(&out, &wrong_instance)));
    let mut wrong_group = good.clone();
    wrong_group.group = Some(3);
    assert!(is_fail(&verdict(&out, &wrong_group)));
    let mut wrong_custom = good;
    wrong_custom.custom_index = 5;
    assert!(is_fail(&verdict(&out, &wrong_custom)));
}

#[test]
fn t_off_by_twice_its_bound_fails() {
    let (scene, ray, rec) = centre();
    let out = trace(&scene, &ray);
    let bound = out.candidates[0].reports[0].t.radius();
    let mut r = rec.clone();
    r.t = (1.0 + 2.0 * bound) as f32;
    let j = judge(&out, &r);
    assert!(is_fail(&j.verdict));
    assert!(j.t_error_rel.unwrap() > 1.9);
    let mut r = rec;
    r.barycentrics[0] =
        0.25 + 2.0 * out.candidates[0].reports[0].barycentrics.unwrap()[0].radius() as f32;
    assert!(is_fail(&verdict(&out, &r)));
}

/// A NaN barycentric fails wherever the model bounds it; where the pair's f32 test may overflow
/// (VARY, `VaryReason::Range`: every quantity unbounded, as lavapipe showed with coordinates near
/// 1e20, `rtconf stress --family extreme-scale --seed 90033 --size small`) it is an allowed outcome.
#[test]
fn a_nan_barycentric_passes_only_where_the_pair_may_overflow() {
    let (scene, ray, rec) = centre();
    let out = trace(&scene, &ray);
    let mut r = rec.clone();
    r.barycentrics[0] = f32::NAN;
    assert!(is_fail(&words_verdict(&out, &r)));
    // The unit triangle scaled by 2^70, seen from 2^70 above along a direction of length 2^60.
    let s = 2f32.powi(70);
    let far = one_instance(BottomLevel {
        geometries: vec![tri_geometry(
            vec![[0.0, 0.0, 0.0], [s, 0.0, 0.0], [0.0, s, 0.0]],
            true,
        )],
    });
    let ray = Ray::new(
        [0.25 * s, 0.25 * s, s],
        [0.0, 0.0, -(2f32.powi(60))],
        0.0,
        f32::INFINITY,
    );
    let out = trace(&far, &ray);
    assert_eq!(
        out.candidates[0].vary_reason,
        Some(model::tracer::VaryReason::Range)
    );
    let mut r = hit(0, 0, 0, 0xFE, 2f32.powi(10), f32::NAN, 0.25, 0);
    assert!(
        !is_fail(&words_verdict(&out, &r)),
        "{:?}",
        words_verdict(&out, &r)
    );
    // Its t still may not be NaN: no test of t against [tmin, tmax] keeps a NaN.
    r.t = f32::NAN;
    assert!(is_fail(&words_verdict(&out, &r)));
}

#[test]
fn a_record_that_ignored_the_instance_transform_fails() {
    // Instance scaled by 2: world triangle (0,0), (2,0), (0,2); at (0.25, 0.25): b = c = 0.125.
    // A driver that traced the world ray against the untransformed triangle reports 0.25.
    let m = Transform3x4([
        [2.0, 0.0, 0.0, 0.0],
        [0.0, 2.0, 0.0, 0.0],
        [0.0, 0.0, 2.0, 0.0],
    ]);
    let scene = Scene {
        bottom_levels: vec![unit_triangle()],
        instances: vec![instance_with(m)],
    };
    let out = trace(&scene, &down(0.25, 0.25));
    assert_eq!(
        verdict(&out, &hit(0, 0, 0, 0xFE, 1.0, 0.125, 0.125, 0)),
        RayVerdict::Pass
    );
    assert!(is_fail(&verdict(
        &out,
        &hit(0, 0, 0, 0xFE, 1.0, 0.25, 0.25, 0)
    )));
    // Translated away: the untransformed triangle would be hit where the instance is not.
    let scene = Scene {
        bottom_levels: vec![unit_triangle()],
        instances: vec![instance_with(Transform3x4::translation([10.0, 0.0, 0.0]))],
    };
    let out = trace(&scene, &down(0.25, 0.25));
    assert!(is_fail(&verdict(
        &out,
        &hit(0, 0, 0, 0xFE, 1.0, 0.25, 0.25, 0)
    )));
    assert_eq!(
        verdict(&out, &RayRecord::miss(MISS_GROUP)),
        RayVerdict::Pass
    );
}

#[test]
fn an_inverted_facing_fails() {
    let (scene, ray, mut rec) = centre();
    let out = trace(&scene, &ray);
    rec.hit_kind = 0xFF;
    assert!(is_fail(&verdict(&out, &rec)));
}

#[test]
fn an_ignored_mask_fails() {
    let (mut scene, mut ray, rec) = centre();
    scene.instances[0].mask = 0x0F;
    ray.cull_mask = 0xF0;
    let out = trace(&scene, &ray);
    assert!(is_fail(&verdict(&out, &rec)));
    assert_eq!(
        verdict(&out, &RayRecord::miss(MISS_GROUP)),
        RayVerdict::Pass
    );
}

#[test]
fn skip_closest_hit_ignored_fails() {
    let (scene, ray, rec) = centre();
    let ray = ray.with_flags(RayFlags::SKIP_CLOSEST_HIT_SHADER);
    let out = trace(&scene, &ray);
    assert!(is_fail(&verdict(&out, &rec)));
    assert_eq!(verdict(&out, &RayRecord::no_shader()), RayVerdict::Pass);
    // And the silent outcome on a ray that must miss into a real miss shader fails.
    let out = trace(&scene, &down(5.0, 5.0));
    assert!(is_fail(&verdict(&out, &RayRecord::no_shader())));
}

/// Two non-opaque layers at t = 1 and t = 2, accepting any-hit shaders, NO_DUPLICATE_ANY_HIT.
fn layers() -> Scene {
    let mut bl = BottomLevel {
        geometries: vec![
            tri_geometry(
                vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                false,
            ),
            tri_geometry(
                vec![[0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 1.0, -1.0]],
                false,
            ),
        ],
    };
    for g in &mut bl.geometries {
        g.flags.no_duplicate_any_hit = true;
    }
    one_instance(bl)
}

fn seen(instance: u32, geometry: u32, primitive: u32, t: f32) -> SeenCandidate {
    SeenCandidate {
        instance,
        geometry,
        primitive,
        t,
    }
}

#[test]
fn terminate_on_first_hit_ignored_fails() {
    let accept = |_: u32, g: u32| HitShaders::with_any_hit(g, AnyHitRule::Accept);
    let ray = down(0.25, 0.25).with_flags(RayFlags::TERMINATE_ON_FIRST_HIT);
    let out = trace_with(&layers(), &ray, &accept, Precision::F64WithExactFallback);
    // True: the farther layer accepted first and ended the trace.
    let mut good = hit(0, 1, 0, 0xFE, 2.0, 0.25, 0.25, 1);
    good.any_hit_count = 1;
    good.seen = vec![seen(0, 1, 0, 2.0)];
    assert_eq!(verdict(&out, &good), RayVerdict::Pass);
    // Doctored: traversal went on after the first accepted hit.
    let mut bad = hit(0, 0, 0, 0xFE, 1.0, 0.25, 0.25, 0);
    bad.any_hit_count = 2;
    bad.seen = vec![seen(0, 1, 0, 2.0), seen(0, 0, 0, 1.0)];
    assert!(is_fail(&verdict(&out, &bad)));
    // Without the flag that record is fine, and committing the farther layer is not.
    let out = trace_with(
        &layers(),
        &down(0.25, 0.25),
        &accept,
        Precision::F64WithExactFallback,
    );
    assert_eq!(verdict(&out, &bad), RayVerdict::Pass);
    assert!(is_fail(&verdict(&out, &good)));
}

#[test]
fn any_hit_for_an_opaque_or_impossible_candidate_fails() {
    let accept = |_: u32, g: u32| HitShaders::with_any_hit(g, AnyHitRule::Accept);
    let out = trace_with(
        &layers(),
        &down(0.25, 0.25).with_flags(RayFlags::OPAQUE),
        &accept,
        Precision::F64WithExactFallback,
    );
    let mut r = hit(0, 0, 0, 0xFE, 1.0, 0.25, 0.25, 0);
    assert_eq!(verdict(&out, &r), RayVerdict::Pass);
    r.any_hit_count = 1;
    r.seen = vec![seen(0, 0, 0, 1.0)];
    assert!(is_fail(&verdict(&out, &r)));
    // A duplicate with NO_DUPLICATE_ANY_HIT.
    let out = trace_with(
        &layers(),
        &down(0.25, 0.25),
        &accept,
        Precision::F64WithExactFallback,
    );
    r.any_hit_count = 2;
    r.seen = vec![seen(0, 0, 0, 1.0), seen(0, 0, 0, 1.0)];
    assert!(is_fail(&verdict(&out, &r)));
}

/// A hit that ended the trace shows no hole in a nearer watertight group: the ray down through the
/// diagonal of an opaque quad (instance 0, t = 1) reaches a non-opaque triangle behind it (instance 1,
/// t = 1.5) whose committed hit the record reports. When that hit ended the trace (its any-hit
/// terminates, or the ray ends at its first hit), the traversal may have reached it first, so the
/// quad was never passed: a pass. When nothing ended the trace early, the ray passed the quad's
/// shared edge without a hit there: a hole, warned.
#[test]
fn a_trace_ended_by_a_farther_hit_shows_no_hole_in_a_nearer_group() {
    let behind = BottomLevel {
        geometries: vec![tri_geometry(
            vec![[0.0, 0.0, -0.5], [2.0, 0.0, -0.5], [0.0, 2.0, -0.5]],
            false,
        )],
    };
    let scene = Scene {
        bottom_levels: vec![build::grid(1, 1, 1.0), behind],
        instances: vec![SceneInstance::of(0), SceneInstance::of(1)],
    };
    for (rule, flags, warned) in [
        (AnyHitRule::Terminate, RayFlags::default(), false),
        (AnyHitRule::Accept, RayFlags::TERMINATE_ON_FIRST_HIT, false),
        (AnyHitRule::Accept, RayFlags::default(), true),
    ] {
        let shaders = move |i: u32, _: u32| {
            if i == 1 {
                HitShaders::with_any_hit(1, rule)
            } else {
                HitShaders::closest(0)
            }
        };
        let ray = down(0.5, 0.5).with_flags(flags);
        let out = trace_with(&scene, &ray, &shaders, Precision::F64WithExactFallback);
        assert_eq!(out.watertight.len(), 1, "the quad's diagonal is a group");
        let mut behind_hit = hit(1, 0, 0, 0xFE, 1.5, 0.25, 0.25, 1);
        behind_hit.any_hit_count = 1;
        behind_hit.seen = vec![seen(1, 0, 0, 1.5)];
        let v = verdict(&out, &behind_hit);
        assert_eq!(
            matches!(v, RayVerdict::Warn(_)),
            warned,
            "{rule:?} with flags {:?}: {v:?}",
            flags.0
        );
        if !warned {
            assert_eq!(v, RayVerdict::Pass, "{rule:?}");
        }
    }
}

/// The quad of two triangles sharing the diagonal, non-opaque with accepting any-hit.
fn quad_scene() -> Scene {
    let mut bl = build::grid(1, 1, 1.0);
    bl.geometries[0].flags.opaque = false;
    one_instance(bl)
}

#[test]
fn a_double_hit_on_a_shared_edge_fails_and_a_hole_warns() {
    let accept = |_: u32, _: u32| HitShaders::with_any_hit(0, AnyHitRule::Accept);
    let out = trace_with(
        &quad_scene(),
        &down(0.5, 0.5),
        &accept,
        Precision::F64WithExactFallback,
    );
    assert_eq!(out.watertight.len(), 1);
    // On the diagonal of triangle 0 = (0,0),(1,0),(1,1): (0.5, 0.5) = 0.5·v0 + 0·v1 + 0.5·v2.
    let mut good = hit(0, 0, 0, 0xFE, 1.0, 0.0, 0.5, 0);
    good.any_hit_count = 1;
    good.seen = vec![seen(0, 0, 0, 1.0)];
    assert_eq!(verdict(&out, &good), RayVerdict::Pass);
    let mut double = good.clone();
    double.any_hit_count = 2;
    double.seen = vec![seen(0, 0, 0, 1.0), seen(0, 0, 1, 1.0)];
    assert!(is_fail(&verdict(&out, &double)));
    let hole = RayRecord::miss(MISS_GROUP);
    assert!(matches!(verdict(&out, &hole), RayVerdict::Warn(_)));
    // A boundary edge is VARY: a miss there is neither.
    let out = trace_with(
        &quad_scene(),
        &down(0.5, 0.0),
        &accept,
        Precision::F64WithExactFallback,
    );
    assert_eq!(
        verdict(&out, &RayRecord::miss(MISS_GROUP)),
        RayVerdict::Pass
    );
}

#[test]
fn summaries_count_verdicts_and_errors() {
    let (scene, ray, rec) = centre();
    let out = trace(&scene, &ray);
    let mut s = Summary::default();
    s.add(&judge(&out, &rec));
    s.add(&judge(&out, &RayRecord::miss(MISS_GROUP)));
    let quad = trace(&quad_scene(), &down(0.5, 0.5));
    s.add(&judge(&quad, &RayRecord::miss(MISS_GROUP)));
    assert_eq!((s.rays, s.pass, s.warn, s.fail, s.vary), (3, 1, 1, 1, 1));
    assert_eq!(s.t_error_ulps.count, 1);
    assert_eq!(s.t_error_ulps.median(), Some(0.0));
    let text = serde_json::to_string(&s).unwrap();
    let back: Summary = serde_json::from_str(&text).unwrap();
    assert_eq!(back, s);
}

/// A driver that skips a box the ray crosses (its intersection shader never run) is caught, though
/// the box's sphere is missed and so nothing is hit: the box [−1, 1]³ around the unit sphere,
/// crossed through its corner region; one the ray passes beside may run the shader or not.
#[test]
fn a_skipped_box_fails_and_an_enlarged_one_passes() {
    let scene = sphere_scene();
    let proc = |_: u32, _: u32| HitShaders::procedural(7, None);
    let down_at = |x: f32| Ray::new([x, 0.95, 4.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY);
    let miss_with = |count: u32| RayRecord {
        intersection_count: count,
        ..RayRecord::miss(MISS_GROUP)
    };
    let crossing = trace_with(
        &scene,
        &down_at(0.95),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert!(is_fail(&verdict(&crossing, &miss_with(0))));
    assert_eq!(verdict(&crossing, &miss_with(1)), RayVerdict::Pass);
    assert_eq!(verdict(&crossing, &miss_with(3)), RayVerdict::Pass);
    let beside = trace_with(
        &scene,
        &down_at(1.5),
        &proc,
        Precision::F64WithExactFallback,
    );
    for count in [0, 1] {
        assert_eq!(verdict(&beside, &miss_with(count)), RayVerdict::Pass);
    }
}
