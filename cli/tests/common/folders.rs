//! What the run-folder tests share: the built `rtconf` run on lavapipe, a folder per test under
//! `target/tmp/` (kept as the test's artifacts), committed cases copied under another name, and a run
//! folder's results read back by case.

#![allow(dead_code)] // each test binary uses its own part

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A fresh folder for one test under `target/tmp/`; what the test leaves there stays for a person.
pub fn fresh_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("a folder under target/tmp");
    d
}

/// `rtconf ARGS` on lavapipe, with `env` added.
pub fn rtconf(args: &[&str], env: &[(&str, &str)]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_rtconf"))
        .args(args)
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .envs(env.iter().copied())
        .current_dir(repo())
        .output()
        .expect("the rtconf binary runs");
    out
}

/// The text of a command's standard output and error, for assertion messages.
pub fn text(o: &Output) -> String {
    format!(
        "status {:?}\n--- stdout\n{}\n--- stderr\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A committed case file (path under `cases/`) written into `dir` as case `name`.
pub fn case_as(committed: &str, name: &str, dir: &Path) -> PathBuf {
    let text =
        std::fs::read_to_string(repo().join("cases").join(committed)).expect("a committed case");
    let renamed: String = text
        .lines()
        .map(|l| {
            if l.starts_with("name:") {
                format!("name: {name}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, renamed + "\n").expect("write the case");
    path
}

/// The lines of a run folder's `results.jsonl`, by case name.
pub fn results(run: &Path) -> BTreeMap<String, Value> {
    std::fs::read_to_string(run.join("results.jsonl"))
        .expect("results.jsonl")
        .lines()
        .map(|l| {
            let v: Value = serde_json::from_str(l).expect("a JSON line");
            (v["case"].as_str().expect("a case name").to_string(), v)
        })
        .collect()
}

/// A run folder's `summary.json`.
pub fn summary(run: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).expect("summary.json"))
        .expect("summary.json parses")
}
