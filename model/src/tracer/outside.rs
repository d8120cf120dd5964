//! A plain-f64 pre-test that certifies the commonest REQ-miss, a ray robustly outside two edges of
//! a triangle, before the band and the error-tracked edge functions are computed: three edge
//! functions in plain f64 with one a-priori error bound, against one upper bound of the three edge
//! bands. Where it certifies, the exact signs of two edge functions against their bands are
//! opposite, so the full classification (filter or exact) is `ReqMiss(Outside)` too; otherwise it
//! decides nothing, and its edge functions and their bound go on to [`super::plain`], which
//! classifies the pair from them where its own bounds decide, before the filter's error-tracked
//! evaluation does.
//!
//! A pair of mixed signs at face value that the upper bound leaves undecided (about one in fifty on
//! the standard workloads, mostly rays passing near an edge line of a triangle they miss) is tried
//! once more against the pair's own bands `B_i` ([`super::band::triangle_band`], which the full
//! classification computes first anyway), before the error-tracked edge functions:
//! [`PlainEdges::outside_of`].
//!
//! The error bound. World vertices `ŵ_k` are f64 values within `ε` (the largest error bound of their
//! coordinates) of the exact `w_k`; `o`, `d` are exact. `â_k = fl(ŵ_k − o)` is within
//! `δ = ε + u·|â|/(1 − u) ≤ ε + 2u·A` of `a_k = w_k − o`, componentwise, with `A` the largest
//! `|â_{k,c}|`. With `ê_i = fl(d·fl(â_j × â_k))` (in any order of its sums):
//! - rounding: each cross component `fl(fl(xy) − fl(zw))` is within `(2u + u²)(|xy| + |zw|)` of
//!   `xy − zw`, and `|xy| + |zw| ≤ 2A²`; the three-term dot adds `γ₃·Σ|d_c||ĉ_c|`; in all at most
//!   `5.03u·D₁·2A² < 16u·D₁·A²`, `D₁ = Σ|d_c|`;
//! - input error: `|ab − âb̂| ≤ 2Aδ + δ²` per product, two per cross component, so
//!   `|d·(a_j × a_k) − d·(â_j × â_k)| ≤ D₁·2·(2Aδ + δ²)`.
//!
//! `E = D₁·(2(2Aδ + δ²) + 16u·A²)` is evaluated with a relative slack of 10⁻⁹ (far above the
//! rounding of its dozen non-negative operations) and an absolute `10⁻³⁰⁰` (far above the
//! absolute error of subnormal results), so `|ê_i − e_i| ≤ E`.
//!
//! The band bound. [`super::band::triangle_band`] computes, from the same `â_k`, `len_k = |â_k|`,
//! `perp_k = |â_k × d|/|d| + 10⁻¹²·len_k`, `cross_i = |â_j × â_k| + 10⁻¹²·len_j·len_k` and
//! `α_k = r_k + test_rel·len_k + r_o`; every edge band is a non-negative polynomial in these,
//! increasing in each. With `L = max len_k`, `h` the longest side `|â_k − â_j|`, and `p₀` the
//! computed `|â_0 × d|/|d|`: `|â_k × d|/|d| ≤ |â_0 × d|/|d| + |â_k − â_0|` and
//! `|â_j × â_k| = |â_j × (â_k − â_j)| ≤ L·h`; a computed cross product's norm is within
//! `6u·|x|·|y|` of the exact one (its factors `x`, `y`), and computed norms and sides within `4u`
//! relative, all far below the `10⁻¹²·L` added here and the relative 10⁻⁹, so every computed
//! `perp_k ≤ P̄ = (p₀ + h + 2·10⁻¹²·L)(1 + 10⁻⁹)` and `cross_i ≤ C̄ = (L·h + 2·10⁻¹²·L²)
//! (1 + 10⁻⁹)`. `ᾱ = R + test_rel·L + r_o` (`R = max r_k`, the same operations, so at least every
//! computed `α_k`) and `B̄ = |d|·(2ᾱP̄ + ᾱ² + P·(C̄ + 2ᾱL + ᾱ²))·SLACK` bounds every computed
//! `B_i` once a relative 10⁻⁹ covers the two evaluations' roundings (each under 30 operations on
//! non-negative values, so within `(1 ± u)^30`).
//! Both add [`super::band::underflow_floor`]'s edge term, the same increasing function of the
//! largest distance (`L`) and `|d|`.
//!
//! The test. `T = (B̄ + E)·(1 + 10⁻⁹) ≥ B̄ + E`; `ê_i > T` gives `e_i ≥ ê_i − E > B̄ ≥ B_i`
//! (the band's Positive side), `ê_i < −T` gives `e_i < −B_i` (Negative). Non-finite values fail
//! every comparison or are refused, so overflow and NaN decide nothing. The second test is the
//! same with each edge's own computed band: `T_i = (B_i + E)·(1 + 10⁻⁹)`, `ê_i > T_i` gives
//! `e_i > B_i`; the full classification compares the same `e_i` with the same `B_i`.

