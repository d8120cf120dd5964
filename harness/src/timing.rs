//! Where a case's time goes in the worker: each phase of its execution (device creation, resources and
//! their shaders, acceleration structures, pipelines, the call recorded under the layer, the GPU's run,
//! reading back) timed exclusively — entering a phase pauses the one around it, so the phases of a
//! case add up to the time spent inside them. Counted per thread; the worker takes them after each case.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::time::Instant;

/// One phase of a case's execution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Phase {
    /// Creating the VkDevice (and its per-device caches) for a new enabled state, and destroying one
    /// that makes room for it.
    Device,
    /// Buffers, memory, images, descriptors and the other objects of the case's world.
    Resources,
    /// Compiling a case's own shaders (the resource-state modules).
    Shaders,
    /// Building acceleration structures (the scene, or a build case's structures) and waiting for them.
    Structures,
    /// Creating ray tracing pipelines and reading their group handles.
    Pipeline,
    /// Recording the command buffer: the case's state and the call, validated by the layer as recorded.
    Record,
    /// The submitted launch running on the device, until its fence signals.
    Gpu,
    /// Reading the output records back.
    Readback,
}

impl Phase {
    pub const ALL: [Phase; 8] = [
        Phase::Device,
        Phase::Resources,
        Phase::Shaders,
        Phase::Structures,
        Phase::Pipeline,
        Phase::Record,
        Phase::Gpu,
        Phase::Readback,
    ];

    /// The phase's name in results and summaries.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Device => "device",
            Phase::Resources => "resources",
            Phase::Shaders => "shaders",
            Phase::Structures => "structures",
            Phase::Pipeline => "pipeline",
            Phase::Record => "record",
            Phase::Gpu => "gpu",
            Phase::Readback => "readback",
        }
    }
}

struct Clock {
    /// The phase now running and since when (None: outside every phase).
    current: Option<(Phase, Instant)>,
    /// Milliseconds per phase since the last [`take`].
    spent: [f64; Phase::ALL.len()],
}

thread_local! {
    static CLOCK: RefCell<Clock> = const {
        RefCell::new(Clock {
            current: None,
            spent: [0.0; Phase::ALL.len()],
        })
    };
}

fn switch(to: Option<Phase>) -> Option<Phase> {
    CLOCK.with(|c| {
        let mut c = c.borrow_mut();
        let now = Instant::now();
        let before = c.current.map(|(p, _)| p);
        if let Some((p, since)) = c.current {
            c.spent[p as usize] += now.duration_since(since).as_secs_f64() * 1000.0;
        }
        c.current = to.map(|p| (p, now));
        before
    })
}

/// Time in `phase` until the returned guard drops; the phase around it resumes then.
pub fn span(phase: Phase) -> Span {
    Span {
        outer: switch(Some(phase)),
    }
}

/// A running phase (see [`span`]).
#[must_use = "the phase ends when the guard drops"]
pub struct Span {
    outer: Option<Phase>,
}

impl Drop for Span {
    fn drop(&mut self) {
        switch(self.outer);
    }
}

/// The milliseconds spent per phase since the last call (phases with none left out), and a fresh
/// start.
pub fn take() -> BTreeMap<String, f64> {
    CLOCK.with(|c| {
        let mut c = c.borrow_mut();
        let spent = std::mem::replace(&mut c.spent, [0.0; Phase::ALL.len()]);
        Phase::ALL
            .iter()
            .zip(spent)
            .filter(|(_, ms)| *ms > 0.0)
            .map(|(p, ms)| (p.name().to_string(), ms))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn nested_phases_are_exclusive_and_add_up() {
        let _ = take();
        let started = Instant::now();
        {
            let _outer = span(Phase::Resources);
            std::thread::sleep(Duration::from_millis(20));
            {
                let _inner = span(Phase::Pipeline);
                std::thread::sleep(Duration::from_millis(30));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let total = started.elapsed().as_secs_f64() * 1000.0;
        let t = take();
        let (res, pipe) = (t["resources"], t["pipeline"]);
        // The inner phase is not counted in the outer one.
        assert!(
            (28.0..total).contains(&pipe),
            "pipeline {pipe} ms of {total}"
        );
        assert!(
            (28.0..total - pipe + 1.0).contains(&res),
            "resources {res} ms"
        );
        assert!(res + pipe <= total + 0.5, "{res} + {pipe} > {total}");
        // Taken once: the next take starts from nothing.
        assert!(take().is_empty());
    }
}
