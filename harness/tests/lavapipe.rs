//! Cases run on real lavapipe under the validation layer: a valid indirect launch whose read-back words
//! equal the model's expectation, and invalid calls whose VUIDs the 1.3.239 layer reports.

use harness::{execute, Driver, Executor, Status};
use model::call::{Address, Call, StridedRegion, TraceRaysIndirect};
use model::case::{Case, Intent};
use model::flags::BufferUsage;
use model::world::*;

fn device() -> DeviceState {
    DeviceState {
        extensions: ["VK_KHR_ray_tracing_pipeline", "VK_KHR_acceleration_structure", "VK_KHR_deferred_host_operations"]
            .map(String::from)
            .into(),
        features: ["rayTracingPipeline", "rayTracingPipelineTraceRaysIndirect", "bufferDeviceAddress", "accelerationStructure"]
            .map(String::from)
            .into(),
    }
}

fn at(buffer: &str, offset: u64) -> Address {
    Address::InBuffer { buffer: buffer.into(), offset }
}

/// Raygen + two miss groups + one triangle hit group; records laid out at shaderGroupBaseAlignment (32);
/// three rays (hit the triangle, miss with index 0, miss with index 1); an indirect 4x2x1 launch.
fn valid_case() -> Case {
    let sbt_usage = BufferUsage::SHADER_BINDING_TABLE_BIT_KHR | BufferUsage::SHADER_DEVICE_ADDRESS_BIT;
    let records = |offset, handles: Vec<HandleRef>| Contents::ShaderRecords { offset, stride: 32, handles };
    let world = World {
        device: device(),
        buffers: vec![
            Buffer {
                name: "sbt".into(),
                size: 256,
                usage: sbt_usage,
                flags: Default::default(),
                memory: MemoryBinding::Whole,
                contents: vec![
                    records(0, vec![HandleRef::Group(0)]),
                    records(64, vec![HandleRef::Group(1), HandleRef::Group(2)]),
                    records(128, vec![HandleRef::Group(3)]),
                ],
            },
            Buffer {
                name: "indirect".into(),
                size: 64,
                usage: BufferUsage::INDIRECT_BUFFER_BIT | BufferUsage::SHADER_DEVICE_ADDRESS_BIT,
                flags: Default::default(),
                memory: MemoryBinding::Whole,
                contents: vec![Contents::TraceRaysIndirectCommand { offset: 0, width: 4, height: 2, depth: 1 }],
            },
        ],
        pipeline: Some(Pipeline {
            api: PipelineApi::Khr,
            flags: Default::default(),
            groups: vec![
                ShaderGroup::General { stage: GeneralStage::Raygen },
                ShaderGroup::General { stage: GeneralStage::Miss },
                ShaderGroup::General { stage: GeneralStage::Miss },
                ShaderGroup::TrianglesHit { closest_hit: true, any_hit: false },
            ],
            max_recursion_depth: 1,
            dynamic_stack_size: false,
        }),
        command_buffer: CommandBufferState::default(),
        launch: Launch {
            instances: vec![Instance { geometries: vec![GeometryKind::Triangles], sbt_record_offset: 0, mask: 0xff }],
            rays: vec![
                ray(RayTarget::Geometry { instance: 0, geometry: 0 }, 0),
                ray(RayTarget::Nothing, 0),
                ray(RayTarget::Nothing, 1),
            ],
            callables: vec![],
            extra_recursion: 0,
        },
    };
    let call = Call::TraceRaysIndirect(TraceRaysIndirect {
        raygen: StridedRegion { address: at("sbt", 0), stride: 32, size: 32 },
        miss: StridedRegion { address: at("sbt", 64), stride: 32, size: 64 },
        hit: StridedRegion { address: at("sbt", 128), stride: 32, size: 32 },
        callable: StridedRegion::unused(),
        indirect_address: at("indirect", 0),
    });
    Case { name: "hand-made-valid".into(), profile: "lavapipe".into(), seed: None, intent: Intent::Valid, world, call }
}

fn ray(target: RayTarget, miss_index: u32) -> TraceRay {
    TraceRay { target, sbt_offset: 0, sbt_stride: 0, miss_index, cull_mask: 0xff, ray_flags: 0 }
}

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
