//! The rest of a pair's classification in plain f64, after the pre-test's edge functions
//! ([`super::outside`]): the sum `S`, the plane distance `N` and the window gaps, each with an
//! error bound derived once from the magnitudes of the inputs, and every sign the filter's
//! [`triangle_signs`] decides, certified against the same band constants, in the same order,
//! with the same early returns. Where one sign is not certified, nothing is returned and the filter
//! (then exact arithmetic) classifies the pair as before. Where every one is, each is the exact
//! sign of the same quantity against the same constant, so the classification is the one the
//! filter or exact arithmetic gives; the values are the filter's bit for bit (the same operations
//! in the same order), and only their error bounds differ: these, not the filter's running ones,
//! both sound. A ray through a triangle is the pair this is for: there the filter's error-tracked
//! evaluation took about a thousand instructions a pair (callgrind, `launch_instructions`), this
//! about a third of that.
//!
//! The bounds. Notation of `outside.rs`: `â_k = fl(ŵ_k − o)` within `δ` of the exact `a_k`
//! componentwise, `A` the largest `|â_{k,c}|`, `E` the bound of each `|ê_i − e_i|`, `u` the unit
//! roundoff; `D = Σ_c |â_{0,c}|`.
//! - `Ŝ = fl(fl(ê₀ + ê₁) + ê₂)`: `|Ŝ − S| ≤ 3E + u·|ê₀ + ê₁| + u·|fl(ê₀ + ê₁) + ê₂|
//!   ≤ 3E + 2.01u·Σ|ê_i|`.
//! - `N̂ = fl(â₀ · fl(â₁ × â₂))`, the dot and cross in the filter's order: taking the `â` as exact,
//!   its rounding is below `16u·D·A²` (`outside.rs`'s derivation for `ê_i`, with `â₀` for `d`);
//!   and `|â₀·(â₁ × â₂) − a₀·(a₁ × a₂)| ≤ |(â₀ − a₀)·(â₁ × â₂)| + |a₀·(â₁ × â₂ − a₁ × a₂)|
//!   ≤ 3δ·2A² + (D + 3δ)·2(2Aδ + δ²)` (each cross component of `â`s at most `2A²`, and within
//!   `2(2Aδ + δ²)` of the exact one).
//! - a window gap `ĝ = fl(N̂ − fl(τ·Ŝ))` or `fl(fl(τ·Ŝ) − N̂)`, `τ` the ray's f32 tmin or tmax (an
//!   exact f64): `|ĝ − g| ≤ E_N + |τ|·E_S + u·|τ|·|Ŝ| + 2u·|ĝ|` (the product's rounding, then the
//!   difference's, `u·|x| ≤ 2u·|fl(x)|`).
//! - the sign of `x − b` for an f64 constant `b` (a band, or a window's band): `fl(x̂ − b)` is
//!   within `E_x + 2u·|fl(x̂ − b)|` of `x − b`, so its sign is certified where it exceeds that.
//!
//! Each bound is evaluated with the relative slack `GROW` of `outside.rs` (far above the rounding
//! of its dozen non-negative operations) and the sum and plane bounds with an absolute `10⁻³⁰⁰`
//! (far above the absolute error of subnormal results). A value or bound that is not finite
//! certifies nothing (the bounds assume no overflow).

use super::band::TriangleBand;
use super::outside::PlainEdges;
use super::triangle::{EdgeSide, TriangleSigns, TriangleValues, WindowSide};
use std::cmp::Ordering;

/// Unit roundoff of f64.
const U: f64 = f64::EPSILON / 2.0;

/// Relative slack on each bound computed here (see the module comment).
const GROW: f64 = 1.0 + 1e-9;

/// A plain f64 value with an a-priori bound on its distance to the exact value.
#[derive(Clone, Copy)]
struct Plain {
    value: f64,
    error: f64,
}

impl Plain {
    /// The certified sign of `exact − b`, None where the bound does not decide it (or a value is
    /// not finite).
    #[inline(always)]
    fn above(self, b: f64, scale: f64) -> Option<Ordering> {
        let g = self.value - b;
        let bound = (self.error + 2.0 * U * g.abs()) * GROW * scale;
        if !(g.is_finite() && bound.is_finite()) {
            None
        } else if g > bound {
            Some(Ordering::Greater)
        } else if g < -bound {
            Some(Ordering::Less)
        } else {
            None
        }
    }

