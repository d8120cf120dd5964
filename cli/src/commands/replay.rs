//! `rtconf replay CASE.yaml`: one case (any command) on a driver, in this process, with the full
//! comparison printed: the device, driver and layer that ran it, the call sequence, the model's
//! violations, the layer's messages in full, the output check, the outcome (or all of it as JSON).

use clap::Args;
use harness::observe::{Hits, Status, TracedBuild};
use harness::TraceCheck;
use session::Outcome;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReplayArgs {
    /// The case file (YAML) of any command.
    case: PathBuf,
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// Registry sources for the rules (default: the installed registry).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// The device profile the model judges with (default: the case's own).
    #[arg(long)]
    profile: Option<String>,
    /// Build cases: how the built structure is traced (auto: ray query where the device has it, else a
    /// ray tracing pipeline).
    #[arg(long, value_enum, default_value = "auto")]
    check: CheckArg,
    /// Print what the replay found as one JSON object instead.
    #[arg(long)]
    json: bool,
    /// Cases run as valid: write the ray records read back to this file (little-endian u32 words, 28
    /// per launch ID of a trace, per ray of a build's traced check), as an exported program's
    /// `--records` does.
    #[arg(long)]
    records: Option<PathBuf>,
    /// Seconds the case may take in its worker process (at least 1).
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    timeout: u64,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum CheckArg {
    Auto,
    RayQuery,
    Pipeline,
}

/// What `--json` prints.
#[derive(serde::Serialize)]
struct ReplayJson<'a> {
    case: &'a str,
    command: &'a str,
    running_on: &'a harness::RunningOn,
    /// The raw outcome against the model and the triage files.
    outcome: Outcome,
    detail: &'a str,
    /// The VUIDs the model says the case as it ran violates.
    model: &'a [String],
    /// Every VUID of the layer's errors during the call (all scopes).
    layer_vuids: Vec<String>,
    layer_messages: Vec<harness::LayerMessage>,
    output_matches: Option<bool>,
    /// The call sequence.
    calls: Vec<String>,
}

pub fn run(a: ReplayArgs) -> super::Exit {
    let case = session::replay::read_case(&a.case)?;
    let config = session::ReplayConfig {
        driver: a.driver,
        from: a.from,
        profile: a.profile,
        check: match a.check {
            CheckArg::Auto => TraceCheck::Auto,
            CheckArg::RayQuery => TraceCheck::RayQuery,
            CheckArg::Pipeline => TraceCheck::Pipeline,
        },
        timeout: a.timeout,
    };
    let replayed = session::replay(&case, &config)?;
    let r = &replayed.ran;
    if let Some(path) = &a.records {
        // A valid trace's launch records, or a valid build's traced check's.
        let words = r
            .observation
            .as_ref()
            .and_then(|o| o.words().or_else(|| o.traced().map(|t| &t.records[..])))
            .ok_or_else(|| {
                session::SessionError::Usage(format!(
                    "--records: {} read no ray records back (only a case run as valid does: a trace's launch, a build's traced check)",
                    r.case.name
                ))
            })?;
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        std::fs::write(path, bytes)
            .map_err(|e| session::SessionError::io(path.display().to_string(), e))?;
    }
    let calls = replayed
        .plan
        .as_ref()
        .map(|p| p.describe())
        .unwrap_or_default();
    if a.json {
        let json = ReplayJson {
            case: &r.case.name,
            command: r.case.command().vk_name(),
            running_on: &replayed.running_on,
            outcome: r.report.outcome,
            detail: &r.report.detail,
            model: &r.report.model,
            layer_vuids: r
                .observation
                .as_ref()
                .map(|o| o.layer_vuids.clone())
                .unwrap_or_default(),
            layer_messages: r
                .observation
                .as_ref()
                .map(|o| o.layer_messages.clone())
                .unwrap_or_default(),
            output_matches: r.report.output_matches,
            calls,
        };
        println!(
            "{}",
            serde_json::to_string_pretty(&json).unwrap_or_default()
        );
        return Ok(exit_status(&r.report));
    }
    println!("case:    {} ({})", r.case.name, r.case.command().vk_name());
    println!("intent:  {}", intent(&r.case.intent));
    let on = &replayed.running_on;
    println!("device:  {}, Vulkan {}", on.device, on.api_version);
    println!("driver:  {}", on.driver);
    println!("layer:   {}", on.layer.as_deref().unwrap_or("not loaded"));
    if !calls.is_empty() {
        println!("calls:");
        for c in &calls {
            println!("  {c}");
        }
    } else if r.observation.is_some() {
        println!("calls:   not listed (the harness cannot realise the case; the status says why)");
    }
    match &r.observation {
        Some(obs) => println!("status:  {}", status(&obs.status)),
        None => {
            println!("status:  not run (the gate kept it from the driver; the outcome says why)");
            // What keeps it from the driver, located in the case file.
            if let Some(t) = r.case.as_trace() {
                let problems = t.scene_problems();
                if !problems.is_empty() {
                    let text = session::replay::case_text(&a.case).unwrap_or_default();
                    let why = model::NotRunnable {
                        at: problems[0].path.clone(),
                        scene: problems,
                        reads: vec![],
                    };
                    for line in why.located(&a.case.display().to_string(), &text) {
                        println!("         {line}");
                    }
                }
            }
        }
    }
    if let Some(a) = r.case.as_accel() {
        for (i, s) in a.world.sizes.iter().enumerate() {
            println!(
                "sizes:   info {i}: structure {} bytes, build scratch {}, update scratch {}",
                s.structure, s.build_scratch, s.update_scratch
            );
        }
    }
    let model: Vec<&str> = r.verdict.vuids().into_iter().collect();
    println!(
        "model:   {}",
        if model.is_empty() {
            "valid".into()
        } else {
            model.join(", ")
        }
    );
    for v in &r.verdict.violations {
        println!("         {} at {}: {}", v.vuid, v.context, v.problem);
    }
    if let Some(obs) = &r.observation {
        println!(
            "layer:   {}",
            if obs.layer_vuids.is_empty() {
                "nothing".into()
            } else {
                obs.layer_vuids.join(", ")
            }
        );
        for m in &obs.layer_messages {
            println!("         [{}] {}", m.severity, m.id);
            for line in m.text.lines() {
                println!("           {line}");
            }
        }
        if let (Some(body), Some(t)) = (r.case.as_accel(), obs.traced()) {
            print_traced(body, t, replayed.deviation.as_deref());
        }
    }
    print_outcome(&r.report);
    if r.report.outcome == Outcome::CaseError {
        eprintln!(
            "rtconf: {}",
            session::replay::located(&a.case, &r.report.detail)
        );
    }
    Ok(exit_status(&r.report))
}

