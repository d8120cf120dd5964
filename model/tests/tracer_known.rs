//! Known answers written by hand: each expected value is derived in the comment beside it, never
//! taken from the tracer's output.

mod tracer_common;

use model::scene::build;
use model::scene::{
    Aabb, Aabbs, BottomLevel, Geometry, GeometryData, GeometryFlags, InstanceFlags, Ray, RayFlags,
    Scene, SceneInstance, Sphere, Transform3x4,
};
use model::tracer::{AnyHitRule, HitShaders, Precision, Presence, PrimitiveRef, WatertightShape};
use tracer_common::*;

fn prim(instance: u32, geometry: u32, primitive: u32) -> PrimitiveRef {
    PrimitiveRef {
        instance,
        geometry,
        primitive,
    }
}

#[test]
fn ray_through_an_interior_point_is_a_required_hit_with_known_t_and_barycentrics() {
    // (0.25, 0.25) on the unit triangle: b (weight of v1 = x) = 0.25, c (weight of v2 = y) = 0.25;
    // from z = 1 going −z, t = 1. n = (0,0,1), d·n = −1 < 0: front-facing, HitKind 0xFE.
    let out = trace(&one_instance(unit_triangle()), &down(0.25, 0.25));
    assert!(!out.miss.allowed);
    assert_eq!(out.committable.len(), 1);
    let c = &out.candidates[out.committable[0]];
    assert_eq!(c.primitive, prim(0, 0, 0));
    assert_eq!(c.presence, Presence::Required);
    assert_eq!(c.reports.len(), 1);
    let r = &c.reports[0];
    assert_eq!(r.hit_kind, 0xFE);
    assert_eq!(r.t_exact, 1.0);
    assert_eq!(r.barycentrics_exact, Some([0.25, 0.25]));
    // The band here is about 1e-4 relative (|w − o| ≈ 1, see tracer::band).
    assert!(r.t.contains(1.0) && r.t.radius() < 1e-3 && r.t.radius() > 0.0);
    let b = r.barycentrics.unwrap();
    assert!(b[0].contains(0.25) && b[1].contains(0.25));
    assert!(!out.vary);
}

#[test]
fn ray_far_outside_is_a_required_miss() {
    let out = trace(&one_instance(unit_triangle()), &down(5.0, 5.0));
    assert!(out.candidates.is_empty());
    assert!(out.miss.allowed && out.miss.required);
}

#[test]
fn ray_just_outside_an_edge_but_beyond_the_band_is_a_required_miss() {
    // 0.01 below the edge y = 0: far beyond a band of about 1e-5.
    let out = trace(&one_instance(unit_triangle()), &down(0.5, -0.01));
    assert!(out.candidates.is_empty());
}

#[test]
fn ray_exactly_on_a_boundary_edge_is_vary() {
    // (0.5, 0): on the edge v0–v1, which no other triangle shares.
    let out = trace(&one_instance(unit_triangle()), &down(0.5, 0.0));
    assert_eq!(out.candidates.len(), 1);
    assert_eq!(out.candidates[0].presence, Presence::Possible);
    assert!(out.miss.allowed && !out.miss.discouraged);
    assert!(out.watertight.is_empty());
    assert!(out.vary);
}

/// A unit quad from two triangles sharing the diagonal (0,0)–(1,1), wound the same way.
fn quad() -> BottomLevel {
    build::grid(1, 1, 1.0)
}

#[test]
fn ray_on_the_shared_edge_of_a_quad_forms_a_watertight_group() {
    let out = trace(&one_instance(quad()), &down(0.5, 0.5));
    assert_eq!(out.candidates.len(), 2);
    assert!(out
        .candidates
        .iter()
        .all(|c| c.presence == Presence::Possible));
    assert_eq!(out.watertight.len(), 1);
    let g = &out.watertight[0];
    assert_eq!(g.shape, WatertightShape::SharedEdge);
    assert_eq!(g.members, vec![prim(0, 0, 0), prim(0, 0, 1)]);
    // Either triangle may be committed; a miss is allowed but a quality warning.
    assert_eq!(out.committable.len(), 2);
    assert!(out.miss.allowed && out.miss.discouraged);
}

