//! `rtconf export` on lavapipe: a build case is exported as C, compiled with the system compiler (`cc
//! repro.c -lvulkan -o repro`) and run; the program's verdict — the VUIDs the layer reported — equals
//! `rtconf replay`'s. Trace cases (rendered scenes, which the call plan does not describe yet) are
//! refused with exit 2 and that reason, writing no program, while replay still runs and judges them
//! and lists no calls for them.

#[path = "common/folders.rs"]
mod common;

use common::{fresh_dir, rtconf, text};
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

/// What an exported program printed.
struct ProgramVerdict {
    status: Option<i32>,
    model: BTreeSet<String>,
    layer: BTreeSet<String>,
    /// Some(whether the output matched) when it ran the launch for real.
    output: Option<bool>,
    stdout: String,
}

fn vuid_list(s: &str) -> BTreeSet<String> {
    if s == "nothing" || s == "valid" {
        BTreeSet::new()
    } else {
        s.split(", ").map(String::from).collect()
    }
}

/// The reason every trace case is refused, as `rtconf export` prints it.
const NOT_DESCRIBED: &str = "the call plan does not yet describe rendered-scene trace cases";

/// Exports a trace case into `dir`: refused (exit 2) with [`NOT_DESCRIBED`], and no program written.
fn export_refused(case: &Path, dir: &Path) {
    let o = rtconf(
        &[
            "export",
            case.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(NOT_DESCRIBED),
        "{}",
        text(&o)
    );
    assert!(!dir.join("repro.c").exists(), "{}", text(&o));
}

/// Exports `case` into `dir`, builds it with the printed command and runs it on lavapipe.
fn export_build_run(case: &Path, dir: &Path) -> ProgramVerdict {
    let o = rtconf(
        &[
            "export",
            case.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    let printed = String::from_utf8_lossy(&o.stdout).into_owned();
    let build = printed
        .lines()
        .find_map(|l| l.strip_prefix("build: "))
        .and_then(|l| l.split(" && ").nth(1))
        .expect("the build command");
    assert_eq!(build, "cc repro.c -lvulkan -o repro");
    let cc = Command::new("sh")
        .args(["-c", build])
        .current_dir(dir)
        .output()
        .expect("the system C compiler");
    assert!(cc.status.success(), "{}", text(&cc));
    let run = Command::new(dir.join("repro"))
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .current_dir(dir)
        .output()
        .expect("the reproducer runs");
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    std::fs::write(dir.join("repro.out"), &stdout).unwrap();
    let field = |prefix: &str| {
        stdout
            .lines()
            .find_map(|l| l.strip_prefix(prefix))
            .map(|s| s.trim().to_string())
    };
    ProgramVerdict {
        status: run.status.code(),
        model: vuid_list(&field("model:").unwrap_or_default()),
        layer: vuid_list(&field("layer reported:").expect(&stdout)),
        output: field("output:").map(|o| o.starts_with("matches the model")),
        stdout,
    }
}

fn replay(case: &Path) -> Value {
    let o = rtconf(&["replay", case.to_str().unwrap(), "--json"], &[]);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    serde_json::from_slice(&o.stdout).expect("replay --json prints JSON")
}

fn set(v: &Value) -> BTreeSet<String> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap().to_string())
        .collect()
}

/// The program's verdict is the replay's.
fn same_verdict(name: &str, p: &ProgramVerdict, r: &Value) {
    assert_eq!(
        p.layer,
        set(&r["layer_vuids"]),
        "{name}: layer\n{}",
        p.stdout
    );
    assert_eq!(p.model, set(&r["model"]), "{name}: model\n{}", p.stdout);
    assert_eq!(
        p.output,
        r["output_matches"].as_bool(),
        "{name}: output\n{}",
        p.stdout
    );
    let agrees = p.layer == p.model && p.output != Some(false);
    assert_eq!(
        p.status,
        Some(if agrees { 0 } else { 1 }),
        "{name}\n{}",
        p.stdout
    );
    for line in [
        "device:  llvmpipe",
        "driver:  llvmpipe",
        "layer:   VK_LAYER_KHRONOS_validation 1.3.239",
    ] {
        assert!(p.stdout.contains(line), "{name}: `{line}` in\n{}", p.stdout);
    }
}

#[test]
fn exported_reproducers_compile_run_on_lavapipe_and_agree_with_replay() {
    let dir = fresh_dir("export-c");
    let repo = common::repo();

    // A valid trace case: replay submits it and judges its records (and lists no calls: the call plan
    // does not describe it); export refuses it.
    let valid = repo.join("cases/hand/trace-indirect-records-32.yaml");
    let r = replay(&valid);
    assert_eq!(r["outcome"], "pass", "{r}");
    assert_eq!(r["output_matches"], true, "{r}");
    assert_eq!(r["calls"], serde_json::json!([]), "{r}");
    let o = rtconf(&["replay", valid.to_str().unwrap()], &[]);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("calls:   not listed"),
        "{}",
        text(&o)
    );
    export_refused(&valid, &dir.join("valid"));

    // A build case: recorded under the layer, which reports a second VUID beside the unavoidable one.
    let build = repo.join("cases/build/layer-1.3.239-03701.yaml");
    let p = export_build_run(&build, &dir.join("build"));
    let r = replay(&build);
    same_verdict("build", &p, &r);
    assert!(
        p.layer
            .contains("VUID-vkCmdBuildAccelerationStructuresIndirectKHR-pInfos-03403"),
        "{}",
        p.stdout
    );
    assert!(
        p.stdout
            .contains("vkGetAccelerationStructureBuildSizesKHR for info 0"),
        "{}",
        p.stdout
    );

    // A triaged layer gap: the shader binding table holds another pipeline's handle, which the layer
    // does not read.
    let gen = dir.join("gap");
    let g = rtconf(
        &[
            "gen",
            "--vuid",
            "VUID-vkCmdTraceRaysIndirectKHR-None-03429",
            "--count",
            "1",
            "--seed",
            "1",
            "--out",
            gen.to_str().unwrap(),
        ],
        &[],
    );
    assert!(g.status.success(), "{}", text(&g));
    let gap = gen.join("vkCmdTraceRaysIndirectKHR-None-03429-1-0.yaml");
    let r = replay(&gap);
    assert_eq!(r["outcome"], "triaged", "{r}");
    assert!(
        r["detail"].as_str().unwrap().contains("triaged layer-gap"),
        "{r}"
    );
    // The layer gap is a trace case too: replay triages it (above), export refuses it.
    export_refused(&gap, &dir.join("gap-c"));
}

#[test]
fn cases_the_writer_does_not_handle_are_refused_with_the_reason() {
    let dir = fresh_dir("export-refused");
    // A case with a resource state (descriptors, samplers).
    let g = rtconf(
        &[
            "gen",
            "--vuid",
            "VUID-vkCmdTraceRaysIndirectKHR-None-02702",
            "--count",
            "1",
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(g.status.success(), "{}", text(&g));
    let case = dir.join("vkCmdTraceRaysIndirectKHR-None-02702-1-0.yaml");
    let o = rtconf(
        &[
            "export",
            case.to_str().unwrap(),
            "--out",
            dir.join("c").to_str().unwrap(),
        ],
        &[],
    );
    // A trace case: refused before its resource state is looked at, for the reason every trace case is.
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(NOT_DESCRIBED),
        "{}",
        text(&o)
    );
}