use super::arith::BoundedF64;
use super::band::{norm3, underflow_floor, InstanceBand, TriangleBand};

/// Unit roundoff of f64.
const U: f64 = f64::EPSILON / 2.0;

/// Relative slack on each bound computed here (see the module comment).
const GROW: f64 = 1.0 + 1e-9;

/// What the pre-test found of a pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum PreTest {
    /// The exact edge functions are robustly on opposite sides of the bands of two of its edges
    /// (the pair is `ReqMiss(Outside)` in every certified classification).
    Outside,
    /// Signs of both kinds at face value, the upper bound of the bands too wide to certify them:
    /// the edge functions, for the test against the pair's own bands (and then for the rest of
    /// the classification in plain f64, [`PlainEdges::signs`]).
    Mixed(PlainEdges),
    /// No two signs opposite at face value (mostly a ray through the triangle): the edge functions,
    /// for the rest of the classification in plain f64.
    SameSide(PlainEdges),
    /// Nothing certified, and nothing to go on with (a value not finite).
    Undecided,
}

/// A pair's edge functions in plain f64 and their a-priori error bound `E` (see the module
/// comment), with what they were computed from: the vertices less the origin `â_k` (as the filter
/// computes them), their largest magnitude `A` and their componentwise error bound `δ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PlainEdges {
    pub(super) edge: [f64; 3],
    pub(super) error: f64,
    pub(super) a: [[f64; 3]; 3],
    pub(super) big: f64,
    pub(super) delta: f64,
}

impl PlainEdges {
    /// Whether two of the exact edge functions are robustly on opposite sides of their bands `band`
    /// (the pair's own, as [`super::band::triangle_band`] computes them from the same world
    /// vertices and ray): then the pair is `ReqMiss(Outside)` in every certified classification.
    #[inline]
    pub(crate) fn outside_of(&self, band: &TriangleBand) -> bool {
        self.outside_of_scaled(band, 1.0)
    }

    /// [`PlainEdges::outside_of`] with the bounds multiplied by `scale` (1 is the proven test).
    #[inline(always)]
    fn outside_of_scaled(&self, band: &TriangleBand, scale: f64) -> bool {
        let t = |i: usize| (band.edge[i] + self.error) * GROW * scale;
        // Also false where a bound is NaN or infinite.
        let positive = (0..3).any(|i| self.edge[i] > t(i));
        let negative = (0..3).any(|i| self.edge[i] < -t(i));
        positive && negative
    }
}

/// The pre-test of a pair.
#[inline]
pub(crate) fn pre_test(
    band: &InstanceBand,
    world: [&[BoundedF64; 3]; 3],
    static_radius: &[f64; 3],
    origin: [f64; 3],
    origin_norm: f64,
    direction: [f64; 3],
    direction_norm: f64,
) -> PreTest {
    outside_with(
        band,
        world,
        static_radius,
        origin,
        origin_norm,
        direction,
        direction_norm,
        1.0,
    )
}

