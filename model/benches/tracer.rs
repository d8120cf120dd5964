//! Rays per second of the reference tracer per precision mode on the standard workloads, the share
//! of ray/primitive tests that needed the exact fallback, the VARY share, and how often plain f32
//! signs would have classified a ray differently. Ratios against the default mode are printed
//! beside the rates (a driver's rate on the same workloads is the peer a later step adds).
//!
//! `cargo bench -p rtconf-model --bench tracer` (set `RTCONF_BENCH_LARGE=1` for the 1e6 grid).

use model::tracer::workload::{run, standard_workloads};
use model::tracer::{AllowedOutcomes, Precision, PreparedScene, TracerConfig};
use std::time::Instant;

fn shape(
    o: &AllowedOutcomes,
) -> Vec<(model::tracer::PrimitiveRef, model::tracer::Presence, usize)> {
    o.candidates
        .iter()
        .map(|c| (c.primitive, c.presence, c.reports.len()))
        .collect()
}

fn main() {
    let large = std::env::var("RTCONF_BENCH_LARGE").is_ok();
    let side = 128;
    println!(
        "{:<24} {:>8} {:>7} {:<22} {:>12} {:>7} {:>10} {:>10} {:>10} {:>9}",
        "workload",
        "prims",
        "rays",
        "mode",
        "rays/s",
        "ratio",
        "pairs/ray",
        "exact %",
        "VARY %",
        "diff"
    );
    for w in standard_workloads(side, large) {
        let t = Instant::now();
        let prepared = PreparedScene::new(&w.scene).expect("defined workload");
        let prep = t.elapsed().as_secs_f64();
        let mut default_rate = 0.0;
        let mut reference: Vec<AllowedOutcomes> = Vec::new();
        for precision in [
            Precision::F64WithExactFallback,
            Precision::F32FilterOnly,
            Precision::ExactOnly,
        ] {
            // Exact arithmetic for every pair is slow: every sixteenth ray.
            let strided: Vec<_> = w.rays.iter().step_by(16).copied().collect();
            let rays = if precision == Precision::ExactOnly {
                &strided[..]
            } else {
                &w.rays[..]
            };
            let config = TracerConfig::with_precision(precision);
            // Median of three timed passes (the machine may be shared).
            let mut rates = Vec::new();
            let mut last = None;
            for _ in 0..3 {
                let t = Instant::now();
                let r = run(&prepared, rays, &config);
                rates.push(rays.len() as f64 / t.elapsed().as_secs_f64());
                last = Some(r);
            }
            rates.sort_by(f64::total_cmp);
            let rate = rates[1];
            let (outs, stats) = last.expect("three passes");
            let vary_rays = outs.iter().filter(|o| o.vary).count();
            let diff = match precision {
                Precision::F64WithExactFallback => {
                    default_rate = rate;
                    reference = outs;
                    String::from("-")
                }
                Precision::ExactOnly => {
                    let d = outs
                        .iter()
                        .zip(reference.iter().step_by(16))
                        .filter(|(a, b)| shape(a) != shape(b))
                        .count();
                    format!("{d}/{}", outs.len())
                }
                _ => {
                    let d = outs
                        .iter()
                        .zip(&reference)
                        .filter(|(a, b)| shape(a) != shape(b))
                        .count();
                    format!("{d}/{}", outs.len())
                }
            };
            println!(
                "{:<24} {:>8} {:>7} {:<22} {:>12.0} {:>7.3} {:>10.2} {:>10.4} {:>10.3} {:>9}",
                w.name,
                prepared.primitive_count(),
                rays.len(),
                format!("{precision:?}"),
                rate,
                rate / default_rate,
                stats.pair_tests as f64 / rays.len() as f64,
                100.0 * stats.exact_share(),
                100.0 * stats.vary_share(),
                diff,
            );
            if precision == Precision::F64WithExactFallback {
                println!(
                    "{:<24} prepare {:.3} s; rays with a VARY part {:.3} %; far rejections/ray {:.1}",
                    "",
                    prep,
                    100.0 * vary_rays as f64 / rays.len() as f64,
                    stats.far_rejections as f64 / rays.len() as f64
                );
            }
        }
    }
}
