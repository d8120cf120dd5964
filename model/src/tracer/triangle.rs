//! One ray against one triangle in world space: the exact quantities (edge functions, their sum,
//! the plane distance), their bands, and the classification REQ-hit / VARY / REQ-miss as a precise
//! function of the inputs (spec, "Ray Intersection Candidate Determination", "Ray Face Culling").
//!
//! With `a_k = w_k − o` (world vertices `w_k = M·(G·v_k)`, exact rationals of the f32 inputs):
//! `e_i = d·(a_{i+1} × a_{i+2})`, `S = e_0 + e_1 + e_2 = d·n` with `n = (w1 − w0) × (w2 − w0)`,
//! `N = a_0·(a_1 × a_2)`; the exact hit has `t = N / S` and barycentrics `(b, c) = (e_1, e_2) / S`.
//! An instance transform with negative determinant flips the world normal against the object
//! normal, so the object-space facing (the spec's sign of the ray-space area) is
//! `sign(det A) · sign(S)`: negative is front-facing. The classification compares each quantity with
//! its band from [`super::band`]; the band constants are computed in f64 the same way in every mode,
//! so only the signs of `quantity − constant` differ between modes, and those are certified.

use super::arith::{map3, sub3, Num, V3};
use super::band::TriangleBand;
use std::cmp::Ordering;

/// Where the ray stands against one edge of the triangle, relative to the orientation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EdgeSide {
    /// `e_i > B_i`.
    Positive,
    /// `e_i < −B_i`.
    Negative,
    /// Within the band: the ray is near this edge's line.
    Band,
}

impl EdgeSide {
    /// Robustly on the other side of its edge line than `o` is of its own.
    #[inline]
    pub fn opposite(self, o: EdgeSide) -> bool {
        matches!(
            (self, o),
            (EdgeSide::Positive, EdgeSide::Negative) | (EdgeSide::Negative, EdgeSide::Positive)
        )
    }
}

/// Where the exact t stands against the ray interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WindowSide {
    /// Every t the band allows lies strictly inside (tmin, tmax).
    Inside,
    /// Every t the band allows lies strictly before tmin or after tmax.
    Outside,
    /// Neither: the decision hinges on t near tmin or tmax, or t is unbounded.
    Band,
}

/// The certified signs a classification is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TriangleSigns {
    pub edges: [EdgeSide; 3],
    /// The robust sign of S (`Some` when `|S| > B_S`).
    pub orientation: Option<Ordering>,
    pub window: WindowSide,
}

/// The f64 approximations (with error bounds) of the quantities, for intervals. A pair robustly
/// outside two edges needs no more than its edge functions: its sum and plane are not evaluated
/// (NaN, with an infinite bound), nor its third edge function where the first two decide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleValues {
    pub edge: [(f64, f64); 3],
    pub sum: (f64, f64),
    pub plane: (f64, f64),
}

fn sign_above<T: Num>(x: &T, bound: f64) -> Option<Ordering> {
    x.sub(&T::from_f64(bound)).sign()
}

fn sign_below<T: Num>(x: &T, bound: f64) -> Option<Ordering> {
    x.add(&T::from_f64(bound)).sign()
}

