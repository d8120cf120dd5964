//! The exact arithmetic behind [`super::Claim::check`]: world-space triangles as dyadic
//! rationals, the edge functions and plane distance of a ray, and the topological checks (closed
//! meshes, closed fans, exact translations).

use super::claims::{ClaimError, Member};
use super::StressCase;
use crate::scene::{GeometryData, Ray, Scene, Transform3x4};
use crate::tracer::arith::{affine, cross3, dot3, linear, sub3, triple, v3, Dyadic, Num, V3};
use std::cmp::Ordering;
use std::collections::HashMap;

pub(super) type X = Dyadic;

/// What identifies the triangles of a bottom level an index was built from: per geometry, where
/// its positions and indices live and how many there are.
type Fingerprint = Vec<(usize, usize, usize, usize)>;

fn fingerprint(scene: &Scene, bottom_level: u32) -> Fingerprint {
    let Some(bl) = scene.bottom_levels.get(bottom_level as usize) else {
        return Vec::new();
    };
    bl.geometries
        .iter()
        .map(|g| match &g.data {
            GeometryData::Triangles(t) => (
                t.positions.as_ptr() as usize,
                t.positions.len(),
                t.primitive_count(),
                1,
            ),
            GeometryData::Aabbs(_) => (0, 0, 0, 0),
        })
        .collect()
}

/// The triangles around each vertex (by its bits) of a bottom level, built once and asked per
/// vertex claim: a fan's "every triangle around the vertex" check is then the vertex's list, not
/// a pass over a million triangles per ray. Rebuilt whenever the bottom level it was built from
/// is not the one asked about (see `Fingerprint`); [`super::StressCase::check_claims`] uses a
/// fresh one, so the final proof never rests on a stale index.
#[derive(Debug, Default)]
pub struct FanIndex {
    built: HashMap<u32, (Fingerprint, AroundVertex)>,
}

/// The triangles with a vertex of these bits.
type AroundVertex = HashMap<[u32; 3], Vec<Member>>;

impl FanIndex {
    /// The triangles of `bottom_level` with a vertex of bits `vertex`.
    pub(super) fn around(
        &mut self,
        scene: &Scene,
        bottom_level: u32,
        vertex: [u32; 3],
    ) -> &[Member] {
        let print = fingerprint(scene, bottom_level);
        let stale = self
            .built
            .get(&bottom_level)
            .is_none_or(|(f, _)| *f != print);
        if stale {
            let mut map: AroundVertex = HashMap::new();
            if let Some(bl) = scene.bottom_levels.get(bottom_level as usize) {
                for (g, geometry) in bl.geometries.iter().enumerate() {
                    let GeometryData::Triangles(t) = &geometry.data else {
                        continue;
                    };
                    for p in 0..t.primitive_count() {
                        let mut keys = t.vertices(p).map(key);
                        keys.sort_unstable();
                        for (i, k) in keys.iter().enumerate() {
                            if i == 0 || keys[i - 1] != *k {
                                map.entry(*k).or_default().push((g as u32, p as u32));
                            }
                        }
                    }
                }
            }
            self.built.insert(bottom_level, (print, map));
        }
        self.built
            .get(&bottom_level)
            .and_then(|(_, m)| m.get(&vertex))
            .map_or(&[], |v| v.as_slice())
    }
}

pub(super) fn err<T>(claim: &'static str, problem: impl Into<String>) -> Result<T, ClaimError> {
    Err(ClaimError {
        claim,
        problem: problem.into(),
    })
}

pub(super) fn sign(x: &X) -> Ordering {
    x.sign().expect("exact")
}

pub(super) fn cmp(a: &X, b: &X) -> Ordering {
    sign(&a.sub(b))
}

pub(super) fn xf(x: f64) -> X {
    X::from_f64(x)
}

pub(super) fn ray_of<'a>(
    case: &'a StressCase,
    ray: u32,
    claim: &'static str,
) -> Result<&'a Ray, ClaimError> {
    match case.rays.get(ray as usize) {
        Some(r) => Ok(r),
        None => err(claim, format!("no ray {ray}")),
    }
}

