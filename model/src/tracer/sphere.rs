//! One ray against one AABB primitive and the sphere its intersection shader reports (spec, "AABB
//! Intersection Candidates", "Ray Intersection Candidate Determination"; semantics.md §3).
//!
//! The intersection shader rtconf's harness runs for every box, in the instance's space, is:
//! ```glsl
//! vec3 oc = gl_ObjectRayOriginEXT - center;  vec3 d = gl_ObjectRayDirectionEXT;
//! float a = dot(d, d);  float tc = -dot(oc, d) / a;  vec3 pc = oc + tc * d;
//! float disc = radius * radius - dot(pc, pc);
//! if (disc >= 0.0) {
//!     float s = sqrt(disc / a);
//!     if (tc - s >= gl_RayTminEXT) reportIntersectionEXT(tc - s, 0u);   // entry: HitKind 0
//!     else                         reportIntersectionEXT(tc + s, 1u);   // from inside: HitKind 1
//! }
//! ```
//! (closest-approach form, so the discriminant does not cancel when the ray starts far away).
//!
//! Boxes may be enlarged without bound, so the shader may run for any box; it must run for a box
//! the ray robustly crosses (`box_crossing.rs`) or whose sphere it robustly crosses. Here the
//! reported sphere hit is classified. Exactly, without inverting: with
//! `adj = adj(A)`, `O = adj·(o − T) − det(A)·c` and `D = adj·d` (both `det(A)` times the object-space
//! quantities), the object-space distance `h` of the ray's line from the centre has
//! `h² = |O × D|² / (det² |D|²)` and the roots `t0 ≤ t1` of `|O + t·D|² = det² r²` are
//! `(−b ∓ √Δ)/a` with `a = |D|²`, `b = O·D`, `Δ = det² r² a − |O × D|²`; every comparison below is a
//! polynomial sign.

use super::arith::{adjugate, cross3, determinant, dot3, linear, mat_vec, sub3, v3, Num};
use super::band::{InstanceBand, BAND_SAFETY_FACTOR, SPHERE_SHADER_ERROR, U32};
use super::triangle::Interval;
use crate::scene::Sphere;
use std::cmp::Ordering;

/// Three-way certified outcome of a comparison with a band.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Side {
    Yes,
    No,
    Band,
}

/// The band constants of one (ray, sphere) pair, computed in f64 the same way in every mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereBand {
    /// Object-space radius of the combined ray and shader error (doubled: the ray point and the
    /// radius each move by up to half of it).
    pub margin: f64,
    /// Object-space error of the entry and exit t (half widths).
    pub t0_error: f64,
    pub t1_error: f64,
    /// Enclosures of the reported t of each kind.
    pub t0: Interval,
    pub t1: Interval,
    /// The object-space distance of the ray's line from the centre (f64).
    pub distance: f64,
    /// `margin / |d'|` in t units.
    pub t_margin: f64,
}

/// Computes the band constants (f64) of a ray against a sphere of an instance.
pub fn sphere_band(
    band: &InstanceBand,
    sphere: &Sphere,
    origin: [f64; 3],
    direction: [f64; 3],
) -> SphereBand {
    let o = band.object_origin(origin);
    let d = super::band::mat_vec_f64(&band.a_inv, direction);
    let c = sphere.center.map(|x| x as f64);
    let r = sphere.radius as f64;
    let oc = [0, 1, 2].map(|k| o[k] - c[k]);
    let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let dn = a.sqrt();
    let tc = -(oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2]) / a;
    let pc = [0, 1, 2].map(|k| oc[k] + tc * d[k]);
    let h = super::band::norm3(pc);
    let n = super::band::norm3;
    let dist_obj = n(oc) + r;
    let ray =
        band.norm_a_inv * band.origin_radius(origin) + band.direction_rel * band.kappa * dist_obj;
    let shader = BAND_SAFETY_FACTOR * SPHERE_SHADER_ERROR * (n(o) + n(c) + r + dist_obj);
    // f64 evaluation of h and tc: far below the band.
    let margin = 2.0 * (ray + shader) * (1.0 + 1e-9) + 1e-12 * (dist_obj + n(o));
    let outer = ((r + margin).powi(2) - h * h).max(0.0).sqrt() / dn;
    let inner = ((r - margin).max(0.0).powi(2) - h * h).max(0.0).sqrt() / dn;
    let rel = BAND_SAFETY_FACTOR * 4.0 * U32;
    let widen = |lo: f64, hi: f64| {
        let w = rel * lo.abs().max(hi.abs()) + margin / dn * 1e-6;
        Interval {
            lo: lo - w,
            hi: hi + w,
        }
    };
    let t0 = widen(tc - outer, tc - inner);
    let t1 = widen(tc + inner, tc + outer);
    let exact_half = ((r * r - h * h).max(0.0)).sqrt() / dn;
    let (e0, e1) = (tc - exact_half, tc + exact_half);
    SphereBand {
        margin,
        t0_error: (e0 - t0.lo).max(t0.hi - e0),
        t1_error: (e1 - t1.lo).max(t1.hi - e1),
        t0,
        t1,
        distance: h,
        t_margin: margin / dn,
    }
}