/// An intent as a person reads it.
fn intent(i: &model::Intent) -> String {
    match i {
        model::Intent::Valid => "valid".into(),
        model::Intent::Violates { vuid, also } if also.is_empty() => format!("violates {vuid}"),
        model::Intent::Violates { vuid, also } => {
            format!("violates {vuid} (and, unavoidably, {})", also.join(", "))
        }
    }
}

/// How a run ended, as a person reads it.
fn status(s: &Status) -> String {
    match s {
        Status::Ran => "ran".into(),
        Status::Unsupported { reason, lacks } => {
            format!("unsupported (the device lacks {lacks}): {reason}")
        }
        Status::NotRealised { reason } => format!("not realised: {reason}"),
        Status::Crash { message } => format!("crash: {message}"),
        Status::Timeout { seconds } => format!("timeout after {seconds:.1} s"),
        Status::OutOfMemory { message } => format!("out of device memory: {message}"),
    }
}

/// What a ray hit.
fn hit(h: &Option<(u32, u32, u32)>) -> String {
    h.map_or("miss".into(), |(i, g, p)| {
        format!("instance {i} geometry {g} primitive {p}")
    })
}

/// A build's traced check: what each ray hit, the reference tracer's verdict on its record, and what
/// explains the failures.
fn print_traced(body: &model::AccelBody, t: &TracedBuild, deviation: Option<&str>) {
    println!(
        "check:   {} ray(s) traced with {}",
        t.hits.len(),
        match t.check {
            TraceCheck::Pipeline => "a ray tracing pipeline",
            _ => "ray query",
        }
    );
    let check = model::accel::check::BuildCheck::of(body);
    let verdicts = check.as_ref().ok().and_then(|c| {
        model::accel::check::judge_against(&c.rays, &c.allowed, &c.stats, &t.records).ok()
    });
    for (k, h) in t.hits.iter().enumerate() {
        let from = check
            .as_ref()
            .ok()
            .and_then(|c| c.rays.get(k))
            .map(|r| format!(" from {:?} along {:?}", r.origin, r.direction))
            .unwrap_or_default();
        match verdicts.as_ref().and_then(|v| v.verdicts.get(k)) {
            Some(model::tracer::judge::RayVerdict::Fail(f)) => {
                println!("         ray {k}{from}: {}; FAILS: {f}", hit(h))
            }
            _ => println!("         ray {k}{from}: {}", hit(h)),
        }
    }
    if let Err(e) = &check {
        println!("         the model cannot judge these rays: {e}");
    }
    if let Some(d) = deviation {
        // Alternatives are separated by `|`; a `+…-drops-primitives` one explains them up to dropped
        // primitives (model::accel::check::deviation).
        println!("         the device's records are those of the build under `{d}`");
    }
    if !t.direct_layer_vuids.is_empty() {
        println!(
            "         direct build: layer reported {}",
            t.direct_layer_vuids.join(", ")
        );
    }
    if let Some(ind) = &t.indirect {
        let differ = differing(&t.hits, &ind.hits);
        println!("indirect: ran for real; {differ} ray(s) differ from the direct build");
    }
}

fn differing(a: &Hits, b: &Hits) -> usize {
    a.iter().zip(b).filter(|(d, i)| d != i).count()
}

/// Prints the end of a replay's report: the output check and the outcome.
fn print_outcome(report: &session::CaseReport) {
    if let Some(ok) = report.output_matches {
        println!(
            "output:  {}",
            if ok {
                "matches the model"
            } else {
                "DIFFERS from the model"
            }
        );
    }
    println!(
        "outcome: {}{}",
        session::report::outcome_name(report.outcome),
        if report.detail.is_empty() {
            String::new()
        } else {
            format!(" — {}", report.detail)
        }
    );
}

/// 0 when the case passed or disagreed only as the triage files say; 2 when the case is at fault.
fn exit_status(report: &session::CaseReport) -> i32 {
    match report.outcome {
        Outcome::Pass | Outcome::Triaged => 0,
        Outcome::CaseError => 2,
        _ => 1,
    }
}
