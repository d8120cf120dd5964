//! Resource states realised on lavapipe under the 1.3.239 validation layer: the valid case with
//! descriptor sets, samplers, images, texel buffers and push constants runs silently and writes what
//! the model expects; each realised invalid case of `cases/resources` draws the targeted rule from the
//! layer (under the name the layer gives it); families the harness does not realise are unsupported
//! with a reason.

mod common;

use common::{body, execute, executor, world};
use harness::Status;
use model::case::{Case, Intent};

fn case(name: &str) -> Case {
    common::committed(&format!("resources/{name}.yaml"))
}

/// The rule's tag (`None-02691` → `02691`) as either trace command reports it.
fn reported(vuids: &[String], tag: &str) -> bool {
    vuids
        .iter()
        .any(|v| v.starts_with("VUID-vkCmdTraceRays") && v.ends_with(tag))
}

#[test]
fn valid_resource_case_runs_silently_and_writes_the_models_words() {
    let mut ctx = executor();
    let c = case("trace-indirect-valid-resources");
    assert!(!body(&c).world.resources.is_empty());
    let obs = execute(&c, &mut ctx);
    assert_eq!(obs.status, Status::Ran, "{obs:?}");
    assert!(obs.layer_vuids.is_empty(), "{:#?}", obs.layer_messages);
    common::assert_records(&c, &obs);
}

#[test]
fn realised_invalid_cases_draw_their_rule_from_the_layer() {
    let mut ctx = executor();
    // Format features, Unknown formats, view type and numeric type, filters, depth comparison, push
    // constants: the layer checks each at record time (naming vkCmdTraceRaysKHR for the indirect call).
    for (name, tag) in [
        ("vkCmdTraceRaysIndirectKHR-None-02691-4-0", "-02691"),
        ("vkCmdTraceRaysIndirectKHR-OpTypeImage-07027-4-0", "-07027"),
        ("vkCmdTraceRaysIndirectKHR-OpTypeImage-07028-4-0", "-07028"),
        ("vkCmdTraceRaysIndirectKHR-OpTypeImage-07029-4-0", "-07029"),
        ("vkCmdTraceRaysIndirectKHR-OpTypeImage-07030-4-0", "-07030"),
        ("vkCmdTraceRaysIndirectKHR-viewType-07752-4-0", "-07752"),
        ("vkCmdTraceRaysIndirectKHR-format-07753-4-0", "-07753"),
        ("vkCmdTraceRaysIndirectKHR-magFilter-04553-4-0", "-04553"),
        ("vkCmdTraceRaysIndirectKHR-mipmapMode-04770-4-0", "-04770"),
        ("vkCmdTraceRaysIndirectKHR-None-06479-4-0", "-06479"),
        ("vkCmdTraceRaysIndirectKHR-maintenance4-06425-4-0", "-06425"),
    ] {
        let c = case(name);
        assert!(matches!(c.intent, Intent::Violates { .. }));
        let obs = execute(&c, &mut ctx);
        assert_eq!(obs.status, Status::Ran, "{name}: {obs:?}");
        assert!(
            reported(&obs.layer_vuids, tag),
            "{name}: the layer reported {:?}",
            obs.layer_vuids
        );
        assert_eq!(
            obs.words(),
            None,
            "{name}: invalid cases are never submitted"
        );
    }
}

#[test]
fn narrow_texel_writes_reach_the_layer_as_narrow() {
    // The model's 04115 case writes a 3-component texel through a known-format image; the layer checks
    // the component count only for Unknown-format images, so the same write with format Unknown must
    // draw 04115 — which shows the harness's patched OpImageWrite carries 3 components.
    let mut ctx = executor();
    let mut c = case("vkCmdTraceRaysIndirectKHR-None-04115-4-0");
    let narrow = world(&mut c).resources.stages[0]
        .accesses
        .iter_mut()
        .find(|a| a.texel_components.is_some_and(|k| k < 4))
        .expect("a narrow write");
    narrow
        .image
        .as_mut()
        .expect("an image access")
        .format_unknown = true;
    let obs = execute(&c, &mut ctx);
    assert_eq!(obs.status, Status::Ran, "{obs:?}");
    assert!(
        reported(&obs.layer_vuids, "-04115"),
        "{:?}",
        obs.layer_vuids
    );
}

#[test]
fn push_constants_unset_after_a_case_that_pushed() {
    // The command buffer is reused across cases: a push recorded by an earlier case must not count.
    let mut ctx = executor();
    let mut pushed = case("trace-indirect-valid-resources");
    world(&mut pushed).resources.pushes = vec![model::resources::Push {
        layout: "pl".into(),
        offset: 0,
        size: 16,
    }];
    world(&mut pushed).resources.stages[0].push_constants = Some([0, 16]);
    let obs = execute(&pushed, &mut ctx);
    assert_eq!(obs.status, Status::Ran, "{obs:?}");
    assert!(obs.layer_vuids.is_empty(), "{:#?}", obs.layer_messages);
    let obs = execute(
        &case("vkCmdTraceRaysIndirectKHR-maintenance4-06425-4-0"),
        &mut ctx,
    );
    assert!(
        reported(&obs.layer_vuids, "-06425"),
        "{:?}",
        obs.layer_vuids
    );
}

#[test]
fn families_the_harness_does_not_realise_say_so() {
    let mut ctx = executor();
    let name = "vkCmdTraceRaysIndirectKHR-None-08117-4-0";
    let obs = execute(&case(name), &mut ctx);
    match &obs.status {
        Status::NotRealised { reason } => {
            assert!(reason.contains("descriptor buffers"), "{name}: {reason}")
        }
        other => panic!("{name}: {other:?}"),
    }
}
