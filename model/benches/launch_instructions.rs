//! A fixed amount of `model::semantics::expected_launch` work per standard workload, for counting
//! instructions per ray under callgrind: the 64x64 launch of the hand-made indirect case (as in
//! `expected_launch.rs`), warmed once (prepared scene and its topology made), then
//! `RTCONF_BENCH_PASSES` launches (default 4) inside [`measured`], the one function to collect.
//!
//! ```text
//! cargo bench -p rtconf-model --bench launch_instructions --no-run
//! RTCONF_BENCH_ONLY=grid taskset -c 0 valgrind --tool=callgrind --collect-atstart=no \
//!     --toggle-collect='launch_instructions::measured' target/release/deps/launch_instructions-*
//! ```
//!
//! `taskset -c 0` keeps the launch on one thread, so every instruction is under [`measured`];
//! instructions per ray = callgrind's total / (passes × 4096). Run plainly it prints the launch
//! count only (no timing: the rates are `expected_launch.rs`'s); `RTCONF_BENCH_DUMP=DIR` writes
//! each workload's allowed outcomes and counters to `DIR/NAME.txt`, to diff before and after a
//! change that must not change them.

use model::tracer::workload::standard_workloads;

const SIDE: u32 = 64;

mod common;
use common::hand_case;

/// The launches whose instructions are counted.
#[inline(never)]
fn measured(body: &model::case::TraceBody, passes: usize) -> usize {
    let mut rays = 0;
    for _ in 0..passes {
        let e = model::semantics::expected_launch(&body.world, &body.call).expect("outcomes");
        rays += e.stats.rays as usize;
    }
    rays
}

fn main() {
    let passes: usize = std::env::var("RTCONF_BENCH_PASSES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4);
    let only = std::env::var("RTCONF_BENCH_ONLY").unwrap_or_default();
    for w in standard_workloads(SIDE, false) {
        if !w.launchable() || !w.name.contains(only.as_str()) {
            continue;
        }
        let case = w.as_launch_of(hand_case(), SIDE);
        let body = case.as_trace().expect("a trace case").clone();
        let warm = model::semantics::expected_launch(&body.world, &body.call).expect("outcomes");
        if let Ok(dir) = std::env::var("RTCONF_BENCH_DUMP") {
            // The launch's whole answer, to compare before and after a change of the tracer.
            let path = std::path::Path::new(&dir).join(format!("{}.txt", w.name.replace(' ', "-")));
            std::fs::write(&path, format!("{:#?}\n{:#?}", warm.allowed, warm.stats))
                .expect("the dump is written");
        }
        let rays = measured(&body, passes);
        println!("{:<24} {passes} launches, {rays} rays", w.name);
    }
}
