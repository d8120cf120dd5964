//! Inputs that once crashed the model or made it allocate from a size they state (found by fuzzing,
//! kept under `tests/hostile/`): each is read and judged as `rtconf check` and `rtconf run` do — the
//! verdict, the undefined-reads gate, the expected launch, the build's primitives and its traced check —
//! within a bounded address space, and finishes with a verdict or a located error, never a panic or an
//! abort.

use model::{Case, DeviceProfile, RuleSet};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The address space every test of this binary runs in: far below the sizes the inputs state (100 GB,
/// u64::MAX, a word per one of 34 billion invocations), far above what judging a case needs.
const ADDRESS_SPACE: u64 = 6 << 30;

fn bounded() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let limit = libc::rlimit {
            rlim_cur: ADDRESS_SPACE,
            rlim_max: libc::RLIM_INFINITY,
        };
        // SAFETY: setrlimit with a valid struct; it only lowers this process's soft limit.
        let rc = unsafe { libc::setrlimit(libc::RLIMIT_AS, &limit) };
        assert_eq!(rc, 0, "setrlimit(RLIMIT_AS)");
    });
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn hostile(name: &str) -> (String, String) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/hostile")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    (path.display().to_string(), text)
}

fn rules() -> &'static RuleSet {
    static RULES: OnceLock<RuleSet> = OnceLock::new();
    RULES.get_or_init(|| {
        let set = vk_registry::source::load_vuids(Path::new("/usr/share/vulkan/registry")).unwrap();
        RuleSet::from_vuids(&set)
    })
}

fn lavapipe() -> DeviceProfile {
    let text = std::fs::read_to_string(root().join("profiles/lavapipe.json")).unwrap();
    DeviceProfile::from_profiles_json("lavapipe", &text).unwrap()
}

/// What the model computes from a case on its way to and from a driver; returns the verdict's VUIDs.
fn judge_everything(case: &Case, profile: &DeviceProfile) -> Vec<String> {
    let verdict = model::validate(rules(), profile, case);
    let _ = case.runnable(profile);
    let _ = case.runs_as_valid(profile);
    if let Some(t) = case.as_trace() {
        if let Some(e) = model::semantics::expected_launch(&t.world, &t.call) {
            let last = e.invocations().saturating_sub(1);
            let _ = e.ray_of(usize::try_from(last).unwrap_or(usize::MAX));
        }
    }
    if let Some(a) = case.as_accel() {
        let _ = model::accel::indirect_build(&a.world, &a.call);
        if let Ok(check) = model::accel::check::BuildCheck::of(a) {
            let misses: Vec<u32> = check
                .rays
                .iter()
                .flat_map(|_| model::tracer::record::RayRecord::miss(1).to_words())
                .collect();
            let _ = model::accel::check::deviation(a, &misses);
        }
    }
    verdict.vuids().into_iter().map(String::from).collect()
}

