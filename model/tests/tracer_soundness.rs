//! The f64 filter against exact arithmetic, and the BVH against brute force: on random geometry
//! (triangles, spheres, transforms with rotation, scale, mirror and translation) and random rays —
//! many aimed exactly at vertices and edge points with binary-fraction coordinates — every
//! classification the filter certifies equals the exact one, and the BVH finds exactly what testing
//! every primitive finds. Spheres in roomy boxes: the far test of a box's sphere leaves out nothing a
//! shader could report, and every report the harness's intersection shader makes in f32 is allowed.

mod tracer_common;

use model::scene::build::{similarity, SceneRng};
use model::scene::{
    Aabb, Aabbs, BottomLevel, Geometry, GeometryData, GeometryFlags, Ray, Scene, SceneInstance,
    Sphere, Transform3x4, Triangles,
};
use model::tracer::arith::{v3, BoundedF64, Dyadic, Num};
use model::tracer::band::{InstanceBand, TriangleBand};
use model::tracer::triangle::triangle_signs;
use model::tracer::{
    trace_ray, AllowedOutcomes, HitShaders, MissShader, Precision, PreparedScene, ShaderTable,
    TracerConfig, TracerStats,
};
use std::cmp::Ordering;

fn random_transform(rng: &mut SceneRng) -> Transform3x4 {
    match rng.below(4) {
        0 => Transform3x4::IDENTITY,
        1 => Transform3x4::translation([0, 1, 2].map(|_| rng.fraction(-8.0, 8.0, 4))),
        _ => {
            let axis = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(0.1, 1.0),
            ];
            let t = [0, 1, 2].map(|_| rng.range(-4.0, 4.0));
            let mut m = similarity(
                axis,
                rng.range(0.0, 6.3),
                rng.range(0.25, 4.0),
                rng.below(2) == 0,
                t,
            );
            if rng.below(2) == 0 {
                // Anisotropic: stretch one column.
                let c = rng.below(3) as usize;
                let s = rng.range(0.1, 10.0) as f32;
                for r in 0..3 {
                    m.0[r][c] *= s;
                }
            }
            m
        }
    }
}

/// A small random scene: a bottom level of triangles with shared vertices (a jittered grid with a
/// geometry transform on half the cases), one of boxes with spheres, and two or three instances.
fn random_scene(rng: &mut SceneRng) -> Scene {
    let n = 3;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let jitter = if rng.below(3) == 0 {
                0.0
            } else {
                rng.fraction(-0.25, 0.25, 6) as f64
            };
            positions.push([
                (i as f64 + jitter) as f32,
                (j as f64 + jitter * 0.5) as f32,
                rng.fraction(-0.5, 0.5, 5),
            ]);
        }
    }
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            indices.extend([a, a + 1, a + n + 2, a, a + n + 2, a + n + 1]);
        }
    }
    let transform = if rng.below(2) == 0 {
        Some(random_transform(rng))
    } else {
        None
    };
    let tris = BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags {
                opaque: rng.below(2) == 0,
                no_duplicate_any_hit: true,
            },
            data: GeometryData::Triangles(Triangles {
                positions,
                indices: Some(model::scene::Indices::U32(indices)),
                transform,
            }),
        }],
    };
    let mut boxes = Vec::new();
    let mut spheres = Vec::new();
    for _ in 0..3 {
        let c = [0, 1, 2].map(|_| rng.fraction(-2.0, 2.0, 4));
        let r = rng.fraction(0.25, 1.0, 4);
        spheres.push(Sphere {
            center: c,
            radius: r,
        });
        boxes.push(Aabb {
            min: c.map(|x| x - r - 0.125),
            max: c.map(|x| x + r + 0.125),
        });
    }
    let procedural = BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags::default(),
            data: GeometryData::Aabbs(Aabbs { boxes, spheres }),
        }],
    };
    let mut instances = vec![
        SceneInstance {
            transform: random_transform(rng),
            ..SceneInstance::of(0)
        },
        SceneInstance {
            transform: random_transform(rng),
            ..SceneInstance::of(1)
        },
    ];
    if rng.below(2) == 0 {
        instances.push(SceneInstance {
            transform: random_transform(rng),
            ..SceneInstance::of(0)
        });
    }
    Scene {
        bottom_levels: vec![tris, procedural],
        instances,
    }
}