/// Evaluates the signs with numbers of type `T`; `None` when `T` cannot certify one of them.
pub fn triangle_signs<T: Num>(
    world: &[V3<T>; 3],
    origin: &V3<T>,
    direction: &V3<T>,
    tmin: f32,
    tmax: f32,
    band: &TriangleBand,
) -> Option<(TriangleSigns, TriangleValues)> {
    let a = map3([0, 1, 2], |k| sub3(&world[k], origin));
    let side = |e: &T, bound: f64| -> Option<EdgeSide> {
        Some(if sign_above(e, bound)? == Ordering::Greater {
            EdgeSide::Positive
        } else if sign_below(e, bound)? == Ordering::Less {
            EdgeSide::Negative
        } else {
            EdgeSide::Band
        })
    };
    let [e0, e1] = T::triples([(direction, &a[1], &a[2]), (direction, &a[2], &a[0])]);
    let mut values = TriangleValues {
        edge: [
            (e0.approx(), e0.error()),
            (e1.approx(), e1.error()),
            (f64::NAN, f64::INFINITY),
        ],
        sum: (f64::NAN, f64::INFINITY),
        plane: (f64::NAN, f64::INFINITY),
    };
    let mut edges = [
        side(&e0, band.edge[0])?,
        side(&e1, band.edge[1])?,
        EdgeSide::Band,
    ];
    if edges[0].opposite(edges[1]) {
        // Robustly on different sides of two edge lines: no perturbation can hit, whatever the
        // third edge (its value is not evaluated: NaN with an infinite bound, its side Band).
        let signs = TriangleSigns {
            edges,
            orientation: None,
            window: WindowSide::Band,
        };
        return Some((signs, values));
    }
    // The third edge function beside the plane distance (two at once where `T` pairs them); the
    // distance is needed unless the three edges decide a miss.
    let [e2, n] = T::triples([(direction, &a[0], &a[1]), (&a[0], &a[1], &a[2])]);
    values.edge[2] = (e2.approx(), e2.error());
    edges[2] = side(&e2, band.edge[2])?;
    let e = [e0, e1, e2];
    let mixed = edges.contains(&EdgeSide::Positive) && edges.contains(&EdgeSide::Negative);
    if mixed {
        // Robustly on different sides of two edge lines: no perturbation can hit. Nothing else is
        // needed for the classification.
        let signs = TriangleSigns {
            edges,
            orientation: None,
            window: WindowSide::Band,
        };
        return Some((signs, values));
    }
    let s = e[0].add(&e[1]).add(&e[2]);
    values.sum = (s.approx(), s.error());
    values.plane = (n.approx(), n.error());
    let orientation = if sign_above(&s, band.sum)? == Ordering::Greater {
        Some(Ordering::Greater)
    } else if sign_below(&s, band.sum)? == Ordering::Less {
        Some(Ordering::Less)
    } else {
        None
    };
    let window = match orientation {
        None => WindowSide::Band,
        Some(o) => {
            let (n, s) = if o == Ordering::Less {
                (n.neg(), s.neg())
            } else {
                (n, s)
            };
            let tmin_t = T::from_f32(tmin);
            // t_lo = (N − B_N)/(S + B_S) > tmin  ⇔  N − tmin·S > B_N + tmin·B_S (spec: t > tmin).
            let k_lo = band.plane + tmin as f64 * band.sum;
            let lo_gap = n.sub(&tmin_t.mul(&s));
            let lo_in = sign_above(&lo_gap, k_lo)? == Ordering::Greater;
            // t_hi = (N + B_N)/(S − B_S) < tmin  ⇔  tmin·S − N > B_N + tmin·B_S.
            let lo_out = sign_above(&lo_gap.neg(), k_lo)? == Ordering::Greater;
            let (hi_in, hi_out) = if tmax.is_infinite() {
                (true, false)
            } else {
                let k_hi = band.plane + tmax as f64 * band.sum;
                let hi_gap = T::from_f32(tmax).mul(&s).sub(&n);
                // t_hi < tmax ⇔ tmax·S − N > B_N + tmax·B_S; t_lo > tmax ⇔ N − tmax·S > same.
                (
                    sign_above(&hi_gap, k_hi)? == Ordering::Greater,
                    sign_above(&hi_gap.neg(), k_hi)? == Ordering::Greater,
                )
            };
            if lo_out || hi_out {
                WindowSide::Outside
            } else if lo_in && hi_in {
                WindowSide::Inside
            } else {
                WindowSide::Band
            }
        }
    };
    Some((
        TriangleSigns {
            edges,
            orientation,
            window,
        },
        values,
    ))
}

/// The geometric class of a (ray, triangle) pair before culling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PairClass {
    ReqHit,
    Vary(VaryReason),
    ReqMiss(MissReason),
}