/// Reads and judges one hostile case on lavapipe's profile; returns its verdict.
fn check(name: &str) -> Vec<String> {
    bounded();
    let (path, text) = hostile(name);
    let case = Case::from_yaml(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    judge_everything(&case, &lavapipe())
}

#[test]
fn a_storage_buffer_of_u64_max_bytes_is_judged_without_allocating_it() {
    // The build is otherwise valid: only the device's missing indirect build is reported.
    assert_eq!(
        check("build-storage-size-u64-max.yaml"),
        ["VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650"]
    );
}

#[test]
fn a_scratch_buffer_of_100_gb_is_judged_without_allocating_it() {
    assert_eq!(
        check("build-scratch-size-100-gb.yaml"),
        ["VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650"]
    );
}

#[test]
fn range_records_at_a_stride_of_u64_max_lie_past_the_buffer() {
    let v = check("build-range-records-stride-u64-max.yaml");
    assert!(
        v.iter()
            .any(|v| v.contains("accelerationStructureIndirectBuild-03650")),
        "{v:?}"
    );
}

#[test]
fn a_vertex_stride_of_u64_max_reads_past_the_address_space_without_overflow() {
    let (path, text) = hostile("build-vertex-stride-u64-max.yaml");
    bounded();
    let case = Case::from_yaml(&path, &text).unwrap();
    let a = case.as_accel().unwrap();
    let e = model::accel::indirect_build(&a.world, &a.call).unwrap_err();
    assert!(
        e.problem.contains("past the end") || e.problem.contains("outside"),
        "{e}"
    );
    judge_everything(&case, &lavapipe());
}

#[test]
fn pointers_and_vertex_data_at_offset_u64_max_are_judged() {
    for name in [
        "build-pointer-target-offset-u64-max.yaml",
        "build-vertex-data-offset-u64-max.yaml",
    ] {
        let v = check(name);
        assert!(!v.is_empty(), "{name}: {v:?}");
    }
}

#[test]
fn a_structure_at_offset_u64_max_is_judged_by_the_overlap_rules() {
    let v = check("build-structure-offset-u64-max-overlap.yaml");
    assert!(!v.is_empty(), "{v:?}");
}

#[test]
fn four_billion_primitives_at_stride_0_are_refused_by_the_model_not_built() {
    let (path, text) = hostile("build-primitive-count-u32-max-stride-0.yaml");
    bounded();
    let case = Case::from_yaml(&path, &text).unwrap();
    let a = case.as_accel().unwrap();
    let e = model::accel::indirect_build(&a.world, &a.call).unwrap_err();
    assert!(e.problem.contains("more than the model builds"), "{e}");
    assert!(model::accel::check::check_rays(a).is_none());
    // The rules judge it as the case declares; run as valid, it has no meaning to check the device
    // against: not runnable, at the range record that states the count.
    let v = judge_everything(&case, &lavapipe());
    assert_eq!(v, case.expected_vuids());
    let why = case.runnable(&lavapipe()).unwrap_err();
    assert_eq!(why.at, "world.buffers[1].contents[0].ranges[0]");
    assert!(why.to_string().contains("4294967295 primitives"), "{why}");
}

#[test]
fn an_indirect_launch_of_34_billion_invocations_has_one_outcome_set_per_ray() {
    let (path, text) = hostile("trace-indirect-dimensions-34-billion-invocations.yaml");
    bounded();
    let case = Case::from_yaml(&path, &text).unwrap();
    let t = case.as_trace().unwrap();
    let e = model::semantics::expected_launch(&t.world, &t.call).unwrap();
    assert_eq!(e.invocations(), 4294967295 * 8);
    assert_eq!(e.allowed.len(), t.world.launch.rays.len());
    assert_eq!(e.ray_of(3), e.ray_of(0), "launch ID 3 traces ray 0 again");
    let v = judge_everything(&case, &lavapipe());
    assert!(
        v.iter().any(|v| v.contains("maxRayDispatchInvocationCount")
            || v.contains("-03")
            || v.contains("-04")),
        "the dispatch limit is exceeded: {v:?}"
    );
}

#[test]
fn an_indirect_launch_of_u32_max_cubed_passes_every_limit_without_overflow() {
    let v = check("trace-indirect-dimensions-u32-max.yaml");
    assert!(!v.is_empty(), "{v:?}");
}

#[test]
fn a_miss_stride_of_u64_max_is_judged() {
    let v = check("trace-miss-stride-u64-max.yaml");
    assert!(!v.is_empty(), "{v:?}");
}

#[test]
fn a_declared_access_at_offset_u64_max_is_reported_without_overflow() {
    let v = check("trace-declared-access-offset-u64-max.yaml");
    assert!(!v.is_empty(), "{v:?}");
}

#[test]
fn extra_recursion_of_u32_max_passes_the_pipeline_limit_without_overflow() {
    let v = check("trace-extra-recursion-u32-max.yaml");
    assert!(
        v.iter()
            .any(|v| v.contains("03636") || v.contains("Recursion") || v.contains("recursion")),
        "{v:?}"
    );
}

#[test]
fn a_second_yaml_document_is_a_located_error() {
    bounded();
    for name in ["trace-two-documents.yaml", "build-two-documents.yaml"] {
        let (path, text) = hostile(name);
        let e = Case::from_yaml(&path, &text).unwrap_err();
        let second = text
            .lines()
            .position(|l| l == "---")
            .map(|i| i + 1)
            .unwrap();
        assert_eq!(e.location, Some((second, 1)), "{name}: {e}");
        assert!(
            e.to_string().starts_with(&format!("{path}:{second}:1: ")),
            "{e}"
        );
    }
}

/// A handle size no uint32_t holds: the profile reader refuses the file at the member's path; a
/// profile made in code with that size still gets every hand case judged, without a panic.
#[test]
fn a_profile_with_a_handle_size_of_u64_max_judges_the_hand_cases() {
    bounded();
    let (path, text) = hostile("profile-shader-group-handle-size-u64-max.json");
    let e = DeviceProfile::from_profiles_json(&path, &text).unwrap_err();
    assert!(
        e.location.ends_with(
            ".properties.VkPhysicalDeviceRayTracingPipelinePropertiesKHR.shaderGroupHandleSize"
        ) && e.problem == "18446744073709551615 is not a uint32_t",
        "{e}"
    );
    let handle_size = "\"shaderGroupHandleSize\": 18446744073709551615";
    assert!(text.contains(handle_size));
    let mut profile = DeviceProfile::from_profiles_json(
        &path,
        &text.replace(handle_size, "\"shaderGroupHandleSize\": 32"),
    )
    .unwrap();
    profile.properties.insert(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleSize".into(),
        model::profile::PropertyValue::Int(u64::MAX),
    );
    assert_eq!(profile.limit("shaderGroupHandleSize"), Some(u64::MAX));
    for case in [
        "cases/hand/trace-indirect-records-32.yaml",
        "cases/build/aabbs-valid.yaml",
    ] {
        let p = root().join(case);
        let c = Case::from_yaml(case, &std::fs::read_to_string(p).unwrap()).unwrap();
        judge_everything(&c, &profile);
        if c.as_trace().is_some() {
            let reads = c.runnable(&profile).unwrap_err().reads;
            assert!(reads.iter().any(|r| r.contains("past")), "{reads:?}");
        }
    }
}

#[test]
fn a_sparse_image_reads_what_was_written_last_and_zero_elsewhere() {
    let mut img = model::accel::world::SparseImage::new(u64::MAX);
    img.write(10, &[1, 2, 3, 4]);
    img.write(12, &[9, 9, 9]);
    img.write(u64::MAX - 2, &[7, 7, 7, 7]);
    assert_eq!(img.read(8, 8), Some(vec![0, 0, 1, 2, 9, 9, 9, 0]));
    assert_eq!(img.read(u64::MAX - 3, 3), Some(vec![0, 7, 7]));
    assert_eq!(
        img.read(u64::MAX - 1, 2),
        None,
        "the last byte is past the end"
    );
    let runs: Vec<(u64, Vec<u8>)> = img.runs().map(|(a, b)| (a, b.to_vec())).collect();
    assert_eq!(
        runs,
        [(10, vec![1, 2, 9, 9, 9]), (u64::MAX - 2, vec![7, 7])],
        "touching runs are one"
    );
    // The same bytes written in other pieces are the same image.
    let mut pieces = model::accel::world::SparseImage::new(u64::MAX);
    pieces.write(13, &[9, 9]);
    pieces.write(10, &[1, 2, 9]);
    pieces.write(u64::MAX - 2, &[7, 7]);
    assert_eq!(pieces, img);
}

#[test]
fn flow_collections_nested_past_the_limit_are_refused_at_once_with_their_place() {
    // The YAML scanner's time grows with the square of flow nesting (50,000 levels took half a
    // minute): the readers refuse such input before a parse runs to its end.
    let deep = format!("name: x\nworld: {}\n", "{a: ".repeat(50_000));
    let started = std::time::Instant::now();
    let e = model::Case::from_yaml("deep.yaml", &deep).unwrap_err();
    assert!(
        started.elapsed().as_secs_f64() < 1.0,
        "{:?}",
        started.elapsed()
    );
    let limit = model::case::MAX_FLOW_NESTING;
    assert_eq!(e.location, Some((2, 8 + 4 * limit)), "{e}");
    assert!(e.problem.contains("nested deeper than"), "{e}");
    // Brackets inside quoted scalars and comments are text, not nesting.
    let quoted = format!("a: '{0}'\nb: \"{0}\" # {0}\n", "[".repeat(2 * limit));
    assert_eq!(model::case::flow_nesting_past(&quoted, limit), None);
    assert_eq!(
        model::case::flow_nesting_past(&"[".repeat(limit), limit),
        None
    );
    // An unclosed bracket of a plain scalar does not carry over to the next lines.
    let ranges = "reason: bytes [61, 65) of a range\n".repeat(2 * limit);
    assert_eq!(model::case::flow_nesting_past(&ranges, limit), None);
    // What a count of brackets outside quotes misses, the parser's own reading finds: a quote inside
    // a plain word or after one (text, not a quoted scalar), a quote in a block scalar's text, and
    // nesting spread over lines, each as slow to scan as nesting on one line.
    let levels = 20_000;
    let hidden = [
        (
            format!("en\"try{{a: {}\n", "{a: ".repeat(levels)),
            (1, 11 + 4 * limit),
        ),
        (format!("a \"b: {}\n", "[".repeat(levels)), (1, 7 + limit)),
        (
            format!("reason: |\n  \"\nwhen: {}\n", "[".repeat(levels)),
            (3, 7 + limit),
        ),
        (format!("when:\n{}", "  [\n".repeat(levels)), (2 + limit, 3)),
    ];
    for (text, at) in hidden {
        let started = std::time::Instant::now();
        assert_eq!(
            model::case::flow_nesting_past(&text, limit),
            Some(at),
            "{}",
            &text[..40]
        );
        assert!(
            started.elapsed().as_secs_f64() < 1.0,
            "{:?}",
            started.elapsed()
        );
    }
}

/// The first push constant byte a stage reads that no compatible push set, with the VUID and the
/// problem the model reports for it (the stage reads bytes no push covers; maintenance4 is off).
fn unpushed_byte(name: &str) -> Vec<(String, String)> {
    bounded();
    let (path, text) = hostile(name);
    let case = Case::from_yaml(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        judge_everything(&case, &lavapipe()),
        ["VUID-vkCmdTraceRaysIndirectKHR-maintenance4-06425"]
    );
    model::validate(rules(), &lavapipe(), &case)
        .violations
        .iter()
        .map(|v| (v.context.clone(), v.problem.clone()))
        .collect()
}

#[test]
fn push_constants_read_at_offset_u32_max_are_judged_without_overflow() {
    // Bytes [u32::MAX, u32::MAX + 16) are read; the one push, [0, 16), was made with a layout not
    // compatible with the pipeline's.
    let v = unpushed_byte("trace-push-constants-offset-u32-max.yaml");
    assert_eq!(v.len(), 1, "{v:?}");
    assert_eq!(v[0].0, "world.resources.stages[Raygen].push-constants");
    assert!(v[0].1.starts_with("byte 4294967295 is used"), "{v:?}");
}

#[test]
fn push_constants_of_u32_max_bytes_find_the_gap_between_pushes_at_once() {
    // Bytes [0, u32::MAX) are read; pushes cover [0, 2^31) and [u32::MAX, 2 * u32::MAX): byte 2^31
    // is the first no push covers.
    let v = unpushed_byte("trace-push-constants-size-u32-max.yaml");
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(v[0].1.starts_with("byte 2147483648 is used"), "{v:?}");
}
