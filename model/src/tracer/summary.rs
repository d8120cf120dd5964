//! Run-level numbers: verdict counts, VARY share, and log-scale histograms (median, p99, max) of
//! the t and barycentric errors across rays and cases. Serialisable.

use super::judge::{RayJudgement, RayVerdict};
use serde::{Deserialize, Serialize};

/// Buckets per power of two.
const SUB: f64 = 4.0;
/// Lowest bucket: 2^-64.
const LOW: i32 = -64 * 4;

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
        let i = ((x.log2() * SUB).floor() as i32 - LOW).max(0) as usize;
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