/// Why a pair is VARY.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum VaryReason {
    /// The ray passes within the band of an edge or vertex.
    Edge,
    /// t is within the band of tmin or tmax.
    Window,
    /// The ray grazes the plane: S is within its band.
    Grazing,
    /// An AABB: the box may be enlarged, or the sphere is touched within its band.
    Procedural,
    /// The facing is uncertain and a facing cull flag applies.
    Facing,
    /// An f32 test of the pair may overflow (vertices too far from the ray origin for the
    /// direction's length, see `band::within_f32_range`): hit or miss, at any t.
    Range,
}

/// Why a pair is REQ-miss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MissReason {
    /// The ray segment passes farther from the primitive than any error allows.
    Far,
    /// Robustly outside two edges.
    Outside,
    /// t robustly outside (tmin, tmax).
    Window,
    /// Two coincident vertices: zero area in every implementation.
    Degenerate,
    /// The ray lies exactly in the triangle's plane, in a configuration every implementation
    /// computes exactly (axis-aligned plane, identity transforms): culled (spec, "Ray Face Culling":
    /// a = 0 intersects no face).
    InPlane,
}

/// The classification of a pair from its certified signs.
pub fn classify(signs: &TriangleSigns) -> PairClass {
    let e = &signs.edges;
    if e.contains(&EdgeSide::Positive) && e.contains(&EdgeSide::Negative) {
        return PairClass::ReqMiss(MissReason::Outside);
    }
    if signs.window == WindowSide::Outside {
        return PairClass::ReqMiss(MissReason::Window);
    }
    let inside =
        e.iter().all(|s| *s == EdgeSide::Positive) || e.iter().all(|s| *s == EdgeSide::Negative);
    if inside {
        match signs.window {
            WindowSide::Inside => PairClass::ReqHit,
            _ => PairClass::Vary(VaryReason::Window),
        }
    } else if signs.orientation.is_none() {
        PairClass::Vary(VaryReason::Grazing)
    } else {
        PairClass::Vary(VaryReason::Edge)
    }
}

/// A closed interval of f64.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Interval {
    pub lo: f64,
    pub hi: f64,
}

impl Interval {
    pub const ALL: Interval = Interval {
        lo: f64::NEG_INFINITY,
        hi: f64::INFINITY,
    };
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }
    pub fn mid(&self) -> f64 {
        if self.lo.is_finite() && self.hi.is_finite() {
            0.5 * (self.lo + self.hi)
        } else {
            f64::NAN
        }
    }
    pub fn radius(&self) -> f64 {
        0.5 * (self.hi - self.lo)
    }
    pub fn hull(&self, o: &Interval) -> Interval {
        Interval {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
}

/// `[n ± bn] / [s ± bs]` for `|s| > bs`, widened by `rel`.
pub fn quotient(n: f64, bn: f64, s: f64, bs: f64, rel: f64) -> Interval {
    if s.abs() <= bs || !n.is_finite() || !s.is_finite() || bs.is_nan() {
        return Interval::ALL;
    }
    let cands = [
        (n - bn) / (s - bs),
        (n - bn) / (s + bs),
        (n + bn) / (s - bs),
        (n + bn) / (s + bs),
    ];
    let lo = cands.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = cands.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let w = rel * lo.abs().max(hi.abs());
    Interval {
        lo: lo - w,
        hi: hi + w,
    }
}

/// The t and barycentric intervals of a pair (sound enclosures, f64).
pub fn triangle_intervals(
    values: &TriangleValues,
    band: &TriangleBand,
) -> (Interval, [Interval; 2]) {
    let (s, es) = values.sum;
    let (n, en) = values.plane;
    let t = quotient(n, band.plane + en, s, band.sum + es, band.t_rel);
    let bary = [1, 2].map(|i| {
        let (e, ee) = values.edge[i];
        quotient(e, band.edge[i] + ee, s, band.sum + es, band.t_rel)
    });
    (t, bary)
}
