//! Judging one ray's record against its allowed outcomes: categorical fields exactly where the
//! spec fixes them, membership where it allows a range, and t and barycentrics as errors (ULPs and
//! relative to the derived bound). Failure only on a REQ violation or an error outside its bound;
//! a hole in a watertight group is a quality warning (the spec says "should").

use super::record::{RayRecord, RecordOutcome};
use super::{AllowedOutcomes, AllowedReport, Candidate, Interval, PrimitiveKind, PrimitiveRef};
use serde::{Deserialize, Serialize};

/// The verdict on one ray.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RayVerdict {
    Pass,
    /// Allowed, but below the quality the spec asks for ("should").
    Warn(String),
    /// A REQ violation.
    Fail(String),
}

/// The judgement of one record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RayJudgement {
    pub verdict: RayVerdict,
    /// Every failure and warning found (the verdict is the worst).
    pub findings: Vec<RayVerdict>,
    /// The committed hit the record names, when it is a hit.
    pub chosen: Option<PrimitiveRef>,
    /// Whether the allowed set had any VARY part.
    pub vary: bool,
    /// |t − t_exact| in f32 ULPs of max(|t_exact|, [`AllowedReport::t_scale`]), and relative to the
    /// bound (1.0 = at the bound).
    pub t_error_ulps: Option<f64>,
    pub t_error_rel: Option<f64>,
    /// max over (b, c) of |x − x_exact|, absolute and in f32 ULPs of x_exact where |x_exact| ≥ 1/2,
    /// else of 1/2 ([`BARY_ULP_FLOOR`]).
    pub bary_error_abs: Option<f64>,
    pub bary_error_ulps: Option<f64>,
    /// The bounds used: half widths of the t and barycentric intervals.
    pub t_bound: Option<f64>,
    pub bary_bound: Option<f64>,
}

/// The least magnitude whose ULP measures a barycentric's error: the three barycentrics sum to one and
/// are computed together, so an f32 implementation's rounding error in one is at the scale of the
/// largest (at least 1/3), not of its own value. ULPs of the value itself would count an error of
/// 1e-8 in a coordinate of 1e-30 (a ray through an edge) as about 1e22 ULPs.
pub const BARY_ULP_FLOOR: f64 = 0.5;

/// The size of one f32 ULP at `x`.
pub fn f32_ulp(x: f64) -> f64 {
    let a = (x.abs() as f32).max(f32::MIN_POSITIVE);
    let next = f32::from_bits(a.to_bits() + 1);
    (next - a) as f64
}

fn prim_name(p: &PrimitiveRef) -> String {
    format!(
        "instance {} geometry {} primitive {}",
        p.instance, p.geometry, p.primitive
    )
}

impl RayJudgement {
    /// A judgement with nothing found or measured yet.
    pub fn blank(vary: bool) -> RayJudgement {
        RayJudgement {
            verdict: RayVerdict::Pass,
            findings: Vec::new(),
            chosen: None,
            vary,
            t_error_ulps: None,
            t_error_rel: None,
            bary_error_abs: None,
            bary_error_ulps: None,
            t_bound: None,
            bary_bound: None,
        }
    }
}

/// Judges one record.
pub fn judge(allowed: &AllowedOutcomes, record: &RayRecord) -> RayJudgement {
    let mut j = RayJudgement::blank(allowed.vary);
    judge_into(allowed, record, &mut j);
    j
}

