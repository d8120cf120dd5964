//! The VARY band: how far a conformant f32 implementation may stray from exact arithmetic, stated as
//! a backward error in world space (vertices, ray origin and direction perturbed by bounded amounts)
//! and turned into bounds on the edge functions, the plane distance and t.
//!
//! The spec allows inaccuracy without bounding it ("Ray Intersection Candidate Determination": the
//! test "may be performed with floating-point operations ... inaccuracies are expected"). rtconf
//! therefore models what an implementation that follows the spec's own recipe does in f32, per
//! source of error:
//! - the geometry transform is applied when the bottom level is built, in f32 (pbrt-v4's bound for
//!   an affine transform: γ(3) per component; we use γ(4));
//! - the ray is carried into the instance's space with an inverse the implementation computes in
//!   f32 ("Ray Intersection Candidate Determination"); a cofactor inverse is off by about u·κ·|A⁻¹|,
//!   which in world space moves the origin by about u·κ²·|o − T| and tilts the direction by u·κ²;
//! - the watertight test itself (Woop, Benthin, Wald 2013: translate, shear, 2D edge functions) is
//!   backward stable: it decides exactly for vertices moved by about 12u·|v − o| in object space
//!   (translation 1u, shear 3u + 3u, edge-function products and difference 2u·2, in the
//!   distorted sheared frame); we take [`ETA_TEST`] = 32u, and κ·|w − o| in world space.
//!
//! [`BAND_SAFETY_FACTOR`] multiplies all of it once.

use super::arith::map3;
use crate::scene::Transform3x4;

/// Unit roundoff of f32.
pub const U32: f64 = 1.0 / 16_777_216.0;

/// The one safety factor of the band. Each constituent bound above is a first-order worst case of
/// one specific algorithm (Woop's watertight test, a cofactor inverse, an unfused affine
/// transform). A factor of four covers implementations that spend up to four times as many
/// roundings on the same quantities — Möller–Trumbore or Plücker tests, a reciprocal multiplied
/// instead of a division, hardware reciprocals good to about one ulp, fused and unfused
/// multiply-adds mixed — and the second-order terms the first-order analysis drops.
pub const BAND_SAFETY_FACTOR: f64 = 4.0;

/// Relative backward error of an f32 watertight ray/triangle test (see the module comment).
pub const ETA_TEST: f64 = 32.0 * U32;

/// Coefficient of κ² in the world-space error of a ray carried through a computed f32 inverse.
pub const INVERSE_ERROR: f64 = 8.0 * U32;

/// Relative error of the sphere shader's f32 arithmetic (closest-approach form, see `sphere`).
pub const SPHERE_SHADER_ERROR: f64 = 16.0 * U32;

/// pbrt's γ(n) = n·u / (1 − n·u) for f32.
pub fn gamma(n: u32) -> f64 {
    let nu = n as f64 * U32;
    nu / (1.0 - nu)
}

pub fn norm3(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// An upper bound of the spectral norm of a 3x3 matrix, within 7% of it: with `B = AᵀA / ‖A‖²_F`,
/// `λ_max(B)^16 ≤ trace(B^16) ≤ 3·λ_max(B)^16`, so `‖A‖_F · trace(B^16)^(1/32)` bounds `‖A‖₂` from
/// above by at most a factor `3^(1/32)`. Also never above the Frobenius norm.
pub fn norm2_bound(a: &[[f64; 3]; 3]) -> f64 {
    let frob = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    if frob == 0.0 || !frob.is_finite() {
        return frob;
    }
    let n = a.map(|r| r.map(|x| x / frob));
    let mul = |x: &[[f64; 3]; 3], y: &[[f64; 3]; 3]| {
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| (0..3).map(|k| x[r][k] * y[k][c]).sum::<f64>()))
    };
    let nt = [0, 1, 2].map(|r| [0, 1, 2].map(|c| n[c][r]));
    let mut b = mul(&nt, &n);
    for _ in 0..4 {
        b = mul(&b, &b);
    }
    let trace = b[0][0] + b[1][1] + b[2][2];
    // Rounding in 5 products of matrices with entries in [−1, 1]: far below 1e-9 relative.
    let bound = frob * trace.powf(1.0 / 32.0) * (1.0 + 1e-9);
    bound.min(frob * (1.0 + 1e-12))
}

