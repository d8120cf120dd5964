//! The oracle's run time against its error: for each precision mode (f32 filter only; f64 filter
//! with exact fallback; exact only) on every stress family and the standard workloads, the time
//! per ray (and its ratio to exact-only, the peer measured in the same run), the share of rays and
//! of pairs the model classed VARY, and misclassifications against exact-only — a pair whose REQ
//! decision differs from the exact one, counted both ways: "unsound" (the mode decided REQ where
//! exact decides otherwise) and "lost" (exact decides REQ, the mode says VARY).
//!
//! `cargo bench -p rtconf-model --bench oracle_curve` prints the table and writes
//! `target/oracle_curve.json` and `target/oracle_curve.png` (time per ray against misclassification
//! rate and against VARY share, one point per mode and family). `RTCONF_BENCH_SEEDS` sets the cases
//! per family (default 3).

use model::stress::families;
use model::tracer::workload::{run, standard_workloads};
use model::tracer::{
    AllowedOutcomes, Precision, PreparedScene, Presence, PrimitiveRef, TracerConfig, TracerStats,
};
use plot::{palette, Axis, Chart, Image, Marker, Rect, Scale, Series, Style};
use serde::Serialize;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

const MODES: [Precision; 3] = [
    Precision::F32FilterOnly,
    Precision::F64WithExactFallback,
    Precision::ExactOnly,
];

fn mode_name(p: Precision) -> &'static str {
    match p {
        Precision::F32FilterOnly => "f32-filter-only",
        Precision::F64WithExactFallback => "f64-exact-fallback",
        Precision::ExactOnly => "exact-only",
    }
}

/// Traces every ray of an input with one configuration.
type Tracer = Box<dyn Fn(&TracerConfig) -> (Vec<AllowedOutcomes>, TracerStats)>;

/// One input: a family's cases or a standard workload, with a tracer for it.
struct Input {
    name: String,
    kind: &'static str,
    rays: usize,
    trace: Tracer,
}

#[derive(Debug, Clone, Serialize)]
struct Row {
    input: String,
    kind: &'static str,
    mode: &'static str,
    rays: usize,
    ns_per_ray: f64,
    /// Time per ray over exact-only's on the same input, same run.
    ratio_to_exact: f64,
    vary_ray_share: f64,
    vary_pair_share: f64,
    exact_fallback_share: f64,
    pairs: u64,
    unsound: u64,
    lost: u64,
    misclassification_rate: f64,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Class {
    Req,
    Vary,
}

/// Each pair's class: REQ-hit or VARY for candidates; absent pairs are REQ-miss.
fn classes(outs: &[AllowedOutcomes]) -> Vec<HashMap<PrimitiveRef, Class>> {
    outs.iter()
        .map(|o| {
            o.candidates
                .iter()
                .map(|c| {
                    let k = if c.presence == Presence::Required {
                        Class::Req
                    } else {
                        Class::Vary
                    };
                    (c.primitive, k)
                })
                .collect()
        })
        .collect()
}

/// (unsound, lost) pairs of `mode` against `exact`.
fn misclassified(mode: &[AllowedOutcomes], exact: &[AllowedOutcomes]) -> (u64, u64) {
    let (m, e) = (classes(mode), classes(exact));
    let (mut unsound, mut lost) = (0, 0);
    for (m, e) in m.iter().zip(&e) {
        let keys: std::collections::HashSet<&PrimitiveRef> = m.keys().chain(e.keys()).collect();
        for k in keys {
            // None is REQ-miss.
            match (m.get(k), e.get(k)) {
                (a, b) if a == b => {}
                (Some(Class::Vary), _) => lost += 1,
                _ => unsound += 1,
            }
        }
    }
    (unsound, lost)
}

fn inputs(seeds: u64) -> Vec<Input> {
    let mut out = Vec::new();
    for f in families() {
        let cases: Vec<_> = (0..seeds).map(|s| f.case(s, f.test_size)).collect();
        let prepared: Vec<_> = cases
            .iter()
            .map(|c| PreparedScene::new(&c.scene).expect("defined"))
            .collect();
        let rays = cases.iter().map(|c| c.rays.len()).sum();
        out.push(Input {
            name: f.name.to_string(),
            kind: "stress",
            rays,
            trace: Box::new(move |config| {
                let mut outs = Vec::new();
                let mut stats = TracerStats::default();
                for (c, p) in cases.iter().zip(&prepared) {
                    let (o, s) = c.allowed_in(p, config);
                    outs.extend(o);
                    stats.merge(&s);
                }
                (outs, stats)
            }),
        });
    }
    for w in standard_workloads(24, false) {
        let prepared = PreparedScene::new(&w.scene).expect("defined");
        let rays = w.rays.clone();
        out.push(Input {
            name: w.name.to_string(),
            kind: "workload",
            rays: rays.len(),
            trace: Box::new(move |config| run(&prepared, &rays, config)),
        });
    }
    out
}

/// Median time of up to three passes (one when a pass takes over two seconds).
fn timed(input: &Input, config: &TracerConfig) -> (f64, Vec<AllowedOutcomes>, TracerStats) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..3 {
        let t = Instant::now();
        let r = (input.trace)(config);
        times.push(t.elapsed().as_secs_f64());
        last = Some(r);
        if times[0] > 2.0 {
            break;
        }
    }
    times.sort_by(f64::total_cmp);
    let (outs, stats) = last.expect("a pass");
    (times[times.len() / 2], outs, stats)
}

fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"))
}

fn main() {
    let seeds = std::env::var("RTCONF_BENCH_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let mut rows: Vec<Row> = Vec::new();
    println!(
        "{:<24} {:<19} {:>6} {:>11} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9}",
        "input",
        "mode",
        "rays",
        "us/ray",
        "x exact",
        "VARY r%",
        "VARY p%",
        "exact %",
        "unsound",
        "lost",
        "miscl. %"
    );
    for input in inputs(seeds) {
        let (t_exact, exact, exact_stats) =
            timed(&input, &TracerConfig::with_precision(Precision::ExactOnly));
        for mode in MODES {
            let (t, outs, stats) = if mode == Precision::ExactOnly {
                (t_exact, exact.clone(), exact_stats)
            } else {
                timed(&input, &TracerConfig::with_precision(mode))
            };
            let (unsound, lost) = misclassified(&outs, &exact);
            let pairs = exact_stats.pair_tests;
            let row = Row {
                input: input.name.clone(),
                kind: input.kind,
                mode: mode_name(mode),
                rays: input.rays,
                ns_per_ray: 1e9 * t / input.rays as f64,
                ratio_to_exact: t / t_exact,
                vary_ray_share: outs.iter().filter(|o| o.vary).count() as f64
                    / outs.len().max(1) as f64,
                vary_pair_share: stats.vary_share(),
                exact_fallback_share: stats.exact_share(),
                pairs,
                unsound,
                lost,
                misclassification_rate: (unsound + lost) as f64 / pairs.max(1) as f64,
            };
            println!(
                "{:<24} {:<19} {:>6} {:>11.2} {:>8.4} {:>8.2} {:>8.2} {:>8.3} {:>8} {:>8} {:>9.4}",
                row.input,
                row.mode,
                row.rays,
                row.ns_per_ray / 1e3,
                row.ratio_to_exact,
                100.0 * row.vary_ray_share,
                100.0 * row.vary_pair_share,
                100.0 * row.exact_fallback_share,
                row.unsound,
                row.lost,
                100.0 * row.misclassification_rate
            );
            rows.push(row);
        }
    }
    println!("\nall inputs (time is the sum over inputs; ratio is against exact-only's sum):");
    let total = |mode: &str, f: &dyn Fn(&Row) -> f64| {
        rows.iter().filter(|r| r.mode == mode).map(f).sum::<f64>()
    };
    let exact_time = total("exact-only", &|r| r.ns_per_ray * r.rays as f64);
    let rays = total("exact-only", &|r| r.rays as f64);
    for mode in MODES.map(mode_name) {
        let time = total(mode, &|r| r.ns_per_ray * r.rays as f64);
        let mis = total(mode, &|r| (r.unsound + r.lost) as f64);
        let unsound = total(mode, &|r| r.unsound as f64);
        let pairs = total(mode, &|r| r.pairs as f64);
        let vary = total(mode, &|r| r.vary_ray_share * r.rays as f64);
        // The geometric mean of the per-input ratios: every input weighs the same.
        let n = rows.iter().filter(|r| r.mode == mode).count().max(1) as f64;
        let geo = (total(mode, &|r| r.ratio_to_exact.ln()) / n).exp();
        println!(
            "{mode:<19} {:>9.2} us/ray  x exact {:>7.4} (geometric mean over inputs {:>7.4})  VARY rays {:>6.2} %  misclassified {:>6} of {:>8} pairs ({:.4} %, {} unsound)",
            time / rays / 1e3,
            time / exact_time,
            geo,
            100.0 * vary / rays,
            mis,
            pairs,
            100.0 * mis / pairs.max(1.0),
            unsound
        );
    }
    let dir = target_dir();
    std::fs::create_dir_all(&dir).expect("target directory");
    let dir = dir.canonicalize().unwrap_or(dir);
    let json = dir.join("oracle_curve.json");
    std::fs::write(
        &json,
        serde_json::to_string_pretty(&rows).expect("rows serialise"),
    )
    .expect("write json");
    let png = dir.join("oracle_curve.png");
    plot_curve(&rows).write_png(&png).expect("write png");
    println!("\nwrote {} and {}", json.display(), png.display());
}

fn plot_curve(rows: &[Row]) -> Image {
    let series = |y: &dyn Fn(&Row) -> f64| -> Vec<Series> {
        // Each input's three modes joined by a grey line (unnamed: not in the legend).
        let mut inputs: Vec<&str> = rows.iter().map(|r| r.input.as_str()).collect();
        inputs.dedup();
        let curves = inputs.into_iter().map(|name| Series {
            name: String::new(),
            points: rows
                .iter()
                .filter(|r| r.input == name)
                .map(|r| (r.ns_per_ray / 1e3, y(r)))
                .collect(),
            color: [190, 190, 190],
            style: Style::Line,
        });
        curves
            .chain(MODES.iter().enumerate().map(|(i, m)| {
                Series {
                    name: mode_name(*m).to_string(),
                    points: rows
                        .iter()
                        .filter(|r| r.mode == mode_name(*m))
                        .map(|r| (r.ns_per_ray / 1e3, y(r)))
                        .collect(),
                    color: palette::series(i),
                    style: Style::Scatter(Marker::nth(i)),
                }
            }))
            .collect()
    };
    let left = Chart {
        title: "Misclassified pairs against exact, per family".into(),
        x: Axis::new("time per ray (us)", Scale::Log10),
        y: Axis::new("misclassified pairs (%)", Scale::Linear),
        series: series(&|r| 100.0 * r.misclassification_rate),
        legend: true,
    };
    let right = Chart {
        title: "Rays classed VARY, per family".into(),
        x: Axis::new("time per ray (us)", Scale::Log10),
        y: Axis::new("rays with a VARY part (%)", Scale::Linear).with_range(-5.0, 130.0),
        series: series(&|r| 100.0 * r.vary_ray_share),
        legend: true,
    };
    let (w, h) = (1000, 700);
    let mut img = Image::new(2 * w, h, palette::WHITE);
    left.draw(&mut img, Rect::new(0, 0, w as i32, h as i32));
    right.draw(&mut img, Rect::new(w as i32, 0, w as i32, h as i32));
    img
}