/// [`pre_test`] (`origin_norm` is `norm3(origin)`, `direction_norm` `norm3(direction)`) with both
/// bounds multiplied by `scale` (1 is the proven test; a test's planted fault shrinks them).
#[inline(always)]
#[allow(clippy::too_many_arguments)] // `pre_test`'s arguments and the test's scale
fn outside_with(
    band: &InstanceBand,
    world: [&[BoundedF64; 3]; 3],
    static_radius: &[f64; 3],
    origin: [f64; 3],
    origin_norm: f64,
    direction: [f64; 3],
    direction_norm: f64,
    scale: f64,
) -> PreTest {
    let mut a = [[0f64; 3]; 3];
    let (mut big, mut eps) = (0f64, 0f64);
    for k in 0..3 {
        for c in 0..3 {
            // As `triangle_band` computes it.
            a[k][c] = world[k][c].value - origin[c];
            big = big.max(a[k][c].abs());
            eps = eps.max(world[k][c].error);
        }
    }
    let [d0, d1, d2] = direction;
    let e = |x: &[f64; 3], y: &[f64; 3]| {
        d0 * (x[1] * y[2] - x[2] * y[1])
            + d1 * (x[2] * y[0] - x[0] * y[2])
            + d2 * (x[0] * y[1] - x[1] * y[0])
    };
    let edge = [e(&a[1], &a[2]), e(&a[2], &a[0]), e(&a[0], &a[1])];
    if !(edge[0].is_finite() & edge[1].is_finite() & edge[2].is_finite()) {
        return PreTest::Undecided;
    }
    let d1_norm = d0.abs() + d1.abs() + d2.abs();
    let delta = (eps + 2.0 * U * big) * GROW;
    let error = d1_norm * (2.0 * (2.0 * big * delta + delta * delta) + 16.0 * U * big * big) * GROW
        + 1e-300;
    let plain = PlainEdges {
        edge,
        error,
        a,
        big,
        delta,
    };
    // Signs that are not opposite at face value are not opposite certified either. The
    // comparisons are joined bit by bit, not short-circuited: one branch on the verdict rather
    // than one per comparison, each as hard to predict as the pair's outcome.
    let mixed = ((edge[0] > 0.0) | (edge[1] > 0.0) | (edge[2] > 0.0))
        & ((edge[0] < 0.0) | (edge[1] < 0.0) | (edge[2] < 0.0));
    if !mixed {
        return PreTest::SameSide(plain);
    }
    let square = |v: [f64; 3]| v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    // The largest of the three `norm3`s: the square root is monotone.
    let len = square(a[0]).max(square(a[1])).max(square(a[2])).sqrt();
    let side = |x: &[f64; 3], y: &[f64; 3]| square([x[0] - y[0], x[1] - y[1], x[2] - y[2]]);
    let longest = side(&a[1], &a[0])
        .max(side(&a[2], &a[1]))
        .max(side(&a[0], &a[2]))
        .sqrt();
    let dn = direction_norm;
    let [x, y, z] = a[0];
    let perp_0 = norm3([y * d2 - z * d1, z * d0 - x * d2, x * d1 - y * d0]) / dn;
    let perp = (perp_0 + longest + 2e-12 * len) * GROW;
    let cross = (len * longest + 2e-12 * len * len) * GROW;
    let radius = static_radius[0].max(static_radius[1]).max(static_radius[2]);
    // `band.origin_radius(origin)`, its norm given.
    let alpha = radius + band.test_rel * len + band.origin_coef * (origin_norm + band.norm_t);
    let p = band.direction_rel;
    let edge_band = (dn
        * (2.0 * alpha * perp + alpha * alpha + p * (cross + 2.0 * alpha * len + alpha * alpha))
        + underflow_floor(band, len, dn).0)
        * (1.0 + 1e-9)
        * GROW;
    let t = (edge_band + error) * GROW * scale;
    // Also false where `t` is NaN or infinite (joined bit by bit, as above).
    let positive = (edge[0] > t) | (edge[1] > t) | (edge[2] > t);
    let negative = (edge[0] < -t) | (edge[1] < -t) | (edge[2] < -t);
    if positive & negative {
        PreTest::Outside
    } else {
        PreTest::Mixed(plain)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracer::arith::{affine, sub3, triple, v3, Dyadic, Num};
    use crate::tracer::band::triangle_band;
    use crate::tracer::test_support::{for_each_workload_pair, Lcg, RandomTriangle};
    use std::cmp::Ordering;

    /// What [`verdicts`] counts: pairs called outside by the upper bound of the bands, by the
    /// pair's own bands after it, and of all those the ones unsound.
    #[derive(Debug, Default)]
    struct Verdicts {
        by_upper_bound: usize,
        by_own_bands: usize,
        unsound: usize,
    }

    /// Over random triangles (random similarity-like instance transforms, scales from 1e-3 to 1e3)
    /// and rays aimed at points near their edge lines — just inside and just outside the band —,
    /// the pairs the pre-test calls outside (by the upper bound of the bands scaled by `upper`, or
    /// where that leaves mixed signs, by the pair's own bands scaled by `own`), and of those the
    /// ones whose exact edge signs against the band are not opposite on two edges (unsound).
    fn verdicts([upper, own]: [f64; 2], cases: usize) -> Verdicts {
        let mut rng = Lcg(0x5eed_0017);
        let mut v = Verdicts::default();
        for case in 0..cases {
            let s = [1e-3, 1.0, 1e3][case % 3];
            let RandomTriangle {
                transform,
                band,
                obj,
                world,
                radius,
            } = RandomTriangle::new(&mut rng, case, s);
            let origin: [f32; 3] = [0; 3].map(|_| (rng.range(-8.0, 8.0) * s) as f32);
            // A point on an edge line, nudged across it by a few band widths either way.
            let (i, j) = [(0, 1), (1, 2), (2, 0)][(rng.unit() * 3.0) as usize];
            let f = rng.range(-0.5, 1.5);
            let wv = world.map(|v| v.map(|x| x.value));
            let mut target = [0, 1, 2].map(|c| wv[i][c] + f * (wv[j][c] - wv[i][c]));
            let centre = [0, 1, 2].map(|c| (wv[0][c] + wv[1][c] + wv[2][c]) / 3.0);
            let nudge = rng.range(-1e-5, 1e-5) * [1.0, 1e-2, 1e-4][case % 3];
            for c in 0..3 {
                target[c] += nudge * (target[c] - centre[c]);
            }
            let direction: [f32; 3] = [0, 1, 2].map(|c| (target[c] - origin[c] as f64) as f32);
            let (o64, d64) = (origin.map(|x| x as f64), direction.map(|x| x as f64));
            let b = triangle_band(&band, &wv, &radius, o64, d64, norm3(d64));
            match outside_with(
                &band,
                [&world[0], &world[1], &world[2]],
                &radius,
                o64,
                norm3(o64),
                d64,
                norm3(d64),
                upper,
            ) {
                PreTest::Outside => v.by_upper_bound += 1,
                PreTest::Mixed(edges) if edges.outside_of_scaled(&b, own) => v.by_own_bands += 1,
                _ => continue,
            }
            let exact: [[Dyadic; 3]; 3] = obj.map(|p| affine(&transform.0, &v3::<Dyadic>(p)));
            let a = [0, 1, 2].map(|k| sub3(&exact[k], &v3(origin)));
            let d = v3::<Dyadic>(direction);
            let e = [
                triple(&d, &a[1], &a[2]),
                triple(&d, &a[2], &a[0]),
                triple(&d, &a[0], &a[1]),
            ];
            let side = |k: usize| {
                if e[k].sub(&Dyadic::from_f64(b.edge[k])).sign() == Some(Ordering::Greater) {
                    1
                } else if e[k].add(&Dyadic::from_f64(b.edge[k])).sign() == Some(Ordering::Less) {
                    -1
                } else {
                    0
                }
            };
            let sides = [side(0), side(1), side(2)];
            if !(sides.contains(&1) && sides.contains(&-1)) {
                v.unsound += 1;
            }
        }
        v
    }

    #[test]
    fn what_the_pre_test_calls_outside_is_outside_exactly() {
        let v = verdicts([1.0, 1.0], 20_000);
        assert_eq!(v.unsound, 0, "{v:?}");
        // Most rays miss the edge line by more than the bounds: the upper bound decides them, and
        // the pair's own bands some of those it leaves.
        assert!(v.by_upper_bound > 5_000, "{v:?}");
        assert!(v.by_own_bands > 50, "{v:?}");
    }

    #[test]
    fn the_pre_test_without_its_bounds_calls_band_pairs_outside() {
        // The planted faults: bounds shrunk to 0 take the sign of the f64 value at face value,
        // the upper bound's (which then decides every pair of mixed signs), or the pair's own
        // bands' (the upper bound made infinite, so that it decides none).
        for scales in [[0.0, 1.0], [f64::INFINITY, 0.0]] {
            let v = verdicts(scales, 20_000);
            assert!(v.unsound > 100, "{scales:?}: {v:?}");
        }
    }

    #[test]
    fn on_the_standard_workloads_what_the_pre_test_calls_outside_the_filter_does() {
        use crate::tracer::triangle::{classify, MissReason, PairClass};
        let (mut certified, mut by_own_bands, mut pairs) = (0, 0, 0);
        for_each_workload_pair(|p| {
            pairs += 1;
            match p.pre_test() {
                PreTest::Outside => certified += 1,
                PreTest::Mixed(edges) if edges.outside_of(&p.band) => by_own_bands += 1,
                _ => return,
            }
            let ray = p.ray;
            let (signs, _) = p.filter();
            assert_eq!(
                classify(&signs),
                PairClass::ReqMiss(MissReason::Outside),
                "{}: {ray:?}",
                p.workload
            );
        });
        assert!(certified * 4 > pairs, "{certified} of {pairs}");
        assert!(by_own_bands > 0, "{by_own_bands} of {pairs}");
    }
}
