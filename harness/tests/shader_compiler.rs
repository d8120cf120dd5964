//! The harness compiles the GLSL it templates per case in its own process: every stage's templated
//! source compiles for KHR and NV pipelines to SPIR-V 1.5 of that stage, and it still does in a child
//! process whose PATH is empty and whose TMPDIR is a new folder (so no compiler on PATH and no shader
//! cached on disk by an earlier run can serve it); with the SPIR-V disk cache on, the entries it leaves
//! are whole modules in their own folder, and a torn one is compiled again.

use generator::resources::{move_to_stage, valid_state};
use harness::resource_glsl::{
    compile_stage, module_interface, stage_glsl, stage_source, ShaderBody,
};
use model::resources::Stage;
use model::world::PipelineApi;
use model::DeviceProfile;
use std::process::Command;

/// Set in the child process the test starts with an empty PATH.
const CHILD: &str = "RTCONF_SHADER_COMPILER_CHILD";
const COMPILING_TEST: &str = "every_templated_stage_compiles_in_process";
/// The source suffix a child uses instead of one unique to its process.
const SUFFIX: &str = "RTCONF_SHADER_COMPILER_SUFFIX";

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
    // The cache test's children share one suffix, so the second compiles what the first did.
    let unique = match std::env::var(SUFFIX) {
        Ok(shared) => format!("// {shared}\n"),
        Err(_) => format!(
            "// compiled by process {} at {:?}\n",
            std::process::id(),
            std::time::SystemTime::now()
        ),
    };
    let profile = lavapipe_profile();
    for (stage, khr_model) in STAGES {
        let mut st = valid_state(&profile, 3, 0x1ff);
        move_to_stage(&mut st, stage);
        let (glsl, _) = stage_glsl(&st, stage, stage_source(stage).0).expect("expressible");
        let glsl = format!("{glsl}{unique}");
        for api in [PipelineApi::Khr, PipelineApi::Nv] {
            for (trace, body) in [false, true]
                .into_iter()
                .flat_map(|t| [ShaderBody::Full, ShaderBody::InterfaceOnly].map(|b| (t, b)))
            {
                let words = compile_stage(&glsl, stage, trace, api, body)
                    .unwrap_or_else(|e| panic!("{stage:?} {api:?} trace {trace} {body:?}: {e}"));
                assert_eq!(words[0], 0x0723_0203, "{stage:?} {api:?}: SPIR-V magic");
                assert_eq!(words[1], 0x0001_0500, "{stage:?} {api:?}: SPIR-V 1.5");
                // SPV_NV_ray_tracing's execution models are SPV_KHR_ray_tracing's values.
                assert_eq!(
                    module_interface(&words).model,
                    khr_model,
                    "{stage:?} {api:?}: the stage's execution model"
                );
            }
        }
    }
}

/// Runs the compiling test again in a child process with an empty PATH, `tmp` as its TMPDIR and the
/// SPIR-V disk cache on or off; its output.
fn child_compiles(tmp: &std::path::Path, cache: bool, suffix: Option<&str>) -> String {
    child_run(tmp, cache, suffix, false)
}

/// [`child_compiles`], or with `expect_failure` a child that must fail.
fn child_run(
    tmp: &std::path::Path,
    cache: bool,
    suffix: Option<&str>,
    expect_failure: bool,
) -> String {
    let mut cmd = Command::new(std::env::current_exe().expect("this test binary"));
    match suffix {
        Some(s) => cmd.env(SUFFIX, s),
        None => cmd.env_remove(SUFFIX),
    };
    cmd.args(["--exact", COMPILING_TEST, "--test-threads", "1"])
        .env(CHILD, "1")
        .env("PATH", "")
        .env("TMPDIR", tmp);
    if cache {
        cmd.env_remove("RTCONF_SPIRV_CACHE");
    } else {
        cmd.env("RTCONF_SPIRV_CACHE", "off");
    }
    let out = cmd.output().expect("the test binary starts again");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if expect_failure {
        assert!(!out.status.success(), "the child passed:\n{text}");
        return text;
    }
    assert!(out.status.success(), "the child failed:\n{text}");
    assert!(
        text.contains("1 passed; 0 failed"),
        "the child ran the compiling test:\n{text}"
    );
    text
}

#[test]
fn templated_stages_compile_with_an_empty_path_and_no_shader_cache() {
    let tmp = tempfile::tempdir().expect("a temporary folder");
    child_compiles(tmp.path(), false, None);
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .expect("the child's TMPDIR")
        .collect();
    assert!(left.is_empty(), "the compiler wrote no files: {left:?}");
}

