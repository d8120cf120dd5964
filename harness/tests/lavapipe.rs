//! Cases run on real lavapipe under the validation layer: valid launches (indirect; with callables and
//! recursion; with dynamic stack size; with sparse buffers) whose read-back words equal the model's
//! expectation, invalid calls whose VUIDs the 1.3.239 layer reports, memory bindings the harness
//! cannot realise validly reported as unsupported with the VUID that forbids them, a pool of a
//! family without compute unsupported for lavapipe's one family, and calls into a command buffer made
//! invalid (primary and secondary) reported by the layer.

mod common;

use common::{at, body, call, execute, executor, recursive_callable_case, valid_case, world};
use harness::{Executor, Status};
use model::call::Call;
use model::case::{Case, Intent};
use model::flags::BufferCreate;
use model::tracer::record::RayRecord;
use model::world::MemoryBinding;

/// Gives the miss table stride 40, not a multiple of shaderGroupHandleAlignment (16).
fn break_miss_stride(case: &mut Case) {
    let Call::TraceRaysIndirect(c) = call(case) else {
        unreachable!()
    };
    c.miss.stride = 40;
    c.miss.size = 80;
}

const INDIRECT_03634: &str = "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634";

/// Moves the indirect address 2 bytes off its 4-byte alignment and declares the case invalid for it.
fn misalign_indirect_address(case: &mut Case) {
    let Call::TraceRaysIndirect(c) = call(case) else {
        unreachable!()
    };
    c.indirect_address = at("indirect", 2);
    case.intent = Intent::Violates {
        vuid: INDIRECT_03634.into(),
        also: vec![],
    };
}

/// Runs `case` and checks the status, the layer's VUIDs and, for valid cases, the words against the model.
fn check(ctx: &mut Executor, case: &Case, expect_vuids: &[&str]) {
    let obs = execute(case, ctx);
    assert_eq!(obs.status, Status::Ran, "{}: {:?}", case.name, obs);
    assert_eq!(
        obs.layer_vuids, expect_vuids,
        "{}: {:#?}",
        case.name, obs.layer_messages
    );
    if matches!(case.intent, Intent::Valid) {
        common::assert_records(case, &obs);
    } else {
        assert_eq!(
            obs.words(),
            None,
            "{}: invalid cases are never submitted",
            case.name
        );
    }
}

#[test]
fn valid_indirect_launch_writes_what_the_model_expects() {
    let mut ctx = executor();
    let case = valid_case();
    check(&mut ctx, &case, &[]);
    // The records themselves: id % 3 == 0 hits group 3, 1 misses into group 1, 2 into group 2.
    let obs = execute(&case, &mut ctx);
    let (h, m) = (RayRecord::HIT, RayRecord::MISS);
    assert_eq!(
        common::outcomes(&obs),
        vec![
            (h, 3),
            (m, 1),
            (m, 2),
            (h, 3),
            (m, 1),
            (m, 2),
            (h, 3),
            (m, 1)
        ]
    );
}

#[test]
fn miss_stride_not_a_multiple_of_the_handle_alignment_is_reported() {
    let mut ctx = executor();
    let mut case = valid_case();
    break_miss_stride(&mut case);
    case.intent = Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
        also: vec![],
    };
    check(
        &mut ctx,
        &case,
        &["VUID-vkCmdTraceRaysIndirectKHR-stride-03686"],
    );
}

#[test]
fn indirect_address_not_a_multiple_of_four_is_reported() {
    let mut ctx = executor();
    let mut case = valid_case();
    misalign_indirect_address(&mut case);
    check(&mut ctx, &case, &[INDIRECT_03634]);
}

#[test]
fn a_missing_extension_is_unsupported_naming_what_the_device_lacks() {
    let mut ctx = executor();
    let mut case = valid_case();
    world(&mut case)
        .device
        .features
        .insert("sparseResidencyAliased".into());
    world(&mut case)
        .device
        .extensions
        .insert("VK_NV_ray_tracing".into());
    let obs = execute(&case, &mut ctx);
    let Status::Unsupported { reason, lacks } = &obs.status else {
        panic!("{obs:?}")
    };
    assert!(reason.contains("VK_NV_ray_tracing"), "{reason}");
    assert_eq!(
        lacks,
        &harness::observe::DeviceLack::Extension("VK_NV_ray_tracing".into())
    );
}

