//! Every class of undefined behaviour `Scene::undefined` knows, each found with its path; a
//! defined scene has none; scenes read from readable YAML and reject unknown fields.

use model::scene::{
    Aabb, Aabbs, BottomLevel, Geometry, GeometryData, GeometryFlags, Indices, Problem, ProblemKind,
    Ray, RayFlags, Scene, SceneInstance, Sphere, Transform3x4, Triangles,
};

fn tri(
    positions: Vec<[f32; 3]>,
    indices: Option<Indices>,
    transform: Option<Transform3x4>,
) -> Geometry {
    Geometry {
        flags: GeometryFlags::default(),
        data: GeometryData::Triangles(Triangles {
            positions,
            indices,
            transform,
        }),
    }
}

fn unit() -> Vec<[f32; 3]> {
    vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
}

fn boxes(b: Vec<Aabb>, s: Vec<Sphere>) -> Geometry {
    Geometry {
        flags: GeometryFlags::default(),
        data: GeometryData::Aabbs(Aabbs {
            boxes: b,
            spheres: s,
        }),
    }
}

fn good_ray() -> Ray {
    Ray::new([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
}

fn scene_of(geometries: Vec<Geometry>) -> Scene {
    Scene {
        bottom_levels: vec![BottomLevel { geometries }],
        instances: vec![SceneInstance::of(0)],
    }
}

/// Asserts the problems are exactly `expected` (kind, path).
fn check(problems: Vec<Problem>, expected: &[(ProblemKind, &str)]) {
    let got: Vec<(ProblemKind, String)> =
        problems.iter().map(|p| (p.kind, p.path.clone())).collect();
    let want: Vec<(ProblemKind, String)> =
        expected.iter().map(|(k, p)| (*k, p.to_string())).collect();
    assert_eq!(got, want, "{problems:#?}");
}

#[test]
fn a_defined_scene_has_no_problems() {
    let nan = f32::NAN;
    let s = scene_of(vec![tri(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [nan, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        None,
        None,
    )]);
    check(s.undefined(&[good_ray()]), &[]);
    let s = scene_of(vec![boxes(
        vec![
            Aabb {
                min: [nan, 0.0, 0.0],
                max: [1.0; 3],
            },
            Aabb {
                min: [-1.0; 3],
                max: [1.0; 3],
            },
        ],
        vec![
            Sphere {
                center: [9.0; 3],
                radius: 9.0,
            },
            Sphere {
                center: [0.0; 3],
                radius: 1.0,
            },
        ],
    )]);
    check(s.undefined(&[]), &[]);
}

#[test]
fn ray_problems_are_found_with_their_paths() {
    let s = scene_of(vec![tri(unit(), None, None)]);
    let mut nan_origin = good_ray();
    nan_origin.origin[1] = f32::NAN;
    let mut inf_dir = good_ray();
    inf_dir.direction[0] = f32::INFINITY;
    let mut zero = good_ray();
    zero.direction = [0.0, -0.0, 0.0];
    let mut neg = good_ray();
    neg.tmin = -1.0;
    let mut above = good_ray();
    above.tmin = 2.0;
    above.tmax = 1.0;
    let mut nan_tmax = good_ray();
    nan_tmax.tmax = f32::NAN;
    let exclusive = good_ray().with_flags(RayFlags::OPAQUE | RayFlags::CULL_NO_OPAQUE);
    let skips =
        good_ray().with_flags(RayFlags::SKIP_TRIANGLES | RayFlags::CULL_BACK_FACING_TRIANGLES);
    let unknown = good_ray().with_flags(RayFlags(0x400));
    check(
        s.undefined(&[
            nan_origin, inf_dir, zero, neg, above, nan_tmax, exclusive, skips, unknown,
        ]),
        &[
            (ProblemKind::RayNotFinite, "rays[0].origin"),
            (ProblemKind::RayNotFinite, "rays[1].direction"),
            (ProblemKind::RayZeroDirection, "rays[2].direction"),
            (ProblemKind::RayTminNegative, "rays[3].tmin"),
            (ProblemKind::RayTminAboveTmax, "rays[4].tmax"),
            (ProblemKind::RayNotFinite, "rays[5].tmax"),
            (ProblemKind::RayFlagsExclusive, "rays[6].flags"),
            (ProblemKind::RayFlagsExclusive, "rays[7].flags"),
            (ProblemKind::RayFlagsUnknown, "rays[8].flags"),
        ],
    );
}

#[test]
fn every_pair_of_exclusive_ray_flags_is_undefined() {
    let s = scene_of(vec![]);
    let pairs = [
        (RayFlags::OPAQUE, RayFlags::NO_OPAQUE),
        (RayFlags::CULL_OPAQUE, RayFlags::CULL_NO_OPAQUE),
        (RayFlags::NO_OPAQUE, RayFlags::CULL_OPAQUE),
        (RayFlags::SKIP_TRIANGLES, RayFlags::SKIP_AABBS),
        (
            RayFlags::SKIP_TRIANGLES,
            RayFlags::CULL_FRONT_FACING_TRIANGLES,
        ),
        (
            RayFlags::CULL_BACK_FACING_TRIANGLES,
            RayFlags::CULL_FRONT_FACING_TRIANGLES,
        ),
    ];
    for (a, b) in pairs {
        check(
            s.undefined(&[good_ray().with_flags(a | b)]),
            &[(ProblemKind::RayFlagsExclusive, "rays[0].flags")],
        );
    }
    // Compatible flags are fine.
    let ok = RayFlags::OPAQUE
        | RayFlags::TERMINATE_ON_FIRST_HIT
        | RayFlags::CULL_BACK_FACING_TRIANGLES
        | RayFlags::SKIP_AABBS;
    check(s.undefined(&[good_ray().with_flags(ok)]), &[]);
}

#[test]
fn geometry_problems_are_found_with_their_paths() {
    let nan = f32::NAN;
    let singular = Transform3x4([
        [1.0, 2.0, 3.0, 0.0],
        [2.0, 4.0, 6.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]);
    let mut nan_transform = Transform3x4::IDENTITY;
    nan_transform.0[1][3] = nan;
    let s = Scene {
        bottom_levels: vec![
            BottomLevel {
                geometries: vec![
                    // 0: NaN in Y of an active triangle.
                    tri(
                        vec![[0.0, nan, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                        None,
                        None,
                    ),
                    // 1: NaN in Z of an inactive one (NaN X elsewhere) is still undefined.
                    tri(
                        vec![[nan, 0.0, 0.0], [1.0, 0.0, nan], [0.0, 1.0, 0.0]],
                        None,
                        None,
                    ),
                    // 2: index out of range.
                    tri(unit(), Some(Indices::U16(vec![0, 1, 3])), None),
                    // 3: four indices.
                    tri(unit(), Some(Indices::U32(vec![0, 1, 2, 0])), None),
                    // 4: four vertices without indices.
                    tri(vec![[0.0; 3]; 4], None, None),
                    // 5: singular geometry transform.
                    tri(unit(), None, Some(singular)),
                    // 6: NaN in a geometry transform.
                    tri(unit(), None, Some(nan_transform)),
                    // 7: infinity in a vertex.
                    tri(
                        vec![[0.0, 0.0, f32::INFINITY], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                        None,
                        None,
                    ),
                ],
            },
            BottomLevel {
                geometries: vec![
                    boxes(
                        vec![
                            Aabb {
                                min: [0.0, nan, 0.0],
                                max: [1.0; 3],
                            },
                            Aabb {
                                min: [0.0, 2.0, 0.0],
                                max: [1.0; 3],
                            },
                            Aabb {
                                min: [0.0; 3],
                                max: [1.0; 3],
                            },
                            Aabb {
                                min: [nan, 0.0, 0.0],
                                max: [1.0, nan, 1.0],
                            },
                        ],
                        vec![
                            Sphere {
                                center: [0.5; 3],
                                radius: 0.5,
                            },
                            Sphere {
                                center: [0.5; 3],
                                radius: 0.5,
                            },
                            Sphere {
                                center: [0.5; 3],
                                radius: 0.6,
                            },
                            Sphere {
                                center: [0.5; 3],
                                radius: 0.5,
                            },
                        ],
                    ),
                    boxes(
                        vec![Aabb {
                            min: [0.0; 3],
                            max: [1.0; 3],
                        }],
                        vec![],
                    ),
                ],
            },
            // Mixed types in one bottom level.
            BottomLevel {
                geometries: vec![tri(unit(), None, None), boxes(vec![], vec![])],
            },
        ],
        instances: vec![],
    };
    check(
        s.undefined(&[]),
        &[
            (
                ProblemKind::VertexNotFinite,
                "scene.bottom_levels[0].geometries[0].data.positions[0]",
            ),
            (
                ProblemKind::VertexNotFinite,
                "scene.bottom_levels[0].geometries[1].data.positions[1]",
            ),
            (
                ProblemKind::IndexOutOfRange,
                "scene.bottom_levels[0].geometries[2].data.indices[2]",
            ),
            (
                ProblemKind::IncompletePrimitive,
                "scene.bottom_levels[0].geometries[3].data.indices",
            ),
            (
                ProblemKind::IncompletePrimitive,
                "scene.bottom_levels[0].geometries[4].data.positions",
            ),
            (
                ProblemKind::TransformSingular,
                "scene.bottom_levels[0].geometries[5].data.transform",
            ),
            (
                ProblemKind::TransformNotFinite,
                "scene.bottom_levels[0].geometries[6].data.transform",
            ),
            (
                ProblemKind::VertexNotFinite,
                "scene.bottom_levels[0].geometries[7].data.positions[0]",
            ),
            (
                ProblemKind::AabbNotFinite,
                "scene.bottom_levels[1].geometries[0].data.boxes[0]",
            ),
            (
                ProblemKind::AabbInverted,
                "scene.bottom_levels[1].geometries[0].data.boxes[1]",
            ),
            (
                ProblemKind::SphereOutsideBox,
                "scene.bottom_levels[1].geometries[0].data.spheres[2]",
            ),
            (
                ProblemKind::AabbNotFinite,
                "scene.bottom_levels[1].geometries[0].data.boxes[3]",
            ),
            (
                ProblemKind::SphereOutsideBox,
                "scene.bottom_levels[1].geometries[1].data.spheres",
            ),
            (
                ProblemKind::MixedGeometryTypes,
                "scene.bottom_levels[2].geometries",
            ),
        ],
    );
}

#[test]
fn instance_problems_are_found_with_their_paths() {
    let singular = Transform3x4([
        [0.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]);
    let mut inf = Transform3x4::IDENTITY;
    inf.0[0][0] = f32::INFINITY;
    let s = Scene {
        bottom_levels: vec![BottomLevel {
            geometries: vec![tri(unit(), None, None)],
        }],
        instances: vec![
            SceneInstance {
                bottom_level: Some(3),
                ..SceneInstance::of(0)
            },
            SceneInstance {
                transform: singular,
                ..SceneInstance::of(0)
            },
            SceneInstance {
                transform: inf,
                ..SceneInstance::of(0)
            },
            SceneInstance {
                custom_index: 1 << 24,
                sbt_record_offset: 1 << 24,
                ..SceneInstance::of(0)
            },
            {
                let mut i = SceneInstance::of(0);
                i.flags.force_opaque = true;
                i.flags.force_no_opaque = true;
                i
            },
            // Inactive instances are fine.
            SceneInstance {
                bottom_level: None,
                ..SceneInstance::of(0)
            },
        ],
    };
    check(
        s.undefined(&[]),
        &[
            (
                ProblemKind::BottomLevelOutOfRange,
                "scene.instances[0].bottom_level",
            ),
            (
                ProblemKind::TransformSingular,
                "scene.instances[1].transform",
            ),
            (
                ProblemKind::TransformNotFinite,
                "scene.instances[2].transform",
            ),
            (
                ProblemKind::InstanceFieldTooWide,
                "scene.instances[3].custom_index",
            ),
            (
                ProblemKind::InstanceFieldTooWide,
                "scene.instances[3].sbt_record_offset",
            ),
            (
                ProblemKind::InstanceFlagsExclusive,
                "scene.instances[4].flags",
            ),
        ],
    );
    // The tracer refuses undefined scenes.
    assert!(model::tracer::PreparedScene::new(&s).is_err());
}

#[test]
fn a_nearly_singular_transform_is_not_singular() {
    // det = 2^-60, exactly representable only in exact arithmetic of the f32 entries.
    let tiny = 2f32.powi(-20);
    let m = Transform3x4([
        [tiny, 0.0, 0.0, 0.0],
        [0.0, tiny, 0.0, 0.0],
        [0.0, 0.0, tiny, 0.0],
    ]);
    let s = Scene {
        bottom_levels: vec![],
        instances: vec![SceneInstance {
            transform: m,
            bottom_level: None,
            ..SceneInstance::of(0)
        }],
    };
    check(s.undefined(&[]), &[]);
}

#[test]
fn scenes_read_from_readable_yaml_and_reject_unknown_fields() {
    let text = r#"
bottom_levels:
  - geometries:
      - flags: { opaque: true }
        data: !triangles
          positions: [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
          indices: !u16 [0, 1, 2]
      - data: !triangles
          positions: [[.nan, 0, 0], [1, 0, 0], [0, 1, 0]]
  - geometries:
      - data: !aabbs
          boxes: [{ min: [-1, -1, -1], max: [1, 1, 1] }]
          spheres: [{ center: [0, 0, 0], radius: 1 }]
instances:
  - bottom_level: 0
    transform: [[1, 0, 0, 2], [0, 1, 0, 0], [0, 0, 1, 0]]
    custom_index: 7
    flags: { flip_facing: true }
  - bottom_level: null
"#;
    let s: Scene = serde_yaml::from_str(text).expect("readable YAML");
    assert_eq!(s.instances.len(), 2);
    assert_eq!(s.instances[0].transform.0[0][3], 2.0);
    assert!(s.instances[0].flags.flip_facing);
    assert_eq!(s.instances[0].mask, 0xFF);
    assert!(s.undefined(&[]).is_empty());
    let back: Scene = serde_yaml::from_str(&serde_yaml::to_string(&s).unwrap()).unwrap();
    assert_eq!(format!("{back:?}"), format!("{s:?}"));
    let bad = text.replace("custom_index: 7", "custom_index: 7\n    colour: 3");
    let err = serde_yaml::from_str::<Scene>(&bad).unwrap_err().to_string();
    assert!(err.contains("colour"), "{err}");
    assert!(err.contains("line"), "{err}");
    // Rays read flags by name or number, and +inf as .inf.
    let ray: Ray = serde_yaml::from_str(
        "{ origin: [0, 0, 1], direction: [0, 0, -1], tmax: .inf, flags: [OPAQUE, CULL_BACK_FACING_TRIANGLES_KHR] }",
    )
    .unwrap();
    assert_eq!(
        ray.flags,
        RayFlags::OPAQUE | RayFlags::CULL_BACK_FACING_TRIANGLES
    );
    assert!(ray.tmax.is_infinite());
    let ray: Ray =
        serde_yaml::from_str("{ origin: [0, 0, 1], direction: [0, 0, -1], tmax: 1, flags: 5 }")
            .unwrap();
    assert_eq!(
        ray.flags,
        RayFlags::OPAQUE | RayFlags::TERMINATE_ON_FIRST_HIT
    );
    assert!(serde_yaml::from_str::<Ray>(
        "{ origin: [0, 0, 1], direction: [0, 0, -1], tmax: 1, flags: [OPAQ] }"
    )
    .is_err());
}