/// World position (f64) of an object-space point of bottom level 0 seen through instance `i`.
fn world_point(scene: &Scene, i: usize, p: [f64; 3]) -> [f64; 3] {
    let GeometryData::Triangles(t) = &scene.bottom_levels[0].geometries[0].data else {
        unreachable!()
    };
    let p = match &t.transform {
        Some(g) => g.apply_f64(p),
        None => p,
    };
    scene.instances[i].transform.apply_f64(p)
}

/// Random rays: most aimed at a vertex, an edge point or an interior point of a random triangle
/// of a random triangle instance (so within or near the band), in binary-fraction directions;
/// others anywhere.
fn random_rays(rng: &mut SceneRng, scene: &Scene, count: usize) -> Vec<Ray> {
    let GeometryData::Triangles(t) = &scene.bottom_levels[0].geometries[0].data else {
        unreachable!()
    };
    let tri_instances: Vec<usize> = (0..scene.instances.len())
        .filter(|&i| scene.instances[i].bottom_level == Some(0))
        .collect();
    (0..count)
        .map(|_| {
            let target: [f32; 3] = if rng.below(5) == 0 {
                rng.point(-3.0, 5.0)
            } else {
                let inst = tri_instances[rng.below(tri_instances.len() as u64) as usize];
                let v = t
                    .vertices(rng.below(t.primitive_count() as u64) as usize)
                    .map(|p| p.map(|x| x as f64));
                let (b, c) = match rng.below(4) {
                    0 => ([0.0, 1.0][rng.below(2) as usize], 0.0),
                    1 => (0.5, 0.0),
                    2 => {
                        let eps =
                            10f64.powf(rng.range(-8.0, -3.0)) * [1.0, -1.0][rng.below(2) as usize];
                        (rng.unit(), eps)
                    }
                    _ => (rng.range(0.0, 0.5), rng.range(0.0, 0.5)),
                };
                let a = 1.0 - b - c;
                let p = [0, 1, 2].map(|k| a * v[0][k] + b * v[1][k] + c * v[2][k]);
                world_point(scene, inst, p).map(|x| x as f32)
            };
            let dir = match rng.below(3) {
                0 => [0.0, 0.0, -1.0],
                _ => [
                    rng.fraction(-1.0, 1.0, 8),
                    rng.fraction(-1.0, 1.0, 8),
                    rng.fraction(-1.0, -0.125, 8),
                ],
            };
            let dist = [1.0f32, 2.0, 4.0, 8.0][rng.below(4) as usize];
            let origin = [0, 1, 2].map(|k| target[k] - dist * dir[k]);
            let tmax = if rng.below(4) == 0 {
                dist
            } else {
                f32::INFINITY
            };
            let tmin = if rng.below(4) == 0 {
                rng.fraction(0.0, 1.0, 4)
            } else {
                0.0
            };
            Ray::new(origin, dir, tmin, tmax)
        })
        .collect()
}

/// The classification part of the outcomes: candidate, presence, hit kinds, and committability.
fn shape(out: &AllowedOutcomes) -> Vec<String> {
    out.candidates
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let kinds: Vec<u32> = c.reports.iter().map(|r| r.hit_kind).collect();
            format!(
                "{:?} {:?} {:?} commit={} req={:?}",
                c.primitive,
                c.presence,
                kinds,
                out.committable.contains(&i),
                c.reports.iter().map(|r| r.required).collect::<Vec<_>>()
            )
        })
        .chain(std::iter::once(format!(
            "{:?} {:?} {:?}",
            out.miss, out.any_hit, out.intersection
        )))
        .chain(
            out.watertight
                .iter()
                .map(|g| format!("{:?} {:?}", g.shape, g.members)),
        )
        .collect()
}