#[test]
fn both_violations_in_one_call_are_both_reported() {
    let mut ctx = executor();
    let mut case = valid_case();
    break_miss_stride(&mut case);
    misalign_indirect_address(&mut case);
    case.intent = Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
        also: vec![INDIRECT_03634.into()],
    };
    let expected = case.expected_vuids();
    let expected: Vec<&str> = expected.iter().map(String::as_str).collect();
    check(&mut ctx, &case, &expected);
    // The device, pipeline and scene were reused: a valid case right after still runs correctly.
    check(&mut ctx, &valid_case(), &[]);
}

#[test]
fn callables_and_extra_recursion_run_silently_and_as_the_model_expects() {
    let mut ctx = executor();
    let case = recursive_callable_case();
    let depth = body(&case).world.launch.recursion_depth();
    assert_eq!(depth, 3, "the closest-hit traces twice more");
    assert!(
        depth
            <= body(&case)
                .world
                .pipeline
                .as_ref()
                .unwrap()
                .max_recursion_depth
    );
    let obs = execute(&case, &mut ctx);
    assert_eq!(obs.status, Status::Ran, "{obs:?}");
    assert!(
        obs.layer_messages.is_empty(),
        "no layer message at all: {:#?}",
        obs.layer_messages
    );
    common::assert_records(&case, &obs);
    // The nested traces use their own payload: the outer record is still the first closest-hit's.
    let (h, m) = (RayRecord::HIT, RayRecord::MISS);
    assert_eq!(
        common::outcomes(&obs),
        vec![(h, 3), (m, 1), (m, 2), (h, 3), (m, 1), (m, 2)]
    );
}

#[test]
fn a_dynamic_stack_size_gets_the_pipelines_default_and_runs() {
    let mut ctx = executor();
    let mut case = recursive_callable_case();
    case.name = "dynamic-stack".into();
    world(&mut case)
        .pipeline
        .as_mut()
        .unwrap()
        .dynamic_stack_size = true;
    world(&mut case).command_buffer.stack_size_set = true;
    check(&mut ctx, &case, &[]);
}

#[test]
fn a_non_sparse_unbound_buffer_is_not_realised_naming_02600() {
    let mut ctx = executor();
    let mut case = valid_case();
    world(&mut case).buffers[1].memory = MemoryBinding::Unbound;
    let obs = execute(&case, &mut ctx);
    let Status::NotRealised { reason } = &obs.status else {
        panic!("{obs:?}")
    };
    assert!(
        reason.contains("VUID-VkBufferDeviceAddressInfo-buffer-02600"),
        "{reason}"
    );
}

fn sparse(case: &mut Case, buffer: usize, memory: MemoryBinding) {
    let w = world(case);
    w.device.features.insert("sparseBinding".into());
    let b = &mut w.buffers[buffer];
    b.flags = BufferCreate::SPARSE_BINDING_BIT;
    b.memory = memory;
}

#[test]
fn a_sparse_shader_binding_table_bound_whole_runs_as_expected() {
    let mut ctx = executor();
    let mut case = valid_case();
    sparse(&mut case, 0, MemoryBinding::Whole);
    check(&mut ctx, &case, &[]);
}