#[test]
fn opposite_windings_on_a_shared_edge_form_no_group() {
    // The second triangle of the quad wound the other way: not a shared edge by the spec's wording.
    let bl = BottomLevel {
        geometries: vec![tri_geometry(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
            ],
            true,
        )],
    };
    let out = trace(&one_instance(bl), &down(0.5, 0.5));
    assert_eq!(out.candidates.len(), 2);
    assert!(out.watertight.is_empty());
}

#[test]
fn ray_through_the_centre_of_a_closed_fan_forms_one_fan_group() {
    let out = trace(&one_instance(build::fan(6, 1.0)), &down(0.0, 0.0));
    assert_eq!(out.candidates.len(), 6);
    let fans: Vec<_> = out
        .watertight
        .iter()
        .filter(|g| g.shape == WatertightShape::ClosedFan)
        .collect();
    assert_eq!(fans.len(), 1);
    assert_eq!(fans[0].members.len(), 6);
}

#[test]
fn ray_through_an_open_fan_vertex_forms_no_group() {
    // A grid corner vertex (0,0) belongs to one triangle; an edge-midpoint vertex of the boundary
    // (1,0) of a 2x1 grid to three triangles with boundary edges: open fans.
    let out = trace(&one_instance(build::grid(2, 1, 1.0)), &down(1.0, 0.0));
    assert!(out.candidates.len() >= 2);
    assert!(out
        .watertight
        .iter()
        .all(|g| g.shape != WatertightShape::ClosedFan));
}