/// The f64 inverse of a 3x3 matrix through its adjugate (for bounds and builders, not decisions).
pub fn inverse3(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c =
        |r0: usize, c0: usize, r1: usize, c1: usize| a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0];
    let adj = [
        [c(1, 1, 2, 2), c(0, 2, 2, 1), c(0, 1, 1, 2)],
        [c(1, 2, 2, 0), c(0, 0, 2, 2), c(0, 2, 1, 0)],
        [c(1, 0, 2, 1), c(0, 1, 2, 0), c(0, 0, 1, 1)],
    ];
    let det = a[0][0] * adj[0][0] + a[0][1] * adj[1][0] + a[0][2] * adj[2][0];
    adj.map(|r| r.map(|x| x / det))
}

pub fn mat_vec_f64(a: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| a[r][0] * v[0] + a[r][1] * v[1] + a[r][2] * v[2])
}

/// The ray-independent part of the band of one instance.
#[derive(Debug, Clone, Copy)]
pub struct InstanceBand {
    /// Bound of ‖A‖₂ of the instance's 3x3 part.
    pub norm_a: f64,
    /// Bound of ‖A⁻¹‖₂.
    pub norm_a_inv: f64,
    /// Condition number bound ‖A‖·‖A⁻¹‖.
    pub kappa: f64,
    /// |T|, the translation's length.
    pub norm_t: f64,
    /// World-space origin error per unit of |o| + |T|.
    pub origin_coef: f64,
    /// Relative direction error.
    pub direction_rel: f64,
    /// Vertex error per unit of distance from the origin (the watertight test's backward error).
    pub test_rel: f64,
    /// The f64 inverse of the 3x3 part (for object-space constants).
    pub a_inv: [[f64; 3]; 3],
    pub translation: [f64; 3],
    /// `max(1, ‖A⁻¹‖)`: the most an object-space distance exceeds its world one.
    pub grow: f64,
    /// `max(1, ‖A‖)`: the most a world distance exceeds its object-space one.
    pub shrink: f64,
}

impl InstanceBand {
    pub fn new(m: &Transform3x4) -> InstanceBand {
        let a = m.linear_f64();
        let a_inv = inverse3(&a);
        let norm_a = norm2_bound(&a);
        let norm_a_inv = norm2_bound(&a_inv);
        let kappa = (norm_a * norm_a_inv).max(1.0);
        // The inverse of the identity is exact in any method; so is carrying a ray through it.
        let inverse = if m.linear_f64() == Transform3x4::IDENTITY.linear_f64() {
            0.0
        } else {
            INVERSE_ERROR * kappa * kappa
        };
        let sf = BAND_SAFETY_FACTOR;
        InstanceBand {
            norm_a,
            norm_a_inv,
            kappa,
            norm_t: norm3(m.translation_f64()),
            origin_coef: sf * (inverse + 4.0 * U32 * kappa),
            direction_rel: sf * (inverse + 3.0 * U32 * kappa),
            test_rel: sf * ETA_TEST * kappa,
            a_inv,
            translation: m.translation_f64(),
            grow: norm_a_inv.max(1.0),
            shrink: norm_a.max(1.0),
        }
    }

    /// World-space error radius of the ray origin.
    pub fn origin_radius(&self, origin: [f64; 3]) -> f64 {
        self.origin_coef * (norm3(origin) + self.norm_t)
    }

    /// The ray origin in the instance's space (f64).
    pub fn object_origin(&self, origin: [f64; 3]) -> [f64; 3] {
        let p = [0, 1, 2].map(|k| origin[k] - self.translation[k]);
        mat_vec_f64(&self.a_inv, p)
    }
}

