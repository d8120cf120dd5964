//! Resource states the harness realises with what the device has, on lavapipe under the 1.3.239
//! layer: descriptor buffer pipelines (DESCRIPTOR_BUFFER_BIT_EXT) and descriptors from descriptor
//! buffers (descriptor buffer set layouts, descriptor memory written with vkGetDescriptorEXT, bound
//! with vkCmdBindDescriptorBuffersEXT and vkCmdSetDescriptorBufferOffsetsEXT). Each case runs and the
//! layer says what the triage file records of it (08115 and 08117 swapped, 02697 beside 08117, 08116
//! and 08119 unchecked); descriptor memory that is not resident is a sparse descriptor buffer with no
//! page bound. What the device's features do not allow says why.

mod common;

use common::{execute, executor, world};
use harness::Status;
use model::case::Case;

fn case(name: &str) -> Case {
    common::committed(&format!("resources/{name}.yaml"))
}

fn ran_with(c: &Case, ctx: &mut harness::Executor) -> harness::Observation {
    let obs = execute(c, ctx);
    assert_eq!(obs.status, Status::Ran, "{}: {obs:?}", c.name);
    assert_eq!(
        obs.words(),
        None,
        "{}: invalid cases are never submitted",
        c.name
    );
    obs
}

fn said(obs: &harness::Observation, text: &str) -> bool {
    obs.layer_messages.iter().any(|m| m.text.contains(text))
}

#[test]
fn a_descriptor_buffer_pipeline_with_bound_sets_is_what_the_layer_sees() {
    let mut ctx = executor();
    for name in [
        "vkCmdTraceRaysKHR-None-08115-5-0",
        "vkCmdTraceRaysIndirectKHR-None-08115-1-0",
    ] {
        let c = case(name);
        assert!(world(&mut c.clone()).resources.pipeline_descriptor_buffer);
        let obs = ran_with(&c, &mut ctx);
        // The 1.3.239 layer names the model's 08115 08117 (and the indirect call the direct call's).
        assert_eq!(
            obs.layer_vuids,
            ["VUID-vkCmdTraceRaysKHR-None-08117"],
            "{name}: {:#?}",
            obs.layer_messages
        );
        assert!(
            said(
                &obs,
                "requires a descriptor buffer but has a bound descriptor set"
            ),
            "{name}: the pipeline was created with DESCRIPTOR_BUFFER_BIT_EXT: {:#?}",
            obs.layer_messages
        );
    }
}

#[test]
fn descriptors_from_descriptor_buffers_reach_the_layer_as_placed_buffers() {
    let mut ctx = executor();
    for name in [
        "vkCmdTraceRaysKHR-None-08117-7-0",
        "vkCmdTraceRaysIndirectKHR-None-08117-3-0",
    ] {
        let c = case(name);
        let obs = ran_with(&c, &mut ctx);
        // 08117 under 1.3.239's name for it, and the sets placed by offsets taken for unbound sets.
        assert_eq!(
            obs.layer_vuids,
            [
                "VUID-vkCmdTraceRaysKHR-None-02697",
                "VUID-vkCmdTraceRaysKHR-None-08115"
            ],
            "{name}: {:#?}",
            obs.layer_messages
        );
        assert!(
            said(
                &obs,
                "requires a descriptor set but has a bound descriptor buffer"
            ),
            "{name}: the sets were placed with vkCmdSetDescriptorBufferOffsetsEXT: {:#?}",
            obs.layer_messages
        );
    }
}

#[test]
fn descriptor_buffer_contents_are_written_and_bound_under_a_descriptor_buffer_pipeline() {
    let mut ctx = executor();
    for name in [
        "vkCmdTraceRaysKHR-None-08116-6-0",
        "vkCmdTraceRaysIndirectKHR-None-08116-2-1",
    ] {
        let c = case(name);
        // The invalid descriptor is in descriptor memory, which the layer does not read: silent.
        let obs = ran_with(&c, &mut ctx);
        assert!(
            obs.layer_vuids.is_empty(),
            "{name}: {:#?}",
            obs.layer_messages
        );
        // The same memory under a plain pipeline: the layer sees the bound descriptor buffer, so the
        // silence above is the layer's, not a bind the harness left out.
        let mut plain = c.clone();
        world(&mut plain).resources.pipeline_descriptor_buffer = false;
        let obs = ran_with(&plain, &mut ctx);
        assert!(
            obs.layer_vuids
                .contains(&"VUID-vkCmdTraceRaysKHR-None-08115".to_string()),
            "{name} with a plain pipeline: {:#?}",
            obs.layer_messages
        );
    }
}

#[test]
fn descriptor_memory_that_is_not_resident_is_an_unbound_sparse_descriptor_buffer() {
    let mut ctx = executor();
    for name in [
        "vkCmdTraceRaysKHR-None-08119-2-0",
        "vkCmdTraceRaysIndirectKHR-None-08119-1-0",
    ] {
        let c = case(name);
        assert!(
            world(&mut c.clone())
                .resources
                .descriptor_memory_not_resident
        );
        // The 1.3.239 layer does not check residency (08119): silent, as triaged.
        let obs = ran_with(&c, &mut ctx);
        assert!(
            obs.layer_vuids.is_empty(),
            "{name}: {:#?}",
            obs.layer_messages
        );
    }
}

#[test]
fn descriptor_buffer_states_the_harness_cannot_build_say_why() {
    let mut ctx = executor();
    // Without the descriptorBuffer feature no descriptor buffer can be bound.
    let mut c = case("vkCmdTraceRaysKHR-None-08117-7-0");
    world(&mut c).device.features.remove("descriptorBuffer");
    match execute(&c, &mut ctx).status {
        Status::NotRealised { reason } => assert!(reason.contains("descriptorBuffer"), "{reason}"),
        other => panic!("without descriptorBuffer: {other:?}"),
    }
    // Descriptor memory that is not resident needs a sparse descriptor buffer.
    let mut c = case("vkCmdTraceRaysKHR-None-08119-2-0");
    world(&mut c)
        .device
        .features
        .remove("sparseResidencyBuffer");
    match execute(&c, &mut ctx).status {
        Status::NotRealised { reason } => {
            assert!(reason.contains("sparseResidencyBuffer"), "{reason}")
        }
        other => panic!("without sparseResidencyBuffer: {other:?}"),
    }
}
