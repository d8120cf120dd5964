//! The suite's detection power against run time: a fixed set of rendered cases run once as they are,
//! then once per injection (kind × size, `crate::inject`) with the perturbed copy handed to the driver
//! and the case judged; per cell the share of applicable cases whose outcome catches the fault, and
//! the median number of cases and seconds to the first catch over random orders of the cases; the
//! mutation score over the cells at or above each kind's threshold. Writes `detection.json`,
//! `detection.md` and two plots (`detection.png`: rate against size; `detection-time.png`: seconds
//! to the first catch against size).

use crate::compare::Outcome;
use crate::error::SessionError;
use crate::inject::{applied, detects, Injection, Kind};
use crate::run::Judging;
use crate::sources;
use generator::CaseSpec;
use harness::{Driver, Execution, Request};
use model::scene::build::SceneRng;
use model::{Case, CommandId, RuleSet};
use serde::Serialize;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// What a detection table measures.
#[derive(Debug, Clone)]
pub struct DetectConfig {
    pub driver: String,
    /// The device profile (None: the driver's).
    pub profile: Option<String>,
    /// The trace command whose rendered cases are run.
    pub command: CommandId,
    /// The kinds and their sizes (size 0, the case itself, is always measured too).
    pub cells: Vec<(Kind, Vec<f64>)>,
    /// Rendered cases.
    pub count: usize,
    /// The cases' seed and the injections'.
    pub seed: u64,
    pub jobs: usize,
    /// Seconds a case may take.
    pub timeout: u64,
    pub out: PathBuf,
    /// Registry sources (empty: the layer's version installed).
    pub from: Vec<PathBuf>,
    /// Triage files (empty: the driver's and the layer's).
    pub triage: Vec<PathBuf>,
}

/// Random orders of a cell's cases the medians to first detection are taken over.
pub const ORDERS: usize = 101;

/// The share of seeded faults above threshold the suite must catch.
pub const MUTATION_TARGET: f64 = 0.95;

/// One case of one cell.
#[derive(Debug, Clone, Serialize)]
pub struct CellCase {
    pub case: String,
    pub outcome: Outcome,
    pub detected: bool,
    /// The driver's execution and the judgement, in seconds.
    pub seconds: f64,
    /// What the injection changed.
    pub what: String,
}

/// One row of the table.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    pub kind: String,
    pub size: f64,
    pub unit: String,
    /// Whether the size is at or above the kind's threshold (counted in the mutation score).
    pub above_threshold: bool,
    pub applicable: usize,
    pub not_applicable: usize,
    /// Applicable cases left out because they fail as they are (a catch could not be told apart).
    pub excluded: usize,
    pub detected: usize,
    pub rate: Option<f64>,
    /// Medians over [`ORDERS`] random orders of the applicable cases (None: nothing caught).
    pub median_cases_to_first: Option<f64>,
    pub median_seconds_to_first: Option<f64>,
    pub cases: Vec<CellCase>,
}

/// The mutation score: seeded faults at or above their kind's threshold, and those caught.
#[derive(Debug, Clone, Serialize)]
pub struct MutationScore {
    pub faults: usize,
    pub caught: usize,
    pub score: Option<f64>,
    /// The threshold of each kind and its unit.
    pub thresholds: Vec<(String, f64, String)>,
}

impl MutationScore {
    /// The line the table ends with.
    pub fn line(&self) -> String {
        format!(
            "mutation score: {} of {} seeded faults above threshold caught",
            self.score
                .map_or("-".into(), |s| format!("{:.1}%", 100.0 * s)),
            self.faults
        )
    }

    /// Whether it reaches [`MUTATION_TARGET`].
    pub fn meets_target(&self) -> bool {
        self.score.is_some_and(|s| s >= MUTATION_TARGET)
    }
}

/// `detection.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Detection {
    pub driver: String,
    pub profile: String,
    pub layer: String,
    pub command: String,
    pub count: usize,
    pub seed: u64,
    /// Cases as they are: outcomes.
    pub baseline: Vec<(String, Outcome)>,
    pub cells: Vec<Cell>,
    pub mutation: MutationScore,
    pub seconds: f64,
}

