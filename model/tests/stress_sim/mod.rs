//! A simulated f32 driver for the stress tests: every instance's ray carried into object space
//! through an f32 cofactor inverse, geometry transforms applied to vertices in f32, and Woop,
//! Benthin and Wald's watertight ray/triangle test (written here from the paper's description)
//! with a top-left rule for edge functions that are exactly zero, so that a shared edge or vertex
//! belongs to exactly one triangle. It writes the [`RayRecord`] a driver's shaders would.
#![allow(dead_code)]

use model::scene::{GeometryData, Ray, RayFlags, Scene, Transform3x4};
use model::stress::{StressCase, STRESS_MISS_GROUP};
use model::tracer::record::{RayRecord, RecordOutcome, SeenCandidate};

type V = [f32; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: V, b: V) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The f32 inverse of a 3x4 transform by cofactors.
pub fn inverse_f32(m: &Transform3x4) -> ([[f32; 3]; 3], V) {
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

fn apply(m: &[[f32; 3]; 3], t: V, p: V) -> V {
    [0, 1, 2].map(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + t[r])
}

fn affine(m: &Transform3x4, p: V) -> V {
    [0, 1, 2].map(|r| m.0[r][0] * p[0] + m.0[r][1] * p[1] + m.0[r][2] * p[2] + m.0[r][3])
}

/// A hit: t and the weights (b, c) of vertex 1 and vertex 2.
#[derive(Debug, Clone, Copy)]
pub struct SimHit {
    pub t: f32,
    pub b: f32,
    pub c: f32,
}

/// `x1·y2 − y1·x2`, recomputed in f64 when f32 gives exactly zero (Woop et al., section 3).
fn edge(p: (f32, f32), q: (f32, f32)) -> f32 {
    let e = p.0 * q.1 - p.1 * q.0;
    if e != 0.0 {
        return e;
    }
    (p.0 as f64 * q.1 as f64 - p.1 as f64 * q.0 as f64) as f32
}

/// The watertight test with a top-left rule on exactly-zero edge functions.
pub fn woop(o: V, d: V, v: [V; 3], tmin: f32, tmax: f32) -> Option<SimHit> {
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
    let a = v.map(|w| sub(w, o));
    let p = a.map(|x| (x[kx] - sx * x[kz], x[ky] - sy * x[kz]));
    let e = [0, 1, 2].map(|i| edge(p[(i + 1) % 3], p[(i + 2) % 3]));
    let det = e[0] + e[1] + e[2];
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let s = det.signum();
    for i in 0..3 {
        if e[i] * s < 0.0 || e[i].is_nan() {
            return None;
        }
        if e[i] == 0.0 {
            // The edge from p[i+1] to p[i+2], as if the triangle were counter-clockwise: owned
            // when it runs downward, or leftward along a horizontal.
            let (from, to) = (p[(i + 1) % 3], p[(i + 2) % 3]);
            let (ex, ey) = ((to.0 - from.0) * s, (to.1 - from.1) * s);
            if !(ey < 0.0 || (ey == 0.0 && ex < 0.0)) {
                return None;
            }
        }
    }
    let z = a.map(|x| sz * x[kz]);
    let t = (e[0] * z[0] + e[1] * z[1] + e[2] * z[2]) / det;
    if !(t > tmin && t < tmax) {
        return None;
    }
    Some(SimHit {
        t,
        b: e[1] / det,
        c: e[2] / det,
    })
}

/// One candidate the simulated traversal found.
#[derive(Debug, Clone, Copy)]
struct Found {
    instance: u32,
    custom_index: u32,
    geometry: u32,
    primitive: u32,
    front: bool,
    hit: SimHit,
}

/// The record the simulated driver writes for one ray, with the stress shader table (non-opaque
/// geometry, any-hit accepting, closest-hit everywhere). Candidates are processed in scene order;
/// each one nearer than the current closest runs any-hit and becomes the closest.
pub fn trace(scene: &Scene, ray: &Ray) -> RayRecord {
    let mut found: Vec<Found> = Vec::new();
    for (i, inst) in scene.instances.iter().enumerate() {
        let Some(b) = inst.bottom_level else { continue };
        if inst.mask as u32 & ray.cull_mask & 0xFF == 0 {
            continue;
        }
        let (inv, ti) = inverse_f32(&inst.transform);
        let o = apply(&inv, ti, ray.origin);
        let d = apply(&inv, [0.0; 3], ray.direction);
        for (g, geometry) in scene.bottom_levels[b as usize]
            .geometries
            .iter()
            .enumerate()
        {
            let GeometryData::Triangles(t) = &geometry.data else {
                continue;
            };
            for p in 0..t.primitive_count() {
                if t.is_inactive(p) {
                    continue;
                }
                let v = t.vertices(p).map(|x| match &t.transform {
                    Some(m) => affine(m, x),
                    None => x,
                });
                let Some(hit) = woop(o, d, v, ray.tmin, ray.tmax) else {
                    continue;
                };
                let front = (dot(d, cross(sub(v[1], v[0]), sub(v[2], v[0]))) < 0.0)
                    != inst.flags.flip_facing;
                if !inst.flags.triangle_facing_cull_disable
                    && ((ray.flags.contains(RayFlags::CULL_BACK_FACING_TRIANGLES) && !front)
                        || (ray.flags.contains(RayFlags::CULL_FRONT_FACING_TRIANGLES) && front))
                {
                    continue;
                }
                found.push(Found {
                    instance: i as u32,
                    custom_index: inst.custom_index,
                    geometry: g as u32,
                    primitive: p as u32,
                    front,
                    hit,
                });
            }
        }
    }
    let mut closest: Option<Found> = None;
    let mut seen = Vec::new();
    let mut any_hit_count = 0;
    for f in found {
        // A candidate at exactly the current closest t still runs any-hit (the spec lets it).
        if closest.is_some_and(|c| f.hit.t > c.hit.t) {
            continue;
        }
        any_hit_count += 1;
        if seen.len() < RayRecord::SEEN_SLOTS {
            seen.push(SeenCandidate {
                instance: f.instance,
                geometry: f.geometry,
                primitive: f.primitive,
                t: f.hit.t,
            });
        }
        closest = Some(f);
    }
    match closest {
        None => RayRecord::miss(STRESS_MISS_GROUP),
        Some(c) => RayRecord {
            outcome: RecordOutcome::Hit,
            group: Some(10 * c.instance + c.geometry),
            instance_id: c.instance,
            custom_index: c.custom_index,
            geometry_index: c.geometry,
            primitive_id: c.primitive,
            hit_kind: if c.front { 0xFE } else { 0xFF },
            t: c.hit.t,
            barycentrics: [c.hit.b, c.hit.c],
            any_hit_count,
            intersection_count: 0,
            seen,
        },
    }
}

/// The records of every ray of a case.
pub fn records(case: &StressCase) -> Vec<RayRecord> {
    case.rays.iter().map(|r| trace(&case.scene, r)).collect()
}
