//! What a scene or a ray may not contain: everything the spec leaves undefined (semantics.md §2, §4,
//! §5), each found with the path of the offending value so a case file can point at it.

use super::{GeometryData, Ray, RayFlags, Scene, Transform3x4};
use crate::tracer::arith::{determinant_sign, Dyadic, Num};
use std::cmp::Ordering;

/// The classes of undefined behaviour [`Scene::undefined`] finds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProblemKind {
    /// NaN or infinity in a ray's origin, direction or tmin, or NaN / −inf in tmax.
    RayNotFinite,
    /// `tmin < 0`.
    RayTminNegative,
    /// `tmin > tmax`.
    RayTminAboveTmax,
    /// A zero direction vector.
    RayZeroDirection,
    /// Two mutually exclusive ray flags (spec, "Ray Opacity Culling", "Ray Face Culling",
    /// "Ray Primitive Culling").
    RayFlagsExclusive,
    /// Ray flag bits this model does not know.
    RayFlagsUnknown,
    /// NaN or infinity in a transform.
    TransformNotFinite,
    /// A transform whose 3x3 part is singular (spec, "Ray Intersection Candidate Determination":
    /// the instance transform must be invertible).
    TransformSingular,
    /// NaN anywhere but the X of an inactive triangle's vertex, or infinity in a used vertex.
    VertexNotFinite,
    /// NaN in an AABB anywhere but its minimum X, or infinity.
    AabbNotFinite,
    /// `min > max` on some axis of an active AABB.
    AabbInverted,
    /// A sphere count that is not the box count, a radius that is not positive, or a sphere that
    /// leaves its box.
    SphereOutsideBox,
    /// An index that names no vertex.
    IndexOutOfRange,
    /// An index or vertex count that is not a multiple of three.
    IncompletePrimitive,
    /// Triangles and AABBs in one bottom level (all geometries of a build share one type).
    MixedGeometryTypes,
    /// An instance naming a bottom level that does not exist.
    BottomLevelOutOfRange,
    /// A custom index or SBT record offset wider than 24 bits.
    InstanceFieldTooWide,
    /// FORCE_OPAQUE together with FORCE_NO_OPAQUE.
    InstanceFlagsExclusive,
}

/// One undefined thing, with the path of the value (`scene.instances[2].transform`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Problem {
    pub kind: ProblemKind,
    pub path: String,
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

fn push(out: &mut Vec<Problem>, kind: ProblemKind, path: String, message: impl Into<String>) {
    out.push(Problem {
        kind,
        path,
        message: message.into(),
    });
}

fn check_transform(out: &mut Vec<Problem>, m: &Transform3x4, path: String) {
    if !m.is_finite() {
        push(
            out,
            ProblemKind::TransformNotFinite,
            path,
            "NaN or infinity in the transform",
        );
    } else if determinant_sign(&m.0) == Ordering::Equal {
        push(
            out,
            ProblemKind::TransformSingular,
            path,
            "the 3x3 part is singular",
        );
    }
}

/// The pairs of ray flags the spec makes mutually exclusive.
pub(crate) const EXCLUSIVE_RAY_FLAGS: &[(RayFlags, RayFlags)] = &[
    (RayFlags::OPAQUE, RayFlags::NO_OPAQUE),
    (RayFlags::OPAQUE, RayFlags::CULL_OPAQUE),
    (RayFlags::OPAQUE, RayFlags::CULL_NO_OPAQUE),
    (RayFlags::NO_OPAQUE, RayFlags::CULL_OPAQUE),
    (RayFlags::NO_OPAQUE, RayFlags::CULL_NO_OPAQUE),
    (RayFlags::CULL_OPAQUE, RayFlags::CULL_NO_OPAQUE),
    (RayFlags::SKIP_TRIANGLES, RayFlags::SKIP_AABBS),
    (
        RayFlags::SKIP_TRIANGLES,
        RayFlags::CULL_BACK_FACING_TRIANGLES,
    ),
    (
        RayFlags::SKIP_TRIANGLES,
        RayFlags::CULL_FRONT_FACING_TRIANGLES,
    ),
    (
        RayFlags::CULL_BACK_FACING_TRIANGLES,
        RayFlags::CULL_FRONT_FACING_TRIANGLES,
    ),
];

