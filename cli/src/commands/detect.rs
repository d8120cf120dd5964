//! `rtconf detect`: the suite's detection table on a driver — rendered cases run as they are and with
//! each seeded fault (`--kinds`, `--sizes`), the detection rate and the median cases and seconds to
//! the first catch per kind and size, and the mutation score (`session::detect`). Prints the table and
//! writes DIR/detection.{json,md,png}, DIR/detection-time.png and the cases it ran under DIR/cases/.

use clap::Args;
use session::inject::{Injection, Kind};
use session::SessionError;
use std::path::PathBuf;

#[derive(Args)]
pub struct DetectArgs {
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// The device profile (default: the driver's name).
    #[arg(long)]
    profile: Option<String>,
    /// The trace command whose rendered cases run.
    #[arg(long, default_value = "vkCmdTraceRaysKHR")]
    command: String,
    /// Injection kinds, comma-separated (default: all of vertex-ulps, instance-transform, sbt-stride,
    /// sbt-offset, cull-mask, drop-primitive, t-bias).
    #[arg(long, value_delimiter = ',')]
    kinds: Vec<String>,
    /// Sizes: `KIND=S1,S2,...` for one kind, or `S1,S2,...` for every kind given (repeatable; default:
    /// each kind's own sizes around its threshold). Size 0, the case itself, is always measured.
    #[arg(long)]
    sizes: Vec<String>,
    /// Rendered cases (1 to 10,000; all are generated before the first runs).
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    count: u64,
    /// The seed of the cases and of the injections' choices.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker processes (1 to 256).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=super::MAX_JOBS))]
    jobs: u64,
    /// Seconds a case may take (at least 1).
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    timeout: u64,
    /// Where the table, the plots and the cases go.
    #[arg(long, default_value = "out/detect")]
    out: PathBuf,
    /// Registry sources for the rules (default: the installed registry, the layer's own version).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// Triage files (default: the layer's and the driver's, where present).
    #[arg(long)]
    triage: Vec<PathBuf>,
}

/// The kinds and their sizes from `--kinds` and `--sizes`.
fn cells(kinds: &[String], sizes: &[String]) -> Result<Vec<(Kind, Vec<f64>)>, SessionError> {
    let usage = |m: String| SessionError::Usage(m);
    let kinds: Vec<Kind> = if kinds.is_empty() {
        Kind::ALL.to_vec()
    } else {
        kinds
            .iter()
            .map(|k| {
                Kind::parse(k.trim()).ok_or_else(|| {
                    usage(format!(
                        "unknown injection kind `{k}` (kinds: {})",
                        Kind::ALL.map(Kind::name).join(", ")
                    ))
                })
            })
            .collect::<Result<_, _>>()?
    };
    let mut out: Vec<(Kind, Vec<f64>)> = kinds
        .iter()
        .map(|k| (*k, k.default_sizes().to_vec()))
        .collect();
    for s in sizes {
        let (which, list): (Vec<Kind>, &str) = match s.split_once('=') {
            Some((k, list)) => {
                let k = Kind::parse(k.trim())
                    .ok_or_else(|| usage(format!("--sizes {s}: unknown injection kind `{k}`")))?;
                if !kinds.contains(&k) {
                    return Err(usage(format!("--sizes {s}: {k} is not among --kinds")));
                }
                (vec![k], list)
            }
            None => (kinds.clone(), s.as_str()),
        };
        for k in which {
            let parsed = list
                .split(',')
                .map(|x| Injection::parse_size(k, x.trim()))
                .collect::<Result<Vec<f64>, String>>()
                .map_err(|e| usage(format!("--sizes {s}: {e}")))?;
            if let Some(cell) = out.iter_mut().find(|(c, _)| *c == k) {
                cell.1 = parsed;
            }
        }
    }
    Ok(out)
}

pub fn run(a: DetectArgs) -> super::Exit {
    let config = session::detect::DetectConfig {
        driver: a.driver,
        profile: a.profile,
        command: super::command_id(&a.command)?,
        cells: cells(&a.kinds, &a.sizes)?,
        count: a.count as usize,
        seed: a.seed,
        jobs: a.jobs as usize,
        timeout: a.timeout,
        out: a.out.clone(),
        from: a.from,
        triage: a.triage,
    };
    let detection = session::detect::detect(&config)?;
    detection.write(&a.out)?;
    print!("{}", detection.markdown());
    println!(
        "files:   {0}/detection.md, {0}/detection.json, {0}/detection.png, {0}/detection-time.png, {0}/cases/",
        a.out.display()
    );
    if detection.mutation.faults == 0 {
        eprintln!(
            "rtconf: no seeded fault above threshold was applicable: nothing was measured (raise --count or the sizes)"
        );
        return Ok(1);
    }
    if !detection.mutation.meets_target() {
        eprintln!(
            "rtconf: the mutation score is below {:.0}%",
            100.0 * session::detect::MUTATION_TARGET
        );
        return Ok(1);
    }
    Ok(0)
}