/// The object-space (pre-transform) vertices of a member, and the geometry transform.
pub(super) fn object_triangle(
    scene: &Scene,
    bottom_level: u32,
    m: Member,
    claim: &'static str,
) -> Result<([[f32; 3]; 3], Option<Transform3x4>), ClaimError> {
    let Some(bl) = scene.bottom_levels.get(bottom_level as usize) else {
        return err(claim, format!("no bottom level {bottom_level}"));
    };
    let Some(GeometryData::Triangles(t)) = bl.geometries.get(m.0 as usize).map(|g| &g.data) else {
        return err(
            claim,
            format!("geometry {} is not a triangle geometry", m.0),
        );
    };
    if m.1 as usize >= t.primitive_count() {
        return err(claim, format!("no primitive {} in geometry {}", m.1, m.0));
    }
    Ok((t.vertices(m.1 as usize), t.transform))
}

pub(super) fn instance_bottom_level(
    scene: &Scene,
    instance: u32,
    claim: &'static str,
) -> Result<u32, ClaimError> {
    match scene
        .instances
        .get(instance as usize)
        .and_then(|i| i.bottom_level)
    {
        Some(b) => Ok(b),
        None => err(claim, format!("instance {instance} is missing or inactive")),
    }
}

/// The exact world-space vertices of a member of an instance.
pub(super) fn world_triangle(
    scene: &Scene,
    instance: u32,
    m: Member,
    claim: &'static str,
) -> Result<[V3<X>; 3], ClaimError> {
    let b = instance_bottom_level(scene, instance, claim)?;
    let (v, g) = object_triangle(scene, b, m, claim)?;
    let inst = &scene.instances[instance as usize].transform;
    Ok(v.map(|p| {
        let p = v3::<X>(p);
        let p = match &g {
            Some(g) => affine(&g.0, &p),
            None => p,
        };
        affine(&inst.0, &p)
    }))
}

/// Exact edge functions `e_i = d·(a_{i+1} × a_{i+2})`, their sum `S` and `N = a_0·(a_1 × a_2)`.
pub(super) fn quantities(w: &[V3<X>; 3], ray: &Ray) -> ([X; 3], X, X) {
    let o = v3::<X>(ray.origin);
    let d = v3::<X>(ray.direction);
    let a = [0, 1, 2].map(|k| sub3(&w[k], &o));
    let e = [
        triple(&d, &a[1], &a[2]),
        triple(&d, &a[2], &a[0]),
        triple(&d, &a[0], &a[1]),
    ];
    let s = e[0].add(&e[1]).add(&e[2]);
    let n = triple(&a[0], &a[1], &a[2]);
    (e, s, n)
}

/// Whether `t = N/S` lies strictly inside the ray interval (S ≠ 0).
pub(super) fn strictly_in_interval(n: &X, s: &X, ray: &Ray) -> bool {
    let ss = sign(s);
    let lo = n.sub(&X::from_f32(ray.tmin).mul(s));
    let lo_ok = sign(&lo) == ss;
    let hi_ok = ray.tmax.is_infinite() || sign(&X::from_f32(ray.tmax).mul(s).sub(n)) == ss;
    lo_ok && hi_ok
}

/// The orientation of the ray against a triangle through one of its edges (index `zero`): the
/// sign of the two other edge functions, which must agree with S.
pub(super) fn through_edge(
    w: &[V3<X>; 3],
    ray: &Ray,
    zero: usize,
    claim: &'static str,
) -> Result<Ordering, ClaimError> {
    let (e, s, n) = quantities(w, ray);
    if sign(&e[zero]) != Ordering::Equal {
        return err(
            claim,
            format!("edge function {zero} is not zero: the ray misses the edge"),
        );
    }
    let ss = sign(&s);
    if ss == Ordering::Equal {
        return err(claim, "the ray lies in the triangle's plane");
    }
    for (i, x) in e.iter().enumerate() {
        if i != zero && sign(x) != ss {
            return err(
                claim,
                format!("edge function {i} does not have the sign of S: outside the edge's ends"),
            );
        }
    }
    if !strictly_in_interval(&n, &s, ray) {
        return err(claim, "the crossing is not strictly inside (tmin, tmax)");
    }
    Ok(ss)
}

pub(super) fn key(p: [f32; 3]) -> [u32; 3] {
    p.map(|x| if x == 0.0 { 0 } else { x.to_bits() })
}

