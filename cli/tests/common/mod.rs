//! What the command-line tests share: the `rtconf` binary run on lavapipe with its exit status and
//! output, committed cases, and edited copies of them in a temporary directory.

#![allow(dead_code)] // each test binary uses its own part

use std::path::{Path, PathBuf};
use std::process::Command;

/// One finished `rtconf` command.
#[derive(Debug)]
pub struct Ran {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

impl Ran {
    /// stdout and stderr, for assertion messages.
    pub fn all(&self) -> String {
        format!(
            "exit {}\n--- stdout\n{}\n--- stderr\n{}",
            self.code, self.stdout, self.stderr
        )
    }
}

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `rtconf ARGS` in the repository root with lavapipe selected.
pub fn rtconf(args: &[&str]) -> Ran {
    rtconf_with(args, &[])
}

/// `rtconf ARGS` with extra environment variables.
pub fn rtconf_with(args: &[&str], env: &[(&str, &str)]) -> Ran {
    let out = Command::new(env!("CARGO_BIN_EXE_rtconf"))
        .args(args)
        .current_dir(root())
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .envs(env.iter().copied())
        .output()
        .expect("rtconf runs");
    ran(out)
}

/// `WRAPPER... rtconf ARGS` in the repository root with lavapipe selected: rtconf run by another
/// program (`flock FILE`, a shell that sets a limit first), which must pass its exit status on.
pub fn rtconf_under(wrapper: &[&str], args: &[&str]) -> Ran {
    let out = Command::new(wrapper[0])
        .args(&wrapper[1..])
        .arg(env!("CARGO_BIN_EXE_rtconf"))
        .args(args)
        .current_dir(root())
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .output()
        .expect("the wrapper runs rtconf");
    ran(out)
}

/// A finished command's exit status (-1 for a signal) and output as text.
pub fn ran(out: std::process::Output) -> Ran {
    Ran {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// A committed file's text (path from the repository root).
pub fn committed(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap()
}

/// `text` with `from` replaced once by `to` (which must be there).
pub fn edited(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "`{from}` is not in the text");
    text.replacen(from, to, 1)
}

/// Writes `text` to `dir/name` and returns its path as a string.
pub fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// The 1-based `line:col` of the first `needle` in `text`.
pub fn line_col(text: &str, needle: &str) -> String {
    let at = text.find(needle).unwrap();
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    format!("{line}:{col}")
}

pub const HAND: &str = "cases/hand/trace-indirect-records-32.yaml";