/// The undefined things of one ray (`path` names it, e.g. `rays[3]`).
pub fn ray_problems(ray: &Ray, path: &str) -> Vec<Problem> {
    let mut out = Vec::new();
    let finite3 = |v: &[f32; 3]| v.iter().all(|x| x.is_finite());
    if !finite3(&ray.origin) {
        push(
            &mut out,
            ProblemKind::RayNotFinite,
            format!("{path}.origin"),
            "NaN or infinity",
        );
    }
    if !finite3(&ray.direction) {
        push(
            &mut out,
            ProblemKind::RayNotFinite,
            format!("{path}.direction"),
            "NaN or infinity",
        );
    } else if ray.direction.iter().all(|x| *x == 0.0) {
        push(
            &mut out,
            ProblemKind::RayZeroDirection,
            format!("{path}.direction"),
            "zero direction",
        );
    }
    if !ray.tmin.is_finite() {
        push(
            &mut out,
            ProblemKind::RayNotFinite,
            format!("{path}.tmin"),
            "NaN or infinity",
        );
    } else if ray.tmin < 0.0 {
        push(
            &mut out,
            ProblemKind::RayTminNegative,
            format!("{path}.tmin"),
            "negative tmin",
        );
    }
    if ray.tmax.is_nan() || ray.tmax == f32::NEG_INFINITY {
        push(
            &mut out,
            ProblemKind::RayNotFinite,
            format!("{path}.tmax"),
            "NaN or -inf",
        );
    } else if ray.tmin.is_finite() && ray.tmin > ray.tmax {
        push(
            &mut out,
            ProblemKind::RayTminAboveTmax,
            format!("{path}.tmax"),
            "tmax below tmin",
        );
    }
    for (a, b) in EXCLUSIVE_RAY_FLAGS {
        if ray.flags.contains(*a) && ray.flags.contains(*b) {
            push(
                &mut out,
                ProblemKind::RayFlagsExclusive,
                format!("{path}.flags"),
                format!("{:?} and {:?} are mutually exclusive", a, b),
            );
        }
    }
    if ray.flags.0 & !RayFlags::KNOWN != 0 {
        push(
            &mut out,
            ProblemKind::RayFlagsUnknown,
            format!("{path}.flags"),
            format!("unknown bits 0x{:x}", ray.flags.0 & !RayFlags::KNOWN),
        );
    }
    out
}

