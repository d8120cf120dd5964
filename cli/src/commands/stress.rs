//! `rtconf stress`: the numerical stress families on a driver (`session::stress`), a table per
//! family on the console, `stress.json` and `stress.png` in the output folder.

use clap::Args;
use session::stress::{FamilyResult, Size, StressConfig};
use std::path::PathBuf;

#[derive(Args)]
pub struct StressArgs {
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// The device profile the cases are laid out and judged with: a name in profiles/ or a file
    /// (default: the live device's, probed).
    #[arg(long)]
    profile: Option<String>,
    /// Only these families (repeatable; default: all of them).
    #[arg(long)]
    family: Vec<String>,
    /// Family cases have seeds SEED, SEED+1, ... (one per --seeds).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Cases per family (default 1; at most 10,000, as every case is laid out before the first runs).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    seeds: Option<u64>,
    /// small: each family's test size (a few seconds in all); full: its full size.
    #[arg(long, default_value = "full")]
    size: String,
    /// Worker processes (1 to 256).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=super::MAX_JOBS))]
    jobs: u64,
    /// Seconds a case may take (at least 1).
    #[arg(long, default_value_t = 300, value_parser = clap::value_parser!(u64).range(1..))]
    timeout: u64,
    /// The output folder: stress.json and stress.png.
    #[arg(long, default_value = "out/stress")]
    out: PathBuf,
    /// Registry sources for the rules (default: the installed registry, the layer's own version).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
}

pub fn run(a: StressArgs) -> super::Exit {
    let config = StressConfig {
        driver: a.driver,
        profile: a.profile,
        families: a.family,
        seed: a.seed,
        seeds: a.seeds.map(|s| s as usize),
        size: Size::parse(&a.size)?,
        jobs: a.jobs as usize,
        timeout: a.timeout,
        out: a.out,
        from: a.from,
    };
    let summary = session::stress::stress(&config)?;
    println!(
        "stress on {} ({}), profile {}, layer {}, size {:?}, seeds {}..{}",
        summary.driver,
        summary.device,
        summary.profile,
        summary.layer,
        summary.size,
        summary.seed,
        summary.seed + summary.seeds as u64 - 1
    );
    println!("{}", FamilyResult::header());
    for f in &summary.families {
        println!("{}", f.row());
    }
    for f in &summary.families {
        if !f.note.is_empty() {
            println!("{}: {}", f.family, f.note);
        }
        if f.driver_finding() || f.rays == 0 {
            for line in f.findings.iter().take(5) {
                println!("  {}: {line}", f.family);
            }
        }
    }
    println!(
        "{:.1} s; {} and {}",
        summary.seconds,
        config.out.join("stress.json").display(),
        config.out.join("stress.png").display()
    );
    if summary.exit == 0 {
        println!("{}", summary.verdict);
    } else {
        eprintln!("rtconf: {}", summary.verdict);
    }
    Ok(summary.exit)
}
