//! The harness compiles the GLSL it templates per case in its own process: every stage's templated
//! source compiles for KHR and NV pipelines to SPIR-V 1.5 of that stage, and it still does in a child
//! process whose PATH is empty and whose TMPDIR is a new folder (so no compiler on PATH and no shader
//! cached on disk by an earlier run can serve it).

use generator::resources::{move_to_stage, valid_state};
use harness::resource_glsl::{compile_stage, stage_glsl, stage_source};
use model::resources::Stage;
use model::world::PipelineApi;
use model::DeviceProfile;
use std::process::Command;

/// Set in the child process the test starts with an empty PATH.
const CHILD: &str = "RTCONF_SHADER_COMPILER_CHILD";
const COMPILING_TEST: &str = "every_templated_stage_compiles_in_process";

const STAGES: [(Stage, u32); 6] = [
    (Stage::Raygen, 5313),
    (Stage::ClosestHit, 5316),
    (Stage::Miss, 5317),
    (Stage::AnyHit, 5315),
    (Stage::Intersection, 5314),
    (Stage::Callable, 5318),
];

fn lavapipe_profile() -> DeviceProfile {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    DeviceProfile::from_profiles_json("lavapipe", &text).expect("the lavapipe profile")
}

/// The execution model of a module's first OpEntryPoint (opcode 15).
fn execution_model(words: &[u32]) -> Option<u32> {
    let mut i = 5;
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xFFFF);
        if op == 15 {
            return words.get(i + 1).copied();
        }
        i += count.max(1);
    }
    None
}

/// What the child runs (and the parent too, with its own PATH): each stage's template for a valid
/// resource state, made unique to this process so that no cache of an earlier run holds it.
#[test]
fn every_templated_stage_compiles_in_process() {
    if std::env::var_os(CHILD).is_some() {
        assert_eq!(
            std::env::var_os("PATH").unwrap_or_default(),
            "",
            "the child runs with an empty PATH"
        );
    }
    let unique = format!(
        "// compiled by process {} at {:?}\n",
        std::process::id(),
        std::time::SystemTime::now()
    );
    let profile = lavapipe_profile();
    for (stage, khr_model) in STAGES {
        let mut st = valid_state(&profile, 3, 0x1ff);
        move_to_stage(&mut st, stage);
        let (glsl, _) = stage_glsl(&st, stage, stage_source(stage).0).expect("expressible");
        let glsl = format!("{glsl}{unique}");
        for api in [PipelineApi::Khr, PipelineApi::Nv] {
            for trace in [false, true] {
                let words = compile_stage(&glsl, stage, trace, api)
                    .unwrap_or_else(|e| panic!("{stage:?} {api:?} trace {trace}: {e}"));
                assert_eq!(words[0], 0x0723_0203, "{stage:?} {api:?}: SPIR-V magic");
                assert_eq!(words[1], 0x0001_0500, "{stage:?} {api:?}: SPIR-V 1.5");
                // SPV_NV_ray_tracing's execution models are SPV_KHR_ray_tracing's values.
                assert_eq!(
                    execution_model(&words),
                    Some(khr_model),
                    "{stage:?} {api:?}: the stage's execution model"
                );
            }
        }
    }
}

#[test]
fn templated_stages_compile_with_an_empty_path_and_no_shader_cache() {
    let tmp = tempfile::tempdir().expect("a temporary folder");
    let out = Command::new(std::env::current_exe().expect("this test binary"))
        .args(["--exact", COMPILING_TEST, "--test-threads", "1"])
        .env(CHILD, "1")
        .env("PATH", "")
        .env("TMPDIR", tmp.path())
        .output()
        .expect("the test binary starts again");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "the child failed:\n{text}");
    assert!(
        text.contains("1 passed; 0 failed"),
        "the child ran the compiling test:\n{text}"
    );
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .expect("the child's TMPDIR")
        .collect();
    assert!(left.is_empty(), "the compiler wrote no files: {left:?}");
}
