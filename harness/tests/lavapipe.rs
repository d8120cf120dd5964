//! Cases run on real lavapipe under the validation layer: a valid indirect launch whose read-back words
//! equal the model's expectation, and invalid calls whose VUIDs the 1.3.239 layer reports.

mod common;

use common::{at, valid_case};
use harness::{execute, Driver, Executor, Status};
use model::call::Call;
use model::case::{Case, Intent};

fn executor() -> Executor {
    Executor::new(Driver::Lavapipe).expect("lavapipe and the validation layer are installed by scripts/setup.sh")
}

/// Runs `case` and checks the status, the layer's VUIDs and, for valid cases, the words against the model.
fn check(ctx: &mut Executor, case: &Case, expect_vuids: &[&str]) {
    let obs = execute(case, ctx);
    assert_eq!(obs.status, Status::Ran, "{}: {:?}", case.name, obs);
    assert_eq!(obs.layer_vuids, expect_vuids, "{}: {:#?}", case.name, obs.layer_messages);
    if matches!(case.intent, Intent::Valid) {
        let expected = model::semantics::expected_launch(&case.world, &case.call).expect("dimensions are known");
        assert_eq!(obs.output.as_deref(), Some(expected.words.as_slice()), "{}", case.name);
    } else {
        assert_eq!(obs.output, None, "{}: invalid cases are never submitted", case.name);
    }
}

#[test]
fn valid_indirect_launch_writes_what_the_model_expects() {
    let mut ctx = executor();
    let case = valid_case();
    check(&mut ctx, &case, &[]);
    // The expected words themselves: id % 3 == 0 hits group 3, 1 misses into group 1, 2 into group 2.
    let obs = execute(&case, &mut ctx);
    let h = model::semantics::HIT_TAG;
    let m = model::semantics::MISS_TAG;
    assert_eq!(obs.output.unwrap(), vec![h | 3, m | 1, m | 2, h | 3, m | 1, m | 2, h | 3, m | 1]);
}

#[test]
fn miss_stride_not_a_multiple_of_the_handle_alignment_is_reported() {
    let mut ctx = executor();
    let mut case = valid_case();
    let Call::TraceRaysIndirect(c) = &mut case.call else { unreachable!() };
    c.miss.stride = 40;
    c.miss.size = 80;
    case.intent = Intent::Violates { vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(), also: vec![] };
    check(&mut ctx, &case, &["VUID-vkCmdTraceRaysIndirectKHR-stride-03686"]);
}

#[test]
fn indirect_address_not_a_multiple_of_four_is_reported() {
    let mut ctx = executor();
    let mut case = valid_case();
    let Call::TraceRaysIndirect(c) = &mut case.call else { unreachable!() };
    c.indirect_address = at("indirect", 2);
    case.intent = Intent::Violates { vuid: "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634".into(), also: vec![] };
    check(&mut ctx, &case, &["VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634"]);
}

#[test]
fn a_missing_feature_is_unsupported_with_its_name() {
    let mut ctx = executor();
    let mut case = valid_case();
    case.world.device.features.insert("sparseResidencyAliased".into());
    case.world.device.extensions.insert("VK_NV_ray_tracing".into());
    let obs = execute(&case, &mut ctx);
    let Status::Unsupported { reason } = &obs.status else { panic!("{obs:?}") };
    assert!(reason.contains("VK_NV_ray_tracing"), "{reason}");
}

#[test]
fn both_violations_in_one_call_are_both_reported() {
    let mut ctx = executor();
    let mut case = valid_case();
    let Call::TraceRaysIndirect(c) = &mut case.call else { unreachable!() };
    c.miss.stride = 40;
    c.miss.size = 80;
    c.indirect_address = at("indirect", 2);
    case.intent = Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
        also: vec!["VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634".into()],
    };
    let expected = case.expected_vuids();
    let expected: Vec<&str> = expected.iter().map(String::as_str).collect();
    check(&mut ctx, &case, &expected);
    // The device, pipeline and scene were reused: a valid case right after still runs correctly.
    check(&mut ctx, &valid_case(), &[]);
}