/// [`judge`] written into `j`, a [`RayJudgement::blank`] of `allowed.vary` (a launch's judgements
/// are made where they are kept, not moved there).
pub fn judge_into(allowed: &AllowedOutcomes, record: &RayRecord, j: &mut RayJudgement) {
    let mut findings: Vec<RayVerdict> = Vec::new();
    let fail = |f: &mut Vec<RayVerdict>, s: String| f.push(RayVerdict::Fail(s));
    if record.outcome == RecordOutcome::NotRun {
        fail(&mut findings, "the launch ID did not run".into());
        return finish(j, findings);
    }
    // Invocation counts (spec, "Ray Intersection Confirmation": any-hit at most once per candidate
    // with NO_DUPLICATE_ANY_HIT; intersection may repeat).
    if !allowed.any_hit.contains(record.any_hit_count) {
        fail(
            &mut findings,
            format!(
                "{} any-hit invocations outside {:?}",
                record.any_hit_count, allowed.any_hit
            ),
        );
    }
    if !allowed.intersection.contains(record.intersection_count) {
        fail(
            &mut findings,
            format!(
                "{} intersection invocations outside {:?}",
                record.intersection_count, allowed.intersection
            ),
        );
    }
    // Seen candidates: each must be a candidate the any-hit shader may run for, at a t within its
    // bound, at most once with NO_DUPLICATE_ANY_HIT.
    let mut seen_prims: Vec<PrimitiveRef> = Vec::new();
    for s in &record.seen {
        let p = PrimitiveRef {
            instance: s.instance,
            geometry: s.geometry,
            primitive: s.primitive,
        };
        match allowed.candidate(&p) {
            Some(c) if c.confirmation.runs_any_hit() => {
                if !c.reports.iter().any(|r| r.t.contains(s.t as f64)) {
                    fail(
                        &mut findings,
                        format!(
                            "any-hit saw {} at t = {} outside its bound",
                            prim_name(&p),
                            s.t
                        ),
                    );
                }
                if c.no_duplicate_any_hit && seen_prims.contains(&p) {
                    fail(
                        &mut findings,
                        format!(
                            "any-hit ran twice for {} with NO_DUPLICATE_ANY_HIT",
                            prim_name(&p)
                        ),
                    );
                }
            }
            Some(_) => fail(
                &mut findings,
                format!(
                    "any-hit ran for {}, whose candidate is opaque or has no any-hit shader",
                    prim_name(&p)
                ),
            ),
            None => fail(
                &mut findings,
                format!(
                    "any-hit ran for {}, which cannot be a candidate",
                    prim_name(&p)
                ),
            ),
        }
        seen_prims.push(p);
    }
    for g in &allowed.watertight {
        let mut hit: Vec<&PrimitiveRef> = g
            .members
            .iter()
            .filter(|m| seen_prims.contains(m))
            .collect();
        hit.dedup();
        if hit.len() >= 2 {
            fail(
                &mut findings,
                format!(
                    "double hit on a {:?}: {} and {} (spec, Watertightness)",
                    g.shape,
                    prim_name(hit[0]),
                    prim_name(hit[1])
                ),
            );
        }
    }
    let group_seen = |g: &super::WatertightGroup| g.members.iter().any(|m| seen_prims.contains(m));
    let slots_complete = (record.any_hit_count as usize) <= RayRecord::SEEN_SLOTS;
    // A hole is a group passed without a hit. A committed hit that ended the trace (its any-hit
    // terminated, or the ray ends at its first hit) may have been reached before a nearer group
    // was: that group was not passed, and no hole is shown.
    let hole = |committed_t: Option<f64>, committed: Option<&PrimitiveRef>| -> Option<String> {
        let ended_early = committed
            .and_then(|p| allowed.candidate(p))
            .is_some_and(|c| c.confirmation.ends_trace(allowed.terminate_on_first_hit));
        if ended_early {
            return None;
        }
        allowed
            .watertight
            .iter()
            .find(|g| {
                g.expect_hit
                    && !matches!(committed, Some(c) if g.members.contains(c))
                    && !matches!(committed_t, Some(t) if t <= g.t.hi)
                    && !group_seen(g)
                    && slots_complete
            })
            .map(|g| {
                format!(
                    "hole in a {:?} of {} triangles (spec, Watertightness: should)",
                    g.shape,
                    g.members.len()
                )
            })
    };
    match record.outcome {
        RecordOutcome::NotRun => unreachable!(),
        RecordOutcome::Miss => {
            if !allowed.miss.allowed {
                fail(&mut findings, "missed, but a candidate must be hit".into());
            } else if let Some(w) = hole(None, None) {
                findings.push(RayVerdict::Warn(w));
            }
            if allowed.miss_shader.zero_group {
                fail(
                    &mut findings,
                    "a miss shader ran, but the miss record is a zero group".into(),
                );
            } else if record.group != Some(allowed.miss_shader.group) {
                fail(
                    &mut findings,
                    format!(
                        "miss group {:?}, expected {}",
                        record.group, allowed.miss_shader.group
                    ),
                );
            }
        }
        RecordOutcome::NoShader => {
            let miss_silent = allowed.miss.allowed && allowed.miss_shader.zero_group;
            let hit_silent = allowed.committable.iter().any(|&i| {
                let c = &allowed.candidates[i];
                allowed.skip_closest_hit || c.shaders.zero_group || !c.shaders.closest_hit
            });
            if !miss_silent && !hit_silent {
                fail(
                    &mut findings,
                    "neither a miss nor a closest-hit shader ran, but one must".into(),
                );
            } else if !hit_silent {
                if let Some(w) = hole(None, None) {
                    findings.push(RayVerdict::Warn(w));
                }
            }
        }
        RecordOutcome::Hit => {
            let p = PrimitiveRef {
                instance: record.instance_id,
                geometry: record.geometry_index,
                primitive: record.primitive_id,
            };
            j.chosen = Some(p);
            if allowed.skip_closest_hit {
                fail(
                    &mut findings,
                    "closest-hit ran despite SkipClosestHitShader".into(),
                );
            }
            match allowed.candidate(&p) {
                None => fail(
                    &mut findings,
                    format!("committed {}, which cannot be a candidate", prim_name(&p)),
                ),
                Some(c) => {
                    if !allowed.may_commit(&p) {
                        fail(
                            &mut findings,
                            format!(
                                "committed {}, which cannot be the committed hit",
                                prim_name(&p)
                            ),
                        );
                    }
                    judge_hit(c, record, j, &mut findings);
                    if let Some(w) = hole(Some(record.t as f64), Some(&p)) {
                        findings.push(RayVerdict::Warn(w));
                    }
                }
            }
        }
    }
    finish(j, findings)
}

