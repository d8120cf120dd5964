//! A valid launch's records judged: every launch ID's `RayRecord` against the outcomes the spec
//! allows for its ray (`crate::semantics::expected_launch`, memoised per distinct ray) with
//! `crate::tracer::judge`: categorical fields exactly where the spec fixes them, membership where it
//! allows a range, t and barycentrics as errors against their bounds. A launch ID fails only on a REQ
//! violation or an error outside its bound; a hole on a watertight edge is a warning.

use crate::call::Call;
use crate::semantics::ExpectedLaunch;
use crate::tracer::judge::{judge, RayJudgement, RayVerdict};
use crate::tracer::record::{RayRecord, RecordOutcome};
use crate::tracer::summary::Summary;
use crate::tracer::{AllowedOutcomes, PrimitiveRef};
use crate::TraceBody;
use serde::{Deserialize, Serialize};

/// How many failures and warnings a result keeps in words.
const KEPT: usize = 5;

/// The rendered-output numbers of one case (a field of its `results.jsonl` line).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RenderedResult {
    /// Launch IDs judged.
    pub rays: u64,
    /// Distinct rays traced.
    pub distinct_rays: u64,
    /// Launch IDs whose ray's allowed set is fully fixed by the spec (REQ) or has a VARY part.
    pub req: u64,
    pub vary: u64,
    /// What the driver chose on the VARY launch IDs: a hit, or a miss (or no shader).
    pub vary_hit: u64,
    pub vary_miss: u64,
    pub warnings: u64,
    pub failures: u64,
    /// The worst t error (f32 ULPs, and relative to its bound) and the bound it was judged by.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_t_ulps: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_t_rel: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_t_bound: Option<f64>,
    /// The worst barycentric error (absolute) and its bound.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_bary_abs: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_bary_bound: Option<f64>,
    /// Ray/primitive pairs the tracer classified, and how many needed exact arithmetic.
    pub pair_tests: u64,
    pub exact_evaluations: u64,
    /// The first failures and warnings, as a person reads them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub first_failures: Vec<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub first_warnings: Vec<String>,
    /// Error histograms and verdict counts over the case's launch IDs.
    pub summary: Summary,
}

/// One launch ID's judgement (None: the launch traces no ray and the record was compared whole).
#[derive(Debug, Clone)]
pub struct IdJudgement {
    pub record: Option<RayRecord>,
    pub ray: Option<usize>,
    pub judgement: Option<RayJudgement>,
    pub verdict: RayVerdict,
}

/// Every launch ID of a case judged, and what the model allowed.
#[derive(Debug, Clone)]
pub struct LaunchJudgement {
    pub result: RenderedResult,
    pub expected: std::sync::Arc<ExpectedLaunch>,
    pub ids: Vec<IdJudgement>,
}

fn describe_ray(r: &crate::scene::Ray) -> String {
    format!(
        "origin {:?} direction {:?} t [{}, {}]{}",
        r.origin,
        r.direction,
        r.tmin,
        r.tmax,
        if r.flags.0 != 0 {
            format!(" flags {}", r.flags.names().join("|"))
        } else {
            String::new()
        }
    )
}

fn rank(v: &RayVerdict) -> u8 {
    match v {
        RayVerdict::Pass => 0,
        RayVerdict::Warn(_) => 1,
        RayVerdict::Fail(_) => 2,
    }
}

/// The geometry index word a vkCmdTraceRaysNV pipeline writes: SPV_NV_ray_tracing has no
/// `GeometryIndex`, so the shaders say "not observed" and the geometry is judged by membership.
pub const NV_GEOMETRY_UNOBSERVED: u32 = 0xFFFF_FFFF;

