//! Run-level numbers: verdict counts, VARY share, and log-scale histograms (median, p99, max) of
//! the t and barycentric errors across rays and cases. Serialisable.

use super::judge::{RayJudgement, RayVerdict};
use serde::{Deserialize, Serialize};

/// Buckets per power of two.
const SUB: f64 = 4.0;
/// Lowest bucket: 2^-64.
const LOW: i32 = -64 * 4;

/// The smallest f64 at or above 2^(1/4), 2^(2/4) and 2^(3/4): as each power is irrational, a
/// significand `m` in [1, 2) is at least 2^(k/4) exactly when it is at least the k-th of these.
const QUARTER_POWERS: [f64; 3] = [
    1.189_207_115_002_721_2,
    std::f64::consts::SQRT_2,
    1.681_792_830_507_429_2,
];

/// The bucket of a positive finite `x`: `floor(4·log2 x) − LOW`, at least 0, decided exactly from
/// its exponent and significand (no logarithm, whose rounding may cross a bucket's edge).
fn bucket_of(x: f64) -> usize {
    // Below 2^-64 (subnormals too) is the lowest bucket.
    if x < f64::from_bits(((1023 - 64) as u64) << 52) {
        return 0;
    }
    let bits = x.to_bits();
    let exponent = ((bits >> 52) & 0x7ff) as i32 - 1023;
    let significand = f64::from_bits((bits & ((1 << 52) - 1)) | (1023 << 52));
    let quarters = QUARTER_POWERS.iter().filter(|&&q| significand >= q).count() as i32;
    (exponent * SUB as i32 + quarters - LOW) as usize
}

/// A histogram of non-negative values on a log scale (quarter powers of two), exact maximum.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    pub count: u64,
    pub zeros: u64,
    pub max: f64,
    /// Bucket `i` counts values in `[2^((LOW + i)/4), 2^((LOW + i + 1)/4))`.
    pub buckets: Vec<u64>,
}

impl Histogram {
    pub fn add(&mut self, x: f64) {
        if !x.is_finite() || x < 0.0 {
            self.max = f64::INFINITY;
            self.count += 1;
            let n = self.buckets.len().max(1);
            self.buckets.resize(n, 0);
            *self.buckets.last_mut().expect("one bucket") += 1;
            return;
        }
        self.count += 1;
        self.max = self.max.max(x);
        if x == 0.0 {
            self.zeros += 1;
            return;
        }
        let i = bucket_of(x);
        if self.buckets.len() <= i {
            self.buckets.resize(i + 1, 0);
        }
        self.buckets[i] += 1;
    }

    pub fn merge(&mut self, o: &Histogram) {
        self.count += o.count;
        self.zeros += o.zeros;
        self.max = self.max.max(o.max);
        if self.buckets.len() < o.buckets.len() {
            self.buckets.resize(o.buckets.len(), 0);
        }
        for (a, b) in self.buckets.iter_mut().zip(&o.buckets) {
            *a += b;
        }
    }

    /// The q-quantile (upper edge of its bucket; 0 for zeros), `None` when empty.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let rank = ((q * self.count as f64).ceil() as u64).clamp(1, self.count);
        if rank <= self.zeros {
            return Some(0.0);
        }
        let mut seen = self.zeros;
        for (i, n) in self.buckets.iter().enumerate() {
            seen += n;
            if seen >= rank {
                let upper = 2f64.powf((LOW + i as i32 + 1) as f64 / SUB);
                return Some(upper.min(self.max));
            }
        }
        Some(self.max)
    }

    pub fn median(&self) -> Option<f64> {
        self.quantile(0.5)
    }
    pub fn p99(&self) -> Option<f64> {
        self.quantile(0.99)
    }
}

/// Counts and error histograms over many judged rays.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub rays: u64,
    pub pass: u64,
    pub warn: u64,
    pub fail: u64,
    /// Rays whose allowed set had a VARY part.
    pub vary: u64,
    pub t_error_ulps: Histogram,
    pub t_error_rel: Histogram,
    pub bary_error_abs: Histogram,
    pub bary_error_ulps: Histogram,
}