#[test]
fn filter_and_bvh_agree_with_exact_brute_force_on_random_scenes() {
    let mut rng = SceneRng(0x7261_7973);
    let hit = |i: u32, g: u32| {
        if i == 1 {
            HitShaders::procedural(i, None)
        } else {
            HitShaders::closest(10 * i + g)
        }
    };
    let table = ShaderTable {
        hit: &hit,
        miss: MissShader {
            zero_group: false,
            group: 99,
        },
    };
    let mut filtered = TracerStats::default();
    let mut exact = TracerStats::default();
    let mut unfiltered = TracerStats::default();
    let mut compared = 0;
    let mut candidates = 0;
    for _ in 0..100 {
        let scene = random_scene(&mut rng);
        let prepared = PreparedScene::new(&scene).expect("defined");
        for ray in random_rays(&mut rng, &scene, 60) {
            let f = trace_ray(
                &prepared,
                &ray,
                &table,
                &TracerConfig::default(),
                &mut filtered,
            )
            .unwrap();
            let e = trace_ray(
                &prepared,
                &ray,
                &table,
                &TracerConfig {
                    precision: Precision::ExactOnly,
                    use_bvh: false,
                    far_test: true,
                },
                &mut exact,
            )
            .unwrap();
            assert_eq!(
                shape(&f),
                shape(&e),
                "filter/BVH vs exact/brute force on {ray:?} in {scene:?}"
            );
            // The far test rejects nothing that full classification finds required.
            let all = trace_ray(
                &prepared,
                &ray,
                &table,
                &TracerConfig {
                    precision: Precision::ExactOnly,
                    use_bvh: false,
                    far_test: false,
                },
                &mut unfiltered,
            )
            .unwrap();
            for c in all
                .candidates
                .iter()
                .filter(|c| c.presence == model::tracer::Presence::Required)
            {
                assert!(
                    f.candidate(&c.primitive).is_some(),
                    "far test dropped {c:?} for {ray:?} in {scene:?}"
                );
            }
            compared += 1;
            candidates += f.candidates.len();
        }
    }
    assert_eq!(compared, 6000);
    // The rays aimed at shared points make the comparison meaningful.
    eprintln!("{candidates} candidates, filter {filtered:?}");
    assert!(candidates > 3000, "{candidates} candidates");
    assert!(filtered.vary > 1000, "{filtered:?}");
    assert!(filtered.req_hit > 1000, "{filtered:?}");
    assert_eq!(exact.exact_evaluations, exact.pair_tests);
    assert_eq!(unfiltered.far_rejections, 0);
    assert!(
        unfiltered.pair_tests > 2 * filtered.pair_tests,
        "{unfiltered:?}"
    );
    assert_eq!(
        filtered.filter_decided + filtered.exact_evaluations,
        filtered.pair_tests
    );
}

#[test]
fn the_filter_defers_to_exact_arithmetic_when_it_cannot_decide() {
    // A band constant equal to |e_0| exactly: e_0 − B_0 is exactly zero, which no error bound can
    // certify; the exact path decides it (neither strictly above nor below: Band).
    let w = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let o = [0.25f32, 0.25, 1.0];
    let d = [0.0f32, 0.0, -1.0];
    // e_0 = d·((w1 − o) × (w2 − o)) = −0.5 (computed by hand: (0.75,−0.25,−1)×(−0.25,0.75,−1)
    // = (1, 1, 0.5), dot (0,0,−1) = −0.5).
    let band = TriangleBand {
        edge: [0.5, 1e-9, 1e-9],
        sum: 1e-9,
        plane: 1e-9,
        t_rel: 0.0,
    };
    let bw = w.map(v3::<BoundedF64>);
    let filtered = triangle_signs::<BoundedF64>(&bw, &v3(o), &v3(d), 0.0, f32::INFINITY, &band);
    assert_eq!(filtered, None);
    let dw = w.map(v3::<Dyadic>);
    let (signs, values) =
        triangle_signs::<Dyadic>(&dw, &v3(o), &v3(d), 0.0, f32::INFINITY, &band).unwrap();
    assert_eq!(values.edge[0].0, -0.5);
    assert_eq!(signs.edges[0], model::tracer::triangle::EdgeSide::Band);
}

