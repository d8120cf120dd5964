//! The suite's run time against the size of a driver deviation: `rtconf detect` on lavapipe (the
//! binary, its workers, the layer, the judging) with every injection kind at its default sizes, over
//! `RTCONF_BENCH_CASES` rendered vkCmdTraceRaysKHR cases (default 12). Prints the detection table —
//! kind, size, cases applicable, detection rate, median cases and seconds to the first detection —
//! and the mutation score, and writes `target/detection/detection.{json,md,png}` and
//! `detection-time.png` (median seconds to the first catch against size over the kind's threshold:
//! the suite's curve beside the oracle's, `model/benches/oracle_curve.rs`).
//!
//! Seconds are each case's driver execution and judgement until the first catch, medians over random
//! orders of the cases; the line `detect seconds per case` puts them beside the run's wall time per
//! case run, measured in the same run.

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

fn main() {
    let cases: u64 = std::env::var("RTCONF_BENCH_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(12);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = root.join("target/detection");
    let started = Instant::now();
    let ran = Command::new(env!("CARGO_BIN_EXE_rtconf"))
        .args([
            "detect",
            "--driver",
            "lavapipe",
            "--count",
            &cases.to_string(),
        ])
        .arg("--out")
        .arg(&out)
        .current_dir(&root)
        .output()
        .expect("rtconf detect runs");
    let wall = started.elapsed().as_secs_f64();
    print!("{}", String::from_utf8_lossy(&ran.stdout));
    eprint!("{}", String::from_utf8_lossy(&ran.stderr));
    let text = std::fs::read_to_string(out.join("detection.json")).expect("detection.json");
    let d: serde_json::Value = serde_json::from_str(&text).expect("detection.json is JSON");
    let cells = d["cells"].as_array().map_or(&[][..], |v| v.as_slice());
    // Cases run: the clean pass and every non-zero cell's applicable copies.
    let runs: u64 = d["baseline"].as_array().map_or(0, |b| b.len() as u64)
        + cells
            .iter()
            .filter(|c| c["size"].as_f64() != Some(0.0))
            .map(|c| c["applicable"].as_u64().unwrap_or(0))
            .sum::<u64>();
    let per_case: f64 = cells
        .iter()
        .flat_map(|c| c["cases"].as_array().into_iter().flatten())
        .filter_map(|c| c["seconds"].as_f64())
        .sum::<f64>()
        / cells
            .iter()
            .map(|c| c["cases"].as_array().map_or(0, |v| v.len()))
            .sum::<usize>()
            .max(1) as f64;
    println!(
        "detect seconds per case: {per_case:.3} (driver and judge), {:.3} wall per case run ({runs} runs in {wall:.1} s)",
        wall / runs.max(1) as f64
    );
    println!("wrote {}", out.display());
}
