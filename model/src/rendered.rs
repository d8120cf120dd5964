//! A valid launch's records judged: every launch ID's `RayRecord` against the outcomes the spec
//! allows for its ray (`crate::semantics::expected_launch`, memoised per distinct ray) with
//! `crate::tracer::judge`: categorical fields exactly where the spec fixes them, membership where it
//! allows a range, t and barycentrics as errors against their bounds. A launch ID fails only on a REQ
//! violation or an error outside its bound; a hole on a watertight edge is a warning.

use crate::call::Call;
use crate::semantics::ExpectedLaunch;
use crate::tracer::judge::{judge, judge_into, RayJudgement, RayVerdict};
use crate::tracer::record::{RayRecord, RecordOutcome};
use crate::tracer::summary::Summary;
use crate::tracer::{AllowedOutcomes, PrimitiveRef};
use crate::TraceBody;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

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
    /// Launch IDs whose ray must run an intersection shader at least once (a box it robustly
    /// crosses, or whose sphere it does, before anything may end its trace).
    #[serde(default)]
    pub shader_required: u64,
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

impl IdJudgement {
    /// The slot of a launch ID not judged yet: no record, ray or judgement, verdict Pass.
    fn unjudged() -> IdJudgement {
        IdJudgement {
            record: None,
            ray: None,
            judgement: None,
            verdict: RayVerdict::Pass,
        }
    }
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
    // Fixed chunks of launch IDs, judged on every core and put together in launch order: the
    // result is the same whichever thread judged a chunk, and however many did.
    let chunks = ids.div_ceil(IDS_PER_CHUNK);
    // Every ID's judgement made in its place here (each chunk's part of it lent to one run).
    let mut out: Vec<IdJudgement> = std::iter::repeat_with(IdJudgement::unjudged)
        .take(ids)
        .collect();
    let parts: Vec<Mutex<(&mut [IdJudgement], Option<RenderedResult>)>> = out
        .chunks_mut(IDS_PER_CHUNK)
        .map(|slots| Mutex::new((slots, None)))
        .collect();
    let next = AtomicUsize::new(0);
    let work = || loop {
        let c = next.fetch_add(1, Ordering::Relaxed);
        let Some(part) = parts.get(c) else { break };
        let mut part = part.lock().unwrap_or_else(|e| e.into_inner());
        let (slots, judged) = &mut *part;
        *judged = Some(judge_ids(&expected, words, c * IDS_PER_CHUNK, slots, nv));
    };
    crate::helpers::run_beside(crate::helpers::cores().min(chunks).max(1) - 1, &work);
    let mut result = RenderedResult {
        distinct_rays: expected.stats.rays,
        pair_tests: expected.stats.pair_tests,
        exact_evaluations: expected.stats.exact_evaluations,
        ..RenderedResult::default()
    };
    for part in parts {
        let (_, judged) = part.into_inner().unwrap_or_else(|e| e.into_inner());
        absorb(&mut result, judged.expect("every chunk is judged"));
    }
    Ok(LaunchJudgement {
        result,
        expected,
        ids: out,
    })
}

/// Launch IDs judged together by one thread (enough that taking a chunk costs nothing beside
/// judging it; few enough that a launch of a few thousand IDs keeps every core busy).
const IDS_PER_CHUNK: usize = 512;

/// The launch IDs from `first` on, one per slot of `out`, judged into their slots (each
/// [`IdJudgement::unjudged`]): their counts, worst errors, first
/// failures and summary (none of the launch's own numbers).
fn judge_ids(
    expected: &ExpectedLaunch,
    words: &[u32],
    first: usize,
    out: &mut [IdJudgement],
    nv: bool,
) -> RenderedResult {
    let mut result = RenderedResult::default();
    let no_shader = RayRecord::no_shader().to_words();
    for (slot, id) in out.iter_mut().zip(first..) {
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
            slot.record = RayRecord::from_words(w).ok();
            slot.verdict = verdict;
            continue;
        };
        let allowed = &expected.allowed[k];
        // Made in its slot (a judgement is a few hundred bytes; moving each one into place
        // several times cost about as much as judging it).
        slot.ray = Some(k);
        match RayRecord::from_words(w) {
            Ok(r) => {
                let j = slot.judgement.insert(RayJudgement::blank(allowed.vary));
                if nv {
                    *j = judge_nv(allowed, &r);
                } else {
                    judge_into(allowed, &r, j);
                }
                slot.verdict = j.verdict.clone();
                slot.record = Some(r);
            }
            Err(e) => {
                slot.verdict = RayVerdict::Fail(format!("unreadable record {w:x?}: {e}"));
            }
        }
        if allowed.vary {
            result.vary += 1;
            match slot.record.as_ref().map(|r| r.outcome) {
                Some(RecordOutcome::Hit) => result.vary_hit += 1,
                Some(_) => result.vary_miss += 1,
                None => {}
            }
        } else {
            result.req += 1;
        }
        result.shader_required += u64::from(allowed.intersection.min > 0);
        if let Some(j) = &slot.judgement {
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
        note(&mut result, id, Some(&expected.rays[k]), &slot.verdict);
    }
    result
}