#[test]
fn overflowing_f64_falls_back_to_exact_arithmetic() {
    // Products of nine values near f32::MAX overflow f64 (3e38^9 > 1.8e308).
    let big = 3.0e38f32;
    let mut x = BoundedF64::from_f32(1.0);
    let mut e = Dyadic::from_f32(-1.0);
    for _ in 0..9 {
        x = x.mul(&BoundedF64::from_f32(big));
        e = e.mul(&Dyadic::from_f32(big));
    }
    assert_eq!(x.sign(), None);
    assert_eq!(e.sign(), Some(Ordering::Less));
}

#[test]
fn f32_only_mode_runs_and_counts() {
    let mut rng = SceneRng(5);
    let scene = random_scene(&mut rng);
    let prepared = PreparedScene::new(&scene).unwrap();
    let hit = |_: u32, _: u32| HitShaders::procedural(0, None);
    let table = ShaderTable {
        hit: &hit,
        miss: MissShader {
            zero_group: false,
            group: 0,
        },
    };
    let mut stats = TracerStats::default();
    for ray in random_rays(&mut rng, &scene, 50) {
        trace_ray(
            &prepared,
            &ray,
            &table,
            &TracerConfig::with_precision(Precision::F32FilterOnly),
            &mut stats,
        )
        .unwrap();
    }
    assert_eq!(stats.f32_evaluations, stats.pair_tests);
    assert!(stats.pair_tests > 0);
}

/// Spheres in boxes far larger than they are (each side of a box `r/2` to `3r` beyond its sphere,
/// so most of a box is empty), under the random instance transforms above.
fn roomy_spheres(rng: &mut SceneRng) -> Scene {
    let mut boxes = Vec::new();
    let mut spheres = Vec::new();
    for _ in 0..6 {
        let c = [0, 1, 2].map(|_| rng.fraction(-3.0, 3.0, 4));
        let r = rng.fraction(0.125, 0.75, 6);
        let mut slack = || r * rng.fraction(0.5, 3.0, 2);
        boxes.push(Aabb {
            min: [0, 1, 2].map(|k| c[k] - r - slack()),
            max: [0, 1, 2].map(|k| c[k] + r + slack()),
        });
        spheres.push(Sphere {
            center: c,
            radius: r,
        });
    }
    let level = BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags::default(),
            data: GeometryData::Aabbs(Aabbs { boxes, spheres }),
        }],
    };
    let instances = (0..2 + rng.below(2) as u32)
        .map(|_| SceneInstance {
            transform: random_transform(rng),
            ..SceneInstance::of(0)
        })
        .collect();
    Scene {
        bottom_levels: vec![level],
        instances,
    }
}

/// Rays at the spheres of [`roomy_spheres`]: most aimed at a point of a sphere's surface moved in
/// or out by a relative 10⁻⁹ to 10⁻² (grazing rays, within and beyond the band), some at a box's
/// corner region (through the box, clear of its sphere), some anywhere.
fn rays_at_spheres(rng: &mut SceneRng, scene: &Scene, count: usize) -> Vec<Ray> {
    let GeometryData::Aabbs(a) = &scene.bottom_levels[0].geometries[0].data else {
        unreachable!()
    };
    (0..count)
        .map(|_| {
            let inst = &scene.instances[rng.below(scene.instances.len() as u64) as usize];
            let k = rng.below(a.spheres.len() as u64) as usize;
            let (s, b) = (&a.spheres[k], &a.boxes[k]);
            let object: [f64; 3] = match rng.below(5) {
                0 => rng.point(-4.0, 4.0).map(f64::from),
                1 => [0, 1, 2].map(|j| {
                    let t = rng.range(0.0, 0.1);
                    f64::from(b.min[j]) * (1.0 - t) + f64::from(b.max[j]) * t
                }),
                2 => {
                    // A pole (where the sphere touches its own box), moved out or in.
                    let mut u = [0.0; 3];
                    u[rng.below(3) as usize] = [1.0, -1.0][rng.below(2) as usize];
                    let nudge =
                        10f64.powf(rng.range(-9.0, -2.0)) * [1.0, -1.0][rng.below(2) as usize];
                    let r = f64::from(s.radius) * (1.0 + nudge);
                    [0, 1, 2].map(|j| f64::from(s.center[j]) + r * u[j])
                }
                _ => {
                    let u = [0; 3].map(|_| rng.range(-1.0, 1.0));
                    let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt().max(1e-3);
                    let nudge =
                        10f64.powf(rng.range(-9.0, -2.0)) * [1.0, -1.0][rng.below(2) as usize];
                    let r = f64::from(s.radius) * (1.0 + nudge);
                    [0, 1, 2].map(|j| f64::from(s.center[j]) + r * u[j] / n)
                }
            };
            let target = inst.transform.apply_f64(object).map(|x| x as f32);
            let dir = [0; 3].map(|_| rng.fraction(-1.0, 1.0, 8));
            let dir = if dir == [0.0; 3] {
                [0.0, 0.0, 1.0]
            } else {
                dir
            };
            let dist = [0.5f32, 2.0, 8.0][rng.below(3) as usize];
            let origin = [0, 1, 2].map(|j| target[j] - dist * dir[j]);
            let tmax = if rng.below(4) == 0 {
                dist
            } else {
                f32::INFINITY
            };
            Ray::new(origin, dir, 0.0, tmax)
        })
        .collect()
}