/// The ray-independent error radius of one world-space vertex: the geometry transform applied in
/// f32 at build time, and an implementation that carries vertices (not rays) through the instance.
pub fn vertex_static_radius(
    band: &InstanceBand,
    geometry: Option<&Transform3x4>,
    object: [f64; 3],
    as_space: [f64; 3],
) -> f64 {
    let g = match geometry {
        Some(m) => {
            band.norm_a
                * gamma(4)
                * (norm2_bound(&m.linear_f64()) * norm3(object) + norm3(m.translation_f64()))
        }
        None => 0.0,
    };
    let carry = gamma(4) * (band.norm_a * norm3(as_space) + band.norm_t);
    BAND_SAFETY_FACTOR * (g + carry)
}

/// Bounds on the triangle quantities of one (ray, triangle) pair: `edge[i]` bounds the change of
/// `e_i = d·((w_{i+1} − o) × (w_{i+2} − o))`, `sum` that of `S = Σ e_i`, `plane` that of
/// `N = (w0 − o)·((w1 − o) × (w2 − o))`, under the backward error; `t_rel` is the final division.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleBand {
    pub edge: [f64; 3],
    pub sum: f64,
    pub plane: f64,
    pub t_rel: f64,
}

/// Slack on every f64-computed bound, so its own rounding never makes it smaller than stated.
const SLACK: f64 = 1.0 + 1e-9;

pub(crate) fn cross_f64(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The band of one (ray, triangle) pair from f64 world vertices and their static radii
/// (`direction_norm` is `norm3(direction)`, made once per ray).
///
/// With every `a_k = w_k − o` moved by at most `α_k` and `d` by at most `P·|d|`, expanding
/// `(d + Δd)·((a + Δa) × (b + Δb)) − d·(a × b)` term by term and using
/// `|d·(Δa × b)| = |Δa·(b × d)| ≤ |Δa|·|d|·|b⊥|` (`b⊥` the part of `b` perpendicular to `d`):
/// `|Δe| ≤ |d|(α|b⊥| + β|a⊥| + αβ) + P|d|(|a × b| + α|b| + β|a| + αβ)`. The perpendicular parts
/// keep the band proportional to the triangle's size seen from the ray, not to its distance.
/// Likewise `|ΔN| ≤ Σ α_i |a_j × a_k| + Σ α_i α_j |a_k| + α_0 α_1 α_2` for `N` as the triple
/// product of the moved vertices. A watertight test does not compute it so: it interpolates the
/// numerator of t from its edge functions (`N = Σ e_i·a_{i,z}/d_z` in the sheared frame), each
/// rounded on its own, and that rounding is no single perturbation of the vertices. In the
/// sheared frame a vertex's x and y are its offset from the ray's line seen along the ray, at most
/// `√3·|a_k⊥|`, so an edge function's products and difference round by at most
/// `12u·|a_j⊥|·|a_k⊥|` (`e_i` by `|d_z|` times that), and the weights `|a_{i,z}/d_z| ≤ √3·|a_i|/|d|`
/// and the sum's own products bring `N`'s share to under `52u·Σ |a_j⊥|·|a_k⊥|·|a_i|`; the plane
/// band adds `2·test_rel·Σ |a_j⊥|·|a_k⊥|·|a_i|` (64u times the safety factor and κ). Beside the
/// first term it is negligible where the triangle is small seen from afar (`|a_j⊥|·|a_k⊥|` tiny
/// beside `|a_j × a_k|`) and decides t where it is a needle seen from close (`|a_j × a_k|` tiny
/// beside the offsets).
pub fn triangle_band(
    band: &InstanceBand,
    world: &[[f64; 3]; 3],
    static_radius: &[f64; 3],
    origin: [f64; 3],
    direction: [f64; 3],
    direction_norm: f64,
) -> TriangleBand {
    let r_o = band.origin_radius(origin);
    let dn = direction_norm;
    let p = band.direction_rel;
    let a = map3([0, 1, 2], |k| map3([0, 1, 2], |c| world[k][c] - origin[c]));
    let len = map3(a, norm3);
    // f64 rounding of the cross products: far below 1e-12 of the lengths.
    let perp = map3([0, 1, 2], |k| {
        norm3(cross_f64(a[k], direction)) / dn + 1e-12 * len[k]
    });
    let cross = map3([0, 1, 2], |i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        norm3(cross_f64(a[j], a[k])) + 1e-12 * len[j] * len[k]
    });
    let alpha = map3([0, 1, 2], |k| {
        static_radius[k] + band.test_rel * len[k] + r_o
    });
    let (edge_floor, plane_floor) = underflow_floor(band, len[0].max(len[1]).max(len[2]), dn);
    let edge = map3([0, 1, 2], |i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let (aj, ak) = (alpha[j], alpha[k]);
        let vertices = aj * perp[k] + ak * perp[j] + aj * ak;
        let tilt = p * (cross[i] + aj * len[k] + ak * len[j] + aj * ak);
        (dn * (vertices + tilt) + edge_floor) * SLACK
    });
    let plane = (alpha[0] * cross[0]
        + alpha[1] * cross[1]
        + alpha[2] * cross[2]
        + alpha[0] * alpha[1] * len[2]
        + alpha[1] * alpha[2] * len[0]
        + alpha[0] * alpha[2] * len[1]
        + alpha[0] * alpha[1] * alpha[2]
        + plane_floor
        + 2.0
            * band.test_rel
            * (perp[1] * perp[2] * len[0]
                + perp[2] * perp[0] * len[1]
                + perp[0] * perp[1] * len[2]))
        * SLACK;
    TriangleBand {
        sum: (edge[0] + edge[1] + edge[2]) * SLACK,
        edge,
        plane,
        t_rel: BAND_SAFETY_FACTOR * 4.0 * U32,
    }
}