/// The record with its unobserved geometry indices resolved by membership: the committed hit takes
/// the geometry (among the candidates of its instance and primitive) that judges best, each seen
/// slot a geometry whose candidate runs any-hit at that t.
fn judge_nv(allowed: &AllowedOutcomes, record: &RayRecord) -> RayJudgement {
    let mut record = record.clone();
    for s in record.seen.iter_mut() {
        if s.geometry != NV_GEOMETRY_UNOBSERVED {
            continue;
        }
        let fit = allowed.candidates.iter().find(|c| {
            c.primitive.instance == s.instance
                && c.primitive.primitive == s.primitive
                && c.confirmation.runs_any_hit()
                && c.reports.iter().any(|r| r.t.contains(s.t as f64))
        });
        if let Some(c) = fit {
            s.geometry = c.primitive.geometry;
        }
    }
    if record.outcome == RecordOutcome::Hit && record.geometry_index == NV_GEOMETRY_UNOBSERVED {
        let mut best: Option<RayJudgement> = None;
        let geometries: Vec<u32> = allowed
            .candidates
            .iter()
            .map(|c| c.primitive)
            .filter(|p| p.instance == record.instance_id && p.primitive == record.primitive_id)
            .map(|p: PrimitiveRef| p.geometry)
            .collect();
        for g in geometries {
            let mut r = record.clone();
            r.geometry_index = g;
            let j = judge(allowed, &r);
            if best
                .as_ref()
                .is_none_or(|b| rank(&j.verdict) < rank(&b.verdict))
            {
                best = Some(j);
            }
        }
        if let Some(b) = best {
            return b;
        }
    }
    judge(allowed, &record)
}

/// Judges a valid trace case's records (`words`: [`RayRecord::WORDS`] per launch ID). Err when the
/// model cannot state the expected output (dimensions unknown, scene undefined) or the words cannot
/// be read as records.
pub fn judge_records(body: &TraceBody, words: &[u32]) -> Result<LaunchJudgement, String> {
    // The gate of a valid case traced the launch already: its outcomes are kept for this.
    let expected = crate::expected::of(&body.world, &body.call)
        .ok_or("the model cannot state the launch's expected records")?;
    let invocations = expected.invocations();
    if words.len() as u64 != invocations.saturating_mul(RayRecord::WORDS as u64) {
        return Err(format!(
            "{} record words read back, the launch has {invocations} IDs of {} words",
            words.len(),
            RayRecord::WORDS
        ));
    }
    let ids = words.len() / RayRecord::WORDS;
    let nv = matches!(body.call, Call::TraceRaysNv(_));
    let mut result = RenderedResult {
        distinct_rays: expected.stats.rays,
        pair_tests: expected.stats.pair_tests,
        exact_evaluations: expected.stats.exact_evaluations,
        ..RenderedResult::default()
    };
    let mut out = Vec::with_capacity(ids);
    let no_shader = RayRecord::no_shader().to_words();
    for id in 0..ids {
        let w = &words[id * RayRecord::WORDS..(id + 1) * RayRecord::WORDS];
        result.rays += 1;
        let Some(k) = expected.ray_of(id) else {
            // No ray: the raygen ran and traced nothing.
            let verdict = if w == no_shader {
                RayVerdict::Pass
            } else {
                RayVerdict::Fail(format!(
                    "the launch traces no ray, so its record must be {:x?}; it is {w:x?}",
                    no_shader
                ))
            };
            result.req += 1;
            note(&mut result, id, None, &verdict);
            out.push(IdJudgement {
                record: RayRecord::from_words(w).ok(),
                ray: None,
                judgement: None,
                verdict,
            });
            continue;
        };
        let allowed = &expected.allowed[k];
        let (record, judgement) = match RayRecord::from_words(w) {
            Ok(r) => {
                let j = if nv {
                    judge_nv(allowed, &r)
                } else {
                    judge(allowed, &r)
                };
                (Some(r), Some(j))
            }
            Err(_) => (None, None),
        };
        let verdict = match &judgement {
            Some(j) => j.verdict.clone(),
            None => RayVerdict::Fail(format!(
                "unreadable record {w:x?}: {}",
                RayRecord::from_words(w)
                    .err()
                    .map(|e| e.to_string())
                    .unwrap_or_default()
            )),
        };
        if allowed.vary {
            result.vary += 1;
            match record.as_ref().map(|r| r.outcome) {
                Some(RecordOutcome::Hit) => result.vary_hit += 1,
                Some(_) => result.vary_miss += 1,
                None => {}
            }
        } else {
            result.req += 1;
        }
        if let Some(j) = &judgement {
            result.summary.add(j);
            if j.t_error_rel.unwrap_or(0.0) >= result.worst_t_rel.unwrap_or(0.0)
                && j.t_error_rel.is_some()
            {
                result.worst_t_rel = j.t_error_rel;
                result.worst_t_ulps = j.t_error_ulps;
                result.worst_t_bound = j.t_bound;
            }
            if j.bary_error_abs.unwrap_or(0.0) >= result.worst_bary_abs.unwrap_or(0.0)
                && j.bary_error_abs.is_some()
            {
                result.worst_bary_abs = j.bary_error_abs;
                result.worst_bary_bound = j.bary_bound;
            }
        }
        note(&mut result, id, Some(&expected.rays[k]), &verdict);
        out.push(IdJudgement {
            record,
            ray: Some(k),
            judgement,
            verdict,
        });
    }
    Ok(LaunchJudgement {
        result,
        expected,
        ids: out,
    })
}