pub(super) fn determinant(m: &Transform3x4) -> X {
    let a = linear::<X>(&m.0);
    triple(&a[0], &a[1], &a[2])
}

/// `|n|²` of the triangle's normal `n = (w1 − w0) × (w2 − w0)` (four times the squared area) and
/// the squared length of its longest edge.
pub(super) fn area_and_longest(w: &[V3<X>; 3]) -> (X, X) {
    let n = cross3(&sub3(&w[1], &w[0]), &sub3(&w[2], &w[0]));
    let mut longest = X::zero();
    for k in 0..3 {
        let e = sub3(&w[(k + 1) % 3], &w[k]);
        let l = dot3(&e, &e);
        if cmp(&l, &longest) == Ordering::Greater {
            longest = l;
        }
    }
    (dot3(&n, &n), longest)
}

pub(super) fn closed_mesh(
    scene: &Scene,
    bottom_level: u32,
    geometries: &[u32],
    c: &'static str,
) -> Result<(), ClaimError> {
    let Some(bl) = scene.bottom_levels.get(bottom_level as usize) else {
        return err(c, "no such bottom level");
    };
    let mut transform = None;
    let mut directed: HashMap<([u32; 3], [u32; 3]), u32> = HashMap::new();
    for &g in geometries {
        let Some(GeometryData::Triangles(t)) = bl.geometries.get(g as usize).map(|x| &x.data)
        else {
            return err(c, format!("geometry {g} is not a triangle geometry"));
        };
        match transform {
            None => transform = Some(t.transform),
            Some(m) if m != t.transform => return err(c, "the geometries' transforms differ"),
            Some(_) => {}
        }
        for p in 0..t.primitive_count() {
            let v = t.vertices(p).map(key);
            if v[0] == v[1] || v[1] == v[2] || v[2] == v[0] {
                return err(
                    c,
                    format!("primitive {p} of geometry {g} has coincident vertices"),
                );
            }
            for k in 0..3 {
                *directed.entry((v[k], v[(k + 1) % 3])).or_default() += 1;
            }
        }
    }
    for (&(a, b), &n) in &directed {
        if n != 1 || directed.get(&(b, a)) != Some(&1) {
            return err(
                c,
                "an edge is not shared by exactly two oppositely wound triangles",
            );
        }
    }
    Ok(())
}

pub(super) fn through_vertex(
    scene: &Scene,
    instance: u32,
    r: &Ray,
    vertex: [f32; 3],
    fan: &[Member],
    index: &mut FanIndex,
    c: &'static str,
) -> Result<(), ClaimError> {
    let bottom_level = instance_bottom_level(scene, instance, c)?;
    if fan.len() < 3 {
        return err(c, "a fan needs at least three triangles");
    }
    let vk = key(vertex);
    let mut transform = None;
    let mut outs: HashMap<[u32; 3], u32> = HashMap::new();
    let mut ins: HashMap<[u32; 3], u32> = HashMap::new();
    for m in fan {
        let (v, g) = object_triangle(scene, bottom_level, *m, c)?;
        match transform {
            None => transform = Some(g),
            Some(t) if t != g => return err(c, "the fan's geometry transforms differ"),
            Some(_) => {}
        }
        let Some(i) = (0..3).find(|&i| key(v[i]) == vk) else {
            return err(c, format!("member {m:?} does not contain the vertex"));
        };
        *outs.entry(key(v[(i + 1) % 3])).or_default() += 1;
        *ins.entry(key(v[(i + 2) % 3])).or_default() += 1;
    }
    if outs.values().any(|&n| n != 1)
        || outs.len() != ins.len()
        || outs.keys().any(|k| ins.get(k) != Some(&1))
    {
        return err(
            c,
            "the fan is not closed: its edges at the vertex do not pair up",
        );
    }
    // Every triangle of the bottom level around the vertex is in the fan.
    let Some(bl) = scene.bottom_levels.get(bottom_level as usize) else {
        return err(c, "no such bottom level");
    };
    for &(g, p) in index.around(scene, bottom_level, vk) {
        let Some(GeometryData::Triangles(t)) = bl.geometries.get(g as usize).map(|x| &x.data)
        else {
            continue;
        };
        if Some(t.transform) != transform {
            continue;
        }
        if !fan.contains(&(g, p)) {
            return err(
                c,
                format!("triangle {p} of geometry {g} is around the vertex but not in the fan"),
            );
        }
    }
    // The ray line passes through the world vertex: (w − o) × d = 0, ahead, inside the interval.
    let inst = &scene.instances[instance as usize].transform;
    let p = v3::<X>(vertex);
    let p = match transform.flatten() {
        Some(g) => affine(&g.0, &p),
        None => p,
    };
    let w = affine(&inst.0, &p);
    let o = v3::<X>(r.origin);
    let d = v3::<X>(r.direction);
    let a = sub3(&w, &o);
    let cr = cross3(&a, &d);
    if cr.iter().any(|x| sign(x) != Ordering::Equal) {
        return err(c, "the ray line misses the vertex");
    }
    // t = (a·d) / (d·d) strictly inside (tmin, tmax).
    let ad = dot3(&a, &d);
    let dd = dot3(&d, &d);
    if cmp(&ad, &X::from_f32(r.tmin).mul(&dd)) != Ordering::Greater {
        return err(c, "the vertex is not beyond tmin");
    }
    if r.tmax.is_finite() && cmp(&X::from_f32(r.tmax).mul(&dd), &ad) != Ordering::Greater {
        return err(c, "the vertex is not before tmax");
    }
    Ok(())
}