/// Whether an f32 implementation's watertight test of one (ray, triangle) pair stays clear of
/// overflow, where the band's error analysis holds. That analysis bounds each rounding relative to
/// its operands; an overflowing product has no such bound (it becomes infinite, and what the test
/// then decides is anyone's guess), so such a pair is VARY: an implementation may hit or miss it,
/// at any t (spec, "Ray Intersection Candidate Determination": inaccuracies are expected, and
/// nothing bounds them there; [`super::triangle::VaryReason::Range`]). Underflow is bounded and
/// enters the band instead ([`underflow_floor`]).
///
/// With `hi` the largest distance from the ray origin to a vertex and `|d|` the direction's
/// length, in the space the test runs in (world space, or the instance's, where distances and
/// `|d|` grow by at most `‖A⁻¹‖` and shrink by at most `‖A‖`; both are folded in), f32 ending at
/// 2^128, two ways of computing cover the others' orders of magnitude:
/// - the sheared frame of the test (Woop, Benthin, Wald 2013) multiplies x and y components by
///   at most 2 and divides z by the direction's largest component, at least `|d|/√3`; edge
///   functions are differences of two products of sheared x and y, at most `8·hi²` (under 2^117
///   while `hi ≤ 2^57`); the numerator of t sums three edge functions times a sheared z, at most
///   `24·√3·hi³/|d| < 2^6·hi³/|d|` (under 2^121 while `hi³/|d| ≤ 2^115`);
/// - directly, `e = d·(a_j × a_k)` or `d·n` from a normal made of the edges (at most
///   `2^5·|d|·hi²`, under 2^125 while `|d|·hi² ≤ 2^120`) and `N = a_0·(a_1 × a_2)` (at most
///   `2^3·hi³`, under 2^123 while `hi³ ≤ 2^120`).
///
/// The comparisons are made on squares (no square root). A NaN or an infinity fails them.
pub fn within_f32_range(
    band: &InstanceBand,
    world: &[[f64; 3]; 3],
    origin: [f64; 3],
    direction: [f64; 3],
) -> bool {
    let dist2 = map3([0, 1, 2], |k| {
        let a = map3([0, 1, 2], |c| world[k][c] - origin[c]);
        a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    });
    let d2 =
        direction[0] * direction[0] + direction[1] * direction[1] + direction[2] * direction[2];
    let hi2 = dist2[0].max(dist2[1]).max(dist2[2]);
    range_holds(hi2, d2, band.grow, band.shrink)
}

