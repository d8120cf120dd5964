//! What stands between a case and a driver, asked by every path that hands one over (run, replay, the
//! lavapipe tests through `Judging::run_here`): the case's own errors ([`model::integrity`]), its
//! undefined reads or a build the model gives no meaning ([`model::Case::runnable`]), buffers larger
//! than the profile's device can create or back, push constant bytes past its `maxPushConstantsSize`,
//! and — for a trace case run as valid — a verdict that is not empty. Each is reported without
//! running the case: `case-error` where the case is at fault, `unsupported` where the profile says the
//! device cannot hold it.

use crate::compare::{case_error, not_realisable, not_runnable, CaseReport};
use crate::run::Judging;
use model::{Body, Case, DeviceProfile};

/// The report of a case that must not reach the driver, or None when it may.
pub(crate) fn gate(case: &Case, judging: &Judging) -> Option<CaseReport> {
    if let Some(f) = model::integrity::flaws(case).first() {
        return Some(case_error(case, &f.at, &f.problem));
    }
    if let Err(why) = case.runnable(judging.profile) {
        return Some(not_runnable(case, &why));
    }
    if let Some((at, why)) = too_large(case, &judging.capacity_limits) {
        return Some(not_realisable(case, &at, &why));
    }
    if let Some((at, why)) = push_constants_too_large(case, judging.capacity_limits.push_constants)
    {
        return Some(not_realisable(case, &at, &why));
    }
    if case.as_trace().is_some() && case.runs_as_valid(judging.profile) {
        let verdict = judging.verdict(&case.body);
        if !verdict.is_valid() {
            let vuids: Vec<&str> = verdict.vuids().into_iter().collect();
            return Some(case_error(
                case,
                "intent",
                &format!(
                    "not run: the model judges this valid case invalid: {}",
                    vuids.join(", ")
                ),
            ));
        }
    }
    None
}

/// The profile's limits on what its device can hold: a buffer ([`too_large`]) and push constant
/// bytes ([`push_constants_too_large`]), each with its name: looked up once per run (a lookup by
/// member name scans the profile's properties).
#[derive(Debug, Clone)]
pub(crate) struct CapacityLimits {
    buffer: (&'static str, Option<u64>),
    allocation: (&'static str, Option<u64>),
    sparse: (&'static str, Option<u64>),
    push_constants: (&'static str, Option<u64>),
}

impl CapacityLimits {
    pub(crate) fn of(profile: &DeviceProfile) -> CapacityLimits {
        let named = |limit: &'static str| (limit, profile.limit(limit));
        CapacityLimits {
            buffer: named("maxBufferSize"),
            allocation: named("maxMemoryAllocationSize"),
            sparse: named("sparseAddressSpaceSize"),
            push_constants: named("maxPushConstantsSize"),
        }
    }
}

/// The first push constant bytes of a trace case that end past the profile's
/// `maxPushConstantsSize`: a pipeline layout's range, a push, or what a stage reads. No pipeline
/// layout of the device can hold them (and the harness would make a value of that many bytes, or a
/// shader reading them word by word). The path and why.
fn push_constants_too_large(
    case: &Case,
    (limit, max): (&'static str, Option<u64>),
) -> Option<(String, String)> {
    let (Some(t), Some(max)) = (case.as_trace(), max) else {
        return None;
    };
    let rs = &t.world.resources;
    let end = |offset: u32, size: u32| u64::from(offset) + u64::from(size);
    // Where each stated span is, as indices: the path is written only for the one found.
    let ranges = rs.pipeline_layouts.iter().enumerate().flat_map(|(i, l)| {
        l.push_ranges
            .iter()
            .enumerate()
            .map(move |(j, r)| (PushPlace::Range(i, j), r.offset, r.size))
    });
    let pushes = rs
        .pushes
        .iter()
        .enumerate()
        .map(|(i, p)| (PushPlace::Push(i), p.offset, p.size));
    let stages = rs.stages.iter().enumerate().filter_map(|(i, s)| {
        let [offset, size] = s.push_constants?;
        Some((PushPlace::Stage(i), offset, size))
    });
    let (place, offset, size) = ranges
        .chain(pushes)
        .chain(stages)
        .find(|&(_, offset, size)| end(offset, size) > max)?;
    let at = match place {
        PushPlace::Range(i, j) => format!("world.resources.pipeline_layouts[{i}].push_ranges[{j}]"),
        PushPlace::Push(i) => format!("world.resources.pushes[{i}]"),
        PushPlace::Stage(i) => format!("world.resources.stages[{i}].push_constants"),
    };
    Some((
        at,
        format!(
            "push constant bytes [{offset}, {}) end past the profile's {limit} ({max}): the device cannot hold them",
            end(offset, size)
        ),
    ))
}

/// Where a trace case states push constant bytes: a pipeline layout's range (layout, range), a push,
/// a stage's read.
#[derive(Clone, Copy)]
enum PushPlace {
    Range(usize, usize),
    Push(usize),
    Stage(usize),
}

/// The first buffer the profile's device cannot hold: a non-sparse buffer past `maxBufferSize` or
/// `maxMemoryAllocationSize` (it is bound to one allocation), a sparse one past
/// `sparseAddressSpaceSize`. The path of its size and why.
fn too_large(case: &Case, limits: &CapacityLimits) -> Option<(String, String)> {
    let buffers: Vec<(&str, u64, bool)> = match &case.body {
        Body::Trace(t) => t
            .world
            .buffers
            .iter()
            .map(|b| (b.name.as_str(), b.size, b.is_sparse()))
            .collect(),
        Body::Accel(a) => a
            .world
            .buffers
            .iter()
            .map(|b| (b.name.as_str(), b.size, b.is_sparse()))
            .collect(),
    };
    let (buffer_max, allocation_max, sparse_max) =
        (limits.buffer, limits.allocation, limits.sparse);
    for (i, (name, size, sparse)) in buffers.into_iter().enumerate() {
        let limits = if sparse {
            [buffer_max, sparse_max]
        } else {
            [buffer_max, allocation_max]
        };
        for (limit, max) in limits {
            if let Some(max) = max.filter(|max| size > *max) {
                return Some((
                    format!("world.buffers[{i}].size"),
                    format!(
                        "buffer `{name}` of {size} bytes is larger than the profile's {limit} ({max}): the device cannot hold it"
                    ),
                ));
            }
        }
    }
    None
}
