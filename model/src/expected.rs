//! The expected launches of valid trace cases, kept between the gate and the judgement of the same
//! case: the gate ([`crate::Case::runnable`]) traces a valid launch's rays once, for its undefined
//! reads and for the judgement of its records, and a run's judge finds that result here instead of
//! tracing the rays again. Entries are found by the 128-bit fingerprint of the world and the call
//! ([`crate::fingerprint`]) and kept first in, first out within a budget of rays (a run's judge lags
//! its gate by the cases in flight, a few dozen; a 256x256 launch holds 65,536 rays' outcomes).

use crate::call::Call;
use crate::semantics::{expected_launch, ExpectedLaunch};
use crate::world::World;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// The rays' outcomes kept at most, over every entry.
const RAYS_KEPT: usize = 1 << 19;

struct Kept {
    entries: VecDeque<(u128, Arc<ExpectedLaunch>)>,
    rays: usize,
}

static KEPT: Mutex<Kept> = Mutex::new(Kept {
    entries: VecDeque::new(),
    rays: 0,
});

/// The key a launch's expected outcomes are kept by: the fingerprint of its world and call (None
/// where the world does not serialise).
pub(crate) fn key(world: &World, call: &Call) -> Option<u128> {
    match call {
        Call::TraceRaysIndirect(c) => crate::fingerprint::of(&(world, 0u8, c)),
        Call::TraceRays(c) => crate::fingerprint::of(&(world, 1u8, c)),
        Call::TraceRaysNv(c) => crate::fingerprint::of(&(world, 2u8, c)),
    }
}

/// The expected launch kept by `key` ([`key`]), if it still is.
pub(crate) fn lookup(key: u128) -> Option<Arc<ExpectedLaunch>> {
    let kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    kept.entries
        .iter()
        .find(|(k, _)| *k == key)
        .map(|(_, e)| e.clone())
}

/// The expected launch already computed for this world and call, if it is still kept.
pub fn kept(world: &World, call: &Call) -> Option<Arc<ExpectedLaunch>> {
    lookup(key(world, call)?)
}

/// [`expected_launch`] of the world and call: the kept one, or computed and kept.
pub fn of(world: &World, call: &Call) -> Option<Arc<ExpectedLaunch>> {
    let Some(k) = key(world, call) else {
        return expected_launch(world, call).map(Arc::new);
    };
    if let Some(e) = lookup(k) {
        return Some(e);
    }
    let e = Arc::new(expected_launch(world, call)?);
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    if !kept.entries.iter().any(|(other, _)| *other == k) {
        kept.rays += e.rays.len();
        kept.entries.push_back((k, e.clone()));
        while kept.rays > RAYS_KEPT && kept.entries.len() > 1 {
            if let Some((_, old)) = kept.entries.pop_front() {
                kept.rays -= old.rays.len();
            }
        }
    }
    Some(e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_cases::hand_case;

    #[test]
    fn a_kept_launch_is_the_computed_one_and_a_changed_ray_is_not_found() {
        let mut case = hand_case();
        let t = case.as_trace_mut().expect("a trace case");
        // A tmax of its own, so no other test's entry is this one.
        t.world.launch.rays[0].tmax = 12345.5;
        let fresh = expected_launch(&t.world, &t.call).expect("the launch is defined");
        let kept_first = of(&t.world, &t.call).expect("defined");
        assert_eq!(
            format!("{:?}", fresh.allowed),
            format!("{:?}", kept_first.allowed)
        );
        let again = kept(&t.world, &t.call).expect("kept after the first");
        assert!(Arc::ptr_eq(&kept_first, &again));
        t.world.launch.rays[0].tmax = 12345.25;
        assert!(
            kept(&t.world, &t.call).is_none(),
            "another ray, another entry"
        );
    }

    #[test]
    fn the_misses_of_a_launch_traced_whole_are_the_misses_found_by_tracing_until_known() {
        let files = crate::test_cases::repository_case_files();
        let (mut compared, mut with_misses) = (0, 0);
        for f in files {
            let text = std::fs::read_to_string(&f).expect("a case file reads");
            let Ok(case) = crate::Case::from_yaml("case", &text) else {
                continue;
            };
            let Some(t) = case
                .as_trace()
                .filter(|_| case.intent == crate::Intent::Valid)
            else {
                continue;
            };
            let rays = crate::semantics::traced_rays(&t.world, &t.call);
            let Some(e) = of(&t.world, &t.call).filter(|_| !rays.is_empty()) else {
                continue;
            };
            let whole = crate::semantics::misses_of(&e);
            let traced = crate::semantics::misses_by_tracing(&t.world, &t.call, &rays);
            assert_eq!(whole, traced, "{}", f.display());
            compared += 1;
            with_misses += !whole.is_empty() as usize;
        }
        assert!(
            compared >= 10 && with_misses >= 5,
            "{compared} launches, {with_misses} with misses"
        );
    }
}
