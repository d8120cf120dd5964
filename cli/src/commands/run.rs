//! `rtconf run`: the arguments of a conformance run, a progress bar while `session::run` works, and the
//! summary at the end (the per-VUID table and the specs the profile cannot express only with
//! `--verbose`; both are always in the report). `--command vkCmdBuildAccelerationStructuresIndirectKHR`
//! runs build cases the same way; `--cases DIR` runs a folder of case files; `--list` only lists.

use clap::Args;
use session::report::Summary;
use session::Status;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct RunArgs {
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// The device profile cases are generated from and judged with (default: the driver's name;
    /// nvidia → nvidia-h100).
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
    /// Run the case files (*.yaml, subfolders too) of this folder instead of generated cases: a folder
    /// of regressions, or the failures/ of an earlier run.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["command", "vuid", "valid_only"])]
    cases: Option<PathBuf>,
    /// Print the names of the cases the run would make (after --shard and --skips) and stop.
    #[arg(long)]
    list: bool,
    /// Cases per VUID and valid cases per command (at least 1).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u64).range(1..))]
    count: u64,
    /// Rendered-scene cases per trace command (at least; a larger --count wins; 0: none).
    #[arg(long, default_value_t = session::plan::DEFAULT_RENDERED)]
    rendered: usize,
    /// The run's seed: spec i of a command family draws its cases from seed + i.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Run only shard I of N (1 ≤ I ≤ N): the cases whose name hashes to it, the same on every machine.
    /// Merge the shards' folders with `rtconf merge`.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Expected failures, one `CASE-OR-VUID,STATUS` per line (STATUS: fail, crash or timeout).
    #[arg(long, value_name = "FILE")]
    baseline: Option<PathBuf>,
    /// Cases not to run: one regular expression per line, matched in the case name and target VUID.
    #[arg(long, value_name = "FILE")]
    skips: Option<PathBuf>,
    /// Known flaky cases: one regular expression per line; a failing case that matches is a flake.
    #[arg(long, value_name = "FILE")]
    flakes: Option<PathBuf>,
    /// Run failing, crashing and timed-out cases again up to N times; one whose outcome changes is a
    /// flake.
    #[arg(long, value_name = "N", default_value_t = 0)]
    retries: usize,
    /// Worker processes (1 to 256).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=super::MAX_JOBS))]
    jobs: u64,
    /// Seconds a case may take (at least 1).
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    timeout: u64,
    /// The run folder: results.jsonl, summary.json, junit.xml, report/index.html, failures/,
    /// case-errors/, unexpected-passes/, warnings/ (and with --keep-all triaged/, unsupported/,
    /// not-realised/), details.jsonl, caselist.txt.
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
    /// Triage files (default: triage/layer-VERSION.yaml for the layer's VERSION and triage/DRIVER.yaml, where present).
    #[arg(long)]
    triage: Vec<PathBuf>,
    /// The validation layer build to use: a directory with its manifest, or an unpacked package root
    /// (default: the one the loader finds, or VK_LAYER_PATH). Its reported version picks the triage
    /// file and the registry.
    #[arg(long)]
    layer: Option<PathBuf>,
    /// Fail the run when a triage entry about a command that ran explained nothing (a stale entry).
    #[arg(long)]
    strict: bool,
    /// Also print the per-VUID agreement table and the specs the profile cannot express.
    #[arg(long, short)]
    verbose: bool,
    /// Hand the driver a perturbed copy of each valid trace case while the model judges the case
    /// itself: KIND:SIZE with KIND one of vertex-ulps, instance-transform, sbt-stride, sbt-offset,
    /// cull-mask, drop-primitive, t-bias (`rtconf detect` measures them). A failing case is a caught
    /// fault; cases the kind has nothing to act on run as they are and are counted not applicable.
    #[arg(long, value_name = "KIND:SIZE", value_parser = parse_injection)]
    inject: Option<session::inject::Injection>,
    /// Also keep the case files of triaged, unsupported and not-realised cases (their outcome is
    /// already explained: by a triage entry, which names its own reproducing case, by the profile,
    /// by the harness); every case that did not pass keeps its line in details.jsonl either way.
    #[arg(long)]
    keep_all: bool,
}

