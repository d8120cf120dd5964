//! Axes: linear and base-10 logarithmic scales, data ranges, "nice" tick positions (1, 2, 5 times
//! a power of ten; decades on log axes) and their labels.

/// How data values map to positions along an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    Linear,
    /// Base-10 logarithmic; values ≤ 0 are not drawn.
    Log10,
}

/// One axis of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub label: String,
    pub scale: Scale,
    /// The range shown; `None` takes the data's range, padded.
    pub range: Option<(f64, f64)>,
}

impl Axis {
    pub fn new(label: &str, scale: Scale) -> Axis {
        Axis {
            label: label.to_string(),
            scale,
            range: None,
        }
    }

    /// The same axis with a fixed range.
    pub fn with_range(mut self, lo: f64, hi: f64) -> Axis {
        self.range = Some((lo, hi));
        self
    }

    /// Whether a value can be drawn on this axis.
    pub fn accepts(&self, v: f64) -> bool {
        v.is_finite() && (self.scale == Scale::Linear || v > 0.0)
    }

    /// The value in the axis's own coordinate (log10 for log axes).
    pub fn forward(&self, v: f64) -> f64 {
        match self.scale {
            Scale::Linear => v,
            Scale::Log10 => v.log10(),
        }
    }

    /// The range to draw for these data values: the fixed range, or the data's range padded by
    /// 5% (linear) or a tenth of a decade (log), never empty.
    pub fn resolve(&self, values: impl Iterator<Item = f64>) -> (f64, f64) {
        if let Some(r) = self.range {
            return r;
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values.filter(|v| self.accepts(*v)) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !lo.is_finite() {
            return match self.scale {
                Scale::Linear => (0.0, 1.0),
                Scale::Log10 => (1.0, 10.0),
            };
        }
        match self.scale {
            Scale::Linear => {
                if lo == hi {
                    let w = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
                    (lo - w, hi + w)
                } else {
                    let pad = 0.05 * (hi - lo);
                    (lo - pad, hi + pad)
                }
            }
            Scale::Log10 => {
                let (a, b) = (lo.log10(), hi.log10());
                let pad = if a == b { 0.5 } else { 0.1 * (b - a).max(0.5) };
                (10f64.powf(a - pad), 10f64.powf(b + pad))
            }
        }
    }
}

/// Tick positions in `[lo, hi]`: for linear axes multiples of 1, 2 or 5 × 10^k, at most about
/// `max_ticks`; for log axes the decades inside, thinned to at most `max_ticks` (with 2 and 5
/// within the decade added when the range spans under two decades).
pub fn ticks(lo: f64, hi: f64, scale: Scale, max_ticks: usize) -> Vec<f64> {
    let max_ticks = max_ticks.max(2);
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return Vec::new();
    }
    match scale {
        Scale::Linear => {
            let raw = (hi - lo) / max_ticks as f64;
            let mut e = raw.log10().floor() as i32;
            let mut m = [1i64, 2, 5, 10]
                .into_iter()
                .find(|m| (hi - lo) / (*m as f64 * 10f64.powi(e)) <= max_ticks as f64)
                .unwrap_or(10);
            if m == 10 {
                m = 1;
                e += 1;
            }
            // i·m·10^e with the power of ten applied last, so 3 × 0.2 prints as 0.6.
            let value = |i: i64| {
                if e < 0 {
                    (i * m) as f64 / 10f64.powi(-e)
                } else {
                    (i * m) as f64 * 10f64.powi(e)
                }
            };
            let step = m as f64 * 10f64.powi(e);
            let first = (lo / step - 1e-9).ceil() as i64;
            let last = (hi / step + 1e-9).floor() as i64;
            (first..=last)
                .map(value)
                .filter(|v| *v >= lo - step * 1e-9 && *v <= hi + step * 1e-9)
                .collect()
        }
        Scale::Log10 => {
            if lo <= 0.0 {
                return Vec::new();
            }
            let (a, b) = (lo.log10().ceil() as i32, hi.log10().floor() as i32);
            let decades: Vec<i32> = (a..=b).collect();
            if decades.len() < 2 {
                let mut out = Vec::new();
                for k in (a - 1)..=b {
                    for m in [1.0, 2.0, 5.0] {
                        let v = m * 10f64.powi(k);
                        if v >= lo && v <= hi {
                            out.push(v);
                        }
                    }
                }
                return out;
            }
            let every = decades.len().div_ceil(max_ticks).max(1);
            decades
                .iter()
                .filter(|k| (**k - a) as usize % every == 0)
                .map(|k| 10f64.powi(*k))
                .collect()
        }
    }
}

/// A short label for a tick value: plain decimals between 1e-3 and 1e5, otherwise `1e-7`,
/// `2.5e6`.
pub fn format_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let s = format!("{v:.6}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        return s.to_string();
    }
    let e = a.log10().floor() as i32;
    let m = v / 10f64.powi(e);
    let m = format!("{m:.2}");
    let m = m.trim_end_matches('0').trim_end_matches('.');
    format!("{m}e{e}")
}
