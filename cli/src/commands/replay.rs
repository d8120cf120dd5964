//! `rtconf replay CASE.yaml`: one case (any command) on a driver, in this process, with the full
//! comparison printed: the model's violations, the layer's messages, the output check, the outcome.

use clap::Args;
use harness::TraceCheck;
use session::Outcome;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReplayArgs {
    case: PathBuf,
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// The device profile the model judges with (default: the case's own).
    #[arg(long)]
    profile: Option<String>,
    /// Build cases: how the built structure is traced (auto: ray query where the device has it, else a
    /// ray tracing pipeline).
    #[arg(long, value_enum, default_value = "auto")]
    check: CheckArg,
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
    let build = r.case.as_accel().is_some();
    println!(
        "case:    {}{}",
        r.case.name,
        if build { " (build)" } else { "" }
    );
    println!("intent:  {:?}", r.case.intent);
    match &r.observation {
        Some(obs) => println!("status:  {:?}", obs.status),
        None => {
            println!("status:  not run");
            // What keeps it from the driver, located in the case file.
            if let Some(t) = r.case.as_trace() {
                let problems = t.scene_problems();
                if !problems.is_empty() {
                    let text = std::fs::read_to_string(&a.case).unwrap_or_default();
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
        println!("sizes:   {:?}", a.world.sizes);
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
            println!(
                "         [{}] {}: {}",
                m.severity,
                m.id,
                m.text.chars().take(300).collect::<String>()
            );
        }
        if let (Some(body), Some(t)) = (r.case.as_accel(), obs.traced()) {
            print_traced(body, t, replayed.deviation.as_deref());
        }
    }
    let code = print_outcome(&r.report);
    if r.report.outcome == Outcome::CaseError {
        eprintln!(
            "rtconf: {}",
            session::replay::located(&a.case, &r.report.detail)
        );
        return Ok(2);
    }
    Ok(code)
}

/// A build's traced check: what each ray hit, the mismatches with the model, and what explains them.
fn print_traced(
    body: &model::AccelBody,
    t: &harness::observe::TracedBuild,
    deviation: Option<&str>,
) {
    println!(
        "check:   {} ray(s) traced with {}",
        t.hits.len(),
        match t.check {
            TraceCheck::Pipeline => "pipeline",
            _ => "ray-query",
        }
    );
    for (k, h) in t.hits.iter().enumerate() {
        println!(
            "         ray {k}: {}",
            h.map_or("miss".into(), |(i, g, p)| format!(
                "instance {i} geometry {g} primitive {p}"
            ))
        );
    }
    let rays = model::accel::check::check_rays(body).unwrap_or_default();
    for m in session::compare::ray_mismatches(&rays, &t.hits) {
        println!("         MISMATCH {m}");
    }
    if let Some(d) = deviation {
        println!("         the device's hits are exactly those of the build under `{d}`");
    }
    if !t.direct_layer_vuids.is_empty() {
        println!(
            "         direct build: layer reported {}",
            t.direct_layer_vuids.join(", ")
        );
    }
    if let Some(ind) = &t.indirect {
        let differ = t.hits.iter().zip(&ind.hits).filter(|(d, i)| d != i).count();
        println!("indirect: ran for real; {differ} ray(s) differ from the direct build");
    }
}

/// Prints the end of a replay's report (output check and outcome) and returns the exit status:
/// 0 when the case passed or disagreed only as the triage files say.
fn print_outcome(report: &session::CaseReport) -> i32 {
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
    println!("outcome: {:?} {}", report.outcome, report.detail);
    match report.outcome {
        Outcome::Pass | Outcome::Triaged => 0,
        _ => 1,
    }
}
