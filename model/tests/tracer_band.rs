//! The band against simulated conformant implementations: two f32 ray/triangle tests written here
//! from their papers' descriptions (Woop, Benthin, Wald's watertight test; Möller–Trumbore), each
//! behind an instance transform inverted in f32 by cofactors and a geometry transform applied in
//! f32, must never contradict a REQ classification — every REQ-hit is hit with t and barycentrics
//! inside their intervals, every REQ-miss is missed — on rays aimed within 1e-8..1e-2 of edges and
//! vertices of randomly transformed triangles.

mod tracer_common;

use model::scene::build::{similarity, SceneRng};
use model::scene::{
    BottomLevel, Geometry, GeometryData, GeometryFlags, Ray, Scene, SceneInstance, Transform3x4,
    Triangles,
};
use model::tracer::{
    trace_ray, HitShaders, MissShader, PreparedScene, Presence, ShaderTable, TracerConfig,
    TracerStats,
};

type V = [f32; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// f32 inverse of the 3x4 transform by cofactors, as an implementation building its instances
/// might compute it.
fn inverse_f32(m: &Transform3x4) -> ([[f32; 3]; 3], V) {
    let a = |r: usize, c: usize| m.0[r][c];
    let c = |r0, c0, r1, c1| a(r0, c0) * a(r1, c1) - a(r0, c1) * a(r1, c0);
    let adj = [
        [c(1, 1, 2, 2), c(0, 2, 2, 1), c(0, 1, 1, 2)],
        [c(1, 2, 2, 0), c(0, 0, 2, 2), c(0, 2, 1, 0)],
        [c(1, 0, 2, 1), c(0, 1, 2, 0), c(0, 0, 1, 1)],
    ];
    let det = a(0, 0) * adj[0][0] + a(0, 1) * adj[1][0] + a(0, 2) * adj[2][0];
    let inv = adj.map(|r| r.map(|x| x / det));
    let t = [a(0, 3), a(1, 3), a(2, 3)];
    let ti = [0, 1, 2].map(|r| -(inv[r][0] * t[0] + inv[r][1] * t[1] + inv[r][2] * t[2]));
    (inv, ti)
}

fn apply_f32(m: &[[f32; 3]; 3], t: V, p: V) -> V {
    [0, 1, 2].map(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + t[r])
}

/// A hit: t and the weights (b, c) of vertex 1 and vertex 2.
#[derive(Debug, Clone, Copy)]
struct SimHit {
    t: f32,
    b: f32,
    c: f32,
}

/// Woop, Benthin, Wald (JCGT 2013): permute so the ray's largest direction component is z, shear
/// to make the ray the z axis, 2D edge functions with a double-precision retry at zero, accept when
/// all share a sign.
fn woop(o: V, d: V, v: [V; 3], tmin: f32, tmax: f32) -> Option<SimHit> {
    let abs = d.map(f32::abs);
    let kz = if abs[0] > abs[1] {
        if abs[0] > abs[2] {
            0
        } else {
            2
        }
    } else if abs[1] > abs[2] {
        1
    } else {
        2
    };
    let mut kx = (kz + 1) % 3;
    let mut ky = (kx + 1) % 3;
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let sx = d[kx] / d[kz];
    let sy = d[ky] / d[kz];
    let sz = 1.0 / d[kz];
    let a = sub(v[0], o);
    let b = sub(v[1], o);
    let c = sub(v[2], o);
    let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
    let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
    let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
    let mut u = cx * by - cy * bx;
    let mut vv = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || vv == 0.0 || w == 0.0 {
        let f = |p: f32, q: f32, r: f32, s: f32| (p as f64 * q as f64 - r as f64 * s as f64) as f32;
        u = f(cx, by, cy, bx);
        vv = f(ax, cy, ay, cx);
        w = f(bx, ay, by, ax);
    }
    if (u < 0.0 || vv < 0.0 || w < 0.0) && (u > 0.0 || vv > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + vv + w;
    if det == 0.0 {
        return None;
    }
    let (az, bz, cz) = (sz * a[kz], sz * b[kz], sz * c[kz]);
    let t = (u * az + vv * bz + w * cz) / det;
    if !(t > tmin && t < tmax) {
        return None;
    }
    Some(SimHit {
        t,
        b: vv / det,
        c: w / det,
    })
}

/// Möller–Trumbore (1997) without an epsilon: a zero determinant misses.
fn moller(o: V, d: V, v: [V; 3], tmin: f32, tmax: f32) -> Option<SimHit> {
    let cross = |a: V, b: V| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: V, b: V| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let e1 = sub(v[1], v[0]);
    let e2 = sub(v[2], v[0]);
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(o, v[0]);
    let b = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&b) {
        return None;
    }
    let q = cross(s, e1);
    let c = dot(d, q) * inv;
    if c < 0.0 || b + c > 1.0 {
        return None;
    }
    let t = dot(e2, q) * inv;
    if !(t > tmin && t < tmax) {
        return None;
    }
    Some(SimHit { t, b, c })
}

type Test = fn(V, V, [V; 3], f32, f32) -> Option<SimHit>;

/// The whole simulated implementation: geometry transform at build, ray into object space.
fn simulate(test: Test, scene: &Scene, ray: &Ray) -> Option<SimHit> {
    let GeometryData::Triangles(t) = &scene.bottom_levels[0].geometries[0].data else {
        unreachable!()
    };
    let v = t.vertices(0).map(|p| match &t.transform {
        Some(g) => apply_f32(
            &[0, 1, 2].map(|r| [g.0[r][0], g.0[r][1], g.0[r][2]]),
            [g.0[0][3], g.0[1][3], g.0[2][3]],
            p,
        ),
        None => p,
    });
    let (inv, ti) = inverse_f32(&scene.instances[0].transform);
    let o = apply_f32(&inv, ti, ray.origin);
    let d = apply_f32(&inv, [0.0; 3], ray.direction);
    test(o, d, v, ray.tmin, ray.tmax)
}

fn random_case(rng: &mut SceneRng) -> (Scene, Vec<Ray>) {
    // Triangles from 2 down to 1e-3 across, seen from up to 200 away.
    let size = 10f64.powf(rng.range(-3.0, 0.3));
    let centre = rng.point(-2.0, 2.0);
    let v = [0, 1, 2]
        .map(|_| [0, 1, 2].map(|k| (centre[k] as f64 + size * rng.range(-1.0, 1.0)) as f32));
    let geometry_transform = (rng.below(2) == 0).then(|| {
        similarity(
            [rng.range(-1.0, 1.0), 1.0, rng.range(-1.0, 1.0)],
            rng.range(0.0, 6.3),
            rng.range(0.3, 3.0),
            rng.below(2) == 0,
            [0, 1, 2].map(|_| rng.range(-2.0, 2.0)),
        )
    });
    let mut instance = similarity(
        [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 1.0],
        rng.range(0.0, 6.3),
        rng.range(0.2, 5.0),
        rng.below(2) == 0,
        [0, 1, 2].map(|_| rng.range(-50.0, 50.0)),
    );
    if rng.below(2) == 0 {
        let col = rng.below(3) as usize;
        let s = rng.range(0.2, 5.0) as f32;
        for r in 0..3 {
            instance.0[r][col] *= s;
        }
    }
    if rng.below(4) == 0 {
        instance = Transform3x4::IDENTITY;
    }
    let scene = Scene {
        bottom_levels: vec![BottomLevel {
            geometries: vec![Geometry {
                flags: GeometryFlags {
                    opaque: true,
                    no_duplicate_any_hit: false,
                },
                data: GeometryData::Triangles(Triangles {
                    positions: v.to_vec(),
                    indices: None,
                    transform: geometry_transform,
                }),
            }],
        }],
        instances: vec![SceneInstance {
            transform: instance,
            ..SceneInstance::of(0)
        }],
    };
    // World vertices in f64, to aim at.
    let w = v.map(|p| {
        let p = p.map(|x| x as f64);
        let p = geometry_transform.map_or(p, |g| g.apply_f64(p));
        instance.apply_f64(p)
    });
    let rays = (0..40)
        .map(|_| {
            // Barycentrics near an edge or vertex, some just outside.
            let eps = 10f64.powf(rng.range(-8.0, -2.0)) * [1.0, -1.0][rng.below(2) as usize];
            let (b, c) = match rng.below(3) {
                0 => (rng.unit(), eps),
                1 => (eps, eps * rng.range(-1.0, 1.0)),
                _ => {
                    let b = rng.range(0.05, 0.9);
                    (b, rng.range(0.05, 0.95 - b))
                }
            };
            let a = 1.0 - b - c;
            let p = [0, 1, 2].map(|k| a * w[0][k] + b * w[1][k] + c * w[2][k]);
            let dir = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ];
            let dist = 10f64.powf(rng.range(-0.3, 2.3));
            let origin = [0, 1, 2].map(|k| (p[k] - dist * dir[k]) as f32);
            let tmax = if rng.below(5) == 0 {
                (dist * rng.range(0.9, 1.1)) as f32
            } else {
                f32::INFINITY
            };
            Ray::new(origin, dir.map(|x| x as f32), 0.0, tmax)
        })
        .collect();
    (scene, rays)
}