fn parse_injection(text: &str) -> Result<session::inject::Injection, String> {
    session::inject::Injection::parse(text)
}

/// The progress bar on a terminal (hidden elsewhere), with the unexpected statuses so far.
struct Bar {
    bar: indicatif::ProgressBar,
    unexpected: std::sync::atomic::AtomicU64,
    flakes: std::sync::atomic::AtomicU64,
}

impl session::Progress for Bar {
    fn planned(&self, cases: u64) {
        self.bar.set_length(cases);
    }
    fn advance(&self, n: u64) {
        self.bar.inc(n);
    }
    fn status(&self, status: Status) {
        use std::sync::atomic::Ordering::Relaxed;
        if status.is_failure() {
            self.unexpected.fetch_add(1, Relaxed);
        }
        if status == Status::Flake {
            self.flakes.fetch_add(1, Relaxed);
        }
        let (u, f) = (self.unexpected.load(Relaxed), self.flakes.load(Relaxed));
        if u + f > 0 {
            self.bar.set_message(format!("{u} unexpected, {f} flaky"));
        }
    }
    fn selected(&self, expanded: &[session::names::Expanded]) {
        for e in expanded {
            if e.vuids.len() != 1 || e.vuids[0] != e.pattern {
                self.bar
                    .suspend(|| eprintln!("--vuid {}: {} VUID(s)", e.pattern, e.vuids.len()));
            }
        }
    }
}

fn bar() -> Bar {
    let bar = if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        let b = indicatif::ProgressBar::new(0);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} cases {elapsed_precise} (eta {eta}) {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    Bar {
        bar,
        unexpected: 0.into(),
        flakes: 0.into(),
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
        layer: a.layer,
        strict: a.strict,
        selection: session::Selection {
            cases: a.cases,
            shard: a.shard.as_deref().map(session::Shard::parse).transpose()?,
            baseline: a.baseline,
            skips: a.skips,
            flakes: a.flakes,
            retries: a.retries,
        },
        inject: a.inject,
        keep_all: a.keep_all,
    };
    if a.list {
        // Printed as the cases are made: a long run is listed holding a slice of cases, not all.
        let mut out = std::io::stdout().lock();
        session::list_each(&config, &mut |c| {
            // A closed pipe (`| head`) ends the listing quietly: nothing else is left to do.
            if std::io::Write::write_all(&mut out, format!("{}\n", c.name).as_bytes()).is_err() {
                std::process::exit(0);
            }
        })?;
        return Ok(0);
    }
    let out = config.out.display();
    crate::interrupt::say_on_interrupt(format!(
        "rtconf: interrupted; the results of the cases that finished are in {out}/results.jsonl: \
         `rtconf report {out}` shows them, and `rtconf run --resume --out {out}` with the same \
         arguments runs the rest"
    ));
    let bar = bar();
    let outcome = session::run(&config, &bar)?;
    bar.bar.finish_and_clear();
    for line in &outcome.shrunk {
        println!("{line}");
    }
    for w in &outcome.warnings {
        eprintln!("rtconf: warning: {w}");
    }
    if a.verbose {
        print_vuid_table(&outcome.summary);
        if !outcome.not_expressible.is_empty() {
            println!(
                "{} specs are not expressible on profile {}:",
                outcome.not_expressible.len(),
                outcome.summary.profile
            );
            for e in &outcome.not_expressible {
                println!("  {e}");
            }
            println!();
        }
    }
    for e in &outcome.gen_errors {
        eprintln!("rtconf: could not generate {e}");
    }
    print_unexpected(&config.out);
    if let Err(e) = &outcome.report {
        eprintln!("rtconf: the HTML report could not be written: {e}");
    }
    print_triage(&outcome.summary, config.strict);
    if let Some(i) = &outcome.summary.inject {
        println!(
            "inject {}: {} cases ran the perturbed copy, {} detected; {} not applicable (ran as they are)",
            i.injection, i.applied, i.detected, i.not_applicable
        );
    }
    print_summary(
        &outcome.summary,
        &config.out,
        outcome.not_expressible.len(),
        a.verbose,
    );
    if outcome.summary.cases == 0 {
        eprintln!(
            "rtconf: {}",
            no_case_reason(
                &outcome.not_expressible,
                outcome.other_shards,
                outcome.summary.skipped
            )
        );
    }
    Ok(outcome.exit_code())
}