/// The certified signs of a (ray, sphere) pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SphereSigns {
    /// The ray's line passes within `r − margin` of the centre (Yes), beyond `r + margin` (No).
    pub hit: Side,
    /// The closest approach lies inside the sphere and robustly inside (tmin, tmax): the ray
    /// crosses the box's interior, so the intersection shader must run (spec note: a ray through
    /// the box's interior hits it).
    pub must_run: bool,
    /// Entry `t0 ≥ tmin` (HitKind 0 is reported) robustly: Yes; `t0 < tmin` robustly: No.
    pub entry_after_tmin: Side,
    /// `t0 ≤ tmax` robustly (Yes) or `t0 > tmax` robustly (No).
    pub entry_before_tmax: Side,
    /// `t1 ≥ tmin` robustly (Yes) or not (No).
    pub exit_after_tmin: Side,
    /// `t1 ≤ tmax` robustly (Yes) or not (No).
    pub exit_before_tmax: Side,
}

fn side(yes: Option<bool>, no: Option<bool>) -> Option<Side> {
    Some(if yes? {
        Side::Yes
    } else if no? {
        Side::No
    } else {
        Side::Band
    })
}

fn gt0<T: Num>(x: &T) -> Option<bool> {
    Some(x.sign()? == Ordering::Greater)
}

fn lt0<T: Num>(x: &T) -> Option<bool> {
    Some(x.sign()? == Ordering::Less)
}

/// `t0 > τ`, `t0 < τ`, `t1 > τ`, `t1 < τ` for a constant τ (Δ > 0 assumed).
struct Roots<T> {
    a: T,
    b: T,
    delta: T,
}

impl<T: Num> Roots<T> {
    fn t0_above(&self, tau: f64) -> Option<bool> {
        // −b − √Δ > τa ⇔ X = −b − τa > 0 ∧ X² > Δ.
        let x = self.b.neg().sub(&T::from_f64(tau).mul(&self.a));
        Some(gt0(&x)? && gt0(&x.mul(&x).sub(&self.delta))?)
    }
    fn t0_below(&self, tau: f64) -> Option<bool> {
        let x = self.b.neg().sub(&T::from_f64(tau).mul(&self.a));
        Some(lt0(&x)? || lt0(&x.mul(&x).sub(&self.delta))?)
    }
    fn t1_above(&self, tau: f64) -> Option<bool> {
        // −b + √Δ > τa ⇔ Y = τa + b < 0 ∨ Y² < Δ.
        let y = T::from_f64(tau).mul(&self.a).add(&self.b);
        Some(lt0(&y)? || lt0(&y.mul(&y).sub(&self.delta))?)
    }
    fn t1_below(&self, tau: f64) -> Option<bool> {
        let y = T::from_f64(tau).mul(&self.a).add(&self.b);
        Some(gt0(&y)? && gt0(&y.mul(&y).sub(&self.delta))?)
    }
}