#[test]
fn simulated_f32_implementations_never_contradict_a_req_classification() {
    let mut rng = SceneRng(0xBA4D);
    let hit = |_: u32, _: u32| HitShaders::closest(0);
    let table = ShaderTable {
        hit: &hit,
        miss: MissShader {
            zero_group: false,
            group: 1,
        },
    };
    let mut stats = TracerStats::default();
    let (mut req_hits, mut req_misses, mut vary) = (0, 0, 0);
    let mut vary_disagreements = 0;
    // The largest error seen relative to the band's half width (1.0 = at the band's edge).
    let (mut worst_t, mut worst_b) = (0.0f64, 0.0f64);
    for _ in 0..400 {
        let (scene, rays) = random_case(&mut rng);
        let prepared = PreparedScene::new(&scene).expect("defined");
        for ray in &rays {
            let out =
                trace_ray(&prepared, ray, &table, &TracerConfig::default(), &mut stats).unwrap();
            for (name, test) in [("woop", woop as Test), ("moller", moller as Test)] {
                let sim = simulate(test, &scene, ray);
                match out.candidates.first() {
                    None => {
                        req_misses += 1;
                        assert!(
                            sim.is_none(),
                            "{name} hit a REQ-miss: {sim:?} for {ray:?} in {scene:?}"
                        );
                    }
                    Some(c) if c.presence == Presence::Required => {
                        req_hits += 1;
                        let h = sim.unwrap_or_else(|| {
                            panic!("{name} missed a REQ-hit: {ray:?} in {scene:?}")
                        });
                        let r = &c.reports[0];
                        let bary = r.barycentrics.unwrap();
                        assert!(
                            r.t.contains(h.t as f64),
                            "{name}: t {} outside {:?}",
                            h.t,
                            r.t
                        );
                        worst_t = worst_t.max((h.t as f64 - r.t_exact).abs() / r.t.radius());
                        let be = r.barycentrics_exact.unwrap();
                        worst_b = worst_b.max((h.b as f64 - be[0]).abs() / bary[0].radius());
                        assert!(
                            bary[0].contains(h.b as f64),
                            "{name}: b {} outside {:?}",
                            h.b,
                            bary[0]
                        );
                        assert!(
                            bary[1].contains(h.c as f64),
                            "{name}: c {} outside {:?}",
                            h.c,
                            bary[1]
                        );
                    }
                    Some(c) => {
                        vary += 1;
                        if let Some(h) = sim {
                            let r = &c.reports[0];
                            if !r.t.contains(h.t as f64) {
                                vary_disagreements += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    eprintln!("worst t error / bound {worst_t:.3e}, worst b error / bound {worst_b:.3e}");
    assert!(worst_t < 1.0 && worst_b < 1.0);
    eprintln!("REQ-hit {req_hits}, REQ-miss {req_misses}, VARY {vary} (t outside the band on VARY: {vary_disagreements}); {stats:?}");
    assert!(req_hits > 4000 && req_misses > 2500 && vary > 1000);
}