#[test]
fn a_sphere_far_box_leaves_out_only_pairs_that_give_nothing() {
    // The far box of a procedural primitive is its sphere's, padded: the sphere is all the
    // intersection shader reports and all that makes it required to run. Against classifying every
    // pair in full, on grazing rays and on rays through the empty part of a box, the far test (and
    // the BVH) changes no pair it keeps and no intersection count, and leaves out only pairs whose
    // reports could not fall between tmin and tmax.
    let mut rng = SceneRng(0x5fe7_e5b0);
    let mut tested = TracerStats::default();
    let mut full = TracerStats::default();
    let (mut reports, mut must_run) = (0, 0);
    for case in 0..200 {
        let scene = roomy_spheres(&mut rng);
        let prepared = PreparedScene::new(&scene).expect("defined");
        // Any-hit on half the scenes: every intersection along the ray is then observable.
        let any_hit = (case % 2 == 0).then_some(model::tracer::AnyHitRule::Ignore);
        let hit = move |i: u32, _g: u32| HitShaders::procedural(i, any_hit);
        let table = ShaderTable {
            hit: &hit,
            miss: MissShader {
                zero_group: false,
                group: 7,
            },
        };
        for ray in rays_at_spheres(&mut rng, &scene, 50) {
            let a = trace_ray(
                &prepared,
                &ray,
                &table,
                &TracerConfig::default(),
                &mut tested,
            )
            .expect("defined ray");
            let b = trace_ray(
                &prepared,
                &ray,
                &table,
                &TracerConfig {
                    far_test: false,
                    use_bvh: false,
                    ..TracerConfig::default()
                },
                &mut full,
            )
            .expect("defined ray");
            // What the far test keeps is classified as in full; what it leaves out is nothing
            // required, and nothing a shader could report between tmin and tmax (the full
            // classification allows a grazing pair's reports wherever its line passes).
            for x in &a.candidates {
                assert_eq!(b.candidate(&x.primitive), Some(x), "{ray:?} in {scene:?}");
            }
            for x in &b.candidates {
                if a.candidate(&x.primitive).is_none() {
                    assert!(
                        x.presence != model::tracer::Presence::Required
                            && x.reports
                                .iter()
                                .all(|r| r.t.hi < f64::from(ray.tmin)
                                    || r.t.lo > f64::from(ray.tmax)),
                        "far test left out {x:?} for {ray:?} in {scene:?}"
                    );
                }
            }
            assert_eq!(a.intersection, b.intersection, "{ray:?} in {scene:?}");
            reports += a.candidates.len();
            must_run += usize::from(a.intersection.min > 0);
        }
    }
    eprintln!("{reports} candidates, {must_run} must run; {tested:?} against {full:?}");
    // The rays meet spheres, some must run the shader, and the far test left out many pairs.
    assert!(reports > 3000, "{reports} candidates");
    assert!(must_run > 2000, "{must_run} rays must run an intersection");
    assert!(
        tested.pair_tests * 2 < full.pair_tests,
        "{tested:?} against {full:?}"
    );
}