/// [`within_f32_range`]'s conditions for a largest squared world distance `hi2` (or any bound of
/// it: they only tighten as it grows) and squared direction length `d2`, through an instance that
/// grows object-space distances by at most `grow` and shrinks them by at most `shrink`.
pub fn range_holds(hi2: f64, d2: f64, grow: f64, shrink: f64) -> bool {
    let grow2 = grow * grow;
    let hi2 = hi2 * grow2;
    let (d2_lo, d2_hi) = (d2 / (shrink * shrink), d2 * grow2);
    let cube2 = hi2 * hi2 * hi2;
    hi2 <= RANGE_EDGE_HI2
        && cube2 <= RANGE_SHEARED_HI2 * d2_lo
        && cube2 <= RANGE_DIRECT_HI2
        && d2_hi * hi2 * hi2 <= RANGE_DIRECT_HI2
}

/// `hi ≤ 2^57`, squared: 2^114 (see [`within_f32_range`]).
const RANGE_EDGE_HI2: f64 = 2.076_918_743_413_931e34;
/// `hi³/|d| ≤ 2^115`, squared: 2^230.
const RANGE_SHEARED_HI2: f64 = 1.725_436_586_697_641e69;
/// `hi³ ≤ 2^120` and `|d|·hi² ≤ 2^120`, squared: 2^240.
const RANGE_DIRECT_HI2: f64 = 1.766_847_064_778_384_3e72;
/// 2^-141 and 2^-140, the coefficients of [`underflow_floor`].
const FLOOR_EDGE: f64 = 3.587_324_068_671_532e-43;
const FLOOR_PLANE: f64 = 7.174_648_137_343_064e-43;

/// What underflow adds to the band of one pair: `(edge, plane)`, the absolute amounts by which an
/// f32 implementation's edge functions and plane distance may stray beyond the relative bounds of
/// [`triangle_band`] when products fall below f32's normal range (2^-126), where rounding is off
/// by up to 2^-150 absolute instead of a relative u. `hi` is the largest distance from the origin
/// to a vertex, `dn` the direction's length (world space).
///
/// Two ways of computing cover the others' orders of magnitude:
/// - directly, `e = d·(a_j × a_k)` or `d·n` from a normal made of the edges, and
///   `N = a_0·(a_1 × a_2)`: a cross product's components stray by 2^-149, the dot product adds
///   three more 2^-150: `e` by at most `2^-148·(1 + |d|)`, `N` by at most `2^-147·(1 + hi)`;
/// - in the sheared frame of the test (see [`within_f32_range`]), computing a sheared x or y
///   (`a_x − S_x·a_z`) may underflow by 2^-150, so an edge function (`U = C_x·B_y − C_y·B_x`,
///   components at most `2·hi`) strays by at most `2^-148 + 2^-146·hi`; the numerator of t
///   (`U·A_z + V·B_z + W·C_z`, sheared z at most `2·hi/|d_z|`, which may itself underflow by
///   2^-150 against an edge function of at most `8·hi²`) by at most
///   `2^-145·hi/|d_z| + 2^-148 + 2^-145·hi²`; the shear has determinant `1/d_z`, so the world
///   quantities are those times `d_z` (`|d_z| ≤ |d|`): `e` by at most `|d|·(2^-148 + 2^-146·hi)`,
///   `N` by at most `2^-145·hi + 2^-148·|d| + 2^-145·hi²·|d|`.
///
/// Taken here as `e: 2^-141·(1 + |d|·(1 + hi))` and `N: 2^-140·(1 + hi + |d| + hi²·|d|)`, a factor
/// of 2^5 over every term. In the instance's space distances and `|d|` grow by at most `‖A⁻¹‖`,
/// and triple products there are the world's divided by `det A`, at most `‖A‖³`: both are folded
/// in. At unit scale the floor is some 2^-100 of the band and decides nothing.
#[inline]
pub fn underflow_floor(band: &InstanceBand, hi: f64, dn: f64) -> (f64, f64) {
    let world = band.shrink * band.shrink * band.shrink;
    let (hi, dn) = (hi * band.grow, dn * band.grow);
    let edge = FLOOR_EDGE * (1.0 + dn * (1.0 + hi)) * world;
    let plane = FLOOR_PLANE * (1.0 + hi + dn + hi * hi * dn) * world;
    (edge, plane)
}

