//! `rtconf run`: the arguments of a conformance run, a progress bar while `session::run` works, and the
//! per-VUID agreement table and totals at the end. `--command vkCmdBuildAccelerationStructuresIndirectKHR`
//! runs build cases the same way.

use clap::Args;
use session::report::Summary;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct RunArgs {
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// The device profile cases are generated from (default: the driver's name; nvidia → nvidia-h100).
    #[arg(long)]
    profile: Option<String>,
    /// Commands to run (repeatable; default: every trace command the profile supports). The build
    /// command vkCmdBuildAccelerationStructuresIndirectKHR runs only when named.
    #[arg(long)]
    command: Vec<String>,
    /// Only these VUIDs' invalid cases (repeatable; default: every executable VUID with a mutation): a
    /// full id, a glob (`VUID-vkCmdTraceRaysIndirectKHR-*`) or a short id (`03686`, `stride-03686`).
    /// A name that matches no VUID is an error.
    #[arg(long)]
    vuid: Vec<String>,
    /// Only valid cases (with read-back); no invalid ones.
    #[arg(long, conflicts_with = "vuid")]
    valid_only: bool,
    /// Cases per VUID and valid cases per command (at least 1).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u64).range(1..))]
    count: u64,
    /// Rendered-scene cases per trace command (at least; a larger --count wins; 0: none).
    #[arg(long, default_value_t = session::plan::DEFAULT_RENDERED)]
    rendered: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker processes (at least 1).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..))]
    jobs: u64,
    /// Seconds a case may take (at least 1).
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    timeout: u64,
    #[arg(long, default_value = "out/run")]
    out: PathBuf,
    /// Shrink up to this many failing cases to minimal ones in cases/regressions/ (in this process).
    #[arg(long, default_value_t = 0)]
    shrink: usize,
    /// Continue a killed run: cases already in results.jsonl are not run again.
    #[arg(long)]
    resume: bool,
    /// Registry sources for the rules (default: the installed registry, the layer's own version).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// Triage files (default: triage/layer-<registry version>.yaml and triage/<driver>.yaml, where present).
    #[arg(long)]
    triage: Vec<PathBuf>,
}

/// The progress bar on a terminal (hidden elsewhere).
struct Bar(indicatif::ProgressBar);

impl session::Progress for Bar {
    fn planned(&self, cases: u64) {
        self.0.set_length(cases);
    }
    fn advance(&self, n: u64) {
        self.0.inc(n);
    }
    fn selected(&self, expanded: &[session::select::Expanded]) {
        for e in expanded {
            if e.vuids.len() != 1 || e.vuids[0] != e.pattern {
                self.0
                    .suspend(|| eprintln!("--vuid {}: {} VUID(s)", e.pattern, e.vuids.len()));
            }
        }
    }
}

fn bar() -> Bar {
    if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        let b = indicatif::ProgressBar::new(0);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} cases {elapsed_precise} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Bar(b)
    } else {
        Bar(indicatif::ProgressBar::hidden())
    }
}

pub fn run(a: RunArgs) -> super::Exit {
    let config = session::RunConfig {
        driver: a.driver,
        profile: a.profile,
        scope: session::Scope {
            commands: session::plan::commands(&a.command)?,
            vuids: a.vuid,
            valid_only: a.valid_only,
            seed: a.seed,
            rendered: a.rendered,
        },
        count: a.count as usize,
        jobs: a.jobs as usize,
        timeout: a.timeout,
        out: a.out,
        shrink: a.shrink,
        resume: a.resume,
        from: a.from,
        triage: a.triage,
    };
    let bar = bar();
    let outcome = session::run(&config, &bar)?;
    bar.0.finish_and_clear();
    for line in &outcome.shrunk {
        println!("{line}");
    }
    print_summary(&outcome.summary, &config.out);
    if !outcome.not_expressible.is_empty() {
        println!(
            "{} specs are not expressible on profile {}:",
            outcome.not_expressible.len(),
            outcome.summary.profile
        );
        for e in &outcome.not_expressible {
            println!("  {e}");
        }
    }
    for e in &outcome.gen_errors {
        eprintln!("rtconf: could not generate {e}");
    }
    if outcome.summary.cases == 0 {
        eprintln!(
            "rtconf: the run made no case: nothing was checked (the VUIDs selected have no executable mutation on this profile, or --count made none)"
        );
    }
    Ok(outcome.exit_code())
}

fn print_summary(s: &Summary, out: &Path) {
    println!(
        "{:<78} {:>6} {:>6} {:>6} {:>6}",
        "VUID", "cases", "model", "layer", "agree"
    );
    for (v, t) in &s.vuids {
        println!(
            "{:<78} {:>6} {:>6} {:>6} {:>6}",
            v, t.cases, t.model, t.layer, t.agree
        );
    }
    println!();
    println!(
        "{} cases on {} (profile {}): {} passed, {} failed, {} triaged, {} unsupported, {} crashes, {} timeouts, {} case errors",
        s.cases, s.driver, s.profile, s.passed, s.failed, s.triaged, s.unsupported, s.crashes, s.timeouts, s.case_errors
    );
    println!(
        "{:.1} s, {:.0} cases/s, runner peak RSS {} KiB",
        s.seconds,
        s.cases as f64 / s.seconds.max(1e-9),
        s.runner_peak_rss_kib.map_or("?".into(), |k| k.to_string())
    );
    for (command, r) in &s.rendered {
        let q = |x: &session::rendered::Quantiles| {
            format!(
                "median {} p99 {} max {}",
                num(x.median),
                num(x.p99),
                num(x.max)
            )
        };
        println!(
            "rendered {command}: {} cases, {} launch IDs ({} REQ, {} VARY = {:.2} %: {} hit, {} missed), {} failures, {} warnings, exact fallback {:.4} % of pairs",
            r.cases, r.rays, r.req, r.vary, 100.0 * r.vary_share, r.vary_hit, r.vary_miss, r.failures, r.warnings, 100.0 * r.exact_share
        );
        println!(
            "  t error ulps: {}; relative to bound: {}",
            q(&r.t_error_ulps),
            q(&r.t_error_rel)
        );
        println!(
            "  barycentric error abs: {}; ulps: {}",
            q(&r.bary_error_abs),
            q(&r.bary_error_ulps)
        );
    }
    println!(
        "results: {0}/results.jsonl, summary: {0}/summary.json, junit: {0}/junit.xml, failing cases: {0}/failures/",
        out.display()
    );
}

fn num(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.3e}"))
}