/// The per-VUID agreement table (with `--verbose`).
pub fn print_vuid_table(s: &Summary) {
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
}

/// The cases whose status fails the run (at most 20), each with the command that replays it.
fn print_unexpected(out: &Path) {
    let Ok(lines) = session::results::read_lines(&out.join("results.jsonl")) else {
        return;
    };
    let bad: Vec<session::results::ResultLine> = lines.filter(|l| l.status.is_failure()).collect();
    if bad.is_empty() {
        return;
    }
    println!("unexpected results:");
    for l in bad.iter().take(20) {
        let replay = session::details::case_path(out, &l.report, l.status)
            .filter(|p| p.exists())
            .map(|p| format!("  (rtconf replay {})", p.display()))
            .unwrap_or_default();
        println!("  {:<15} {}{replay}", l.status.name(), l.report.case);
    }
    if bad.len() > 20 {
        println!("  … and {} more (see the report)", bad.len() - 20);
    }
    println!();
}

/// The run's summary: the statuses against the baseline, the raw outcomes, the time, the files; it is
/// what the console ends with.
pub fn print_summary(s: &Summary, out: &Path, not_expressible: usize, verbose: bool) {
    let statuses: Vec<String> = Status::ALL
        .iter()
        .filter(|st| s.count(**st) > 0 || matches!(st, Status::Pass | Status::Fail))
        .map(|st| format!("{} {}", s.count(*st), st.name()))
        .collect();
    println!(
        "{} cases on {} (profile {}, layer {}, registry {}{}){}",
        s.cases,
        s.driver,
        s.profile,
        s.layer.as_deref().unwrap_or("?"),
        s.registry.as_deref().unwrap_or("?"),
        s.shard
            .as_deref()
            .map(|x| format!(", shard {x}"))
            .unwrap_or_default(),
        if s.expectations.is_empty() {
            String::new()
        } else {
            format!(" against {}", s.expectations.join(", "))
        }
    );
    println!("status:  {}", statuses.join(", "));
    println!(
        "outcome: {} pass, {} fail, {} triaged, {} unsupported, {} not-realised, {} crash, {} timeout, {} case-error{}{}",
        s.passed,
        s.failed,
        s.triaged,
        s.unsupported,
        s.not_realised,
        s.crashes,
        s.timeouts,
        s.case_errors,
        if s.skipped > 0 {
            format!("; {} skipped by the skips list", s.skipped)
        } else {
            String::new()
        },
        if s.retries > 0 {
            format!("; {} retries", s.retries)
        } else {
            String::new()
        }
    );
    if not_expressible > 0 && !verbose {
        println!(
            "{not_expressible} specs are not expressible on profile {} (listed with --verbose)",
            s.profile
        );
    }
    println!(
        "time:    {:.1} s, {:.0} cases/s, runner peak RSS {} KiB, runner CPU {} s",
        s.seconds,
        s.cases as f64 / s.seconds.max(1e-9),
        s.runner_peak_rss_kib.map_or("?".into(), |k| k.to_string()),
        s.runner_cpu_seconds
            .map_or("?".into(), |c| format!("{c:.2}"))
    );
    if !s.time.is_empty() {
        let total: f64 = s.time.values().sum();
        let mut parts: Vec<(&String, &f64)> = s.time.iter().collect();
        parts.sort_by(|a, b| b.1.total_cmp(a.1));
        let parts: Vec<String> = parts
            .iter()
            .map(|(k, v)| format!("{k} {v:.1} s ({:.0}%)", 100.0 * **v / total.max(1e-9)))
            .collect();
        println!("spent:   {}", parts.join(", "));
    }
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
            "rendered {command}: {} cases, {} launch IDs ({} REQ, {} VARY = {:.2} %: {} hit, {} missed; {} must run an intersection shader), {} failures, {} warnings, exact fallback {:.4} % of pairs",
            r.cases, r.rays, r.req, r.vary, 100.0 * r.vary_share, r.vary_hit, r.vary_miss, r.shader_required, r.failures, r.warnings, 100.0 * r.exact_share
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
        "files:   {0}/report/index.html, {0}/results.jsonl, {0}/summary.json, {0}/junit.xml",
        out.display()
    );
    println!(
        "verdict: {}",
        if s.cases == 0 {
            "nothing checked".to_string()
        } else if s.unexpected() == 0 {
            "as expected".to_string()
        } else {
            format!("{} unexpected result(s)", s.unexpected())
        }
    );
}

