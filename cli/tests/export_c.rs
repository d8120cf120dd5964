//! `rtconf export` on lavapipe: cases exported as C, compiled with the system compiler (`cc repro.c
//! -lvulkan -o repro`) and run under the validation layer. A build case's and an invalid trace case's
//! program reports the VUIDs `rtconf replay` observed; a valid rendered trace case of
//! vkCmdTraceRaysKHR and of vkCmdTraceRaysIndirectKHR builds its scene from the plan's bytes, reads
//! its ray records back, exits 0 and its records are replay's; one expected value planted wrong in
//! the emitted tables makes the program exit 1. A valid build's program repeats the traced check, and
//! lavapipe's build findings reproduce in C as in replay (records and verdict alike). The NVIDIA
//! DEVICE_LOST evidence cases export to C that compiles (and passes on lavapipe); what the writer does
//! not handle is refused with the reason.

#[path = "common/folders.rs"]
mod common;

use common::{fresh_dir, rtconf, text};
use model::CommandId;
use serde_json::Value;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// What an exported program printed.
struct ProgramVerdict {
    status: Option<i32>,
    model: BTreeSet<String>,
    layer: BTreeSet<String>,
    /// Some(whether the records matched) when it ran the launch for real.
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

/// `rtconf export CASE --out DIR`, which must succeed; what it printed.
fn export_printed(case: &Path, dir: &Path) -> String {
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
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Exports `case` into `dir` and builds it with the printed command.
fn export_build(case: &Path, dir: &Path) {
    let printed = export_printed(case, dir);
    let build = printed
        .lines()
        .find_map(|l| l.strip_prefix("build: "))
        .and_then(|l| l.split(" && ").nth(1))
        .expect("the build command");
    assert_eq!(build, "cc repro.c -lvulkan -o repro");
    compile(dir);
}

/// `cc repro.c -lvulkan -o repro` in `dir`, with every warning shown.
fn compile(dir: &Path) {
    let cc = Command::new("cc")
        .args(["-Wall", "repro.c", "-lvulkan", "-o", "repro"])
        .current_dir(dir)
        .output()
        .expect("the system C compiler");
    assert!(cc.status.success(), "{}: {}", dir.display(), text(&cc));
    assert!(
        !String::from_utf8_lossy(&cc.stderr).contains("warning"),
        "{}: {}",
        dir.display(),
        text(&cc)
    );
}

/// Runs the program built in `dir` on lavapipe, its records (if any) written to `dir/records.bin`.
fn run_program(dir: &Path) -> ProgramVerdict {
    let run: Output = Command::new(dir.join("repro"))
        .args(["--records", "records.bin"])
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
        stdout: format!(
            "{stdout}\n--- stderr\n{}",
            String::from_utf8_lossy(&run.stderr)
        ),
    }
}

fn export_build_run(case: &Path, dir: &Path) -> ProgramVerdict {
    export_build(case, dir);
    run_program(dir)
}

/// `rtconf replay CASE --json`, its records (if any) written to `records`.
fn replay(case: &Path, records: Option<&Path>) -> Value {
    let mut args = vec!["replay", case.to_str().unwrap(), "--json"];
    if let Some(r) = records {
        args.extend(["--records", r.to_str().unwrap()]);
    }
    let o = rtconf(&args, &[]);
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

/// Rendered-scene cases of `command` on lavapipe's profile, drawn as a run draws them, with launches
/// of at most `max_ids` IDs, written into `dir`.
fn rendered_cases(command: CommandId, seed: u64, max_ids: u64, dir: &Path) -> Vec<PathBuf> {
    let set = session::sources::load_sources(&[]).expect("the installed registry");
    let rules = model::RuleSet::from_vuids(&set);
    let profile = session::sources::profile_for("lavapipe").expect("lavapipe's profile");
    let spec = generator::CaseSpec::rendered(command);
    let cases = generator::generate(&profile, "lavapipe", &rules, &spec, 12, seed).unwrap();
    std::fs::create_dir_all(dir).unwrap();
    let mut out = Vec::new();
    for c in cases {
        let t = c.as_trace().expect("a trace case");
        let ids: u64 = t
            .call
            .dimensions(&t.world)
            .map_or(u64::MAX, |d| d.iter().map(|&x| x as u64).product());
        if ids > max_ids || c.runnable(&profile).is_err() {
            continue;
        }
        let p = dir.join(format!("{}.yaml", c.name));
        std::fs::write(&p, c.to_yaml()).unwrap();
        out.push(p);
    }
    out
}

/// The records in a file (little-endian u32).
fn words(path: &Path) -> Vec<u32> {
    std::fs::read(path)
        .unwrap()
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// The program in `dir` with the miss group of ray `ray`'s rule raised by one (its third field).
fn plant_miss_group(dir: &Path, ray: usize) -> bool {
    let path = dir.join("repro.c");
    let source = std::fs::read_to_string(&path).unwrap();
    let marker = format!("/* ray {ray} */ {{");
    let mut planted = false;
    let edited: Vec<String> = source
        .lines()
        .map(|l| match l.trim_start().strip_prefix(&marker) {
            Some(rest) if !planted => {
                let mut fields: Vec<String> = rest.split(", ").map(String::from).collect();
                let group: u32 = fields[2].parse().unwrap();
                fields[2] = (group + 1).to_string();
                planted = true;
                format!("    {marker}{}", fields.join(", "))
            }
            _ => l.to_string(),
        })
        .collect();
    std::fs::write(&path, edited.join("\n")).unwrap();
    planted
}

#[test]
fn rendered_trace_cases_run_as_c_and_their_records_are_replays() {
    let dir = fresh_dir("export-c-rendered");
    let mut planted = false;
    for (command, seed) in [
        (CommandId::TraceRays, 11),
        (CommandId::TraceRaysIndirect, 12),
    ] {
        let cases = rendered_cases(command, seed, 4096, &dir.join("cases"));
        let mut exported = 0;
        for case in cases.iter().take(3) {
            let name = case.file_stem().unwrap().to_str().unwrap().to_string();
            let out = dir.join(&name);
            let replay_records = dir.join(format!("{name}.replay.bin"));
            let r = replay(case, Some(&replay_records));
            if r["outcome"] != "pass" {
                // A case lavapipe fails (a triaged deviation) is not the exporter's to judge.
                continue;
            }
            let calls = r["calls"].as_array().unwrap();
            assert!(
                calls.iter().any(|c| c
                    .as_str()
                    .unwrap()
                    .starts_with("vkCmdBuildAccelerationStructuresKHR: top level")),
                "{name}: the call list names the scene builds: {r}"
            );
            let p = export_build_run(case, &out);
            same_verdict(&name, &p, &r);
            assert_eq!(p.status, Some(0), "{name}\n{}", p.stdout);
            assert_eq!(p.output, Some(true), "{name}\n{}", p.stdout);
            let ours = words(&out.join("records.bin"));
            let theirs = words(&replay_records);
            assert_eq!(ours.len(), theirs.len(), "{name}");
            assert!(ours == theirs, "{name}: the program's records are replay's");
            exported += 1;
            // A planted fault: one expected value (a ray's miss group) edited in the emitted C.
            if !planted {
                let source = std::fs::read_to_string(out.join("repro.c")).unwrap();
                let ray_count = source.matches("/* ray ").count();
                let missed = ours
                    .chunks(28)
                    .position(|w| w[0] == 1)
                    .map(|id| id % ray_count.max(1));
                if let Some(ray) = missed {
                    assert!(plant_miss_group(&out, ray), "{name}");
                    compile(&out);
                    let faulty = run_program(&out);
                    assert_eq!(faulty.status, Some(1), "{name}\n{}", faulty.stdout);
                    assert_eq!(faulty.output, Some(false), "{name}\n{}", faulty.stdout);
                    assert!(
                        faulty.stdout.contains(&format!("(ray {ray}): miss group")),
                        "{name}\n{}",
                        faulty.stdout
                    );
                    planted = true;
                }
            }
        }
        assert!(
            exported >= 1,
            "{}: a rendered case exported and run",
            command.vk_name()
        );
    }
    assert!(
        planted,
        "some exported case misses a ray to plant a fault on"
    );
}

/// The launch IDs the program's judge printed a failure for.
fn failing_ids(stdout: &str) -> BTreeSet<usize> {
    stdout
        .lines()
        .filter_map(|l| {
            l.strip_prefix("  launch ID ")
                .or_else(|| l.strip_prefix("  check ray "))
        })
        .filter_map(|l| l.split([' ', ':']).next()?.parse().ok())
        .collect()
}

#[test]
fn the_programs_judge_is_the_models_on_doctored_records() {
    let dir = fresh_dir("export-c-judge");
    let cases = rendered_cases(CommandId::TraceRays, 11, 4096, &dir.join("cases"));
    let mut judged = 0;
    for case in &cases {
        let name = case.file_stem().unwrap().to_str().unwrap().to_string();
        let records = dir.join(format!("{name}.bin"));
        let r = replay(case, Some(&records));
        if r["outcome"] != "pass" {
            continue;
        }
        let good = words(&records);
        let hits: Vec<usize> = (0..good.len() / 28)
            .filter(|&i| good[i * 28] == 2)
            .collect();
        let misses: Vec<usize> = (0..good.len() / 28)
            .filter(|&i| good[i * 28] == 1)
            .collect();
        let (Some(&hit), Some(&miss)) = (hits.first(), misses.first()) else {
            continue;
        };
        let out = dir.join(&name);
        export_build(case, &out);
        let yaml = std::fs::read_to_string(case).unwrap();
        let model_case = model::Case::read(&name, &yaml).unwrap();
        let body = model_case.as_trace().unwrap();
        let bump = |w: u32, by: f32| (f32::from_bits(w) * by).to_bits();
        type Edit = (&'static str, usize, Box<dyn Fn(&mut [u32])>);
        let edits: Vec<Edit> = vec![
            ("as recorded", hit, Box::new(|_: &mut [u32]| {})),
            ("not run", hit, Box::new(|w: &mut [u32]| w[0] = 0xFFFF_FFFF)),
            ("another instance", hit, Box::new(|w: &mut [u32]| w[2] += 1)),
            (
                "another primitive",
                hit,
                Box::new(|w: &mut [u32]| w[5] += 7),
            ),
            ("custom index", hit, Box::new(|w: &mut [u32]| w[3] ^= 1)),
            ("hit group", hit, Box::new(|w: &mut [u32]| w[1] += 1)),
            ("hit kind", hit, Box::new(|w: &mut [u32]| w[6] ^= 1)),
            (
                "t far off",
                hit,
                Box::new(move |w: &mut [u32]| w[7] = bump(w[7], 1.5)),
            ),
            ("t one ulp", hit, Box::new(|w: &mut [u32]| w[7] += 1)),
            (
                "barycentric",
                hit,
                Box::new(move |w: &mut [u32]| w[8] = (f32::from_bits(w[8]) + 0.25).to_bits()),
            ),
            ("any-hit count", hit, Box::new(|w: &mut [u32]| w[10] = 1000)),
            ("miss group", miss, Box::new(|w: &mut [u32]| w[1] += 1)),
            (
                "miss as no shader",
                miss,
                Box::new(|w: &mut [u32]| w[0] = 3),
            ),
            ("miss as a hit", miss, Box::new(|w: &mut [u32]| w[0] = 2)),
            ("no outcome", miss, Box::new(|w: &mut [u32]| w[0] = 7)),
        ];
        let mut differing = 0;
        for (what, id, edit) in &edits {
            let mut w = good.clone();
            edit(&mut w[id * 28..id * 28 + 28]);
            let file = out.join("doctored.bin");
            let bytes: Vec<u8> = w.iter().flat_map(|x| x.to_le_bytes()).collect();
            std::fs::write(&file, bytes).unwrap();
            let run = Command::new(out.join("repro"))
                .args(["--judge", "doctored.bin"])
                .current_dir(&out)
                .output()
                .unwrap();
            let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
            let model_fails: BTreeSet<usize> = model::rendered::judge_records(body, &w)
                .unwrap()
                .ids
                .iter()
                .enumerate()
                .filter(|(_, j)| matches!(j.verdict, model::tracer::judge::RayVerdict::Fail(_)))
                .map(|(i, _)| i)
                .collect();
            assert_eq!(
                failing_ids(&stdout),
                model_fails,
                "{name}: {what} at launch ID {id}\n{stdout}"
            );
            assert_eq!(
                run.status.code(),
                Some(if model_fails.is_empty() { 0 } else { 1 }),
                "{name}: {what}\n{stdout}"
            );
            differing += !model_fails.is_empty() as usize;
        }
        assert!(differing >= 10, "{name}: {differing} edits the model fails");
        // A file that is not this launch's records.
        std::fs::write(out.join("short.bin"), [0u8; 12]).unwrap();
        let run = Command::new(out.join("repro"))
            .args(["--judge", "short.bin"])
            .current_dir(&out)
            .output()
            .unwrap();
        assert_eq!(run.status.code(), Some(2), "{}", text(&run));
        judged += 1;
        if judged == 2 {
            break;
        }
    }
    assert!(
        judged >= 1,
        "a rendered case with hits and misses to doctor"
    );
}

#[test]
fn invalid_and_build_cases_report_the_layers_vuids_as_replay_does() {
    let dir = fresh_dir("export-c");
    let repo = common::repo();

    // A build case: recorded under the layer, which reports a second VUID beside the unavoidable one.
    let build = repo.join("cases/build/layer-1.3.239-03701.yaml");
    let p = export_build_run(&build, &dir.join("build"));
    let r = replay(&build, None);
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
    // does not read. The program reports what the layer did (nothing of the model's VUID) and exits 1.
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
    let r = replay(&gap, None);
    assert_eq!(r["outcome"], "triaged", "{r}");
    assert!(
        r["detail"].as_str().unwrap().contains("triaged layer-gap"),
        "{r}"
    );
    let p = export_build_run(&gap, &dir.join("gap-c"));
    same_verdict("gap", &p, &r);
    assert!(
        p.model
            .contains("VUID-vkCmdTraceRaysIndirectKHR-None-03429"),
        "{}",
        p.stdout
    );
    assert_eq!(p.status, Some(1), "{}", p.stdout);
    assert!(
        p.stdout
            .contains("vkCreateRayTracingPipelinesKHR (a second pipeline)"),
        "{}",
        p.stdout
    );

    // The hand-made valid indirect case: its eight records, judged in C, are replay's.
    let valid = repo.join("cases/hand/trace-indirect-records-32.yaml");
    let records = dir.join("valid.replay.bin");
    let r = replay(&valid, Some(&records));
    assert_eq!(r["outcome"], "pass", "{r}");
    let p = export_build_run(&valid, &dir.join("valid"));
    same_verdict("valid", &p, &r);
    assert_eq!(
        words(&dir.join("valid/records.bin")),
        words(&records),
        "{}",
        p.stdout
    );
}

#[test]
fn the_nvidia_device_lost_cases_export_to_c_that_compiles() {
    let dir = fresh_dir("export-c-nvidia");
    for name in [
        "trace-indirect-rendered-4-81",
        "trace-indirect-rendered-314-39",
        "trace-rendered-316-19",
    ] {
        let case = common::repo().join(format!("cases/nvidia-h200/device-lost/{name}.yaml"));
        let out = dir.join(name);
        export_build(&case, &out);
        let source = std::fs::read_to_string(out.join("repro.c")).unwrap();
        assert!(source.contains("judge_records(&launch_rules"), "{name}");
        assert!(
            source.contains("pvkCmdBuildAccelerationStructuresKHR(primary"),
            "{name}"
        );
        // Lost the device on the H200; on lavapipe the program runs and every record is the model's.
        let p = run_program(&out);
        assert_eq!(p.status, Some(0), "{name}\n{}", p.stdout);
        assert_eq!(p.output, Some(true), "{name}\n{}", p.stdout);
    }
}

#[test]
fn every_generated_khr_trace_case_exports_to_c_that_compiles_or_is_refused_with_the_reason() {
    let dir = fresh_dir("export-c-generated");
    let set = session::sources::load_sources(&[]).expect("the installed registry");
    let rules = model::RuleSet::from_vuids(&set);
    let profile = session::sources::profile_for("lavapipe").expect("lavapipe's profile");
    let (mut compiled, mut refused) = (0, 0);
    for command in [CommandId::TraceRays, CommandId::TraceRaysIndirect] {
        let mut specs = vec![generator::CaseSpec::valid(command)];
        for row in rules.rows.iter().filter(|r| {
            r.status == model::rules::Status::Executable
                && model::rules::applies_to(&r.scope, command)
        }) {
            if generator::mutations_for(&row.vuid).is_some() {
                specs.push(generator::CaseSpec::violate(command, &row.vuid));
            }
        }
        for (i, spec) in specs.iter().enumerate() {
            let Ok(cases) =
                generator::generate(&profile, "lavapipe", &rules, spec, 1, 100 + i as u64)
            else {
                continue;
            };
            for c in cases {
                let case = dir.join(format!("{}.yaml", c.name));
                std::fs::write(&case, c.to_yaml()).unwrap();
                let out = dir.join(&c.name);
                let o = rtconf(
                    &[
                        "export",
                        case.to_str().unwrap(),
                        "--out",
                        out.to_str().unwrap(),
                    ],
                    &[],
                );
                if o.status.code() == Some(2) {
                    let why = String::from_utf8_lossy(&o.stderr);
                    assert!(
                        why.contains("resource states (descriptors, images, samplers, push constants) are not exported yet")
                            || why.contains("is sparse or not bound whole"),
                        "{}: {}",
                        c.name,
                        text(&o)
                    );
                    refused += 1;
                    continue;
                }
                assert!(o.status.success(), "{}: {}", c.name, text(&o));
                compile(&out);
                compiled += 1;
            }
        }
    }
    eprintln!("{compiled} exported and compiled, {refused} refused");
    assert!(compiled >= 60, "{compiled} compiled");
    assert!(refused < compiled, "{refused} refused");
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
    let refused = |case: &Path, out: &str, why: &str| {
        let o = rtconf(
            &[
                "export",
                case.to_str().unwrap(),
                "--out",
                dir.join(out).to_str().unwrap(),
            ],
            &[],
        );
        assert_eq!(o.status.code(), Some(2), "{}", text(&o));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(why),
            "{}",
            text(&o)
        );
        assert!(!dir.join(out).join("repro.c").exists(), "{}", text(&o));
    };
    refused(
        &dir.join("vkCmdTraceRaysIndirectKHR-None-02702-1-0.yaml"),
        "resources",
        "resource states (descriptors, images, samplers, push constants) are not exported yet",
    );
    // A vkCmdTraceRaysNV case: planned, not written as C.
    refused(
        &common::repo().join("cases/nvidia-h200/vkCmdTraceRaysNV-None-08114-121-0.yaml"),
        "nv",
        "VK_NV_ray_tracing cases are not exported yet",
    );
}

/// A valid build's program repeats the harness's traced check: lavapipe's build findings export to C
/// whose output verdict, exit status and check records are replay's (the findings' programs exit 1,
/// a build lavapipe gets right exits 0), with ray query and with the pipeline (`RTCONF_REPRO_CHECK=
/// pipeline` beside `rtconf replay --check pipeline`), and the program's judge catches one planted
/// fault in records the device wrote: a hit on an unambiguous ray turned into a miss.
#[test]
fn build_findings_export_their_traced_check_as_replay_runs_it() {
    let dir = fresh_dir("export-c-build-check");
    let repo = common::repo();
    let cases = [
        ("aabbs-valid", true),
        ("lavapipe-inactive-aabb-drops-box", false),
        ("lavapipe-inactive-triangle-drops-primitive", false),
        ("indexed-first-vertex-shifted-primitives", false),
        ("lavapipe-first-vertex-twice-hidden-geometry", false),
        ("lavapipe-fourth-component-weights-translation", false),
    ];
    for (name, passes) in cases {
        let case = repo.join(format!("cases/build/{name}.yaml"));
        let records = dir.join(format!("{name}.replay.bin"));
        let r = replay(&case, Some(&records));
        let out = dir.join(name);
        let p = export_build_run(&case, &out);
        same_verdict(name, &p, &r);
        assert_eq!(p.output, Some(passes), "{name}\n{}", p.stdout);
        assert_eq!(
            words(&out.join("records.bin")),
            words(&records),
            "{name}\n{}",
            p.stdout
        );
        assert!(
            p.stdout
                .contains("traced with ray query, one invocation each"),
            "{name}\n{}",
            p.stdout
        );
        // The pipeline path (a device without ray query takes it) gives replay's records too.
        let by_pipeline = dir.join(format!("{name}.replay-pipeline.bin"));
        let o = rtconf(
            &[
                "replay",
                case.to_str().unwrap(),
                "--check",
                "pipeline",
                "--records",
                by_pipeline.to_str().unwrap(),
            ],
            &[],
        );
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
        let run = Command::new(out.join("repro"))
            .args(["--records", "pipeline.bin"])
            .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
            .env("RTCONF_REPRO_CHECK", "pipeline")
            .current_dir(&out)
            .output()
            .expect("the reproducer runs");
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(
            stdout.contains("traced with a ray tracing pipeline, one launch ID each"),
            "{name}\n{stdout}"
        );
        assert_eq!(
            run.status.code(),
            Some(if passes { 0 } else { 1 }),
            "{name}\n{stdout}"
        );
        assert_eq!(
            words(&out.join("pipeline.bin")),
            words(&by_pipeline),
            "{name}\n{stdout}"
        );
    }

    // A valid build lavapipe gets right whose check hits (drawn as `rtconf gen` draws it), its records
    // judged by its program without running anything: as read back they pass; with one hit turned
    // into a miss they fail, naming that ray.
    let drawn = dir.join("drawn");
    let g = rtconf(
        &[
            "gen",
            "--valid",
            "--command",
            "vkCmdBuildAccelerationStructuresIndirectKHR",
            "--count",
            "12",
            "--out",
            drawn.to_str().unwrap(),
        ],
        &[],
    );
    assert!(g.status.success(), "{}", text(&g));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&drawn)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let (case, good, hit) = files
        .iter()
        .find_map(|case| {
            let records = case.with_extension("bin");
            let r = replay(case, Some(&records));
            if r["outcome"] != "pass" {
                return None;
            }
            let good = words(&records);
            let hit = (0..good.len() / 28).find(|&i| good[i * 28] == 2)?;
            Some((case.clone(), good, hit))
        })
        .expect("a drawn valid build that lavapipe passes and whose check hits");
    let out = dir.join("drawn-program");
    let p = export_build_run(&case, &out);
    assert_eq!(p.output, Some(true), "{}", p.stdout);
    assert_eq!(words(&out.join("records.bin")), good, "{}", p.stdout);
    let judge = |records: &[u32], file: &str| {
        let path = out.join(file);
        let bytes: Vec<u8> = records.iter().flat_map(|w| w.to_le_bytes()).collect();
        std::fs::write(&path, bytes).unwrap();
        Command::new(out.join("repro"))
            .args(["--judge", path.to_str().unwrap()])
            .output()
            .expect("the program judges a records file")
    };
    let as_read = judge(&good, "good.bin");
    assert_eq!(as_read.status.code(), Some(0), "{}", text(&as_read));
    let mut missed = good.clone();
    missed[hit * 28] = 1;
    let planted = judge(&missed, "missed.bin");
    assert_eq!(planted.status.code(), Some(1), "{}", text(&planted));
    assert_eq!(
        failing_ids(&String::from_utf8_lossy(&planted.stdout)),
        BTreeSet::from([hit]),
        "{}",
        text(&planted)
    );
}

/// A valid build of two infos: the harness's traced check handles one info, so `rtconf replay` calls
/// the case not realised, and `rtconf export` writes a program that records the build under the
/// layer and traces nothing — and says so, in its run line and in the program's header, instead of
/// claiming the check of info 0.
#[test]
fn a_valid_build_of_two_infos_exports_without_a_traced_check() {
    let dir = fresh_dir("export-c-two-infos");
    let case = common::repo().join("cases/build/two-infos-valid.yaml");
    let printed = export_printed(&case, &dir);
    assert!(
        printed.contains("a valid build of several infos is not checked by tracing"),
        "{printed}"
    );
    assert!(!printed.contains("builds info 0 directly"), "{printed}");
    let source = std::fs::read_to_string(dir.join("repro.c")).unwrap();
    assert!(
        source
            .contains("valid build of several infos: the harness's traced check handles one info"),
        "the program's header says why it traces nothing"
    );
    compile(&dir);
    let p = run_program(&dir);
    let want: BTreeSet<String> = [
        "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650",
    ]
    .map(String::from)
    .into();
    assert_eq!((&p.model, &p.layer), (&want, &want), "{}", p.stdout);
    assert_eq!((p.status, p.output), (Some(0), None), "{}", p.stdout);
    let r = replay(&case, None);
    assert_eq!(r["outcome"], "not-realised", "{r}");
}