    /// The certified sign of `exact + b`.
    #[inline(always)]
    fn below(self, b: f64, scale: f64) -> Option<Ordering> {
        self.neg().above(b, scale).map(Ordering::reverse)
    }

    /// Where the exact value stands against the band `[−b, b]`, as the filter's edge sides and
    /// orientation decide it: above `b`, below `−b`, or neither (each comparison certified, in
    /// that order).
    #[inline(always)]
    fn side(self, b: f64, scale: f64) -> Option<EdgeSide> {
        Some(if self.above(b, scale)? == Ordering::Greater {
            EdgeSide::Positive
        } else if self.below(b, scale)? == Ordering::Less {
            EdgeSide::Negative
        } else {
            EdgeSide::Band
        })
    }

    #[inline(always)]
    fn neg(self) -> Plain {
        Plain {
            value: -self.value,
            error: self.error,
        }
    }
}

impl PlainEdges {
    /// The signs and values of the pair (with the bounds of the module comment), as the filter's
    /// [`triangle_signs`] returns them for the ray's `tmin` and `tmax` against `band`; None where a
    /// sign is not certified here.
    #[inline]
    pub(crate) fn signs(
        &self,
        tmin: f32,
        tmax: f32,
        band: &TriangleBand,
    ) -> Option<(TriangleSigns, TriangleValues)> {
        self.signs_scaled(tmin, tmax, band, 1.0)
    }

