//! The tracer's standard workloads: deterministic scenes and camera rays (soup, closed icosphere,
//! 1e5- and 1e6-triangle grids, instanced copies, spheres in boxes), shared by the benchmark and by
//! whoever compares the tracer's rays per second with a driver's on the same scene in the same run.

use super::{
    trace_ray, AllowedOutcomes, HitShaders, MissShader, PreparedScene, ShaderTable, TracerConfig,
    TracerStats,
};
use crate::scene::build;
use crate::scene::{Ray, Scene, SceneInstance};

/// A named scene with its rays.
#[derive(Debug, Clone)]
pub struct Workload {
    pub name: &'static str,
    pub scene: Scene,
    pub rays: Vec<Ray>,
}

impl Workload {
    /// Whether every geometry of the workload is triangles.
    pub fn triangles_only(&self) -> bool {
        self.every_geometry(|d| matches!(d, crate::scene::GeometryData::Triangles(_)))
    }

    /// Whether every geometry of the workload is boxes with spheres.
    pub fn procedural_only(&self) -> bool {
        self.every_geometry(|d| matches!(d, crate::scene::GeometryData::Aabbs(_)))
    }

    /// Whether the hand-made trace case, whose pipeline has one hit group, can launch the workload
    /// ([`Workload::as_launch_of`]): one kind of geometry throughout.
    pub fn launchable(&self) -> bool {
        self.triangles_only() || self.procedural_only()
    }

    fn every_geometry(&self, kind: impl Fn(&crate::scene::GeometryData) -> bool) -> bool {
        self.scene
            .bottom_levels
            .iter()
            .all(|b| b.geometries.iter().all(|g| kind(&g.data)))
    }

    /// The workload as a launch of `case` (a vkCmdTraceRaysIndirectKHR case): its scene and rays
    /// put into the case's world and every indirect command of its buffers set to `side` x `side`;
    /// for a workload of boxes, the case's triangle hit groups become procedural ones with the same
    /// shaders and an intersection shader (the harness's, which reports each box's sphere).
    pub fn as_launch_of(&self, mut case: crate::Case, side: u32) -> crate::Case {
        if let Some(t) = case.as_trace_mut() {
            if let Some(pipeline) = t.world.pipeline.as_mut().filter(|_| self.procedural_only()) {
                for g in &mut pipeline.groups {
                    if let crate::world::ShaderGroup::TrianglesHit {
                        closest_hit,
                        any_hit,
                        any_hit_rule,
                    } = *g
                    {
                        *g = crate::world::ShaderGroup::ProceduralHit {
                            closest_hit,
                            any_hit,
                            any_hit_rule,
                            intersection: true,
                        };
                    }
                }
            }
            t.world.launch.scene = self.scene.clone();
            t.world.launch.rays = self.rays.clone();
            for b in &mut t.world.buffers {
                for c in &mut b.contents {
                    if let crate::world::Contents::TraceRaysIndirectCommand {
                        width, height, ..
                    } = c
                    {
                        *width = side;
                        *height = side;
                    }
                }
            }
        }
        case
    }
}

fn single(bl: crate::scene::BottomLevel) -> Scene {
    Scene {
        bottom_levels: vec![bl],
        instances: vec![SceneInstance::of(0)],
    }
}

/// The standard workloads with `side`×`side` camera rays each; `large` adds the 1e6-triangle grid.
pub fn standard_workloads(side: u32, large: bool) -> Vec<Workload> {
    let cam = |eye: [f64; 3], target: [f64; 3]| {
        build::pinhole_rays(side, side, eye, target, [0.0, 0.0, 1.0], 0.9)
    };
    let mut out = vec![
        Workload {
            name: "soup 10k",
            scene: single(build::triangle_soup(1, 10_000, 4.0, 0.3)),
            rays: cam([10.0, 9.0, 8.0], [0.0; 3]),
        },
        Workload {
            name: "icosphere 20k (closed)",
            scene: single(build::icosphere(5, 2.0)),
            rays: cam([5.0, 4.0, 3.0], [0.0; 3]),
        },
        Workload {
            name: "grid 1e5",
            scene: single(build::grid(224, 224, 1.0 / 32.0)),
            rays: cam([3.5, -2.0, 4.0], [3.5, 3.5, 0.0]),
        },
        Workload {
            name: "instanced 64 x 1280",
            scene: Scene {
                bottom_levels: vec![build::icosphere(3, 1.0)],
                instances: build::instanced_copies(7, 0, 64, 6.0),
            },
            rays: cam([16.0, 14.0, 12.0], [0.0; 3]),
        },
        Workload {
            name: "spheres 1000",
            scene: single(build::spheres_in_boxes(3, 1000, 5.0, 0.3)),
            rays: cam([14.0, 12.0, 10.0], [0.0; 3]),
        },
    ];
    if large {
        out.push(Workload {
            name: "grid 1e6",
            scene: single(build::grid(708, 708, 1.0 / 64.0)),
            rays: cam([5.5, -3.0, 6.0], [5.5, 5.5, 0.0]),
        });
    }
    out
}

/// The standard workload whose name starts with `name` (`side`×`side` camera rays; not the large
/// grid); panics where there is none (a caller's mistake: the names are fixed above).
pub fn standard_workload(side: u32, name: &str) -> Workload {
    standard_workloads(side, false)
        .into_iter()
        .find(|w| w.name.starts_with(name))
        .unwrap_or_else(|| panic!("no standard workload named {name}"))
}

/// The shader table of the workloads: closest-hit everywhere (procedural where needed).
pub fn workload_shaders(i: u32, g: u32) -> HitShaders {
    HitShaders::procedural(10 * i + g, None)
}

/// Traces every ray of a prepared workload; the outcomes and the counters.
pub fn run(
    prepared: &PreparedScene,
    rays: &[Ray],
    config: &TracerConfig,
) -> (Vec<AllowedOutcomes>, TracerStats) {
    let table = ShaderTable {
        hit: &workload_shaders,
        miss: MissShader {
            zero_group: false,
            group: 0,
        },
    };
    let mut stats = TracerStats::default();
    let outs = rays
        .iter()
        .map(|r| {
            trace_ray(prepared, r, &table, config, &mut stats).expect("workload rays are defined")
        })
        .collect();
    (outs, stats)
}