pub(super) fn translated_copy(
    scene: &Scene,
    copy: u32,
    base: u32,
    offset: [f32; 3],
    c: &'static str,
) -> Result<(), ClaimError> {
    let (Some(a), Some(b)) = (
        scene.bottom_levels.get(copy as usize),
        scene.bottom_levels.get(base as usize),
    ) else {
        return err(c, "no such bottom level");
    };
    if a.geometries.len() != b.geometries.len() {
        return err(c, "different geometry counts");
    }
    for (ga, gb) in a.geometries.iter().zip(&b.geometries) {
        let (GeometryData::Triangles(ta), GeometryData::Triangles(tb)) = (&ga.data, &gb.data)
        else {
            return err(c, "not triangle geometries");
        };
        if ta.indices != tb.indices
            || ta.positions.len() != tb.positions.len()
            || ta.transform != tb.transform
        {
            return err(c, "different indices, vertex counts or transforms");
        }
        for (pa, pb) in ta.positions.iter().zip(&tb.positions) {
            for k in 0..3 {
                let exact = X::from_f32(pb[k]).add(&X::from_f32(offset[k]));
                if cmp(&X::from_f32(pa[k]), &exact) != Ordering::Equal {
                    return err(c, format!("{pa:?} is not {pb:?} + {offset:?}"));
                }
                if cmp(&X::from_f32(pb[k] + offset[k]), &exact) != Ordering::Equal {
                    return err(c, "the f32 sum is not exact");
                }
            }
        }
    }
    Ok(())
}

pub(super) fn exact_translation(
    case: &StressCase,
    instance: u32,
    c: &'static str,
) -> Result<(), ClaimError> {
    let scene = &case.scene;
    let b = instance_bottom_level(scene, instance, c)?;
    let m = scene.instances[instance as usize].transform;
    if m.linear_f64() != Transform3x4::IDENTITY.linear_f64() {
        return err(c, "not a pure translation");
    }
    let t = [m.0[0][3], m.0[1][3], m.0[2][3]];
    for geometry in &scene.bottom_levels[b as usize].geometries {
        let GeometryData::Triangles(tri) = &geometry.data else {
            continue;
        };
        if tri.transform.is_some_and(|g| !g.is_identity()) {
            return err(c, "a geometry transform stands between");
        }
        for p in &tri.positions {
            for k in 0..3 {
                let exact = X::from_f32(p[k]).add(&X::from_f32(t[k]));
                if cmp(&X::from_f32(p[k] + t[k]), &exact) != Ordering::Equal {
                    return err(c, format!("fl({} + {}) is not exact", p[k], t[k]));
                }
            }
        }
    }
    for r in &case.rays {
        for (o, t) in r.origin.iter().zip(&t) {
            let exact = X::from_f32(*o).sub(&X::from_f32(*t));
            if cmp(&X::from_f32(o - t), &exact) != Ordering::Equal {
                return err(c, format!("fl({o} − {t}) is not exact"));
            }
        }
    }
    Ok(())
}