/// Why a run made no case: the shard or the skips list where they kept back every case made (with
/// how many), else the profile's reason where every spec selected was inexpressible on it (the first
/// such spec named, with how many there were), else what else leaves a selection empty.
fn no_case_reason(not_expressible: &[String], other_shards: usize, skipped: usize) -> String {
    if other_shards + skipped > 0 {
        let mut why = Vec::new();
        if other_shards > 0 {
            why.push(format!("{other_shards} belong to other shards"));
        }
        if skipped > 0 {
            why.push(format!("the skips list kept back {skipped}"));
        }
        return format!(
            "the run made no case: nothing was checked; of the {} cases made, {}",
            other_shards + skipped,
            why.join(" and ")
        );
    }
    match not_expressible {
        [] => "the run made no case: nothing was checked (the VUIDs selected have no executable mutation on this profile, or --count made none)".into(),
        [only] => format!("the run made no case: nothing was checked; the one spec selected is not expressible on the profile: {only}"),
        [first, rest @ ..] => format!(
            "the run made no case: nothing was checked; the {} specs selected are not expressible on the profile (all with --verbose), the first: {first}",
            rest.len() + 1
        ),
    }
}

/// The disagreements the triage explained, by kind and direction, and its stale entries.
fn print_triage(s: &Summary, strict: bool) {
    if !s.triaged_by.is_empty() {
        println!("triaged disagreements by kind and direction:");
        for (k, n) in &s.triaged_by {
            println!("  {k:<40} {n:>6}");
        }
    }
    let t = &s.triage;
    if !t.stale_judged {
        println!(
            "triage: {} of {} entries not exercised by this partial run (stale only in a whole run)",
            t.stale.len() + t.unexercised.len(),
            t.entries
        );
        println!();
        return;
    }
    if t.stale.is_empty() {
        println!(
            "triage: {} entries in {} file(s), none stale",
            t.entries,
            t.files.len()
        );
    } else {
        let what = if strict {
            "STALE (an error under --strict)"
        } else {
            "stale"
        };
        println!(
            "triage: {} of {} entries explained nothing although cases with their VUIDs ran, {what}:",
            t.stale.len(),
            t.entries
        );
        for id in &t.stale {
            println!("  {id}");
        }
    }
    if !t.unexercised.is_empty() {
        println!(
            "triage: {} entries not exercised: no case that ran involved their VUIDs (summary.json lists them)",
            t.unexercised.len()
        );
    }
    println!();
}

fn num(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.3e}"))
}
