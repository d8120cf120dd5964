//! A file the user names that never ends (`/dev/zero` here; a disk image or a device by mistake) is
//! refused at the limit of its kind, with its path and a non-zero exit, instead of reading until the
//! machine's memory is gone. Each command runs under an 8 GB address-space limit, so a reader that
//! has no limit fails the test with "out of memory" rather than taking the machine.

mod common;

use common::Ran;
use std::path::Path;

/// `rtconf ARGS` in the repository root on lavapipe, its address space limited to 8 GB.
fn rtconf_limited(args: &[&str]) -> Ran {
    common::rtconf_under(
        &["bash", "-c", "ulimit -v 8000000 && exec \"$0\" \"$@\""],
        args,
    )
}

fn refused(args: &[&str], message: &str) {
    let ran = rtconf_limited(args);
    assert_eq!(ran.code, 2, "{args:?}: {}", ran.all());
    assert!(ran.stderr.contains(message), "{args:?}: {}", ran.all());
}

#[test]
fn every_kind_of_input_file_is_read_up_to_its_limit() {
    refused(
        &["check", "/dev/zero"],
        "/dev/zero: larger than 64 MiB, the most rtconf reads as a case file",
    );
    refused(
        &["replay", "/dev/zero"],
        "/dev/zero: larger than 64 MiB, the most rtconf reads as a case file",
    );
    refused(
        &[
            "gen",
            "--valid",
            "--profile",
            "/dev/zero",
            "--out",
            "unused",
        ],
        "larger than 64 MiB, the most rtconf reads as a profile",
    );
    refused(
        &["coverage", "--from", "/dev/zero"],
        "/dev/zero: larger than 256 MiB, the most rtconf reads as a registry file",
    );
    refused(
        &["run", "--skips", "/dev/zero", "--list"],
        "/dev/zero: larger than 64 MiB, the most rtconf reads as a list of cases or patterns",
    );
    refused(
        &["run", "--baseline", "/dev/zero", "--list"],
        "/dev/zero: larger than 64 MiB, the most rtconf reads as a list of cases or patterns",
    );
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().display().to_string();
    refused(
        &[
            "run",
            "--driver",
            "/dev/zero",
            "--profile",
            "lavapipe",
            "--count",
            "1",
            "--out",
            &out,
        ],
        "larger than 16 MiB, the most rtconf reads as an ICD manifest",
    );
}

#[test]
fn a_run_folder_whose_files_never_end_is_refused_line_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let shown = out.display().to_string();
    let ran = common::rtconf(&[
        "run",
        "--valid-only",
        "--count",
        "1",
        "--rendered",
        "0",
        "--command",
        "vkCmdTraceRaysKHR",
        "--out",
        &shown,
    ]);
    assert_eq!(ran.code, 0, "{}", ran.all());
    let results = out.join("results.jsonl");
    std::fs::remove_file(&results).unwrap();
    std::os::unix::fs::symlink(Path::new("/dev/zero"), &results).unwrap();
    let line_refused = format!(
        "{}:1: unreadable, and nothing after it is read (larger than 64 MiB, the most rtconf reads as a line of results.jsonl)",
        results.display()
    );
    refused(&["report", &shown], &line_refused);
    let merged = dir.path().join("merged").display().to_string();
    refused(
        &["merge", &shown, "--out", &merged],
        &format!(
            "{}:1: larger than 64 MiB, the most rtconf reads as a line of results.jsonl",
            results.display()
        ),
    );
    let fresh = dir.path().join("triaged").display().to_string();
    refused(
        &[
            "run",
            "--triage",
            "/dev/zero",
            "--count",
            "1",
            "--out",
            &fresh,
        ],
        "triage file /dev/zero: larger than 64 MiB, the most rtconf reads as a triage file",
    );
}
