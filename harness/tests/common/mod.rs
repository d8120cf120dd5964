//! Hand-made cases shared by the lavapipe tests and the worker-pool tests.

use model::call::{Address, Call, StridedRegion, TraceRaysIndirect};
use model::case::{Case, Intent};
use model::flags::BufferUsage;
use model::world::*;

pub fn device() -> DeviceState {
    DeviceState {
        extensions: [
            "VK_KHR_ray_tracing_pipeline",
            "VK_KHR_acceleration_structure",
            "VK_KHR_deferred_host_operations",
        ]
        .map(String::from)
        .into(),
        features: [
            "rayTracingPipeline",
            "rayTracingPipelineTraceRaysIndirect",
            "bufferDeviceAddress",
            "accelerationStructure",
        ]
        .map(String::from)
        .into(),
    }
}

pub fn at(buffer: &str, offset: u64) -> Address {
    Address::InBuffer {
        buffer: buffer.into(),
        offset,
    }
}

/// Raygen + two miss groups + one triangle hit group; records laid out at shaderGroupBaseAlignment (32);
/// three rays (hit the triangle, miss with index 0, miss with index 1); an indirect 4x2x1 launch.
pub fn valid_case() -> Case {
    let sbt_usage =
        BufferUsage::SHADER_BINDING_TABLE_BIT_KHR | BufferUsage::SHADER_DEVICE_ADDRESS_BIT;
    let records = |offset, handles: Vec<HandleRef>| Contents::ShaderRecords {
        offset,
        stride: 32,
        handles,
    };
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
                contents: vec![Contents::TraceRaysIndirectCommand {
                    offset: 0,
                    width: 4,
                    height: 2,
                    depth: 1,
                }],
            },
        ],
        pipeline: Some(Pipeline {
            api: PipelineApi::Khr,
            flags: Default::default(),
            groups: vec![
                ShaderGroup::General {
                    stage: GeneralStage::Raygen,
                },
                ShaderGroup::General {
                    stage: GeneralStage::Miss,
                },
                ShaderGroup::General {
                    stage: GeneralStage::Miss,
                },
                ShaderGroup::TrianglesHit {
                    closest_hit: true,
                    any_hit: false,
                },
            ],
            max_recursion_depth: 1,
            dynamic_stack_size: false,
            allow_cluster_acceleration_structures: false,
        }),
        command_buffer: CommandBufferState::default(),
        launch: Launch {
            instances: vec![Instance {
                geometries: vec![GeometryKind::Triangles],
                sbt_record_offset: 0,
                mask: 0xff,
                cluster: false,
            }],
            rays: vec![
                ray(
                    RayTarget::Geometry {
                        instance: 0,
                        geometry: 0,
                    },
                    0,
                ),
                ray(RayTarget::Nothing, 0),
                ray(RayTarget::Nothing, 1),
            ],
            callables: vec![],
            extra_recursion: 0,
        },
        resources: Default::default(), // issue 4
    };
    let call = Call::TraceRaysIndirect(TraceRaysIndirect {
        raygen: StridedRegion {
            address: at("sbt", 0),
            stride: 32,
            size: 32,
        },
        miss: StridedRegion {
            address: at("sbt", 64),
            stride: 32,
            size: 64,
        },
        hit: StridedRegion {
            address: at("sbt", 128),
            stride: 32,
            size: 32,
        },
        callable: StridedRegion::unused(),
        indirect_address: at("indirect", 0),
    });
    Case {
        name: "hand-made-valid".into(),
        profile: "lavapipe".into(),
        seed: None,
        intent: Intent::Valid,
        world,
        call,
    }
}

pub fn ray(target: RayTarget, miss_index: u32) -> TraceRay {
    TraceRay {
        target,
        sbt_offset: 0,
        sbt_stride: 0,
        miss_index,
        cull_mask: 0xff,
        ray_flags: 0,
    }
}

/// The valid case with its miss stride broken (40 is not a multiple of shaderGroupHandleAlignment 16).
#[allow(dead_code)] // used by the worker tests only
pub fn bad_miss_stride_case() -> Case {
    let mut case = valid_case();
    case.name = "bad-miss-stride".into();
    if let Call::TraceRaysIndirect(c) = &mut case.call {
        c.miss.stride = 40;
        c.miss.size = 80;
    }
    case.intent = Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
        also: vec![],
    };
    case
}

/// A direct 3x2x1 launch whose raygen executes callable records 1 and 0 and whose closest-hit traces its ray
/// twice more (extra_recursion 2, maxPipelineRayRecursionDepth 3): raygen, miss, triangle hit, two callable
/// groups; rays hit the triangle, miss with index 0, miss with index 1.
#[allow(dead_code)] // used by the lavapipe tests only
pub fn recursive_callable_case() -> Case {
    let mut case = valid_case();
    case.name = "hand-made-callables-recursion".into();
    let w = &mut case.world;
    w.buffers[0].contents.push(Contents::ShaderRecords {
        offset: 192,
        stride: 32,
        handles: vec![HandleRef::Group(4), HandleRef::Group(5)],
    });
    let p = w.pipeline.as_mut().expect("the valid case has a pipeline");
    p.groups.push(ShaderGroup::General {
        stage: GeneralStage::Callable,
    });
    p.groups.push(ShaderGroup::General {
        stage: GeneralStage::Callable,
    });
    p.max_recursion_depth = 3;
    w.launch.callables = vec![1, 0];
    w.launch.extra_recursion = 2;
    let Call::TraceRaysIndirect(c) = &case.call else {
        unreachable!()
    };
    case.call = Call::TraceRays(model::call::TraceRays {
        raygen: c.raygen.clone(),
        miss: c.miss.clone(),
        hit: c.hit.clone(),
        callable: StridedRegion {
            address: at("sbt", 192),
            stride: 32,
            size: 64,
        },
        width: 3,
        height: 2,
        depth: 1,
    });
    case
}
