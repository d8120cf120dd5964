//! The driver is checked once, up front, by `run` and `replay`: a missing manifest, a manifest that is
//! not JSON, one whose library does not exist, is not a shared object or is not a driver each exit 2 naming the file and
//! what is wrong — not 139 "crash" results, `ERROR_OUT_OF_HOST_MEMORY`, or a missing profile.

mod common;
use common::*;

fn both(driver: &str) -> [Ran; 2] {
    let out = tempfile::tempdir().unwrap();
    let out = out.path().display().to_string();
    [
        rtconf(&[
            "run",
            "--driver",
            driver,
            "--profile",
            "lavapipe",
            "--count",
            "1",
            "--out",
            &out,
        ]),
        rtconf(&["replay", HAND, "--driver", driver]),
    ]
}

/// [`both`], each asserted to exit 2 with `said` on stderr; the runs, for what a test asks beside.
fn both_refuse(driver: &str, said: &str) -> [Ran; 2] {
    let runs = both(driver);
    for r in &runs {
        assert_eq!(r.code, 2, "{}", r.all());
        assert!(r.stderr.contains(said), "{}", r.all());
    }
    runs
}

#[test]
fn a_missing_manifest_is_named_before_any_profile() {
    for r in both_refuse("/missing/path", "`/missing/path` does not exist") {
        assert!(!r.stderr.contains("profile"), "{}", r.all());
    }
    // Without --profile the driver's path used to be taken for a profile's name.
    let out = tempfile::tempdir().unwrap();
    let r = rtconf(&[
        "run",
        "--driver",
        "/missing/path",
        "--out",
        &out.path().display().to_string(),
    ]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(
        r.stderr.contains("`/missing/path` does not exist"),
        "{}",
        r.all()
    );
}

#[test]
fn a_manifest_naming_a_missing_library_is_named_with_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let icd = manifest_naming(
        dir.path(),
        "missing-lib.json",
        "/nonexistent/libvulkan_x.so",
    );
    both_refuse(
        &icd,
        &format!("`{icd}` names the library /nonexistent/libvulkan_x.so, which does not exist"),
    );
}

#[test]
fn a_garbled_manifest_is_named_with_where_it_stops_being_json() {
    let dir = tempfile::tempdir().unwrap();
    let icd = write(dir.path(), "garbled.json", "{\"ICD\": {\"library_path\": ");
    for r in both_refuse(&icd, &format!("`{icd}` is not JSON")) {
        assert!(r.stderr.contains("line 1 column"), "{}", r.all());
    }
}

#[test]
fn a_manifest_naming_a_file_that_is_not_a_library_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let lib = write(dir.path(), "libfake.so", "not a shared object");
    let icd = manifest_naming(dir.path(), "fake.json", &lib);
    both_refuse(&icd, "is not a shared object");
}

/// Writes an ICD manifest `name` in `dir` naming `library`; its path.
fn manifest_naming(dir: &std::path::Path, name: &str, library: &str) -> String {
    write(
        dir,
        name,
        &format!(
            r#"{{"file_format_version": "1.0.0", "ICD": {{"library_path": "{library}", "api_version": "1.3.0"}}}}"#
        ),
    )
}

#[test]
fn lavapipe_passes_the_check() {
    let r = rtconf(&["replay", HAND, "--driver", "lavapipe"]);
    assert_eq!(r.code, 0, "{}", r.all());
}

/// A shared object this process has loaded (the C library), from /proc/self/maps.
fn some_shared_object() -> String {
    let maps = std::fs::read_to_string("/proc/self/maps").expect("/proc/self/maps");
    maps.lines()
        .filter_map(|l| l.split_whitespace().nth(5))
        .find(|p| p.contains("libc.so"))
        .expect("the C library is mapped")
        .to_string()
}

#[test]
fn a_library_that_is_not_a_driver_is_named_with_the_failing_call() {
    // The run's check is its first worker's instance, made while the registry is read; replay makes
    // its own. Both say the same thing, naming the manifest, the library and the call that failed.
    let dir = tempfile::tempdir().unwrap();
    let lib = some_shared_object();
    let icd = manifest_naming(dir.path(), "not-a-driver.json", &lib);
    both_refuse(
        &icd,
        &format!("`{icd}` names the library `{lib}`, with which vkCreateInstance fails"),
    );
}