/// Runs the table; see the module documentation.
pub fn detect(config: &DetectConfig) -> Result<Detection, SessionError> {
    let started = Instant::now();
    if !config.command.is_trace() {
        return Err(SessionError::Usage(format!(
            "detect runs rendered cases of a trace command, not {}",
            config.command.vk_name()
        )));
    }
    if config.count == 0 {
        return Err(SessionError::Usage("--count must be at least 1".into()));
    }
    let layer = harness::validation_layer()?;
    let set = sources::registry_for_layer(&config.from, Some(&layer))?;
    let rules = RuleSet::from_vuids(&set);
    let driver = Driver::parse(&config.driver);
    harness::check_driver(&driver)?;
    let profile_name = config
        .profile
        .clone()
        .unwrap_or_else(|| sources::default_profile_name(&config.driver));
    let profile = sources::profile_for(&profile_name)?;
    let triage = sources::triage_for(&config.triage, Some(&layer.version), &driver)?;
    std::env::set_var(harness::worker::DRIVER_ENV, &config.driver);
    let judging = Judging::new(&rules, &profile, &triage);
    let spec = CaseSpec::rendered(config.command);
    let cases = generator::generate(
        &profile,
        &profile_name,
        &rules,
        &spec,
        config.count,
        config.seed,
    )
    .map_err(|e| SessionError::Usage(format!("could not generate rendered cases: {e}")))?;
    let dir = config.out.join("cases");
    std::fs::create_dir_all(&dir).map_err(|e| SessionError::io(dir.display().to_string(), e))?;
    for c in &cases {
        let p = dir.join(format!("{}.yaml", c.name));
        std::fs::write(&p, c.to_yaml())
            .map_err(|e| SessionError::io(p.display().to_string(), e))?;
    }
    let timeout = Duration::from_secs(config.timeout);
    let run = |copies: Vec<(usize, Case, String)>| -> Vec<(usize, CellCase)> {
        run_cells(&judging, &cases, copies, config.jobs, timeout)
    };
    // The cases as they are; a gated case never runs and is left out of every cell.
    let runnable: Vec<usize> = (0..cases.len())
        .filter(|&i| crate::gate::gate(&cases[i], &judging).is_none())
        .collect();
    let base = run(runnable
        .iter()
        .map(|&i| (i, cases[i].clone(), String::new()))
        .collect());
    let mut baseline_outcome: Vec<Option<CellCase>> = vec![None; cases.len()];
    for (i, c) in base {
        baseline_outcome[i] = Some(c);
    }
    let mut cells = Vec::new();
    for (kind, sizes) in &config.cells {
        let mut sizes = sizes.clone();
        sizes.retain(|s| *s != 0.0);
        sizes.insert(0, 0.0);
        for size in sizes {
            let injection = Injection { kind: *kind, size };
            let mut copies = Vec::new();
            let mut not_applicable = 0;
            let mut excluded = 0;
            let mut zero = Vec::new();
            for &i in &runnable {
                let Some(clean) = &baseline_outcome[i] else {
                    continue;
                };
                match applied(&injection, config.seed, &cases[i], &judging) {
                    Err(_) => not_applicable += 1,
                    // Size 0 hands the driver the case itself: its outcome is the clean run's.
                    Ok(_) if size == 0.0 => zero.push(clean.clone()),
                    Ok(_) if clean.detected => excluded += 1,
                    Ok(inj) => copies.push((i, inj.case, inj.what)),
                }
            }
            let ran: Vec<CellCase> = if size == 0.0 {
                zero
            } else {
                run(copies).into_iter().map(|(_, c)| c).collect()
            };
            cells.push(cell(&injection, ran, not_applicable, excluded, config.seed));
        }
    }
    let mutation = score(&cells, &config.cells);
    Ok(Detection {
        driver: config.driver.clone(),
        profile: profile_name,
        layer: layer.version.clone(),
        command: config.command.vk_name().to_string(),
        count: cases.len(),
        seed: config.seed,
        baseline: cases
            .iter()
            .zip(&baseline_outcome)
            .filter_map(|(c, o)| Some((c.name.clone(), o.as_ref()?.outcome)))
            .collect(),
        cells,
        mutation,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Runs copies `(case index, copy, what)` in worker processes and judges each against its case:
/// the outcome, whether it catches the fault, and the seconds the driver and the judge took.
fn run_cells(
    judging: &Judging,
    cases: &[Case],
    copies: Vec<(usize, Case, String)>,
    jobs: usize,
    timeout: Duration,
) -> Vec<(usize, CellCase)> {
    if copies.is_empty() {
        return vec![];
    }
    let requests: Vec<Request> = copies
        .iter()
        .enumerate()
        .map(|(index, (_, copy, _))| Request {
            index,
            execution: Execution::for_case(copy, judging.profile),
            case: copy.clone(),
        })
        .collect();
    let mut out = Vec::with_capacity(copies.len());
    harness::run_in_workers(&requests, jobs, timeout, |resp| {
        let Some((i, _, what)) = copies.get(resp.index) else {
            return;
        };
        let judged = Instant::now();
        let report = judging.judge(&cases[*i], &resp);
        let seconds = resp.millis / 1000.0 + judged.elapsed().as_secs_f64();
        out.push((
            *i,
            CellCase {
                case: cases[*i].name.clone(),
                outcome: report.outcome,
                detected: detects(report.outcome),
                seconds,
                what: what.clone(),
            },
        ));
    });
    out.sort_by_key(|(i, _)| *i);
    out
}

/// A row from its cases: the rate, and the medians to first detection over random orders.
fn cell(
    injection: &Injection,
    cases: Vec<CellCase>,
    not_applicable: usize,
    excluded: usize,
    seed: u64,
) -> Cell {
    let detected = cases.iter().filter(|c| c.detected).count();
    let n = cases.len();
    let (mut firsts, mut seconds) = (Vec::new(), Vec::new());
    if detected > 0 {
        let mut rng = SceneRng(seed ^ 0x00D3_7EC7);
        let mut order: Vec<usize> = (0..n).collect();
        for _ in 0..ORDERS {
            for i in (1..n).rev() {
                let j = rng.below(i as u64 + 1) as usize;
                order.swap(i, j);
            }
            let mut elapsed = 0.0;
            for (k, &i) in order.iter().enumerate() {
                elapsed += cases[i].seconds;
                if cases[i].detected {
                    firsts.push((k + 1) as f64);
                    seconds.push(elapsed);
                    break;
                }
            }
        }
    }
    Cell {
        kind: injection.kind.name().into(),
        size: injection.size,
        unit: injection.kind.unit().into(),
        above_threshold: injection.size > 0.0 && injection.size >= injection.kind.threshold(),
        applicable: n,
        not_applicable,
        excluded,
        detected,
        rate: (n > 0).then(|| detected as f64 / n as f64),
        median_cases_to_first: median(&mut firsts),
        median_seconds_to_first: median(&mut seconds),
        cases,
    }
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

fn score(cells: &[Cell], kinds: &[(Kind, Vec<f64>)]) -> MutationScore {
    let above: Vec<&Cell> = cells.iter().filter(|c| c.above_threshold).collect();
    let faults: usize = above.iter().map(|c| c.applicable).sum();
    let caught: usize = above.iter().map(|c| c.detected).sum();
    MutationScore {
        faults,
        caught,
        score: (faults > 0).then(|| caught as f64 / faults as f64),
        thresholds: kinds
            .iter()
            .map(|(k, _)| (k.name().to_string(), k.threshold(), k.unit().to_string()))
            .collect(),
    }
}

fn num(x: Option<f64>, digits: usize) -> String {
    x.map_or("-".into(), |v| format!("{v:.digits$}"))
}

impl Detection {
    /// The markdown table, the mutation score line and the thresholds.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# Detection on {} (profile {}, layer {})\n\n{} rendered {} cases, seed {}; {} s in all. \
             Detected: the case's outcome is fail (or the driver crashed or hung on the copy). Medians \
             over {ORDERS} random orders of the applicable cases; seconds are the driver's execution \
             and the judgement of each case until the first catch.\n\n",
            self.driver,
            self.profile,
            self.layer,
            self.count,
            self.command,
            self.seed,
            self.seconds.round()
        );
        let clean = self.baseline.iter().filter(|(_, o)| !detects(*o)).count();
        s += &format!(
            "As they are: {clean} of {} runnable cases pass or are triaged.\n\n",
            self.baseline.len()
        );
        s += "| kind | size | unit | cases applicable | detected | detection rate | median cases to first detection | median seconds to first detection | not applicable | excluded |\n";
        s += "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
        for c in &self.cells {
            s += &format!(
                "| {} | {}{} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                c.kind,
                c.size,
                if c.above_threshold { " *" } else { "" },
                c.unit,
                c.applicable,
                c.detected,
                c.rate.map_or("-".into(), |r| format!("{:.0}%", 100.0 * r)),
                num(c.median_cases_to_first, 0),
                num(c.median_seconds_to_first, 2),
                c.not_applicable,
                c.excluded
            );
        }
        s +=
            "\n`*`: at or above the kind's threshold (counted in the mutation score). Thresholds: ";
        s += &self
            .mutation
            .thresholds
            .iter()
            .map(|(k, t, u)| format!("{k} {t:.3e} {u}"))
            .collect::<Vec<_>>()
            .join(", ");
        s += " (`session::inject::Kind::threshold` says why).\n\n";
        s += &self.mutation.line();
        s += "\n";
        s
    }

    /// Writes `detection.json`, `detection.md`, `detection.png` and `detection-time.png` to `out`.
    pub fn write(&self, out: &std::path::Path) -> Result<(), SessionError> {
        let io = |p: &std::path::Path| {
            let p = p.display().to_string();
            move |e| SessionError::io(p, e)
        };
        std::fs::create_dir_all(out).map_err(io(out))?;
        let json = out.join("detection.json");
        let text = serde_json::to_string_pretty(self).unwrap_or_default() + "\n";
        std::fs::write(&json, text).map_err(io(&json))?;
        let md = out.join("detection.md");
        std::fs::write(&md, self.markdown()).map_err(io(&md))?;
        let rate = out.join("detection.png");
        self.plot(false).write_png(&rate).map_err(io(&rate))?;
        let time = out.join("detection-time.png");
        self.plot(true).write_png(&time).map_err(io(&time))?;
        Ok(())
    }

    /// Detection rate (or median seconds to the first catch) against the size over the kind's
    /// threshold, one series per kind.
    fn plot(&self, seconds: bool) -> plot::Image {
        use plot::{palette, Axis, Chart, Marker, Scale, Series, Style};
        let mut kinds: Vec<&str> = self.cells.iter().map(|c| c.kind.as_str()).collect();
        kinds.dedup();
        let series: Vec<Series> = kinds
            .iter()
            .enumerate()
            .map(|(i, k)| {
                let threshold = Kind::parse(k).map_or(1.0, Kind::threshold);
                Series {
                    name: (*k).to_string(),
                    points: self
                        .cells
                        .iter()
                        .filter(|c| c.kind == *k && c.size > 0.0)
                        .filter_map(|c| {
                            let y = if seconds {
                                c.median_seconds_to_first?
                            } else {
                                100.0 * c.rate?
                            };
                            Some((c.size / threshold, y))
                        })
                        .collect(),
                    color: palette::series(i),
                    style: Style::LineAndMarkers(Marker::nth(i)),
                }
            })
            .collect();
        // Room on the right for the legend, which sits in the upper right corner.
        let xs: Vec<f64> = series
            .iter()
            .flat_map(|s: &Series| s.points.iter().map(|p| p.0))
            .collect();
        let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = xs.iter().copied().fold(0.0, f64::max);
        let mut x = Axis::new("size / the kind's threshold", Scale::Log10);
        if lo.is_finite() && hi > 0.0 {
            x = x.with_range(lo / 2.0, hi * 100.0);
        }
        let chart = Chart {
            title: format!(
                "{} on {}: {}",
                self.command,
                self.driver,
                if seconds {
                    "median seconds to the first catch"
                } else {
                    "faults caught"
                }
            ),
            x,
            y: if seconds {
                Axis::new("median seconds to first detection", Scale::Log10)
            } else {
                Axis::new("detection rate (%)", Scale::Linear).with_range(0.0, 100.0)
            },
            series,
            legend: true,
        };
        chart.render(960, 600)
    }
}