/// The part of [`sphere_signs`] every sphere of one instance shares for one ray: `det(A)`,
/// `adj·(o − T)` and `D = adj·d` in the numbers `T` (computed once per ray and instance, the same
/// operations in the same order, so the signs are those of computing it per sphere).
#[derive(Debug, Clone)]
pub struct ScaledRay<T> {
    det: T,
    origin: [T; 3],
    direction: [T; 3],
}

impl<T: Num> ScaledRay<T> {
    /// The ray `origin + t·direction` in the space of the instance transform `transform`, scaled by
    /// the determinant.
    pub fn of(transform: &[[f32; 4]; 3], origin: [f32; 3], direction: [f32; 3]) -> ScaledRay<T> {
        let a3 = linear::<T>(transform);
        let adj = adjugate(&a3);
        let det = determinant(&a3);
        let t = [0, 1, 2].map(|k| T::from_f32(transform[k][3]));
        let ot = sub3(&v3::<T>(origin), &t);
        ScaledRay {
            origin: mat_vec(&adj, &ot),
            direction: mat_vec(&adj, &v3::<T>(direction)),
            det,
        }
    }
}

/// Evaluates the signs with numbers of type `T`; `None` when `T` cannot certify one of them.
pub fn sphere_signs<T: Num>(
    transform: &[[f32; 4]; 3],
    sphere: &Sphere,
    origin: [f32; 3],
    direction: [f32; 3],
    tmin: f32,
    tmax: f32,
    band: &SphereBand,
) -> Option<SphereSigns> {
    let scaled = ScaledRay::<T>::of(transform, origin, direction);
    sphere_signs_scaled(&scaled, sphere, tmin, tmax, band)
}

/// [`sphere_signs`] of a ray already in the instance's space ([`ScaledRay`]).
pub fn sphere_signs_scaled<T: Num>(
    scaled: &ScaledRay<T>,
    sphere: &Sphere,
    tmin: f32,
    tmax: f32,
    band: &SphereBand,
) -> Option<SphereSigns> {
    let det = scaled.det.clone();
    let c = v3::<T>(sphere.center).map(|x| x.mul(&det));
    let o = sub3(&scaled.origin, &c);
    let d = scaled.direction.clone();
    let cross = cross3(&o, &d);
    let h2 = dot3(&cross, &cross);
    let a = dot3(&d, &d);
    let b = dot3(&o, &d);
    let det2a = det.mul(&det).mul(&a);
    let r = sphere.radius as f64;
    let r_in = r - band.margin;
    let hit_yes = if r_in > 0.0 {
        gt0(&T::from_f64(r_in * r_in).mul(&det2a).sub(&h2))?
    } else {
        false
    };
    let r_out = r + band.margin;
    let hit_no = gt0(&h2.sub(&T::from_f64(r_out * r_out).mul(&det2a)))?;
    let hit = side(Some(hit_yes), Some(hit_no))?;
    match hit {
        Side::Yes => {}
        Side::No => {
            return Some(SphereSigns {
                hit,
                must_run: false,
                entry_after_tmin: Side::Band,
                entry_before_tmax: Side::Band,
                exit_after_tmin: Side::Band,
                exit_before_tmax: Side::Band,
            })
        }
        Side::Band => return Some(grazing_signs(band, tmin, tmax)),
    }
    let rr = T::from_f32(sphere.radius);
    let delta = det2a.mul(&rr).mul(&rr).sub(&h2);
    let roots = Roots {
        a: a.clone(),
        b: b.clone(),
        delta,
    };
    // Closest approach tc = −b/a inside (tmin + τ, tmax − τ).
    let lo = tmin as f64 + band.t_margin;
    let after = gt0(&b.neg().sub(&T::from_f64(lo).mul(&a)))?;
    let before = if tmax.is_infinite() {
        true
    } else {
        gt0(&T::from_f64(tmax as f64 - band.t_margin).mul(&a).add(&b))?
    };
    let tmin = tmin as f64;
    let inf = tmax.is_infinite();
    let tmax = tmax as f64;
    let entry_after_tmin = side(
        roots.t0_above(tmin + band.t0_error),
        roots.t0_below(tmin - band.t0_error),
    )?;
    let entry_before_tmax = if inf {
        Side::Yes
    } else {
        side(
            roots.t0_below(tmax - band.t0_error),
            roots.t0_above(tmax + band.t0_error),
        )?
    };
    let exit_after_tmin = side(
        roots.t1_above(tmin + band.t1_error),
        roots.t1_below(tmin - band.t1_error),
    )?;
    let exit_before_tmax = if inf {
        Side::Yes
    } else {
        side(
            roots.t1_below(tmax - band.t1_error),
            roots.t1_above(tmax + band.t1_error),
        )?
    };
    // Or the ray starts robustly inside: the point at tmin + τ lies in the sphere shrunk by the
    // margin (spec note: a ray started within the AABB hits it).
    let starts_inside = || -> Option<bool> {
        if r_in <= 0.0 || lo >= tmax - band.t_margin {
            return Some(false);
        }
        let p = [0, 1, 2].map(|k| o[k].add(&T::from_f64(lo).mul(&d[k])));
        let det2 = det.mul(&det);
        gt0(&T::from_f64(r_in * r_in).mul(&det2).sub(&dot3(&p, &p)))
    };
    let must_run = (after && before) || starts_inside()?;
    Some(SphereSigns {
        hit,
        must_run,
        entry_after_tmin,
        entry_before_tmax,
        exit_after_tmin,
        exit_before_tmax,
    })
}

