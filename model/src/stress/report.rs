//! The per-family report: what a driver's records for a family's rays say, judged ray by ray with
//! [`crate::tracer::judge::judge`] and summed with [`Summary`] — watertightness double hits
//! (failures: the spec says implementations should not, the CTS fails them) and holes (quality
//! warnings), t and barycentric errors in f32 ULPs, the share of rays the model classed VARY, and
//! what the driver chose on them.

use crate::tracer::judge::{judge, RayVerdict};
use crate::tracer::record::{RayRecord, RecordOutcome};
use crate::tracer::summary::{Histogram, Summary};
use crate::tracer::{AllowedOutcomes, Presence, PrimitiveRef};
use serde::{Deserialize, Serialize};

/// Median, 99th percentile and maximum of an error histogram (quantiles are the upper edges of
/// the summary's quarter-octave buckets; the maximum is exact).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    pub count: u64,
    pub median: Option<f64>,
    pub p99: Option<f64>,
    pub max: Option<f64>,
}

impl ErrorStats {
    pub fn of(h: &Histogram) -> ErrorStats {
        ErrorStats {
            count: h.count,
            median: h.median(),
            p99: h.p99(),
            max: (h.count > 0).then_some(h.max),
        }
    }
}

/// What the driver did on the rays whose allowed set had a VARY part.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct VaryChoices {
    /// Committed a candidate the model required.
    pub hit_required: u64,
    /// Committed a candidate the model only allowed.
    pub hit_possible: u64,
    /// Committed something the model did not allow at all (also counted as a failure).
    pub hit_other: u64,
    pub miss: u64,
    /// Neither a miss nor a closest-hit shader wrote.
    pub no_shader: u64,
    pub not_run: u64,
}

/// The findings kept per report, so a bad driver does not fill memory with messages.
const KEPT_FINDINGS: usize = 32;

/// One family's report over any number of cases.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FamilyReport {
    pub family: String,
    pub cases: u64,
    /// Rays through a shared edge or closed fan whose members would all be confirmed: those
    /// the watertightness counts are out of.
    pub watertight_rays: u64,
    /// Rays on which two members of one watertight group were both reported (failures).
    pub double_hits: u64,
    /// Rays that passed through a watertight group and hit nothing there (quality warnings).
    pub holes: u64,
    /// Failing rays that are not double hits.
    pub other_failures: u64,
    pub on_vary: VaryChoices,
    /// Every judged ray, through [`Summary::add`].
    pub summary: Summary,
    /// The first failures and warnings, as `case#ray: message`.
    pub findings: Vec<String>,
}

impl FamilyReport {
    pub fn new(family: &str) -> FamilyReport {
        FamilyReport {
            family: family.to_string(),
            ..FamilyReport::default()
        }
    }

    /// Judges the records of one case (one per ray, in launch order) against what the model
    /// allows for its rays, and adds them.
    pub fn add_case(&mut self, case: &str, allowed: &[AllowedOutcomes], records: &[RayRecord]) {
        assert_eq!(
            allowed.len(),
            records.len(),
            "{case}: one record per ray is needed"
        );
        self.cases += 1;
        for (i, (a, r)) in allowed.iter().zip(records).enumerate() {
            self.add_ray(&format!("{case}#{i}"), a, r);
        }
    }

    /// Judges and adds one ray.
    pub fn add_ray(&mut self, name: &str, allowed: &AllowedOutcomes, record: &RayRecord) {
        let j = judge(allowed, record);
        self.summary.add(&j);
        if allowed.watertight.iter().any(|g| g.expect_hit) {
            self.watertight_rays += 1;
        }
        let double = double_hit(allowed, record);
        if double {
            self.double_hits += 1;
        }
        // The judge's only warnings are holes in watertight groups.
        if j.findings.iter().any(|f| matches!(f, RayVerdict::Warn(_))) {
            self.holes += 1;
        }
        if matches!(j.verdict, RayVerdict::Fail(_)) && !double {
            self.other_failures += 1;
        }
        if allowed.vary {
            let v = &mut self.on_vary;
            match record.outcome {
                RecordOutcome::Miss => v.miss += 1,
                RecordOutcome::NoShader => v.no_shader += 1,
                RecordOutcome::NotRun => v.not_run += 1,
                RecordOutcome::Hit => match j.chosen.and_then(|p| allowed.candidate(&p)) {
                    Some(c) if c.presence == Presence::Required => v.hit_required += 1,
                    Some(_) => v.hit_possible += 1,
                    None => v.hit_other += 1,
                },
            }
        }
        for f in &j.findings {
            if self.findings.len() >= KEPT_FINDINGS {
                break;
            }
            match f {
                RayVerdict::Fail(m) => self.findings.push(format!("{name}: fail: {m}")),
                RayVerdict::Warn(m) => self.findings.push(format!("{name}: warn: {m}")),
                RayVerdict::Pass => {}
            }
        }
    }