/// The pad by which a primitive's world box is widened for one ray: no conformant implementation
/// can report a hit at `t` unless `o + t·d` lies within this distance of the primitive.
///
/// A hit of the perturbed ray on the perturbed primitive at `t` puts `o + t·d` within
/// `r_static + test_rel·M + r_o + direction_rel·|d|·t` of it, where `M` bounds the distance from
/// the origin to the primitive's points and `|d|·t ≤ M + pad`; solving for the pad gives the
/// division by `1 − 2q`.
pub fn far_pad(static_pad: f64, rel: f64, origin_radius: f64, max_distance: f64) -> f64 {
    if rel >= 0.25 {
        return f64::INFINITY;
    }
    let pad = (static_pad + origin_radius + rel * max_distance) / (1.0 - 2.0 * rel);
    // f64 rounding of the slab test itself, far below the band.
    (pad + 1e-9 * max_distance) * SLACK
}

/// `1 / (1 − 2·rel)` rounded up by a relative 2^-50 (so a pad computed with it is at least
/// [`far_pad`]'s), or infinity where `far_pad` is infinite (`rel ≥ 1/4`, or NaN).
pub fn far_pad_scale(rel: f64) -> f64 {
    if rel.is_nan() || rel >= 0.25 {
        return f64::INFINITY;
    }
    (1.0 / (1.0 - 2.0 * rel)) * (1.0 + f64::EPSILON * 4.0)
}

/// [`far_pad`] with its division precomputed ([`far_pad_scale`]): never below it.
#[inline]
pub fn far_pad_scaled(
    static_pad: f64,
    rel: f64,
    scale: f64,
    origin_radius: f64,
    max_distance: f64,
) -> f64 {
    let pad = (static_pad + origin_radius + rel * max_distance) * scale;
    (pad + 1e-9 * max_distance) * SLACK
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_and_floor_constants_are_the_powers_of_two_they_name() {
        assert_eq!(RANGE_EDGE_HI2, 2f64.powi(114));
        assert_eq!(RANGE_SHEARED_HI2, 2f64.powi(230));
        assert_eq!(RANGE_DIRECT_HI2, 2f64.powi(240));
        assert_eq!(FLOOR_EDGE, 2f64.powi(-141));
        assert_eq!(FLOOR_PLANE, 2f64.powi(-140));
    }

    #[test]
    fn spectral_norm_bound_is_above_and_close() {
        // Identity and rotations: 1; diag(3, 1, 0.5): 3; a shear [[1, 1], [0, 1]] has
        // ‖·‖₂ = (1 + √5)/2 ≈ 1.618.
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let b = norm2_bound(&id);
        assert!((1.0..1.04).contains(&b), "{b}");
        let (s, c) = 0.7f64.sin_cos();
        let rot = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        let b = norm2_bound(&rot);
        assert!((1.0 - 1e-12..1.04).contains(&b), "{b}");
        let d = [[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.5]];
        let b = norm2_bound(&d);
        assert!((3.0..3.0 * 1.04).contains(&b), "{b}");
        let shear = [[1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]];
        let golden = (1.0 + 5f64.sqrt()) / 2.0;
        let b = norm2_bound(&shear);
        assert!((golden..golden * 1.04).contains(&b), "{b}");
    }
}