fn judge_hit(
    c: &Candidate,
    record: &RayRecord,
    j: &mut RayJudgement,
    findings: &mut Vec<RayVerdict>,
) {
    if c.shaders.zero_group || !c.shaders.closest_hit {
        findings.push(RayVerdict::Fail(
            "closest-hit ran for a hit group without one".into(),
        ));
    } else if record.group != Some(c.shaders.group) {
        findings.push(RayVerdict::Fail(format!(
            "hit group {:?}, expected {}",
            record.group, c.shaders.group
        )));
    }
    if record.custom_index != c.custom_index {
        findings.push(RayVerdict::Fail(format!(
            "InstanceCustomIndex {}, expected {}",
            record.custom_index, c.custom_index
        )));
    }
    let Some(r) = c.reports.iter().find(|r| r.hit_kind == record.hit_kind) else {
        let kinds: Vec<String> = c
            .reports
            .iter()
            .map(|r| format!("{:#x}", r.hit_kind))
            .collect();
        findings.push(RayVerdict::Fail(format!(
            "HitKind {:#x}, allowed {}",
            record.hit_kind,
            kinds.join(" or ")
        )));
        return;
    };
    measure(r, c.kind, record, j, findings);
}

fn measure(
    r: &AllowedReport,
    kind: PrimitiveKind,
    record: &RayRecord,
    j: &mut RayJudgement,
    findings: &mut Vec<RayVerdict>,
) {
    let t = record.t as f64;
    let err = (t - r.t_exact).abs();
    let bound = r.t.radius();
    let t_ulp = f32_ulp(r.t_exact.abs().max(r.t_scale));
    j.t_error_ulps = Some(err / t_ulp);
    j.t_error_rel = Some(if bound > 0.0 {
        err / bound
    } else {
        f64::INFINITY
    });
    j.t_bound = Some(bound);
    if !r.t.contains(t) {
        findings.push(RayVerdict::Fail(format!(
            "t = {} outside [{}, {}] (error {:.3e}, {:.1} ulps)",
            record.t,
            r.t.lo,
            r.t.hi,
            err,
            err / t_ulp
        )));
    }
    if kind == PrimitiveKind::Triangle {
        if let (Some(bi), Some(be)) = (r.barycentrics, r.barycentrics_exact) {
            let mut worst: f64 = 0.0;
            let mut worst_ulps: f64 = 0.0;
            let mut bound: f64 = 0.0;
            for k in 0..2 {
                let x = record.barycentrics[k] as f64;
                let e = (x - be[k]).abs();
                worst = worst.max(e);
                worst_ulps = worst_ulps.max(e / f32_ulp(be[k].abs().max(BARY_ULP_FLOOR)));
                bound = bound.max(bi[k].radius());
                // An unbounded interval decides nothing (a pair whose f32 test may overflow,
                // `VaryReason::Range`): there an overflowed division's NaN is an outcome too.
                if !(bi[k].contains(x) || (bi[k] == Interval::ALL && x.is_nan())) {
                    findings.push(RayVerdict::Fail(format!(
                        "barycentric {} = {} outside [{}, {}]",
                        ["b", "c"][k],
                        x,
                        bi[k].lo,
                        bi[k].hi
                    )));
                }
            }
            j.bary_error_abs = Some(worst);
            j.bary_error_ulps = Some(worst_ulps);
            j.bary_bound = Some(bound);
        }
    }
}

fn finish(j: &mut RayJudgement, findings: Vec<RayVerdict>) {
    j.verdict = findings
        .iter()
        .find(|f| matches!(f, RayVerdict::Fail(_)))
        .or_else(|| findings.iter().find(|f| matches!(f, RayVerdict::Warn(_))))
        .cloned()
        .unwrap_or(RayVerdict::Pass);
    j.findings = findings;
}