/// The signs of a grazing pair (its line within the band of the sphere's surface): the shader may
/// find the sphere or not, and where it does, the t it computes lies in the band's enclosure of its
/// kind ([`SphereBand::t0`], [`SphereBand::t1`]), so a comparison with `tmin` or `tmax` that every
/// point of the enclosure settles the same way is settled for every report the shader may make (a
/// grazing ray whose line passes the sphere behind its origin or beyond `tmax` reports nothing).
/// Nothing is required of a grazing pair: the shader need not run.
fn grazing_signs(band: &SphereBand, tmin: f32, tmax: f32) -> SphereSigns {
    let (tmin, tmax) = (f64::from(tmin), f64::from(tmax));
    let settled = |yes: bool, no: bool| {
        if yes {
            Side::Yes
        } else if no {
            Side::No
        } else {
            Side::Band
        }
    };
    let (t0, t1) = (band.t0, band.t1);
    SphereSigns {
        hit: Side::Band,
        must_run: false,
        entry_after_tmin: settled(t0.lo >= tmin, t0.hi < tmin),
        entry_before_tmax: settled(t0.hi <= tmax, t0.lo > tmax),
        exit_after_tmin: settled(t1.lo >= tmin, t1.hi < tmin),
        exit_before_tmax: settled(t1.hi <= tmax, t1.lo > tmax),
    }
}

/// One report the intersection shader may make: its HitKind, t enclosure, and whether it is
/// certain (given that the shader runs).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SphereReport {
    pub hit_kind: u32,
    pub t: Interval,
    pub required: bool,
}

/// The reports the shader may make, from the certified signs.
pub fn sphere_reports(signs: &SphereSigns, band: &SphereBand) -> Vec<SphereReport> {
    if signs.hit == Side::No {
        return Vec::new();
    }
    let robust = signs.hit == Side::Yes;
    let mut out = Vec::new();
    // Kind 0 needs t0 ≥ tmin (the shader's test) and t0 ≤ tmax (reportIntersectionEXT's).
    if signs.entry_after_tmin != Side::No && signs.entry_before_tmax != Side::No {
        let required =
            robust && signs.entry_after_tmin == Side::Yes && signs.entry_before_tmax == Side::Yes;
        out.push(SphereReport {
            hit_kind: 0,
            t: band.t0,
            required,
        });
    }
    // Kind 1 needs t0 < tmin, and tmin ≤ t1 ≤ tmax.
    if signs.entry_after_tmin != Side::Yes
        && signs.exit_after_tmin != Side::No
        && signs.exit_before_tmax != Side::No
    {
        let required = robust
            && signs.entry_after_tmin == Side::No
            && signs.exit_after_tmin == Side::Yes
            && signs.exit_before_tmax == Side::Yes;
        out.push(SphereReport {
            hit_kind: 1,
            t: band.t1,
            required,
        });
    }
    out
}
