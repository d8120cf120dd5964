//! From one ray's candidates to the set of outcomes the spec allows: the committed hits the
//! traversal may produce ("Ray Closest Hit Determination"), the miss rule, and the bounds on the
//! any-hit and intersection invocation counts ("Ray Result Determination"; semantics.md §2, §10).
//!
//! Traversal order is unspecified, so the allowed committed hits are: every confirmable candidate
//! whose t may be at most the t of every required confirmable candidate (the closest, with
//! overlapping intervals VARY), and — when the trace may end early — every confirmable candidate
//! that could be confirmed first (TerminateOnFirstHit: any of them; an any-hit `Terminate` rule:
//! those candidates).

use super::traverse::{opacity, opacity_culled, MustRun};
use super::*;
use crate::scene::{Ray, RayFlags};

/// From the candidates to the allowed committed hits, the miss rule and the invocation counts.
pub(super) fn conclude(
    scene: &PreparedScene,
    ray: &Ray,
    shaders: &ShaderTable<'_>,
    candidates: Vec<Candidate>,
    must_run: Vec<MustRun>,
    watertight: Vec<WatertightGroup>,
) -> AllowedOutcomes {
    let tofh = ray.flags.contains(RayFlags::TERMINATE_ON_FIRST_HIT);
    // Per candidate: confirmable, may end the trace early, and the hull of its t intervals.
    struct Facts {
        confirmable: bool,
        early: bool,
        hull: Interval,
    }
    let fact = |c: &Candidate| {
        let ok = c.confirmation.confirms();
        Facts {
            confirmable: ok,
            early: ok
                && (tofh || c.confirmation == Confirmation::AnyHitAccepts { terminates: true }),
            hull: c.t_hull(),
        }
    };
    // On the stack for the usual few candidates.
    const FEW: usize = 8;
    let mut few = [const {
        Facts {
            confirmable: false,
            early: false,
            hull: Interval::ALL,
        }
    }; FEW];
    let many: Vec<Facts>;
    let facts: &[Facts] = if candidates.len() <= FEW {
        for (f, c) in few.iter_mut().zip(&candidates) {
            *f = fact(c);
        }
        &few[..candidates.len()]
    } else {
        many = candidates.iter().map(fact).collect();
        &many
    };
    let confirmable = |i: usize| facts[i].confirmable;
    let early = |i: usize| facts[i].early;
    let hulls = |i: usize| facts[i].hull;
    let required = || {
        (0..candidates.len())
            .filter(|&i| confirmable(i) && candidates[i].presence == Presence::Required)
    };
    let no_required = required().next().is_none();
    let committable: few::Few<usize, 4> = (0..candidates.len())
        .filter(|&i| {
            confirmable(i) && (early(i) || required().all(|r| r == i || hulls(i).lo <= hulls(r).hi))
        })
        .collect();
    // A candidate must be processed when nothing can end the trace or shrink tmax below it first.
    let must_process = |i: Option<usize>, t_hi: f64| -> bool {
        (0..candidates.len())
            .all(|c| Some(c) == i || !confirmable(c) || (!early(c) && hulls(c).lo > t_hi))
    };
    // Any-hit: at most once per candidate with NO_DUPLICATE_ANY_HIT, unbounded otherwise; with
    // TerminateOnFirstHit every accepting invocation ends the trace.
    let mut any_hit_max: Option<u32> = Some(0);
    let mut accepting_any_hit = false;
    let mut any_hit_min = 0u32;
    for (i, c) in candidates.iter().enumerate() {
        if !c.confirmation.runs_any_hit() {
            continue;
        }
        let accepts = c.confirmation.confirms();
        accepting_any_hit |= accepts;
        if !(tofh && accepts) {
            any_hit_max = match (any_hit_max, c.no_duplicate_any_hit) {
                (Some(m), true) => Some(m + 1),
                _ => None,
            };
        }
        if c.presence == Presence::Required && must_process(Some(i), hulls(i).hi) {
            any_hit_min += 1;
        }
    }
    if tofh && accepting_any_hit {
        any_hit_max = any_hit_max.map(|m| m + 1);
    }
    // Intersection shaders may run for any reachable box (boxes may be enlarged without bound).
    let mut reachable_procedural = false;
    if !ray.flags.contains(RayFlags::SKIP_AABBS) {
        for &(i, g) in &scene.procedural {
            let inst = &scene.scene.instances[i as usize];
            if inst.mask as u32 & ray.cull_mask & 0xFF == 0 {
                continue;
            }
            let b = inst
                .bottom_level
                .expect("a procedural geometry's instance has a level");
            let geometry = &scene.scene.bottom_levels[b as usize].geometries[g as usize];
            let opaque = opacity(ray, inst, geometry.flags.opaque);
            if !opacity_culled(ray, opaque) && (shaders.hit)(i, g).has_intersection() {
                reachable_procedural = true;
            }
        }
    }
    let intersection_min = must_run
        .iter()
        .filter(|m| {
            let own = candidates.iter().position(|c| c.primitive == m.primitive);
            must_process(own, m.t_hi)
        })
        .count() as u32;
    let discouraged = no_required && watertight.iter().any(|g| g.expect_hit);
    let vary = candidates.iter().any(|c| c.presence == Presence::Possible)
        || committable.len() > 1
        || candidates.iter().any(|c| c.reports.len() > 1);
    AllowedOutcomes {
        miss: MissRule {
            allowed: no_required,
            required: committable.is_empty(),
            discouraged,
        },
        committable,
        candidates,
        miss_shader: shaders.miss,
        skip_closest_hit: ray.flags.contains(RayFlags::SKIP_CLOSEST_HIT_SHADER),
        any_hit: CountBounds {
            min: any_hit_min,
            max: any_hit_max,
        },
        intersection: CountBounds {
            min: intersection_min,
            max: if reachable_procedural { None } else { Some(0) },
        },
        watertight,
        vary,
    }
}