impl Summary {
    pub fn add(&mut self, j: &RayJudgement) {
        self.rays += 1;
        match j.verdict {
            RayVerdict::Pass => self.pass += 1,
            RayVerdict::Warn(_) => self.warn += 1,
            RayVerdict::Fail(_) => self.fail += 1,
        }
        if j.vary {
            self.vary += 1;
        }
        let put = |h: &mut Histogram, x: Option<f64>| {
            if let Some(x) = x {
                h.add(x);
            }
        };
        put(&mut self.t_error_ulps, j.t_error_ulps);
        put(&mut self.t_error_rel, j.t_error_rel);
        put(&mut self.bary_error_abs, j.bary_error_abs);
        put(&mut self.bary_error_ulps, j.bary_error_ulps);
    }

    pub fn merge(&mut self, o: &Summary) {
        self.rays += o.rays;
        self.pass += o.pass;
        self.warn += o.warn;
        self.fail += o.fail;
        self.vary += o.vary;
        self.t_error_ulps.merge(&o.t_error_ulps);
        self.t_error_rel.merge(&o.t_error_rel);
        self.bary_error_abs.merge(&o.bary_error_abs);
        self.bary_error_ulps.merge(&o.bary_error_ulps);
    }

    /// Share of rays with a VARY part.
    pub fn vary_share(&self) -> f64 {
        self.vary as f64 / self.rays.max(1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracer::arith::{Dyadic, Num};
    use std::cmp::Ordering;

    /// `x^4 − 2^k`'s sign, exactly.
    fn fourth_power_against(x: f64, k: i32) -> Ordering {
        let d = Dyadic::from_f64(x);
        let fourth = d.mul(&d).mul(&d.mul(&d));
        fourth
            .sub(&Dyadic::from_f64(2f64.powi(k)))
            .sign()
            .expect("exact")
    }

    #[test]
    fn the_quarter_powers_are_the_least_doubles_at_or_above_their_roots() {
        for (k, &q) in QUARTER_POWERS.iter().enumerate() {
            let k = k as i32 + 1;
            assert_eq!(fourth_power_against(q, k), Ordering::Greater, "2^({k}/4)");
            let below = f64::from_bits(q.to_bits() - 1);
            assert_eq!(fourth_power_against(below, k), Ordering::Less, "2^({k}/4)");
        }
    }

    #[test]
    fn a_value_falls_in_the_quarter_power_of_two_that_holds_it() {
        // Bucket i holds [2^((LOW + i)/4), 2^((LOW + i + 1)/4)).
        let holds = |x: f64, i: usize| {
            let k = LOW + i as i32;
            let lo = (k.div_euclid(4), k.rem_euclid(4));
            let hi = ((k + 1).div_euclid(4), (k + 1).rem_euclid(4));
            // 2^(e + r/4) ≤ x ⇔ (x / 2^e)^4 ≥ 2^r, scaling by a power of two being exact here.
            let at_least =
                |(e, r): (i32, i32)| fourth_power_against(x / 2f64.powi(e), r) != Ordering::Less;
            at_least(lo) && !at_least(hi)
        };
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut checked = 0;
        for _ in 0..2000 {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let x = 2f64.powf((seed >> 11) as f64 / (1u64 << 53) as f64 * 120.0 - 60.0);
            assert!(holds(x, bucket_of(x)), "{x:e} in bucket {}", bucket_of(x));
            checked += 1;
        }
        // Either side of every bucket edge in [1, 4): the edge itself rounded up, and the double below.
        for e in 0..2 {
            for &q in [1.0].iter().chain(&QUARTER_POWERS) {
                let edge = q * 2f64.powi(e);
                for x in [edge, f64::from_bits(edge.to_bits() - 1)] {
                    assert!(holds(x, bucket_of(x)), "{x:e} in bucket {}", bucket_of(x));
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 2016);
        assert_eq!(bucket_of(1e-300), 0);
        assert_eq!(bucket_of(1.0), (-LOW) as usize);
    }
}
