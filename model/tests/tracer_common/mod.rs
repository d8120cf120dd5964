//! Helpers shared by the tracer tests: small scenes, default shader tables, one-call tracing.
#![allow(dead_code)]

use model::scene::{
    BottomLevel, Geometry, GeometryData, GeometryFlags, Ray, Scene, SceneInstance, Transform3x4,
    Triangles,
};
use model::tracer::{
    trace_ray, AllowedOutcomes, HitShaders, MissShader, Precision, PreparedScene, ShaderTable,
    TracerConfig, TracerStats,
};

pub const MISS_GROUP: u32 = 100;

pub fn tri_geometry(positions: Vec<[f32; 3]>, opaque: bool) -> Geometry {
    Geometry {
        flags: GeometryFlags {
            opaque,
            no_duplicate_any_hit: false,
        },
        data: GeometryData::Triangles(Triangles {
            positions,
            indices: None,
            transform: None,
        }),
    }
}

pub fn one_instance(bl: BottomLevel) -> Scene {
    Scene {
        bottom_levels: vec![bl],
        instances: vec![SceneInstance::of(0)],
    }
}

pub fn instance_with(transform: Transform3x4) -> SceneInstance {
    SceneInstance {
        transform,
        ..SceneInstance::of(0)
    }
}

/// The unit right triangle (0,0,0), (1,0,0), (0,1,0), opaque.
pub fn unit_triangle() -> BottomLevel {
    BottomLevel {
        geometries: vec![tri_geometry(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            true,
        )],
    }
}

/// A ray straight down (−z) onto (x, y, 0) from z = 1.
pub fn down(x: f32, y: f32) -> Ray {
    Ray::new([x, y, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
}

pub fn trace_with(
    scene: &Scene,
    ray: &Ray,
    hit: &dyn Fn(u32, u32) -> HitShaders,
    precision: Precision,
) -> AllowedOutcomes {
    let prepared = PreparedScene::new(scene).expect("a defined scene");
    let table = ShaderTable {
        hit,
        miss: MissShader {
            zero_group: false,
            group: MISS_GROUP,
        },
    };
    let config = TracerConfig::with_precision(precision);
    let mut stats = TracerStats::default();
    trace_ray(&prepared, ray, &table, &config, &mut stats).expect("a defined ray")
}

/// Traces with closest-hit group `10 * instance + geometry` everywhere.
pub fn trace(scene: &Scene, ray: &Ray) -> AllowedOutcomes {
    trace_with(
        scene,
        ray,
        &|i, g| HitShaders::closest(10 * i + g),
        Precision::F64WithExactFallback,
    )
}

/// One box [−1, 1]³ with the unit sphere in it.
pub fn sphere_scene() -> Scene {
    let bl = BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags {
                opaque: true,
                no_duplicate_any_hit: false,
            },
            data: GeometryData::Aabbs(model::scene::Aabbs {
                boxes: vec![model::scene::Aabb {
                    min: [-1.0; 3],
                    max: [1.0; 3],
                }],
                spheres: vec![model::scene::Sphere {
                    center: [0.0; 3],
                    radius: 1.0,
                }],
            }),
        }],
    };
    one_instance(bl)
}
