//! Throughput on lavapipe: invalid cases per second (recorded under the layer, dropped, never submitted)
//! and valid cases per second (recorded, submitted, read back), at small launch sizes, in one process
//! with the device, pipelines and scene cached as in `rtconf run`.

use harness::{execute, Driver, Executor, Status};
use model::call::{Address, Call, StridedRegion, TraceRaysIndirect};
use model::case::{Case, Intent};
use model::flags::BufferUsage;
use model::world::*;
use std::time::{Duration, Instant};

fn case(miss_stride: u64, width: u32) -> Case {
    let at = |b: &str, o| Address::InBuffer {
        buffer: b.into(),
        offset: o,
    };
    let records = |offset, handles: Vec<HandleRef>| Contents::ShaderRecords {
        offset,
        stride: 32,
        handles,
    };
    let ray = |target, miss_index| TraceRay {
        target,
        sbt_offset: 0,
        sbt_stride: 0,
        miss_index,
        cull_mask: 0xff,
        ray_flags: 0,
    };
    let world = World {
        device: DeviceState {
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
        },
        buffers: vec![
            Buffer {
                name: "sbt".into(),
                size: 256,
                usage: BufferUsage::SHADER_BINDING_TABLE_BIT_KHR
                    | BufferUsage::SHADER_DEVICE_ADDRESS_BIT,
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
                    width,
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
                ray(RayTarget::Nothing, 1),
            ],
            callables: vec![],
            extra_recursion: 0,
        },
        resources: Default::default(), // issue 4
    };
    let valid = miss_stride % 16 == 0;
    Case {
        name: format!("bench-{miss_stride}-{width}"),
        profile: "lavapipe".into(),
        seed: None,
        intent: if valid {
            Intent::Valid
        } else {
            Intent::Violates {
                vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
                also: vec![],
            }
        },
        world,
        call: Call::TraceRaysIndirect(TraceRaysIndirect {
            raygen: StridedRegion {
                address: at("sbt", 0),
                stride: 32,
                size: 32,
            },
            miss: StridedRegion {
                address: at("sbt", 64),
                stride: miss_stride,
                size: miss_stride * 2,
            },
            hit: StridedRegion {
                address: at("sbt", 128),
                stride: 32,
                size: 32,
            },
            callable: StridedRegion::unused(),
            indirect_address: at("indirect", 0),
        }),
    }
}

fn rate(ctx: &mut Executor, cases: &[Case], budget: Duration) -> f64 {
    let start = Instant::now();
    let mut n = 0usize;
    while start.elapsed() < budget {
        let obs = execute(&cases[n % cases.len()], ctx);
        if obs.status != Status::Ran {
            eprintln!("case did not run: {:?}", obs.status);
            std::process::exit(1);
        }
        n += 1;
    }
    n as f64 / start.elapsed().as_secs_f64()
}

fn main() {
    let mut ctx = match Executor::new(Driver::Lavapipe) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let invalid: Vec<Case> = [40, 24, 48 + 8].iter().map(|&s| case(s, 4)).collect();
    let valid: Vec<Case> = [4, 8, 16].iter().map(|&w| case(32, w)).collect();
    // Warm-up: device, pipeline and scene creation are paid once.
    for c in invalid.iter().chain(&valid) {
        execute(c, &mut ctx);
    }
    let budget = Duration::from_secs(3);
    let inv = rate(&mut ctx, &invalid, budget);
    let val = rate(&mut ctx, &valid, budget);
    println!("invalid cases/s: {inv:.0}");
    println!("valid cases/s: {val:.0}");
}