#[test]
fn a_sparse_table_scattered_over_two_memory_objects_runs_as_expected() {
    let mut ctx = executor();
    let mut case = valid_case();
    // Two sparse blocks at least: the records at 0..256 stay in the first, the second block is bound to a
    // second memory object.
    world(&mut case).buffers[0].size = 1 << 17;
    sparse(&mut case, 0, MemoryBinding::Scattered);
    let obs = execute(&case, &mut ctx);
    match &obs.status {
        Status::Ran => check(&mut ctx, &case, &[]),
        // A driver whose sparse block is larger than half the buffer cannot scatter it: it says so.
        Status::NotRealised { reason } => assert!(reason.contains("sparse block"), "{reason}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_sparse_buffer_without_the_feature_enabled_is_not_realised_naming_00915() {
    let mut ctx = executor();
    let mut case = valid_case();
    sparse(&mut case, 0, MemoryBinding::Whole);
    world(&mut case).device.features.remove("sparseBinding");
    let obs = execute(&case, &mut ctx);
    let Status::NotRealised { reason } = &obs.status else {
        panic!("{obs:?}")
    };
    assert!(
        reason.contains("VUID-VkBufferCreateInfo-flags-00915"),
        "{reason}"
    );
}

#[test]
fn an_unbound_sparse_buffer_of_an_invalid_case_is_recorded_not_submitted() {
    let mut ctx = executor();
    let mut case = valid_case();
    // The indirect command lives in an unbound sparse buffer: the layer cannot see that, so the case is
    // declared invalid only by intent here; what matters is that it is realised and never submitted.
    sparse(&mut case, 1, MemoryBinding::Unbound);
    misalign_indirect_address(&mut case);
    check(&mut ctx, &case, &[INDIRECT_03634]);
}

#[test]
fn a_pool_without_compute_is_unsupported_on_lavapipe_and_leaves_its_other_cases_running() {
    let mut ctx = executor();
    let mut case = valid_case();
    let cbs = &mut world(&mut case).command_buffer;
    cbs.pool_queue = model::flags::QueueFlags::TRANSFER_BIT;
    cbs.pipeline_bound = false;
    case.intent = Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-commandBuffer-cmdpool".into(),
        also: vec!["VUID-vkCmdTraceRaysIndirectKHR-None-02700".into()],
    };
    // The plan realises it (the command buffer from a family without compute, holding the call alone);
    // lavapipe's one family has compute, so the device lacks such a family.
    let plan = harness::plan::CallPlan::of(&case, &harness::Execution::default()).expect("a plan");
    assert_eq!(
        plan.device.pool_family,
        Some(model::flags::QueueFlags::TRANSFER_BIT)
    );
    let obs = execute(&case, &mut ctx);
    let Status::Unsupported { reason, lacks } = &obs.status else {
        panic!("{obs:?}")
    };
    assert_eq!(
        lacks,
        &harness::observe::DeviceLack::QueueFamilyWithout("VK_QUEUE_COMPUTE_BIT".into())
    );
    assert!(reason.contains("1 queue family has compute"), "{reason}");
    assert!(obs.layer_vuids.is_empty(), "{obs:?}");
    // The device of the same extensions and features with the compute family only is another one.
    check(&mut ctx, &valid_case(), &[]);
}

/// The committed lavapipe profile.
fn lavapipe_profile() -> model::DeviceProfile {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    model::DeviceProfile::from_profiles_json("lavapipe", &text).expect("a profile")
}

#[test]
fn a_call_into_an_invalid_command_buffer_is_realised_and_reported_at_either_level() {
    use model::world::{CommandBufferLevel, CommandBufferLifecycle};
    let mut ctx = executor();
    for level in [CommandBufferLevel::Primary, CommandBufferLevel::Secondary] {
        let mut case = valid_case();
        case.name = format!("invalid-{level:?}");
        let cbs = &mut world(&mut case).command_buffer;
        cbs.lifecycle = CommandBufferLifecycle::Invalid;
        cbs.level = level;
        // The model's verdict: the command buffer is not recording, and nothing else.
        let rules = generator::registry::default_rules().expect("the installed registry");
        let verdict = model::rules::validate(&rules, &lavapipe_profile(), &case);
        assert_eq!(
            verdict.vuids().into_iter().collect::<Vec<_>>(),
            ["VUID-vkCmdTraceRaysIndirectKHR-commandBuffer-recording"],
            "{}",
            case.name
        );
        let obs = execute(&case, &mut ctx);
        // Realised (submitted once with ONE_TIME_SUBMIT, so invalid), not refused; the 1.3.239 layer
        // names the direct command's VUID for the indirect call (triaged as a layer mislabel).
        assert_eq!(obs.status, Status::Ran, "{}: {obs:?}", case.name);
        assert_eq!(obs.words(), None, "{}: never submitted", case.name);
        assert!(
            obs.layer_vuids.len() == 1 && obs.layer_vuids[0].ends_with("-commandBuffer-recording"),
            "{}: {:#?}",
            case.name,
            obs.layer_messages
        );
    }
    // The command buffers left invalid are begun again: a valid case right after runs correctly.
    check(&mut ctx, &valid_case(), &[]);
}