    /// [`PlainEdges::signs`] with every certifying bound multiplied by `scale` (1 is the proven
    /// test; a test's planted fault shrinks them).
    #[inline(always)]
    fn signs_scaled(
        &self,
        tmin: f32,
        tmax: f32,
        band: &TriangleBand,
        scale: f64,
    ) -> Option<(TriangleSigns, TriangleValues)> {
        let e = self.edge.map(|value| Plain {
            value,
            error: self.error,
        });
        let side = |x: Plain, b: f64| x.side(b, scale);
        let mut values = TriangleValues {
            edge: [
                (e[0].value, e[0].error),
                (e[1].value, e[1].error),
                (f64::NAN, f64::INFINITY),
            ],
            sum: (f64::NAN, f64::INFINITY),
            plane: (f64::NAN, f64::INFINITY),
        };
        let mut edges = [
            side(e[0], band.edge[0])?,
            side(e[1], band.edge[1])?,
            EdgeSide::Band,
        ];
        let undecided_window = |edges| TriangleSigns {
            edges,
            orientation: None,
            window: WindowSide::Band,
        };
        if edges[0].opposite(edges[1]) {
            return Some((undecided_window(edges), values));
        }
        values.edge[2] = (e[2].value, e[2].error);
        edges[2] = side(e[2], band.edge[2])?;
        if edges.contains(&EdgeSide::Positive) && edges.contains(&EdgeSide::Negative) {
            return Some((undecided_window(edges), values));
        }
        let s = Plain {
            value: e[0].value + e[1].value + e[2].value,
            error: (3.0 * self.error
                + 2.01 * U * (e[0].value.abs() + e[1].value.abs() + e[2].value.abs()))
                * GROW
                + 1e-300,
        };
        let n = self.plane();
        values.sum = (s.value, s.error);
        values.plane = (n.value, n.error);
        let orientation = match s.side(band.sum, scale)? {
            EdgeSide::Positive => Some(Ordering::Greater),
            EdgeSide::Negative => Some(Ordering::Less),
            EdgeSide::Band => None,
        };
        let window = match orientation {
            None => WindowSide::Band,
            Some(o) => {
                let (n, s) = if o == Ordering::Less {
                    (n.neg(), s.neg())
                } else {
                    (n, s)
                };
                // As the filter: t_lo > tmin ⇔ N − tmin·S > B_N + tmin·B_S, and the others.
                let gap = |value: f64, tau: f64| Plain {
                    value,
                    error: (n.error + tau.abs() * s.error + U * tau.abs() * s.value.abs()) * GROW
                        + 2.0 * U * value.abs() * GROW,
                };
                let tmin_t = tmin as f64;
                let k_lo = band.plane + tmin_t * band.sum;
                let lo_gap = gap(n.value - tmin_t * s.value, tmin_t);
                let lo_in = lo_gap.above(k_lo, scale)? == Ordering::Greater;
                let lo_out = lo_gap.neg().above(k_lo, scale)? == Ordering::Greater;
                let (hi_in, hi_out) = if tmax.is_infinite() {
                    (true, false)
                } else {
                    let tmax_t = tmax as f64;
                    let k_hi = band.plane + tmax_t * band.sum;
                    let hi_gap = gap(tmax_t * s.value - n.value, tmax_t);
                    (
                        hi_gap.above(k_hi, scale)? == Ordering::Greater,
                        hi_gap.neg().above(k_hi, scale)? == Ordering::Greater,
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

    /// `N = a₀ · (a₁ × a₂)` as the filter computes its value, with the bound of the module comment.
    #[inline(always)]
    fn plane(&self) -> Plain {
        let [x, y, z] = self.a;
        let c = [
            y[1] * z[2] - y[2] * z[1],
            y[2] * z[0] - y[0] * z[2],
            y[0] * z[1] - y[1] * z[0],
        ];
        let value = x[0] * c[0] + x[1] * c[1] + x[2] * c[2];
        let (big, delta) = (self.big, self.delta);
        let d = x[0].abs() + x[1].abs() + x[2].abs();
        let error = (16.0 * U * d * big * big
            + 6.0 * delta * big * big
            + (d + 3.0 * delta) * 2.0 * (2.0 * big * delta + delta * delta))
            * GROW
            + 1e-300;
        Plain { value, error }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracer::arith::{affine, sub3, triple, v3, BoundedF64, Dyadic, Num};
    use crate::tracer::band::{norm3, triangle_band};
    use crate::tracer::outside::{pre_test, PreTest};
    use crate::tracer::test_support::{for_each_workload_pair, Lcg, RandomTriangle};
    use crate::tracer::triangle::triangle_signs;

    /// What [`verdicts`] counts.
    #[derive(Debug, Default)]
    struct Verdicts {
        /// Pairs the pre-test left for the rest of the classification.
        pairs: usize,
        /// Of those, the ones this module classified.
        certified: usize,
        /// Certified pairs whose signs differ from exact arithmetic's.
        wrong_signs: usize,
        /// Certified pairs with a value farther from the exact one than its bound.
        wrong_bounds: usize,
        /// Certified pairs with a value other than the exact one (so the bounds are put to use).
        inexact: usize,
        /// Certified pairs the filter decides too, whose signs or values differ from the filter's.
        unlike_filter: usize,
    }

    /// Whether `value` is within `error` of `exact`, in exact arithmetic.
    fn within(exact: &Dyadic, (value, error): (f64, f64)) -> bool {
        if !value.is_finite() {
            // A quantity this path did not evaluate carries an infinite bound.
            return error == f64::INFINITY;
        }
        let gap = exact.sub(&Dyadic::from_f64(value));
        let e = Dyadic::from_f64(error);
        gap.sub(&e).sign() != Some(Ordering::Greater) && gap.add(&e).sign() != Some(Ordering::Less)
    }

    /// Over random triangles (similarity-like instance transforms, scales from 1e-3 to 1e3) and
    /// rays aimed at points near their edge lines, inside them, or grazing their plane, with ray
    /// intervals that end near the hit or not at all, the pairs the pre-test leaves to this module
    /// and what it makes of them with its bounds scaled by `scale`: compared with exact arithmetic
    /// (signs, and each value against its bound) and with the filter.
    fn verdicts(scale: f64, adversarial: bool, cases: usize) -> Verdicts {
        let mut rng = Lcg(0x5eed_0b1a);
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
            let wv = world.map(|p| p.map(|x| x.value));
            // A point of the plane: inside, or on an edge line nudged across it.
            let mut w = [rng.unit(), rng.unit(), rng.unit()];
            if case % 4 == 1 {
                w[(case / 4) % 3] = rng.range(-1e-5, 1e-5) * rng.pick(&[1.0, 1e-2, 1e-4]);
            }
            let sum: f64 = w.iter().sum();
            let target = [0, 1, 2].map(|c| (0..3).map(|k| w[k] / sum * wv[k][c]).sum::<f64>());
            let origin: [f32; 3] = if case % 8 == 3 {
                // Grazing: from far along the plane, lifted off it by a little.
                let n = crate::tracer::band::cross_f64(
                    [0, 1, 2].map(|c| wv[1][c] - wv[0][c]),
                    [0, 1, 2].map(|c| wv[2][c] - wv[0][c]),
                );
                let along = [0, 1, 2].map(|c| wv[1][c] - wv[0][c]);
                let lift = rng.range(-1e-4, 1e-4) * rng.pick(&[1.0, 1e-2, 1e-4]) / norm3(n);
                [0, 1, 2].map(|c| (target[c] + 5.0 * along[c] + lift * n[c]) as f32)
            } else {
                [0; 3].map(|_| (rng.range(-8.0, 8.0) * s) as f32)
            };
            let direction: [f32; 3] = [0, 1, 2].map(|c| (target[c] - origin[c] as f64) as f32);
            // The hit is near t = 1: ray intervals that end near it, or that do not.
            let near = |rng: &mut Lcg| {
                (1.0 + rng.range(-1.0, 1.0) * rng.pick(&[1e-2, 1e-4, 1e-6, 1e-7])) as f32
            };
            let (tmin, tmax) = match case % 5 {
                0 => (0.0, f32::INFINITY),
                1 => (near(&mut rng), f32::INFINITY),
                2 => (0.0, near(&mut rng)),
                3 => (0.5, 1e30),
                _ => (near(&mut rng), 2.0),
            };
            let (o64, d64) = (origin.map(|x| x as f64), direction.map(|x| x as f64));
            let b = triangle_band(&band, &wv, &radius, o64, d64, norm3(d64));
            let edges = match pre_test(
                &band,
                [&world[0], &world[1], &world[2]],
                &radius,
                o64,
                norm3(o64),
                d64,
                norm3(d64),
            ) {
                PreTest::Mixed(e) if !e.outside_of(&b) => e,
                PreTest::SameSide(e) => e,
                _ => continue,
            };
            v.pairs += 1;
            let b = if adversarial {
                adversarial_band(&edges, tmin, case, &mut rng)
            } else {
                b
            };
            let Some((signs, values)) = edges.signs_scaled(tmin, tmax, &b, scale) else {
                continue;
            };
            v.certified += 1;
            let exact_world: [[Dyadic; 3]; 3] = obj.map(|p| affine(&transform.0, &v3::<Dyadic>(p)));
            let (o, d) = (v3::<Dyadic>(origin), v3::<Dyadic>(direction));
            let (exact, _) = triangle_signs::<Dyadic>(&exact_world, &o, &d, tmin, tmax, &b)
                .expect("exact arithmetic decides every sign");
            if signs != exact {
                v.wrong_signs += 1;
            }
            let a = [0, 1, 2].map(|k| sub3(&exact_world[k], &o));
            let e = [
                triple(&d, &a[1], &a[2]),
                triple(&d, &a[2], &a[0]),
                triple(&d, &a[0], &a[1]),
            ];
            let sum = e[0].add(&e[1]).add(&e[2]);
            let plane = triple(&a[0], &a[1], &a[2]);
            let bounded = (0..3).all(|i| within(&e[i], values.edge[i]))
                && within(&sum, values.sum)
                && within(&plane, values.plane);
            if !bounded {
                v.wrong_bounds += 1;
            }
            let off = |exact: &Dyadic, (value, _): (f64, f64)| {
                value.is_finite() && !within(exact, (value, 0.0))
            };
            if off(&sum, values.sum) || off(&plane, values.plane) {
                v.inexact += 1;
            }
            if let Some((filter, filter_values)) =
                triangle_signs::<BoundedF64>(&world, &v3(origin), &v3(direction), tmin, tmax, &b)
            {
                let value_bits = |x: &TriangleValues| {
                    [x.edge[0].0, x.edge[1].0, x.edge[2].0, x.sum.0, x.plane.0].map(f64::to_bits)
                };
                if filter != signs || value_bits(&filter_values) != value_bits(&values) {
                    v.unlike_filter += 1;
                }
            }
        }
        v
    }

    /// A band whose constants lie where one sign of the pair hinges on the rounding of its value:
    /// by turns the edge bands, the sum's band or the window's, each at a distance from the
    /// plain value of a few of its bounds, a fraction of one, or one unit in the last place (the
    /// others 0, so the signs before it are robust).
    fn adversarial_band(edges: &PlainEdges, tmin: f32, case: usize, rng: &mut Lcg) -> TriangleBand {
        let mut band = TriangleBand {
            edge: [0.0; 3],
            sum: 0.0,
            plane: 0.0,
            t_rel: 0.0,
        };
        let near = |rng: &mut Lcg, value: f64, error: f64| {
            let ulp = f64::from_bits(value.abs().to_bits() + 1) - value.abs();
            value.abs()
                + rng.pick(&[-2.0, -0.5, 0.5, 2.0]) * error * (rng.unit() < 0.5) as u8 as f64
                + rng.pick(&[-1.0, 1.0]) * ulp
        };
        let s = edges.edge[0] + edges.edge[1] + edges.edge[2];
        match case / 5 % 3 {
            0 => {
                band.edge = edges.edge.map(|e| near(rng, e, edges.error));
            }
            1 => band.sum = near(rng, s, 3.0 * edges.error),
            _ => {
                // Oriented as the classification orients N and S (the sum's band is 0).
                let plane = edges.plane();
                let (n, s) = if s < 0.0 {
                    (-plane.value, -s)
                } else {
                    (plane.value, s)
                };
                let gap = n - tmin as f64 * s;
                band.plane = gap + (near(rng, gap, plane.error) - gap.abs());
            }
        }
        band
    }

    #[test]
    fn what_the_plain_path_certifies_is_exact_and_the_filters() {
        let v = verdicts(1.0, false, 30_000);
        assert_eq!(v.wrong_signs, 0, "{v:?}");
        assert_eq!(v.wrong_bounds, 0, "{v:?}");
        assert_eq!(v.unlike_filter, 0, "{v:?}");
        // Random rays are rarely within rounding of a band's edge: the bounds decide them all.
        assert!(v.pairs > 20_000, "{v:?}");
        assert!(v.inexact > v.pairs / 2, "{v:?}");
        assert_eq!(v.certified, v.pairs, "{v:?}");
    }

    #[test]
    fn against_bands_at_the_rounding_of_its_values_the_plain_path_is_exact() {
        let v = verdicts(1.0, true, 30_000);
        assert_eq!(v.wrong_signs, 0, "{v:?}");
        assert_eq!(v.wrong_bounds, 0, "{v:?}");
        assert_eq!(v.unlike_filter, 0, "{v:?}");
        // Bands a few bounds away are decided here, the others left to the filter.
        assert!(v.certified > v.pairs / 10, "{v:?}");
        assert!(v.certified < v.pairs * 9 / 10, "{v:?}");
    }

    #[test]
    fn the_plain_path_without_its_bounds_takes_signs_it_cannot_know() {
        // The planted fault: bounds shrunk to 0 take each sign at face value, and against bands a
        // unit in the last place from the values, a quarter of them come out wrong. (A tenth or a
        // hundredth of the bounds still decides these exactly: the bounds are a-priori ones, far
        // above the roundings of most pairs.)
        let v = verdicts(0.0, true, 30_000);
        assert!(v.wrong_signs > 3_000, "{v:?}");
    }

    #[test]
    fn on_the_standard_workloads_the_plain_path_gives_the_filters_signs_and_values() {
        let (mut certified, mut pairs) = (0, 0);
        for_each_workload_pair(|p| {
            let edges = match p.pre_test() {
                PreTest::Mixed(e) if !e.outside_of(&p.band) => e,
                PreTest::SameSide(e) => e,
                _ => return,
            };
            pairs += 1;
            let ray = p.ray;
            let Some((signs, values)) = edges.signs(ray.tmin, ray.tmax, &p.band) else {
                return;
            };
            certified += 1;
            let (filter, filter_values) = p.filter();
            assert_eq!(signs, filter, "{}: {ray:?}", p.workload);
            for (x, y) in [
                (values.edge[0], filter_values.edge[0]),
                (values.edge[1], filter_values.edge[1]),
                (values.edge[2], filter_values.edge[2]),
                (values.sum, filter_values.sum),
                (values.plane, filter_values.plane),
            ] {
                assert_eq!(x.0.to_bits(), y.0.to_bits(), "{}: {ray:?}", p.workload);
            }
        });
        assert!(
            certified > 0 && certified == pairs,
            "{certified} of {pairs}"
        );
    }
}
