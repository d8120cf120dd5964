//! What a stress case claims about itself, and the proof of each claim in exact dyadic arithmetic
//! (every f32 value is a dyadic rational, and every claim is a polynomial sign condition, so no
//! claim is ever decided by rounding).

use super::proofs::*;
use super::StressCase;
use crate::scene::{GeometryData, Transform3x4};
use crate::tracer::arith::{cross3, dot3, linear, sub3, v3, Num, V3};
use std::cmp::Ordering;

/// A triangle of one geometry: `(geometry index, primitive index)`.
pub type Member = (u32, u32);

/// Which end of the ray interval a [`Claim::TWindow`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TLimit {
    Tmin,
    Tmax,
}

/// One claim of a case about its scene and rays. Ray, instance and bottom-level numbers index the
/// case's `rays`, `scene.instances` and `scene.bottom_levels`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Claim {
    /// The triangles of these geometries (with identical geometry transforms) close a surface:
    /// every directed edge (by vertex position) appears exactly once, and so does its reverse;
    /// no triangle has two coincident vertices.
    ClosedMesh {
        bottom_level: u32,
        geometries: Vec<u32>,
    },
    /// At least `count` triangles in the bottom level.
    MinTriangles { bottom_level: u32, count: u64 },
    /// The ray passes exactly through the interior of the edge the two triangles share (same
    /// vertex positions, opposite directions), crossing their common plane strictly inside
    /// `(tmin, tmax)`; both face the ray the same way.
    ThroughSharedEdge {
        ray: u32,
        instance: u32,
        first: Member,
        second: Member,
    },
    /// The ray passes exactly through `vertex` (object space), strictly inside `(tmin, tmax)`;
    /// `fan` is every triangle of the instance's geometries around it, and it is closed.
    ThroughSharedVertex {
        ray: u32,
        instance: u32,
        vertex: [f32; 3],
        fan: Vec<Member>,
    },
    /// The ray passes exactly through the interior of the triangle, strictly inside the interval.
    ThroughInterior {
        ray: u32,
        instance: u32,
        member: Member,
    },
    /// Bottom level `copy` is bottom level `base` moved by `offset`, exactly in f32: same
    /// indices, every position `p + offset` with the f32 sum exact.
    TranslatedCopy {
        copy: u32,
        base: u32,
        offset: [f32; 3],
    },
    /// The instance's transform is a pure translation `T`, and f32 arithmetic carries it exactly:
    /// for every vertex of its bottom level `fl(p + T) = p + T`, for every ray `fl(o − T) = o − T`.
    ExactTranslation { instance: u32 },
    /// Every world-space vertex of the instance is at least `min_distance` from the origin along
    /// some axis.
    FarFromOrigin { instance: u32, min_distance: f32 },
    /// Every nonzero vertex coordinate of the bottom level is a normal f32 with magnitude in
    /// `[min_abs, max_abs]`.
    CoordinateRange {
        bottom_level: u32,
        min_abs: f32,
        max_abs: f32,
    },
    /// The ray's direction is exactly `base · 2^exponent` (the same line as the base ray).
    ScaledDirection {
        ray: u32,
        base: [f32; 3],
        exponent: i32,
    },
    /// The triangle's height over its longest edge is at most `max_aspect`, and its area is not 0.
    Sliver {
        instance: u32,
        member: Member,
        max_aspect: f64,
    },
    /// Every edge of the triangle is at most `max_extent` long (world space); its area is not 0.
    Tiny {
        instance: u32,
        member: Member,
        max_extent: f64,
    },
    /// The sine of the angle between the ray and the triangle's plane is at most `max_sine`.
    Grazing {
        ray: u32,
        instance: u32,
        member: Member,
        max_sine: f64,
    },
    /// The ray passes strictly inside the triangle's edges, and the exact t of its hit differs
    /// from the named end of the interval, but by at most `max_ulps` f32 ULPs of that end.
    TWindow {
        ray: u32,
        instance: u32,
        member: Member,
        limit: TLimit,
        max_ulps: u32,
    },
    /// The Frobenius condition number `‖A‖_F · ‖A⁻¹‖_F` of the instance's 3x3 part lies in
    /// `[min_kappa, max_kappa]` (it bounds the spectral one from above, by at most a factor 3).
    Conditioned {
        instance: u32,
        min_kappa: f64,
        max_kappa: f64,
    },
    /// The instance's 3x3 part has a negative determinant.
    Mirrored { instance: u32 },
    /// The geometry has a geometry transform, the instance a transform, neither is the identity
    /// and both are invertible.
    StackedTransforms { instance: u32, geometry: u32 },
}