#[test]
fn the_spirv_disk_cache_holds_whole_modules_and_serves_a_second_process() {
    let tmp = tempfile::tempdir().expect("a temporary folder");
    let suffix = format!("cache test of process {}", std::process::id());
    child_compiles(tmp.path(), true, Some(&suffix));
    let top: Vec<String> = std::fs::read_dir(tmp.path())
        .expect("the child's TMPDIR")
        .map(|e| {
            e.expect("an entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert_eq!(top, ["rtconf-spirv"], "the cache keeps to its folder");
    let entries: Vec<std::path::PathBuf> = std::fs::read_dir(tmp.path().join("rtconf-spirv"))
        .expect("the cache folder")
        .map(|e| e.expect("an entry").path())
        .collect();
    // Every templated stage, for KHR and NV: whole modules, no staged file left.
    assert!(entries.len() >= STAGES.len() * 2, "{entries:?}");
    for e in &entries {
        assert!(e.extension().is_some_and(|x| x == "spv"), "{}", e.display());
        let bytes = std::fs::read(e).expect("an entry reads");
        assert!(bytes.len() % 4 == 0 && bytes.starts_with(&[0x03, 0x02, 0x23, 0x07]));
    }
    // A second process compiles the same stages from the entries (a torn one is compiled again).
    std::fs::write(&entries[0], b"torn").expect("writable");
    child_compiles(tmp.path(), true, Some(&suffix));
    let again = std::fs::read(&entries[0]).expect("the torn entry was written again");
    assert!(again.starts_with(&[0x03, 0x02, 0x23, 0x07]));
    let after = std::fs::read_dir(tmp.path().join("rtconf-spirv"))
        .expect("the cache folder")
        .count();
    assert_eq!(
        after,
        entries.len(),
        "the second process made no entry of its own"
    );
    // And the entries are what it uses: a module of another stage planted in an entry is what the
    // next process gets (its execution model check fails).
    let words = |p: &std::path::Path| -> Vec<u32> {
        std::fs::read(p)
            .expect("an entry reads")
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let (a, b) = entries
        .iter()
        .flat_map(|a| entries.iter().map(move |b| (a, b)))
        .find(|(a, b)| module_interface(&words(a)).model != module_interface(&words(b)).model)
        .expect("entries of two stages");
    std::fs::copy(b, a).expect("an entry is writable");
    let text = child_run(tmp.path(), true, Some(&suffix), true);
    assert!(text.contains("execution model"), "{text}");
}

/// An access past its binding's end, which GLSL refuses as a constant index, compiles to a module that
/// indexes the binding with that element as an ordinary constant: no specialisation constant of the
/// harness's fixed range is left, and an OpAccessChain takes an OpConstant of the element's value.
#[test]
fn an_index_past_a_bindings_end_is_an_ordinary_constant_of_the_module() {
    const PAST: u32 = 4099;
    let profile = lavapipe_profile();
    let mut st = valid_state(&profile, 3, 0x1ff);
    move_to_stage(&mut st, Stage::Raygen);
    let stage = st
        .stages
        .iter_mut()
        .find(|s| s.stage == Stage::Raygen)
        .expect("the raygen stage");
    stage.accesses.first_mut().expect("an access").element = PAST;
    let (glsl, _) = stage_glsl(&st, Stage::Raygen, stage_source(Stage::Raygen).0)
        .expect("an index past the end is expressed");
    let words = compile_stage(
        &glsl,
        Stage::Raygen,
        false,
        PipelineApi::Khr,
        ShaderBody::Full,
    )
    .expect("compiles");
    let mut insts = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let n = (words[i] >> 16).max(1) as usize;
        insts.push(&words[i..(i + n).min(words.len())]);
        i += n;
    }
    let op = |inst: &[u32]| inst[0] & 0xFFFF;
    assert!(
        !insts
            .iter()
            .any(|inst| op(inst) == 71 && inst.len() == 4 && inst[2] == 1 && inst[3] >= 100),
        "a fixed specialisation constant is left"
    );
    let past: Vec<u32> = insts
        .iter()
        .filter(|inst| op(inst) == 43 && inst.len() == 4 && inst[3] == PAST)
        .map(|inst| inst[2])
        .collect();
    assert!(!past.is_empty(), "no constant {PAST}");
    assert!(
        insts
            .iter()
            .any(|inst| op(inst) == 65 && inst.len() > 4 && past.contains(&inst[4])),
        "no access chain indexes with {PAST}"
    );
}