/// The harness's intersection shader (see `model::tracer::sphere`) run in f32 on the ray as one
/// conformant implementation hands it over: the instance's inverse rounded to f32 and applied in
/// f32. The report it makes, if any, as (HitKind, t), kept only where `reportIntersectionEXT`
/// accepts it (tmin ≤ t ≤ tmax).
fn f32_shader(transform: &Transform3x4, sphere: &Sphere, ray: &Ray) -> Option<(u32, f32)> {
    // The instance's f64 inverse (as the band takes it), rounded to f32.
    let inv = InstanceBand::new(transform)
        .a_inv
        .map(|r| r.map(|x| x as f32));
    let t = [0, 1, 2].map(|k| transform.0[k][3]);
    let mul =
        |v: [f32; 3]| [0, 1, 2].map(|i| inv[i][0] * v[0] + inv[i][1] * v[1] + inv[i][2] * v[2]);
    let o = mul([0, 1, 2].map(|k| ray.origin[k] - t[k]));
    let d = mul(ray.direction);
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let oc = [0, 1, 2].map(|k| o[k] - sphere.center[k]);
    let a = dot(d, d);
    let tc = -dot(oc, d) / a;
    let pc = [0, 1, 2].map(|k| oc[k] + tc * d[k]);
    let disc = sphere.radius * sphere.radius - dot(pc, pc);
    if disc < 0.0 {
        return None;
    }
    let s = (disc / a).sqrt();
    let (kind, t_hit) = if tc - s >= ray.tmin {
        (0, tc - s)
    } else {
        (1, tc + s)
    };
    (ray.tmin <= t_hit && t_hit <= ray.tmax).then_some((kind, t_hit))
}

#[test]
fn an_f32_sphere_shader_reports_only_what_the_outcomes_allow() {
    // On grazing rays, rays through a box's empty part and random ones, under rotation, scale,
    // mirror and translation: every report the f32 shader makes is among the pair's allowed
    // reports, its t inside the report's enclosure — grazing pairs included, whose reports the
    // outcomes allow only between tmin and tmax.
    let mut rng = SceneRng(0x6772_617a);
    let proc = |i: u32, _g: u32| HitShaders::procedural(i, None);
    let table = ShaderTable {
        hit: &proc,
        miss: MissShader {
            zero_group: false,
            group: 7,
        },
    };
    let (mut made, mut grazing) = (0, 0);
    for _ in 0..150 {
        let scene = roomy_spheres(&mut rng);
        let prepared = PreparedScene::new(&scene).expect("defined");
        let GeometryData::Aabbs(a) = &scene.bottom_levels[0].geometries[0].data else {
            unreachable!()
        };
        for ray in rays_at_spheres(&mut rng, &scene, 40) {
            let mut stats = TracerStats::default();
            let out = trace_ray(
                &prepared,
                &ray,
                &table,
                &TracerConfig::default(),
                &mut stats,
            )
            .expect("defined ray");
            for (i, inst) in scene.instances.iter().enumerate() {
                for (k, sphere) in a.spheres.iter().enumerate() {
                    let Some((kind, t)) = f32_shader(&inst.transform, sphere, &ray) else {
                        continue;
                    };
                    made += 1;
                    let p = model::tracer::PrimitiveRef {
                        instance: i as u32,
                        geometry: 0,
                        primitive: k as u32,
                    };
                    let c = out.candidate(&p);
                    grazing += usize::from(
                        c.is_some_and(|c| c.presence == model::tracer::Presence::Possible),
                    );
                    assert!(
                        c.is_some_and(|c| c
                            .reports
                            .iter()
                            .any(|r| r.hit_kind == kind && r.t.contains(f64::from(t)))),
                        "kind {kind} at t = {t} of {p:?} for {ray:?}: {c:?} in {scene:?}"
                    );
                }
            }
        }
    }
    eprintln!("{made} reports, {grazing} of pairs the outcomes allow but do not require");
    assert!(made > 2000, "{made} reports");
    assert!(grazing > 20, "{grazing} grazing reports");
}