/// A claim that does not hold.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{claim}: {problem}")]
pub struct ClaimError {
    pub claim: &'static str,
    pub problem: String,
}

impl Claim {
    /// The claim's kind, as named in reports.
    pub fn kind(&self) -> &'static str {
        match self {
            Claim::ClosedMesh { .. } => "closed-mesh",
            Claim::MinTriangles { .. } => "min-triangles",
            Claim::ThroughSharedEdge { .. } => "through-shared-edge",
            Claim::ThroughSharedVertex { .. } => "through-shared-vertex",
            Claim::ThroughInterior { .. } => "through-interior",
            Claim::TranslatedCopy { .. } => "translated-copy",
            Claim::ExactTranslation { .. } => "exact-translation",
            Claim::FarFromOrigin { .. } => "far-from-origin",
            Claim::CoordinateRange { .. } => "coordinate-range",
            Claim::ScaledDirection { .. } => "scaled-direction",
            Claim::Sliver { .. } => "sliver",
            Claim::Tiny { .. } => "tiny",
            Claim::Grazing { .. } => "grazing",
            Claim::TWindow { .. } => "t-window",
            Claim::Conditioned { .. } => "conditioned",
            Claim::Mirrored { .. } => "mirrored",
            Claim::StackedTransforms { .. } => "stacked-transforms",
        }
    }

    /// Proves the claim about `case` in exact arithmetic.
    pub fn check(&self, case: &StressCase) -> Result<(), ClaimError> {
        self.check_indexed(case, &mut FanIndex::default())
    }

    /// [`Claim::check`] with the triangles around each vertex looked up in `index` (built on first
    /// use, shared by the claims of one scene).
    pub fn check_indexed(&self, case: &StressCase, index: &mut FanIndex) -> Result<(), ClaimError> {
        let c = self.kind();
        let scene = &case.scene;
        match self {
            Claim::ClosedMesh {
                bottom_level,
                geometries,
            } => closed_mesh(scene, *bottom_level, geometries, c),
            Claim::MinTriangles {
                bottom_level,
                count,
            } => {
                let Some(bl) = scene.bottom_levels.get(*bottom_level as usize) else {
                    return err(c, "no such bottom level");
                };
                let n: usize = bl
                    .geometries
                    .iter()
                    .map(|g| match &g.data {
                        GeometryData::Triangles(t) => t.primitive_count(),
                        GeometryData::Aabbs(_) => 0,
                    })
                    .sum();
                if (n as u64) < *count {
                    return err(c, format!("{n} triangles, fewer than {count}"));
                }
                Ok(())
            }
            Claim::ThroughSharedEdge {
                ray,
                instance,
                first,
                second,
            } => {
                let r = ray_of(case, *ray, c)?;
                let b = instance_bottom_level(scene, *instance, c)?;
                let (v1, g1) = object_triangle(scene, b, *first, c)?;
                let (v2, g2) = object_triangle(scene, b, *second, c)?;
                if g1 != g2 {
                    return err(c, "the two triangles have different geometry transforms");
                }
                // The shared edge: from → to in the first, to → from in the second.
                let mut shared = None;
                for i in 0..3 {
                    let (p, q) = (key(v1[(i + 1) % 3]), key(v1[(i + 2) % 3]));
                    for j in 0..3 {
                        if (key(v2[(j + 1) % 3]), key(v2[(j + 2) % 3])) == (q, p) {
                            shared = Some((i, j));
                        }
                    }
                }
                let Some((i, j)) = shared else {
                    return err(c, "the triangles share no edge in opposite directions");
                };
                let w1 = world_triangle(scene, *instance, *first, c)?;
                let w2 = world_triangle(scene, *instance, *second, c)?;
                let s1 = through_edge(&w1, r, i, c)?;
                let s2 = through_edge(&w2, r, j, c)?;
                if s1 != s2 {
                    return err(c, "the two triangles face the ray opposite ways (a fold)");
                }
                Ok(())
            }
            Claim::ThroughSharedVertex {
                ray,
                instance,
                vertex,
                fan,
            } => {
                let r = ray_of(case, *ray, c)?;
                through_vertex(scene, *instance, r, *vertex, fan, index, c)
            }
            Claim::ThroughInterior {
                ray,
                instance,
                member,
            } => {
                let r = ray_of(case, *ray, c)?;
                let w = world_triangle(scene, *instance, *member, c)?;
                let (e, s, n) = quantities(&w, r);
                let ss = sign(&s);
                if ss == Ordering::Equal || e.iter().any(|x| sign(x) != ss) {
                    return err(c, "the ray is not strictly inside the triangle's edges");
                }
                if !strictly_in_interval(&n, &s, r) {
                    return err(c, "the hit is not strictly inside (tmin, tmax)");
                }
                Ok(())
            }
            Claim::TranslatedCopy { copy, base, offset } => {
                translated_copy(scene, *copy, *base, *offset, c)
            }
            Claim::ExactTranslation { instance } => exact_translation(case, *instance, c),
            Claim::FarFromOrigin {
                instance,
                min_distance,
            } => {
                let b = instance_bottom_level(scene, *instance, c)?;
                let m = scene.instances[*instance as usize].transform;
                let lim = X::from_f32(*min_distance);
                for (g, geometry) in scene.bottom_levels[b as usize]
                    .geometries
                    .iter()
                    .enumerate()
                {
                    let GeometryData::Triangles(t) = &geometry.data else {
                        continue;
                    };
                    for p in 0..t.primitive_count() {
                        let w = world_triangle(scene, *instance, (g as u32, p as u32), c)?;
                        for v in &w {
                            let far = v.iter().any(|x| {
                                cmp(x, &lim) != Ordering::Less
                                    || cmp(&x.neg(), &lim) != Ordering::Less
                            });
                            if !far {
                                return err(c, format!("a vertex of primitive {p} is nearer than {min_distance} ({m:?})"));
                            }
                        }
                    }
                }
                Ok(())
            }
            Claim::CoordinateRange {
                bottom_level,
                min_abs,
                max_abs,
            } => {
                let Some(bl) = scene.bottom_levels.get(*bottom_level as usize) else {
                    return err(c, "no such bottom level");
                };
                for geometry in &bl.geometries {
                    let GeometryData::Triangles(t) = &geometry.data else {
                        continue;
                    };
                    for x in t.positions.iter().flatten() {
                        if *x != 0.0 && (!x.is_normal() || x.abs() < *min_abs || x.abs() > *max_abs)
                        {
                            return err(
                                c,
                                format!("coordinate {x:e} outside [{min_abs:e}, {max_abs:e}]"),
                            );
                        }
                    }
                }
                Ok(())
            }
            Claim::ScaledDirection {
                ray,
                base,
                exponent,
            } => {
                let r = ray_of(case, *ray, c)?;
                let s = xf(2f64.powi(*exponent));
                for (k, (b, d)) in base.iter().zip(&r.direction).enumerate() {
                    let want = X::from_f32(*b).mul(&s);
                    if cmp(&X::from_f32(*d), &want) != Ordering::Equal {
                        return err(c, format!("direction[{k}] is not base·2^{exponent}"));
                    }
                }
                Ok(())
            }
            Claim::Sliver {
                instance,
                member,
                max_aspect,
            } => {
                let w = world_triangle(scene, *instance, *member, c)?;
                let (area2, longest2) = area_and_longest(&w);
                if sign(&area2) == Ordering::Equal {
                    return err(c, "zero area");
                }
                // height = 2A / L ≤ r·L  ⇔  (2A)² ≤ r²·L⁴.
                let bound = xf(max_aspect * max_aspect).mul(&longest2).mul(&longest2);
                if cmp(&area2, &bound) == Ordering::Greater {
                    return err(c, format!("height over longest edge above {max_aspect:e}"));
                }
                Ok(())
            }
            Claim::Tiny {
                instance,
                member,
                max_extent,
            } => {
                let w = world_triangle(scene, *instance, *member, c)?;
                let (area2, _) = area_and_longest(&w);
                if sign(&area2) == Ordering::Equal {
                    return err(c, "zero area");
                }
                let lim = xf(max_extent * max_extent);
                for k in 0..3 {
                    let e = sub3(&w[(k + 1) % 3], &w[k]);
                    if cmp(&dot3(&e, &e), &lim) == Ordering::Greater {
                        return err(c, format!("edge {k} longer than {max_extent:e}"));
                    }
                }
                Ok(())
            }
            Claim::Grazing {
                ray,
                instance,
                member,
                max_sine,
            } => {
                let r = ray_of(case, *ray, c)?;
                let w = world_triangle(scene, *instance, *member, c)?;
                let n = cross3(&sub3(&w[1], &w[0]), &sub3(&w[2], &w[0]));
                let d = v3::<X>(r.direction);
                let dn = dot3(&d, &n);
                let rhs = xf(max_sine * max_sine)
                    .mul(&dot3(&d, &d))
                    .mul(&dot3(&n, &n));
                if cmp(&dn.mul(&dn), &rhs) == Ordering::Greater {
                    return err(
                        c,
                        format!("the ray meets the plane at a sine above {max_sine:e}"),
                    );
                }
                Ok(())
            }
            Claim::TWindow {
                ray,
                instance,
                member,
                limit,
                max_ulps,
            } => {
                let r = ray_of(case, *ray, c)?;
                let w = world_triangle(scene, *instance, *member, c)?;
                let (e, s, n) = quantities(&w, r);
                let ss = sign(&s);
                if ss == Ordering::Equal || e.iter().any(|x| sign(x) != ss) {
                    return err(c, "the ray is not strictly inside the triangle's edges");
                }
                let lim = match limit {
                    TLimit::Tmin => r.tmin,
                    TLimit::Tmax => r.tmax,
                };
                if !lim.is_finite() || lim <= 0.0 {
                    return err(c, "the limit is not a positive finite number");
                }
                let ulp = f32::from_bits(lim.to_bits() + 1) - lim;
                // |N/S − lim| ≤ k·ulp  ⇔  |N − lim·S| ≤ k·ulp·|S|; and N ≠ lim·S.
                let gap = n.sub(&X::from_f32(lim).mul(&s));
                let abs = |x: &X| {
                    if sign(x) == Ordering::Less {
                        x.neg()
                    } else {
                        x.clone()
                    }
                };
                let window = xf(*max_ulps as f64 * ulp as f64).mul(&abs(&s));
                if sign(&gap) == Ordering::Equal {
                    return err(c, "the hit is exactly at the limit");
                }
                if cmp(&abs(&gap), &window) == Ordering::Greater {
                    return err(
                        c,
                        format!("the hit is more than {max_ulps} ulps from the limit"),
                    );
                }
                Ok(())
            }
            Claim::Conditioned {
                instance,
                min_kappa,
                max_kappa,
            } => {
                let Some(inst) = scene.instances.get(*instance as usize) else {
                    return err(c, "no such instance");
                };
                let a = linear::<X>(&inst.transform.0);
                let adj = crate::tracer::arith::adjugate(&a);
                let frob = |m: &[V3<X>; 3]| {
                    m.iter()
                        .flatten()
                        .fold(X::zero(), |acc, x| acc.add(&x.mul(x)))
                };
                // κ_F² = ‖A‖²_F · ‖adj A‖²_F / det².
                let det = determinant(&inst.transform);
                let lhs = frob(&a).mul(&frob(&adj));
                let d2 = det.mul(&det);
                if sign(&d2) == Ordering::Equal {
                    return err(c, "singular");
                }
                if cmp(&lhs, &xf(min_kappa * min_kappa).mul(&d2)) == Ordering::Less {
                    return err(c, format!("condition number below {min_kappa:e}"));
                }
                if cmp(&lhs, &xf(max_kappa * max_kappa).mul(&d2)) == Ordering::Greater {
                    return err(c, format!("condition number above {max_kappa:e}"));
                }
                Ok(())
            }
            Claim::Mirrored { instance } => {
                let Some(inst) = scene.instances.get(*instance as usize) else {
                    return err(c, "no such instance");
                };
                if sign(&determinant(&inst.transform)) != Ordering::Less {
                    return err(c, "the determinant is not negative");
                }
                Ok(())
            }
            Claim::StackedTransforms { instance, geometry } => {
                let b = instance_bottom_level(scene, *instance, c)?;
                let inst = &scene.instances[*instance as usize].transform;
                let (_, g) = object_triangle(scene, b, (*geometry, 0), c)?;
                let Some(g) = g else {
                    return err(c, "no geometry transform");
                };
                for (name, m) in [("geometry", &g), ("instance", inst)] {
                    if m.linear_f64() == Transform3x4::IDENTITY.linear_f64() {
                        return err(
                            c,
                            format!("the {name} transform has the identity's 3x3 part"),
                        );
                    }
                    if sign(&determinant(m)) == Ordering::Equal {
                        return err(c, format!("the {name} transform is singular"));
                    }
                }
                Ok(())
            }
        }
    }
}
