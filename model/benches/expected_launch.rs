//! Rays per second of `model::semantics::expected_launch` — the oracle the session judges rendered
//! cases with, shader binding table resolution and prepared-scene memo included — on the workloads
//! of `model::tracer::workload` (triangles, and spheres in boxes) as a 64x64 launch of the hand-made indirect case (the
//! scene and rays `harness/benches/render_rays.rs` gives lavapipe), beside the bare tracer
//! (`workload::run`, one shader table for every ray) on the same rays as the peer in the same run,
//! and the launch's CPU time per ray (all threads). The bare tracer's rays are also timed apart by
//! whether they have a candidate (`ns/hit`, `ns/miss`: one thread, medians of the passes), and
//! `hit time %` is the share of the tracer's time the rays with a candidate take.
//!
//! `cargo bench -p rtconf-model --bench expected_launch` (`RTCONF_BENCH_PASSES` sets the passes,
//! default 9; each rate is their
//! median; `RTCONF_BENCH_ONLY=NAME` keeps the workloads whose name contains NAME;
//! `RTCONF_BENCH_EVICT=MB` writes MB megabytes between passes, untimed, so each pass starts on
//! caches another program filled, as the oracle's passes do in `render_rays` after lavapipe's).

use model::tracer::workload::{run, standard_workloads};
use model::tracer::{PreparedScene, TracerConfig};
use std::time::Instant;

const SIDE: u32 = 64;

mod common;
use common::hand_case;

/// CPU seconds this process has used (all threads): a rate from it is less disturbed by other
/// processes on a shared machine than one from wall time.
fn cpu_seconds() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let passes: usize = std::env::var("RTCONF_BENCH_PASSES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(9);
    let only = std::env::var("RTCONF_BENCH_ONLY").unwrap_or_default();
    let evict_mb: usize = std::env::var("RTCONF_BENCH_EVICT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let mut other = vec![0u8; evict_mb << 20];
    let mut evict = |pass: usize| {
        for (k, b) in other.iter_mut().enumerate().step_by(64) {
            *b = (pass + k) as u8;
        }
        std::hint::black_box(&other);
    };
    println!(
        "{:<24} {:>7} {:>7} {:>16} {:>14} {:>16} {:>8} {:>10} {:>10} {:>10} {:>7} {:>8} {:>8} {:>11}",
        "workload",
        "prims",
        "rays",
        "launch rays/s",
        "cpu µs/ray",
        "tracer rays/s",
        "ratio",
        "nodes/ray",
        "far/ray",
        "pairs/ray",
        "hits %",
        "ns/hit",
        "ns/miss",
        "hit time %"
    );
    for w in standard_workloads(SIDE, false) {
        if !w.launchable() || !w.name.contains(only.as_str()) {
            continue;
        }
        let case = w.as_launch_of(hand_case(), SIDE);
        let body = case.as_trace().expect("a trace case").clone();
        let ids = (SIDE * SIDE) as f64;
        // Warm-up: the prepared scene is made once.
        let warm = model::semantics::expected_launch(&body.world, &body.call)
            .expect("the workload's outcomes");
        let per_ray = |n: u64| n as f64 / warm.stats.rays.max(1) as f64;
        let mut launch = Vec::new();
        let mut cpu = Vec::new();
        for pass in 0..passes {
            evict(pass);
            let (t, c) = (Instant::now(), cpu_seconds());
            let e = model::semantics::expected_launch(&body.world, &body.call);
            launch.push(ids / t.elapsed().as_secs_f64());
            cpu.push(1e6 * (cpu_seconds() - c) / ids);
            assert!(e.is_some());
        }
        let prepared = PreparedScene::new(&w.scene).expect("defined workload");
        let mut tracer = Vec::new();
        let mut outcomes = Vec::new();
        for pass in 0..passes {
            evict(pass);
            let t = Instant::now();
            let r = run(&prepared, &w.rays, &TracerConfig::default());
            tracer.push(w.rays.len() as f64 / t.elapsed().as_secs_f64());
            assert_eq!(r.0.len(), w.rays.len());
            outcomes = r.0;
        }
        // The rays with a candidate and those without, each traced alone: ns per ray.
        let (hit_rays, miss_rays): (Vec<_>, Vec<_>) = w
            .rays
            .iter()
            .zip(&outcomes)
            .partition(|(_, o)| !o.candidates.is_empty());
        let mut ns_per_ray = |rays: Vec<(&model::scene::Ray, _)>| {
            let rays: Vec<model::scene::Ray> = rays.into_iter().map(|(r, _)| *r).collect();
            let mut times = Vec::new();
            for pass in 0..passes {
                evict(pass);
                let t = Instant::now();
                let r = run(&prepared, &rays, &TracerConfig::default());
                times.push(1e9 * t.elapsed().as_secs_f64() / rays.len().max(1) as f64);
                assert_eq!(r.0.len(), rays.len());
            }
            (median(times), rays.len() as f64)
        };
        let (hit_ns, hits) = ns_per_ray(hit_rays);
        let (miss_ns, misses) = ns_per_ray(miss_rays);
        let (l, r) = (median(launch), median(tracer));
        println!(
            "{:<24} {:>7} {:>7} {:>16.0} {:>14.2} {:>16.0} {:>8.2} {:>10.1} {:>10.1} {:>10.1} {:>7.1} {:>8.0} {:>8.0} {:>11.1}",
            w.name,
            prepared.primitive_count(),
            w.rays.len(),
            l,
            median(cpu),
            r,
            l / r,
            per_ray(warm.stats.nodes_visited),
            per_ray(warm.stats.far_rejections),
            per_ray(warm.stats.pair_tests),
            100.0 * hits / (hits + misses),
            hit_ns,
            miss_ns,
            100.0 * hits * hit_ns / (hits * hit_ns + misses * miss_ns)
        );
    }
}