/// Counts a verdict and keeps its words while there are few (the ray described only for those).
fn note(result: &mut RenderedResult, id: usize, ray: Option<&crate::scene::Ray>, v: &RayVerdict) {
    let at = || match ray {
        Some(r) => format!("launch ID {id} ({})", describe_ray(r)),
        None => format!("launch ID {id}"),
    };
    match v {
        RayVerdict::Pass => {}
        RayVerdict::Warn(w) => {
            result.warnings += 1;
            if result.first_warnings.len() < KEPT {
                result.first_warnings.push(format!("{}: {w}", at()));
            }
        }
        RayVerdict::Fail(f) => {
            result.failures += 1;
            if result.first_failures.len() < KEPT {
                result.first_failures.push(format!("{}: {f}", at()));
            }
        }
    }
}

/// The named deviation that every failure of a judged launch is, when there is one: a watertight
/// group (a shared edge, a closed fan's vertex) hit twice — `double-hit-shared-edge`,
/// `double-hit-closed-fan`, or `double-hit-shared-edge-and-closed-fan` when both occur. None when the
/// launch has no failure or any failure is something else. The triage's `output` entries name
/// deviations by these keys.
pub fn deviation(j: &LaunchJudgement) -> Option<String> {
    let mut shapes = std::collections::BTreeSet::new();
    let mut any = false;
    for id in &j.ids {
        if !matches!(id.verdict, RayVerdict::Fail(_)) {
            continue;
        }
        any = true;
        let judgement = id.judgement.as_ref()?;
        for f in &judgement.findings {
            let RayVerdict::Fail(text) = f else {
                continue;
            };
            let shape = double_hit_shape(text)?;
            shapes.insert(shape);
        }
    }
    if !any || shapes.is_empty() {
        return None;
    }
    Some(format!(
        "double-hit-{}",
        shapes.into_iter().collect::<Vec<_>>().join("-and-")
    ))
}

/// The watertight shape a failure text names, when it is a double hit (the judge's wording,
/// `crate::tracer::judge`).
fn double_hit_shape(text: &str) -> Option<&'static str> {
    let rest = text.strip_prefix("double hit on a ")?;
    if rest.starts_with(&format!(
        "{:?}:",
        crate::tracer::WatertightShape::SharedEdge
    )) {
        Some("shared-edge")
    } else if rest.starts_with(&format!("{:?}:", crate::tracer::WatertightShape::ClosedFan)) {
        Some("closed-fan")
    } else {
        None
    }
}