impl Scene {
    /// Everything in the scene and the rays that the spec leaves undefined. A case with any of these
    /// is never handed to a driver. Paths start with `scene.` and `rays[i]`.
    pub fn undefined(&self, rays: &[Ray]) -> Vec<Problem> {
        let mut out = Vec::new();
        for (b, bl) in self.bottom_levels.iter().enumerate() {
            let mut kinds = bl
                .geometries
                .iter()
                .map(|g| matches!(g.data, GeometryData::Aabbs(_)));
            if let Some(first) = kinds.next() {
                if kinds.any(|k| k != first) {
                    push(
                        &mut out,
                        ProblemKind::MixedGeometryTypes,
                        format!("scene.bottom_levels[{b}].geometries"),
                        "triangles and AABBs in one bottom level",
                    );
                }
            }
            for (g, geometry) in bl.geometries.iter().enumerate() {
                let gp = format!("scene.bottom_levels[{b}].geometries[{g}].data");
                match &geometry.data {
                    GeometryData::Triangles(t) => {
                        if let Some(m) = &t.transform {
                            check_transform(&mut out, m, format!("{gp}.transform"));
                        }
                        let count = match &t.indices {
                            Some(ix) => {
                                if ix.len() % 3 != 0 {
                                    push(
                                        &mut out,
                                        ProblemKind::IncompletePrimitive,
                                        format!("{gp}.indices"),
                                        format!("{} indices, not a multiple of 3", ix.len()),
                                    );
                                }
                                let mut bad = false;
                                for i in 0..ix.len() {
                                    if ix.get(i) as usize >= t.positions.len() {
                                        push(
                                            &mut out,
                                            ProblemKind::IndexOutOfRange,
                                            format!("{gp}.indices[{i}]"),
                                            format!(
                                                "index {} with {} vertices",
                                                ix.get(i),
                                                t.positions.len()
                                            ),
                                        );
                                        bad = true;
                                    }
                                }
                                if bad {
                                    continue;
                                }
                                ix.len() / 3
                            }
                            None => {
                                if t.positions.len() % 3 != 0 {
                                    push(
                                        &mut out,
                                        ProblemKind::IncompletePrimitive,
                                        format!("{gp}.positions"),
                                        format!(
                                            "{} vertices without indices, not a multiple of 3",
                                            t.positions.len()
                                        ),
                                    );
                                }
                                t.positions.len() / 3
                            }
                        };
                        for p in 0..count {
                            let ids = t.vertex_indices(p);
                            let inactive = t.is_inactive(p);
                            for (k, &vi) in ids.iter().enumerate() {
                                let v = t.positions[vi];
                                let bad = if inactive {
                                    v[1].is_nan() || v[2].is_nan()
                                } else {
                                    v.iter().any(|x| !x.is_finite())
                                };
                                if bad {
                                    push(
                                        &mut out,
                                        ProblemKind::VertexNotFinite,
                                        format!("{gp}.positions[{vi}]"),
                                        format!(
                                            "vertex {k} of primitive {p}: NaN is only allowed in X \
                                             (inactive triangle), infinity nowhere"
                                        ),
                                    );
                                }
                            }
                        }
                    }
                    GeometryData::Aabbs(a) => {
                        if a.spheres.len() != a.boxes.len() {
                            push(
                                &mut out,
                                ProblemKind::SphereOutsideBox,
                                format!("{gp}.spheres"),
                                format!("{} spheres for {} boxes", a.spheres.len(), a.boxes.len()),
                            );
                        }
                        for (i, bx) in a.boxes.iter().enumerate() {
                            let bp = format!("{gp}.boxes[{i}]");
                            let inactive = bx.is_inactive();
                            let others = bx.min[1..].iter().chain(bx.max.iter());
                            let bad_nan = others.clone().any(|x| x.is_nan());
                            let bad_inf =
                                bx.min.iter().chain(bx.max.iter()).any(|x| x.is_infinite());
                            if bad_nan || bad_inf {
                                push(
                                    &mut out,
                                    ProblemKind::AabbNotFinite,
                                    bp.clone(),
                                    "NaN is only allowed in min X (inactive AABB), infinity nowhere",
                                );
                                continue;
                            }
                            if inactive {
                                continue;
                            }
                            if (0..3).any(|k| bx.min[k] > bx.max[k]) {
                                push(&mut out, ProblemKind::AabbInverted, bp.clone(), "min > max");
                                continue;
                            }
                            if let Some(s) = a.spheres.get(i) {
                                let sp = format!("{gp}.spheres[{i}]");
                                let finite =
                                    s.center.iter().all(|x| x.is_finite()) && s.radius.is_finite();
                                // Inside the box, compared exactly.
                                let inside = finite
                                    && s.radius > 0.0
                                    && (0..3).all(|k| {
                                        let c = Dyadic::from_f32(s.center[k]);
                                        let r = Dyadic::from_f32(s.radius);
                                        let lo = c.sub(&r).sub(&Dyadic::from_f32(bx.min[k]));
                                        let hi = Dyadic::from_f32(bx.max[k]).sub(&c.add(&r));
                                        lo.sign() != Some(Ordering::Less)
                                            && hi.sign() != Some(Ordering::Less)
                                    });
                                if !inside {
                                    push(
                                        &mut out,
                                        ProblemKind::SphereOutsideBox,
                                        sp,
                                        "the sphere must have a positive radius and lie in its box",
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
        for (i, inst) in self.instances.iter().enumerate() {
            let ip = format!("scene.instances[{i}]");
            if let Some(b) = inst.bottom_level {
                if b as usize >= self.bottom_levels.len() {
                    push(
                        &mut out,
                        ProblemKind::BottomLevelOutOfRange,
                        format!("{ip}.bottom_level"),
                        format!("bottom level {b} of {}", self.bottom_levels.len()),
                    );
                }
            }
            check_transform(&mut out, &inst.transform, format!("{ip}.transform"));
            if inst.custom_index > 0xFF_FFFF {
                push(
                    &mut out,
                    ProblemKind::InstanceFieldTooWide,
                    format!("{ip}.custom_index"),
                    "wider than 24 bits",
                );
            }
            if inst.sbt_record_offset > 0xFF_FFFF {
                push(
                    &mut out,
                    ProblemKind::InstanceFieldTooWide,
                    format!("{ip}.sbt_record_offset"),
                    "wider than 24 bits",
                );
            }
            if inst.flags.force_opaque && inst.flags.force_no_opaque {
                push(
                    &mut out,
                    ProblemKind::InstanceFlagsExclusive,
                    format!("{ip}.flags"),
                    "FORCE_OPAQUE with FORCE_NO_OPAQUE",
                );
            }
        }
        for (r, ray) in rays.iter().enumerate() {
            out.extend(ray_problems(ray, &format!("rays[{r}]")));
        }
        out
    }
}