    pub fn rays(&self) -> u64 {
        self.summary.rays
    }

    /// Rays the model classed VARY (any part of the allowed set).
    pub fn vary_share(&self) -> f64 {
        self.summary.vary_share()
    }

    /// |t − t_exact| in f32 ULPs of max(|t_exact|, the ray's reach to the triangle in t), over the
    /// committed hits (see `AllowedReport::t_scale`).
    pub fn t_error_ulps(&self) -> ErrorStats {
        ErrorStats::of(&self.summary.t_error_ulps)
    }

    /// |t − t_exact| over the half width of the allowed t interval (1.0 = at the bound): the
    /// measure that stays meaningful when t_exact is near 0.
    pub fn t_error_bound(&self) -> ErrorStats {
        ErrorStats::of(&self.summary.t_error_rel)
    }

    /// max over (b, c) of the barycentric error in f32 ULPs of the exact value, over the
    /// committed triangle hits (the judge's measure: unbounded for weights that are exactly 0, as
    /// on every edge-aimed ray — see [`FamilyReport::bary_error_eps`]).
    pub fn bary_error_ulps(&self) -> ErrorStats {
        ErrorStats::of(&self.summary.bary_error_ulps)
    }

    /// max over (b, c) of the absolute barycentric error in units of `f32::EPSILON` (the ULP of
    /// 1.0): the measure that stays meaningful for weights near 0.
    pub fn bary_error_eps(&self) -> ErrorStats {
        let s = ErrorStats::of(&self.summary.bary_error_abs);
        let e = f32::EPSILON as f64;
        ErrorStats {
            count: s.count,
            median: s.median.map(|x| x / e),
            p99: s.p99.map(|x| x / e),
            max: s.max.map(|x| x / e),
        }
    }

    pub fn merge(&mut self, o: &FamilyReport) {
        self.cases += o.cases;
        self.watertight_rays += o.watertight_rays;
        self.double_hits += o.double_hits;
        self.holes += o.holes;
        self.other_failures += o.other_failures;
        let (a, b) = (&mut self.on_vary, &o.on_vary);
        a.hit_required += b.hit_required;
        a.hit_possible += b.hit_possible;
        a.hit_other += b.hit_other;
        a.miss += b.miss;
        a.no_shader += b.no_shader;
        a.not_run += b.not_run;
        self.summary.merge(&o.summary);
        let room = KEPT_FINDINGS.saturating_sub(self.findings.len());
        self.findings.extend(o.findings.iter().take(room).cloned());
    }

    /// The header of [`FamilyReport::row`].
    pub fn header() -> String {
        format!(
            "{:<20} {:>6} {:>5} {:>5} {:>5} {:>7} {:>6} {:>6} {:>8} {:>20} {:>15} {:>20} {:>26}",
            "family",
            "rays",
            "fail",
            "warn",
            "other",
            "w-tight",
            "double",
            "holes",
            "VARY %",
            "t ulps med/p99/max",
            "t/bound p99/max",
            "bary eps med/p99/max",
            "on VARY req/pos/miss/other"
        )
    }

    /// One line of a table.
    pub fn row(&self) -> String {
        let e = |s: ErrorStats| {
            let f = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.3}"));
            format!("{}/{}/{}", f(s.median), f(s.p99), f(s.max))
        };
        let v = &self.on_vary;
        format!(
            "{:<20} {:>6} {:>5} {:>5} {:>5} {:>7} {:>6} {:>6} {:>8.2} {:>20} {:>15} {:>20} {:>26}",
            self.family,
            self.rays(),
            self.summary.fail,
            self.summary.warn,
            self.other_failures,
            self.watertight_rays,
            self.double_hits,
            self.holes,
            100.0 * self.vary_share(),
            e(self.t_error_ulps()),
            {
                let b = self.t_error_bound();
                let f = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.3}"));
                format!("{}/{}", f(b.p99), f(b.max))
            },
            e(self.bary_error_eps()),
            format!(
                "{}/{}/{}/{}",
                v.hit_required,
                v.hit_possible,
                v.miss,
                v.hit_other + v.no_shader + v.not_run
            ),
        )
    }
}

/// Whether two members of one watertight group were both reported by the any-hit shader.
fn double_hit(allowed: &AllowedOutcomes, record: &RayRecord) -> bool {
    let seen: Vec<PrimitiveRef> = record
        .seen
        .iter()
        .map(|s| PrimitiveRef {
            instance: s.instance,
            geometry: s.geometry,
            primitive: s.primitive,
        })
        .collect();
    allowed.watertight.iter().any(|g| {
        let mut hit: Vec<&PrimitiveRef> = g.members.iter().filter(|m| seen.contains(m)).collect();
        hit.dedup();
        hit.len() >= 2
    })
}