#[test]
fn a_mirrored_instance_keeps_the_facing() {
    // Mirror X: world vertices (0,0,0), (−1,0,0), (0,−... ) wound the other way in world space,
    // but facing is decided in object space: still front (0xFE) for a ray going −z.
    let mirror = Transform3x4([
        [-1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]);
    let scene = Scene {
        bottom_levels: vec![unit_triangle()],
        instances: vec![instance_with(mirror)],
    };
    let out = trace(&scene, &down(-0.25, 0.25));
    assert_eq!(out.candidates.len(), 1);
    assert_eq!(out.candidates[0].reports[0].hit_kind, 0xFE);
    // b is the weight of v1, which sits at world (−1, 0, 0): 0.25.
    assert_eq!(
        out.candidates[0].reports[0].barycentrics_exact,
        Some([0.25, 0.25])
    );
}

#[test]
fn a_mirroring_geometry_transform_changes_the_facing() {
    let mut bl = unit_triangle();
    if let GeometryData::Triangles(t) = &mut bl.geometries[0].data {
        t.transform = Some(Transform3x4([
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ]));
    }
    let out = trace(&one_instance(bl), &down(-0.25, 0.25));
    assert_eq!(out.candidates[0].reports[0].hit_kind, 0xFF);
}

#[test]
fn flip_facing_inverts_the_hit_kind() {
    let mut scene = one_instance(unit_triangle());
    scene.instances[0].flags.flip_facing = true;
    let out = trace(&scene, &down(0.25, 0.25));
    assert_eq!(out.candidates[0].reports[0].hit_kind, 0xFF);
}

#[test]
fn cull_flags_drop_by_facing_unless_the_instance_disables_culling() {
    let scene = one_instance(unit_triangle());
    let front = down(0.25, 0.25);
    let out = trace(
        &scene,
        &front.with_flags(RayFlags::CULL_FRONT_FACING_TRIANGLES),
    );
    assert!(out.candidates.is_empty() && out.miss.required);
    let out = trace(
        &scene,
        &front.with_flags(RayFlags::CULL_BACK_FACING_TRIANGLES),
    );
    assert_eq!(out.candidates.len(), 1);
    let mut disabled = scene.clone();
    disabled.instances[0].flags = InstanceFlags {
        triangle_facing_cull_disable: true,
        ..Default::default()
    };
    let out = trace(
        &disabled,
        &front.with_flags(RayFlags::CULL_FRONT_FACING_TRIANGLES),
    );
    assert_eq!(out.candidates.len(), 1);
    assert!(!out.miss.allowed);
}

#[test]
fn instance_masks_skip_instances_whose_mask_misses_the_cull_mask() {
    let mut scene = one_instance(unit_triangle());
    scene.instances[0].mask = 0x0F;
    let mut ray = down(0.25, 0.25);
    ray.cull_mask = 0xF0;
    assert!(trace(&scene, &ray).miss.required);
    ray.cull_mask = 0x1_0001; // only the low 8 bits count: 0x01 & 0x0F ≠ 0
    assert!(!trace(&scene, &ray).miss.allowed);
    ray.cull_mask = 0x1_0000;
    assert!(trace(&scene, &ray).miss.required);
}

#[test]
fn opacity_follows_ray_flags_then_instance_then_geometry() {
    let mut scene = one_instance(unit_triangle()); // geometry OPAQUE
    let ray = down(0.25, 0.25);
    let anyhit = |_: u32, _: u32| HitShaders::with_any_hit(0, AnyHitRule::Ignore);
    let opaque = |s: &Scene, r: &Ray| {
        trace_with(s, r, &anyhit, Precision::F64WithExactFallback).candidates[0].opaque
    };
    assert!(opaque(&scene, &ray));
    scene.instances[0].flags.force_no_opaque = true;
    assert!(!opaque(&scene, &ray));
    assert!(opaque(&scene, &ray.with_flags(RayFlags::OPAQUE)));
    scene.instances[0].flags = InstanceFlags {
        force_opaque: true,
        ..Default::default()
    };
    scene.bottom_levels[0].geometries[0].flags.opaque = false;
    assert!(opaque(&scene, &ray));
    assert!(!opaque(&scene, &ray.with_flags(RayFlags::NO_OPAQUE)));
    // CULL_OPAQUE drops an opaque candidate; an ignoring any-hit on a non-opaque one allows a miss.
    assert!(
        trace(&scene, &ray.with_flags(RayFlags::CULL_OPAQUE))
            .miss
            .required
    );
    let out = trace_with(
        &scene,
        &ray.with_flags(RayFlags::NO_OPAQUE),
        &anyhit,
        Precision::F64WithExactFallback,
    );
    assert!(out.miss.required);
    assert_eq!(out.any_hit.min, 1);
}

/// Two stacked opaque triangles under the ray: z = 0 (t = 1) and z = −1 (t = 2).
fn two_layers() -> Scene {
    let bl = BottomLevel {
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
    one_instance(bl)
}

#[test]
fn the_closest_required_hit_is_the_only_committable_one() {
    // Without any-hit shaders the layer behind the required hit is unobservable and left out.
    let out = trace(&two_layers(), &down(0.25, 0.25));
    assert_eq!(out.candidates.len(), 1);
    assert_eq!(out.committable.len(), 1);
    assert_eq!(out.candidates[out.committable[0]].primitive, prim(0, 0, 0));
    // With them, any-hit may run for the farther layer: it stays a candidate, never committable.
    let accept = |_: u32, _: u32| HitShaders::with_any_hit(0, AnyHitRule::Accept);
    let out = trace_with(
        &two_layers(),
        &down(0.25, 0.25),
        &accept,
        Precision::F64WithExactFallback,
    );
    assert_eq!(out.candidates.len(), 2);
    assert_eq!(out.committable.len(), 1);
    assert_eq!(out.candidates[out.committable[0]].primitive, prim(0, 0, 0));
}

#[test]
fn terminate_on_first_hit_allows_any_confirmed_candidate() {
    let ray = down(0.25, 0.25).with_flags(RayFlags::TERMINATE_ON_FIRST_HIT);
    let out = trace(&two_layers(), &ray);
    assert_eq!(out.committable.len(), 2);
    // With accepting any-hit shaders the first invocation ends the trace: at most one.
    let accept = |_: u32, _: u32| HitShaders::with_any_hit(0, AnyHitRule::Accept);
    let out = trace_with(
        &two_layers(),
        &ray,
        &accept,
        Precision::F64WithExactFallback,
    );
    assert_eq!(out.any_hit.max, Some(1));
}

#[test]
fn an_ignoring_any_hit_lets_the_farther_layer_be_committed() {
    let rule = |_: u32, g: u32| {
        HitShaders::with_any_hit(
            g,
            if g == 0 {
                AnyHitRule::Ignore
            } else {
                AnyHitRule::Accept
            },
        )
    };
    let out = trace_with(
        &two_layers(),
        &down(0.25, 0.25),
        &rule,
        Precision::F64WithExactFallback,
    );
    assert_eq!(out.committable.len(), 1);
    assert_eq!(out.candidates[out.committable[0]].primitive, prim(0, 1, 0));
    // The ignored nearer layer must have been offered to any-hit; the farther one may be too.
    assert_eq!(out.any_hit.min, 2);
}

#[test]
fn skip_closest_hit_is_recorded() {
    let out = trace(
        &one_instance(unit_triangle()),
        &down(0.25, 0.25).with_flags(RayFlags::SKIP_CLOSEST_HIT_SHADER),
    );
    assert!(out.skip_closest_hit && !out.miss.allowed);
}

#[test]
fn inactive_triangles_and_instances_keep_their_numbering() {
    // Primitive 0 inactive (NaN X), primitive 1 the unit triangle shifted to x ∈ [2, 3].
    let nan = f32::NAN;
    let bl = BottomLevel {
        geometries: vec![tri_geometry(
            vec![
                [nan, 0.0, 0.0],
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
            SceneInstance {
                bottom_level: None,
                ..SceneInstance::of(0)
            },
            SceneInstance::of(0),
        ],
    };
    let out = trace(&scene, &down(2.25, 0.25));
    assert_eq!(out.candidates.len(), 1);
    assert_eq!(out.candidates[0].primitive, prim(1, 0, 1));
    // Where the inactive triangle would be: nothing.
    assert!(trace(&scene, &down(0.25, 0.25)).miss.required);
}

#[test]
fn inactive_aabbs_keep_their_numbering() {
    let nan = f32::NAN;
    let bl = BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags {
                opaque: true,
                no_duplicate_any_hit: false,
            },
            data: GeometryData::Aabbs(Aabbs {
                boxes: vec![
                    Aabb {
                        min: [nan, 0.0, 0.0],
                        max: [1.0, 1.0, 1.0],
                    },
                    Aabb {
                        min: [2.0, 0.0, -1.0],
                        max: [4.0, 2.0, 1.0],
                    },
                ],
                spheres: vec![
                    Sphere {
                        center: [0.5, 0.5, 0.5],
                        radius: 0.5,
                    },
                    Sphere {
                        center: [3.0, 1.0, 0.0],
                        radius: 1.0,
                    },
                ],
            }),
        }],
    };
    let proc = |_: u32, _: u32| HitShaders::procedural(0, None);
    let out = trace_with(
        &one_instance(bl),
        &Ray::new([3.0, 1.0, 4.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert_eq!(out.candidates.len(), 1);
    assert_eq!(out.candidates[0].primitive, prim(0, 0, 1));
    // Entry at z = 1: t = 3, HitKind 0.
    let r = &out.candidates[0].reports[0];
    assert_eq!(r.hit_kind, 0);
    assert!(r.t.contains(3.0) && r.t.radius() < 1e-3);
    assert_eq!(out.candidates[0].presence, Presence::Required);
    assert_eq!(out.intersection.min, 1);
    assert_eq!(out.intersection.max, None);
}

#[test]
fn zero_area_triangles_are_never_hit() {
    // v1 == v2: coincident vertices.
    let bl = BottomLevel {
        geometries: vec![tri_geometry(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            true,
        )],
    };
    assert!(trace(&one_instance(bl), &down(0.5, 0.0)).miss.required);
}

#[test]
fn a_ray_in_the_plane_of_a_triangle_is_culled() {
    // The ray runs along +x in the plane z = 0, through the interior at y = 0.25.
    let ray = Ray::new([-1.0, 0.25, 0.0], [1.0, 0.0, 0.0], 0.0, f32::INFINITY);
    assert!(trace(&one_instance(unit_triangle()), &ray).miss.required);
}

#[test]
fn a_ray_through_the_sphere_is_a_required_hit_entry_or_inside() {
    let proc = |_: u32, _: u32| HitShaders::procedural(7, None);
    // From z = 4 going −z through the centre: entry at z = 1, t = 3, HitKind 0.
    let out = trace_with(
        &sphere_scene(),
        &Ray::new([0.0, 0.0, 4.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert!(!out.miss.allowed);
    assert_eq!(out.candidates[0].reports.len(), 1);
    assert_eq!(out.candidates[0].reports[0].hit_kind, 0);
    // From the centre: starts inside, exit at t = 1, HitKind 1.
    let out = trace_with(
        &sphere_scene(),
        &Ray::new([0.0; 3], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert!(!out.miss.allowed);
    assert_eq!(out.candidates[0].reports[0].hit_kind, 1);
    assert!(out.candidates[0].reports[0].t.contains(1.0));
}

#[test]
fn a_box_the_ray_crosses_must_run_its_shader_one_it_passes_may() {
    let proc = |_: u32, _: u32| HitShaders::procedural(7, None);
    // Passes beside the box at x = 1.5: the shader may run (enlarged box), reports nothing.
    let out = trace_with(
        &sphere_scene(),
        &Ray::new([1.5, 0.0, 4.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert!(out.miss.required);
    assert_eq!(out.intersection.min, 0);
    assert_eq!(out.intersection.max, None);
    // A ray through a box corner region outside the sphere: the box is a candidate (spec, "Ray
    // Intersection Candidate Determination"), so the shader must run, and reports nothing.
    let corner = |origin_z: f32, tmin: f32, tmax: f32| {
        trace_with(
            &sphere_scene(),
            &Ray::new([0.95, 0.95, origin_z], [0.0, 0.0, -1.0], tmin, tmax),
            &proc,
            Precision::F64WithExactFallback,
        )
    };
    let out = corner(4.0, 0.0, f32::INFINITY);
    assert!(out.miss.required);
    assert_eq!(out.intersection.min, 1);
    assert_eq!(out.intersection.max, None);
    // So too from inside the box, and where the segment ends inside it.
    assert_eq!(corner(0.5, 0.0, f32::INFINITY).intersection.min, 1);
    assert_eq!(corner(4.0, 0.0, 3.5).intersection.min, 1);
    // A segment that ends before the box (z = 1 at t = 3), starts past it, or only touches its
    // face: nothing required.
    for (tmin, tmax) in [(0.0, 2.5), (5.5, f32::INFINITY), (0.0, 3.0)] {
        let out = corner(4.0, tmin, tmax);
        assert_eq!(out.intersection.min, 0, "[{tmin}, {tmax}]");
        assert!(out.miss.required);
    }
    // Along the box's face x = 1 (outside the sphere but for the touch at z = 0): the box may or
    // may not be met.
    let face = trace_with(
        &sphere_scene(),
        &Ray::new([1.0, 0.5, 4.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert_eq!(face.intersection.min, 0);
    // Skipping AABBs: the shader can never run.
    let out = trace_with(
        &sphere_scene(),
        &Ray::new([0.0, 0.0, 4.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
            .with_flags(RayFlags::SKIP_AABBS),
        &proc,
        Precision::F64WithExactFallback,
    );
    assert_eq!(out.intersection.max, Some(0));
    assert!(out.miss.required);
}

#[test]
fn a_grazing_ray_reports_nothing_behind_its_origin_or_beyond_tmax() {
    // Along x = 1, tangent to the unit sphere where it touches z = 0: its line lies within the band
    // of the surface, so the shader may find the sphere or not. Every pair is classified in full
    // (no far test, no BVH): the classification alone decides.
    let prepared = model::tracer::PreparedScene::new(&sphere_scene()).expect("defined");
    let proc = |_: u32, _: u32| HitShaders::procedural(7, None);
    let table = model::tracer::ShaderTable {
        hit: &proc,
        miss: model::tracer::MissShader {
            zero_group: false,
            group: MISS_GROUP,
        },
    };
    let config = model::tracer::TracerConfig {
        far_test: false,
        use_bvh: false,
        ..Default::default()
    };
    let trace = |origin_z: f32, tmin: f32, tmax: f32| {
        let ray = Ray::new([1.0, 0.0, origin_z], [0.0, 0.0, -1.0], tmin, tmax);
        let mut stats = model::tracer::TracerStats::default();
        model::tracer::trace_ray(&prepared, &ray, &table, &config, &mut stats).expect("defined")
    };
    // Touching at t = 4: a possible hit there, nothing required.
    let touch = trace(4.0, 0.0, f32::INFINITY);
    assert_eq!(touch.candidates.len(), 1, "{touch:?}");
    let c = &touch.candidates[0];
    assert_eq!(c.presence, Presence::Possible);
    assert!(!c.reports.is_empty() && c.reports.iter().any(|r| r.t.contains(4.0)));
    assert_eq!(touch.intersection.min, 0);
    assert!(touch.miss.allowed && !touch.miss.required);
    // So too where tmax is the touch itself.
    assert_eq!(trace(4.0, 0.0, 4.0).candidates.len(), 1);
    // Where the touch lies beyond tmax, behind the origin, or before tmin, no report can be made.
    for (origin_z, tmin, tmax) in [
        (4.0, 0.0, 3.0),
        (-4.0, 0.0, f32::INFINITY),
        (4.0, 5.0, f32::INFINITY),
    ] {
        let out = trace(origin_z, tmin, tmax);
        assert!(
            out.candidates.is_empty() && out.miss.required,
            "{origin_z} {tmin} {tmax}: {out:?}"
        );
    }
}

#[test]
fn t_exactly_at_tmin_or_tmax_is_vary() {
    let scene = one_instance(unit_triangle());
    let mut ray = down(0.25, 0.25);
    ray.tmax = 1.0;
    let out = trace(&scene, &ray);
    assert_eq!(out.candidates[0].presence, Presence::Possible);
    ray.tmax = f32::INFINITY;
    ray.tmin = 1.0;
    assert_eq!(
        trace(&scene, &ray).candidates[0].presence,
        Presence::Possible
    );
    ray.tmin = 1.5;
    assert!(trace(&scene, &ray).miss.required);
}

#[test]
fn a_translated_rotated_instance_is_hit_where_its_transform_puts_it() {
    // Rotate 90° about z (x → y, y → −x) and translate by (10, 0, 0): object (0.25, 0.25) lands at
    // world (10 − 0.25, 0.25) = (9.75, 0.25).
    let m = Transform3x4([
        [0.0, -1.0, 0.0, 10.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]);
    let scene = Scene {
        bottom_levels: vec![unit_triangle()],
        instances: vec![instance_with(m)],
    };
    let out = trace(&scene, &down(9.75, 0.25));
    assert!(!out.miss.allowed);
    assert_eq!(
        out.candidates[0].reports[0].barycentrics_exact,
        Some([0.25, 0.25])
    );
    // The untransformed position misses.
    assert!(trace(&scene, &down(0.25, 0.25)).miss.required);
}

#[test]
fn every_shared_point_of_a_grid_forms_its_group() {
    // A 4x4 grid of cells 1/4: 16 diagonals + 12 + 12 interior edges = 40 shared-edge points and
    // 9 interior vertices, each of six triangles (the diagonals meet at every other corner twice).
    let (edges, vertices) = build::grid_shared_points(4, 4, 0.25);
    assert_eq!((edges.len(), vertices.len()), (40, 9));
    let scene = one_instance(build::grid(4, 4, 0.25));
    for ray in build::rays_down_onto(&edges, 1.0) {
        let out = trace(&scene, &ray);
        assert_eq!(out.candidates.len(), 2, "{ray:?}");
        assert_eq!(out.watertight.len(), 1, "{ray:?}");
        assert_eq!(out.watertight[0].shape, WatertightShape::SharedEdge);
        assert!(out.miss.discouraged);
    }
    for ray in build::rays_down_onto(&vertices, 1.0) {
        let out = trace(&scene, &ray);
        assert_eq!(out.candidates.len(), 6, "{ray:?}");
        let fans: Vec<_> = out
            .watertight
            .iter()
            .filter(|g| g.shape == WatertightShape::ClosedFan)
            .collect();
        assert_eq!(fans.len(), 1, "{ray:?}");
        assert_eq!(fans[0].members.len(), 6);
    }
}

#[test]
fn an_icosphere_is_closed_and_rays_at_its_vertices_meet_fans() {
    let bl = build::icosphere(2, 1.0);
    let GeometryData::Triangles(t) = &bl.geometries[0].data else {
        unreachable!()
    };
    assert_eq!(t.primitive_count(), 320);
    // Closed: every directed edge appears once, and so does its reverse.
    let mut edges = std::collections::HashMap::new();
    for p in 0..t.primitive_count() {
        let v = t.vertex_indices(p);
        for k in 0..3 {
            *edges.entry((v[k], v[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    assert!(edges
        .iter()
        .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1)));
    // A ray from outside straight at vertex 0 (radius 1, from distance 4: t = 3; the antipodal
    // vertex, also a fan, at t = 5 lies beyond tmax = 4).
    let v = t.positions[0];
    let ray = Ray::new(v.map(|x| 4.0 * x), v.map(|x| -x), 0.0, 4.0);
    let out = trace(&one_instance(bl), &ray);
    assert_eq!(out.watertight.len(), 1);
    assert_eq!(out.watertight[0].shape, WatertightShape::ClosedFan);
    assert_eq!(out.watertight[0].members.len(), 5);
}
