//! Rays per second of the reference tracer against lavapipe on the same scenes and rays, measured in
//! one run: the workloads of `model::tracer::workload` (a 64x64 pinhole camera each; the spheres in
//! boxes through a procedural hit group, `Workload::as_launch_of`) traced as a
//! vkCmdTraceRaysIndirectKHR launch of the hand-made case on lavapipe (structures, pipeline and
//! shader table cached after a warm-up, so a pass is record, submit and read back the 28-word
//! records), and by the model (`expected_launch`: the allowed outcomes of every launch ID, the
//! prepared scene cached likewise). Each rate is the median of the passes; the ratio is the oracle's
//! rate over lavapipe's, and `paired` the median of the passes' own ratios (each pass times the two
//! back to back, so a change in the machine's load between passes moves both sides alike), with
//! their interquartile range beside it (`paired IQR`: how far one run's ratio can be trusted on a
//! machine whose speed moves). Also the share of ray/primitive tests that needed the exact
//! fallback, and whether lavapipe's records pass the judgement. `judged ratio` adds what a run's
//! oracle also spends on a launch: the judgement of the records lavapipe wrote
//! (`rendered::judge_records`, each pass on that pass's records), its time added to the tracer's
//! before the rate is taken (median of the passes' own ratios). Lavapipe runs llvmpipe on every core, and the model
//! traces a launch's distinct rays on every core too (`expected_launch`), so the ratio compares the
//! two on the same machine; `cargo bench -p rtconf-model --bench expected_launch` gives the model's
//! CPU time per ray beside it.
//!
//! `cargo bench -p rtconf-harness --bench render_rays` (lavapipe through `VK_DRIVER_FILES`;
//! `RTCONF_BENCH_PASSES` sets the passes, default 31, and `RTCONF_BENCH_ONLY=NAME` keeps the
//! workloads whose name contains NAME; `scripts/bench-ab.sh` runs two builds of it in turn).
//! Thirty-one passes rather than fifteen: over forty full runs of each on the 2-core machine, the
//! instanced copies' ratio had a standard deviation of 0.037 against 0.065 (same median, 2.14), for
//! a run of about 4 s instead of 2 s.

use harness::{Driver, Execution, Executor, Status};
use model::case::Intent;
use model::tracer::workload::standard_workloads;
use std::time::Instant;

/// Launch side: 64x64 launch IDs, one camera ray each.
const SIDE: u32 = 64;

#[path = "../../model/benches/common/mod.rs"]
mod common;
use common::hand_case;

fn median(v: Vec<f64>) -> f64 {
    quantile(v, 0.5)
}

/// The value at fraction `q` of the sorted values (the nearest rank; `v` not empty).
fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let mut ctx = match Executor::new(Driver::Lavapipe) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    println!(
        "{:<24} {:>7} {:>7} {:>14} {:>14} {:>8} {:>8} {:>11} {:>13} {:>9} {:>8}",
        "workload",
        "prims",
        "rays",
        "oracle rays/s",
        "lvp rays/s",
        "ratio",
        "paired",
        "paired IQR",
        "judged ratio",
        "exact %",
        "judged"
    );
    let passes: usize = std::env::var("RTCONF_BENCH_PASSES")
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|&n| n > 0)
        .unwrap_or(31);
    let only = std::env::var("RTCONF_BENCH_ONLY").unwrap_or_default();
    let mut ratios = Vec::new();
    for w in standard_workloads(SIDE, false) {
        // The hand case's pipeline has one hit group: workloads of one kind of geometry.
        if !w.launchable() || !w.name.contains(&only) {
            continue;
        }
        let mut case = w.as_launch_of(hand_case(), SIDE);
        case.name = format!("bench-{}", w.name);
        let prims: usize = w
            .scene
            .instances
            .iter()
            .filter_map(|i| i.bottom_level)
            .map(|b| {
                w.scene.bottom_levels[b as usize]
                    .geometries
                    .iter()
                    .map(|g| match &g.data {
                        model::scene::GeometryData::Triangles(t) => t.primitive_count(),
                        model::scene::GeometryData::Aabbs(a) => a.boxes.len(),
                    })
                    .sum::<usize>()
            })
            .sum();
        let profile = harness_profile();
        if let Err(e) = case.runnable(&profile) {
            eprintln!("{}: not runnable: {e}", case.name);
            std::process::exit(1);
        }
        let exec = Execution {
            run_valid: case.intent == Intent::Valid,
            ..Default::default()
        };
        let body = case.as_trace().expect("a trace case").clone();
        let ids = (SIDE * SIDE) as f64;
        // Warm-up: structures, pipeline and the prepared scene are made once.
        let warm = ctx.execute(&case, &exec);
        if warm.status != Status::Ran {
            eprintln!("{}: {:?}", case.name, warm.status);
            std::process::exit(1);
        }
        let expected = model::semantics::expected_launch(&body.world, &body.call)
            .expect("the workload's outcomes");
        let mut lvp = Vec::new();
        let mut oracle = Vec::new();
        let mut paired = Vec::new();
        let mut with_judgement = Vec::new();
        let mut last = warm;
        for _ in 0..passes {
            let t = Instant::now();
            last = ctx.execute(&case, &exec);
            let l = ids / t.elapsed().as_secs_f64();
            let t = Instant::now();
            let e = model::semantics::expected_launch(&body.world, &body.call);
            let traced = t.elapsed().as_secs_f64();
            let o = ids / traced;
            assert!(e.is_some());
            let words = last.words().expect("lavapipe's records");
            let t = Instant::now();
            let j = model::rendered::judge_records(&body, words);
            let judging = t.elapsed().as_secs_f64();
            assert!(j.is_ok());
            lvp.push(l);
            oracle.push(o);
            paired.push(o / l);
            with_judgement.push(ids / (traced + judging) / l);
        }
        let judged = match last
            .words()
            .map(|w| model::rendered::judge_records(&body, w))
        {
            Some(Ok(j)) if j.result.failures == 0 => "pass".to_string(),
            Some(Ok(j)) => format!("{} fail", j.result.failures),
            Some(Err(e)) => format!("error: {e}"),
            None => "no records".into(),
        };
        let (o, l) = (median(oracle), median(lvp));
        ratios.push(o / l);
        let spread = format!(
            "{:.2}-{:.2}",
            quantile(paired.clone(), 0.25),
            quantile(paired.clone(), 0.75)
        );
        println!(
            "{:<24} {:>7} {:>7} {:>14.0} {:>14.0} {:>8.2} {:>8.2} {:>11} {:>13.2} {:>9.4} {:>8}",
            w.name,
            prims,
            SIDE * SIDE,
            o,
            l,
            o / l,
            median(paired),
            spread,
            median(with_judgement),
            100.0 * expected.stats.exact_share(),
            judged
        );
    }
    println!(
        "oracle / lavapipe rays/s: median ratio {:.2} over {} workloads",
        median(ratios.clone()),
        ratios.len()
    );
}

fn harness_profile() -> model::DeviceProfile {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
    let text = std::fs::read_to_string(path).expect("profiles/lavapipe.json");
    model::DeviceProfile::from_profiles_json("lavapipe", &text).expect("a valid profile")
}