/// Adds the judgement of the launch IDs after those `total` holds, as if judged one by one after
/// them: counts and summaries added, the worst errors the later where they tie, the first
/// failures and warnings still the first [`KEPT`]. (One difference: a histogram counts a
/// non-finite error in its last bucket at the time, so such an error may sit in another bucket
/// than one thread would have put it in; its count and the maximum are the same.)
fn absorb(total: &mut RenderedResult, part: RenderedResult) {
    total.rays += part.rays;
    total.req += part.req;
    total.vary += part.vary;
    total.vary_hit += part.vary_hit;
    total.vary_miss += part.vary_miss;
    total.shader_required += part.shader_required;
    total.warnings += part.warnings;
    total.failures += part.failures;
    if part
        .worst_t_rel
        .is_some_and(|w| w >= total.worst_t_rel.unwrap_or(0.0))
    {
        total.worst_t_rel = part.worst_t_rel;
        total.worst_t_ulps = part.worst_t_ulps;
        total.worst_t_bound = part.worst_t_bound;
    }
    if part
        .worst_bary_abs
        .is_some_and(|w| w >= total.worst_bary_abs.unwrap_or(0.0))
    {
        total.worst_bary_abs = part.worst_bary_abs;
        total.worst_bary_bound = part.worst_bary_bound;
    }
    for (kept, more) in [
        (&mut total.first_failures, part.first_failures),
        (&mut total.first_warnings, part.first_warnings),
    ] {
        kept.extend(more);
        kept.truncate(KEPT);
    }
    total.summary.merge(&part.summary);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracer::record::RecordOutcome;

    /// A 48x48 launch of the closed icosphere (2,304 IDs, five chunks) with records the model's own
    /// choice where a candidate may be committed (its t nudged by 0 to 4 ULPs, varying with the
    /// ID), a miss elsewhere, and every 97th ID a record that did not run: failures in every chunk,
    /// and errors measured in each.
    fn launch_with_records() -> (TraceBody, Vec<u32>) {
        let w = crate::tracer::workload::standard_workload(48, "icosphere");
        let case = w.as_launch_of(crate::test_cases::hand_case(), 48);
        let body = case.as_trace().expect("a trace case").clone();
        let expected = crate::expected::of(&body.world, &body.call).expect("defined");
        let ids = expected.invocations() as usize;
        let mut words = Vec::with_capacity(ids * RayRecord::WORDS);
        for id in 0..ids {
            let allowed = &expected.allowed[expected.ray_of(id).expect("a ray per ID")];
            let mut record = RayRecord::miss(allowed.miss_shader.group);
            if let Some(&i) = allowed.committable.first() {
                let c = &allowed.candidates[i];
                record = RayRecord::hit_on(c, &c.reports[0]);
                record.t = f32::from_bits(record.t.to_bits() + (id as u32 * 7) % 5);
            }
            if id % 97 == 3 {
                record.outcome = RecordOutcome::NotRun;
            }
            words.extend(record.to_words());
        }
        (body, words)
    }

    #[test]
    fn a_launch_judged_in_chunks_is_judged_as_one_id_after_another() {
        let (body, words) = launch_with_records();
        let whole = judge_records(&body, &words).expect("judged");
        let ids = whole.ids.len();
        assert!(ids > 4 * IDS_PER_CHUNK, "{ids} IDs");
        let mut judged: Vec<IdJudgement> = (0..ids).map(|_| IdJudgement::unjudged()).collect();
        let mut one_by_one = judge_ids(&whole.expected, &words, 0, &mut judged, false);
        one_by_one.distinct_rays = whole.expected.stats.rays;
        one_by_one.pair_tests = whole.expected.stats.pair_tests;
        one_by_one.exact_evaluations = whole.expected.stats.exact_evaluations;
        assert_eq!(whole.result, one_by_one);
        assert_eq!(
            format!(
                "{:?}",
                whole.ids.iter().map(|j| &j.verdict).collect::<Vec<_>>()
            ),
            format!(
                "{:?}",
                judged.iter().map(|j| &j.verdict).collect::<Vec<_>>()
            )
        );
        // What the comparison must see: failures in every chunk, more than are kept in words, and
        // measured errors.
        assert_eq!(whole.result.failures, ids.div_ceil(97) as u64);
        assert_eq!(whole.result.first_failures.len(), KEPT);
        assert!(whole.result.first_failures[0].starts_with("launch ID 3 "));
        assert!(whole.result.worst_t_rel.is_some_and(|w| w > 0.0));
        assert!(whole.result.summary.t_error_ulps.count > 100);
    }
}
