//! Rendered scenes, valid by construction from `model::scene::build`: triangle soups, closed meshes
//! (subdivided icosahedra, grids and fans with shared edges), instanced copies with rotation, scale,
//! mirror and translation, boxes with spheres; valid flag, mask and cull combinations (never mutually
//! exclusive flags, never NaN or infinite rays); pinhole-camera, random and edge- or vertex-aimed
//! rays; launches from 1x1 to 256x256, most small. Scene masks use only
//! [`crate::aim::RENDERED_MASKS`], so aimed parts of a case never see them.
//!
//! The draw's first fields are the sizes (launch, instances, primitives), so proptest shrinks those
//! first.

use crate::aim::RENDERED_MASKS;
use model::scene::build::{self, SceneRng};
use model::scene::{
    BottomLevel, GeometryData, Indices, InstanceFlags, Ray, RayFlags, Scene, SceneInstance,
};
use model::tracer::AnyHitRule;
use model::world::{Camera, Launch};
use proptest::prelude::*;

/// What a rendered scene is drawn from.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneDraw {
    /// Launch width and height (the camera's, or the number of random rays).
    pub width: u32,
    pub height: u32,
    /// Instances of the bottom level (the first has the identity transform).
    pub instances: u32,
    /// Roughly how many primitives the bottom level has.
    pub primitives: u32,
    pub family: u8,
    pub rays: u8,
    pub seed: u64,
    /// Selectors: ray flags, cull mask, instance flags and masks, geometry flags, t interval,
    /// index type and geometry transform, SBT parameters, any-hit rule.
    pub ray_flags: u8,
    pub cull: u8,
    pub instance_sel: u8,
    pub geometry_sel: u8,
    pub interval: u8,
    pub layout_sel: u8,
    pub sbt_sel: u8,
    pub any_hit: u8,
}

/// The draw strategy: most launches small, a few up to 256x256; most scenes small.
pub fn draw_strategy() -> impl Strategy<Value = SceneDraw> {
    let launch = prop_oneof![
        10 => (1..=12u32, 1..=12u32),
        3 => (13..=48u32, 1..=48u32),
        1 => (64..=256u32, 64..=256u32),
    ];
    let sizes = (
        launch,
        prop_oneof![3 => Just(1u32), 2 => 2..=6u32],
        prop_oneof![4 => 1..=48u32, 1 => 49..=2000u32],
    );
    let kinds = (0..6u8, 0..4u8, any::<u64>());
    let sel = (
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
    );
    (sizes, kinds, sel).prop_map(|(s, k, x)| SceneDraw {
        width: s.0 .0,
        height: s.0 .1,
        instances: s.1,
        primitives: s.2,
        family: k.0,
        rays: k.1,
        seed: k.2,
        ray_flags: x.0,
        cull: x.1,
        instance_sel: x.2,
        geometry_sel: x.3,
        interval: x.4,
        layout_sel: x.5,
        sbt_sel: x.6,
        any_hit: x.7,
    })
}

/// Ray flag combinations that are never mutually exclusive (and need no primitive-culling feature).
const RAY_FLAGS: &[u32] = &[
    0,
    0,
    0,
    RayFlags::OPAQUE.0,
    RayFlags::NO_OPAQUE.0,
    RayFlags::TERMINATE_ON_FIRST_HIT.0,
    RayFlags::SKIP_CLOSEST_HIT_SHADER.0,
    RayFlags::CULL_BACK_FACING_TRIANGLES.0,
    RayFlags::CULL_FRONT_FACING_TRIANGLES.0,
    RayFlags::CULL_OPAQUE.0,
    RayFlags::CULL_NO_OPAQUE.0,
    RayFlags::TERMINATE_ON_FIRST_HIT.0 | RayFlags::CULL_BACK_FACING_TRIANGLES.0,
    RayFlags::NO_OPAQUE.0 | RayFlags::CULL_FRONT_FACING_TRIANGLES.0,
    RayFlags::OPAQUE.0 | RayFlags::TERMINATE_ON_FIRST_HIT.0,
];

/// The any-hit rules a rendered case's hit groups draw from.
pub const ANY_HIT_RULES: [AnyHitRule; 4] = [
    AnyHitRule::Accept,
    AnyHitRule::Ignore,
    AnyHitRule::Terminate,
    AnyHitRule::IgnoreOddPrimitives,
];

/// Whether a draw's bottom level is procedural (boxes with spheres).
pub fn is_procedural(d: &SceneDraw) -> bool {
    d.family % 6 == 4
}

/// The any-hit rule of the draw's hit groups.
pub fn any_hit_rule(d: &SceneDraw) -> Option<AnyHitRule> {
    match d.any_hit % 5 {
        4 => None,
        k => Some(ANY_HIT_RULES[k as usize]),
    }
}

fn bottom_level(d: &SceneDraw) -> (BottomLevel, Vec<[f32; 3]>) {
    let n = d.primitives.max(1);
    let seed = d.seed;
    // Points exactly on shared edges and vertices, for aimed rays (world space of instance 0).
    let mut aim_points = Vec::new();
    let bl = match d.family % 6 {
        0 => build::triangle_soup(seed, n as usize, 2.0, 0.6),
        1 => {
            let s = if n <= 20 {
                0
            } else if n <= 80 {
                1
            } else {
                2
            };
            let bl = build::icosphere(s, 1.5);
            if let GeometryData::Triangles(t) = &bl.geometries[0].data {
                aim_points.extend(t.positions.iter().take(12).copied());
            }
            bl
        }
        2 | 5 => {
            let nx = ((n as f64 / 2.0).sqrt().ceil() as u32).clamp(1, 32);
            let ny = (n / (2 * nx)).clamp(1, 32);
            let (edges, vertices) = build::grid_shared_points(nx, ny, 0.25);
            aim_points.extend(edges);
            aim_points.extend(vertices);
            let mut bl = build::grid(nx, ny, 0.25);
            // Centred on the origin, by an exact translation of every vertex.
            if let GeometryData::Triangles(t) = &mut bl.geometries[0].data {
                let (cx, cy) = (0.125 * nx as f32, 0.125 * ny as f32);
                for p in t.positions.iter_mut() {
                    p[0] -= cx;
                    p[1] -= cy;
                }
                for p in aim_points.iter_mut() {
                    p[0] -= cx;
                    p[1] -= cy;
                }
            }
            bl
        }
        3 => {
            aim_points.push([0.0, 0.0, 0.0]);
            build::fan(n.clamp(3, 64), 1.5)
        }
        _ => build::spheres_in_boxes(seed, n.min(400) as usize, 2.0, 0.4),
    };
    (bl, aim_points)
}

/// The rendered scene, its rays and the launch dimensions of a draw.
pub fn realise(d: &SceneDraw) -> (Launch, [u32; 3]) {
    let mut rng = SceneRng(d.seed ^ 0x5EED_5CE7E);
    let (mut bl, aim_points) = bottom_level(d);
    // Geometry flags, index width and a geometry transform.
    for g in bl.geometries.iter_mut() {
        g.flags.opaque = d.geometry_sel & 1 == 0;
        g.flags.no_duplicate_any_hit = d.geometry_sel & 2 != 0;
        if let GeometryData::Triangles(t) = &mut g.data {
            if d.layout_sel & 1 != 0 {
                if let Some(Indices::U16(v)) = &t.indices {
                    t.indices = Some(Indices::U32(v.iter().map(|&i| i as u32).collect()));
                }
            }
            if d.layout_sel & 6 == 6 {
                t.transform = Some(build::similarity(
                    [0.3, 0.2, 1.0],
                    0.4,
                    0.75,
                    d.layout_sel & 8 != 0,
                    [0.125, -0.25, 0.0],
                ));
            }
        }
    }
    // Instances: the first untransformed, the others copies; masks and flags by selector.
    let count = d.instances.max(1) as usize;
    let mut instances = vec![SceneInstance::of(0)];
    instances.extend(build::instanced_copies(d.seed, 0, count - 1, 3.0));
    let masks = [RENDERED_MASKS, 0x01, 0x02, 0x03, 0x3C, 0x00];
    for (i, inst) in instances.iter_mut().enumerate() {
        let s = d.instance_sel.rotate_left(i as u32 * 3);
        inst.custom_index = (i as u32 * 7 + 1) & 0xFF_FFFF;
        inst.mask = if i == 0 {
            masks[(s % 5) as usize]
        } else {
            masks[(s % 6) as usize]
        };
        inst.flags = InstanceFlags {
            triangle_facing_cull_disable: s & 0x08 != 0,
            flip_facing: s & 0x10 != 0,
            force_opaque: s & 0x60 == 0x20,
            force_no_opaque: s & 0x60 == 0x40,
        };
        if i > 0 && s & 0x87 == 0x87 {
            inst.bottom_level = None;
        }
    }
    let scene = Scene {
        bottom_levels: vec![bl],
        instances,
    };
    // Ray parameters shared by the launch's rays.
    let flags = RayFlags(RAY_FLAGS[d.ray_flags as usize % RAY_FLAGS.len()]);
    let cull_mask = match d.cull % 4 {
        0 | 1 => RENDERED_MASKS as u32,
        2 => 0x01,
        _ => (d.cull as u32 >> 2) & RENDERED_MASKS as u32 | 1,
    };
    let (tmin, tmax) = match d.interval % 6 {
        0..=2 => (0.0, f32::INFINITY),
        3 => (0.0, 1000.0),
        4 => (1.5, f32::INFINITY),
        _ => (0.25, 6.0 + (d.interval / 6) as f32 * 0.25),
    };
    let (sbt_offset, sbt_stride, miss_index) = (
        (d.sbt_sel & 1) as u32,
        ((d.sbt_sel >> 1) & 1) as u32,
        ((d.sbt_sel >> 2) & 1) as u32,
    );
    let (w, h) = (d.width.max(1), d.height.max(1));
    let params = |r: Ray| Ray {
        flags,
        cull_mask,
        sbt_offset,
        sbt_stride,
        miss_index,
        tmin,
        tmax,
        ..r
    };
    let mut launch = Launch {
        scene,
        ..Launch::default()
    };
    let dist = 7.0 + 3.0 * rng.unit();
    match d.rays % 4 {
        // A pinhole camera looking at the origin.
        0 | 1 => {
            let theta = rng.range(0.0, std::f64::consts::TAU);
            let phi = rng.range(-1.2, 1.2);
            let eye = [
                dist * phi.cos() * theta.cos(),
                dist * phi.cos() * theta.sin(),
                dist * phi.sin(),
            ];
            let n = (eye[0] * eye[0] + eye[1] * eye[1] + eye[2] * eye[2]).sqrt();
            let f = eye.map(|x| -x / n);
            // right = f × z (normalised), up = right × f.
            let mut r = [f[1], -f[0], 0.0];
            let rn = (r[0] * r[0] + r[1] * r[1]).sqrt().max(1e-9);
            r = r.map(|x| x / rn);
            let u = [
                r[1] * f[2] - r[2] * f[1],
                r[2] * f[0] - r[0] * f[2],
                r[0] * f[1] - r[1] * f[0],
            ];
            let half = 0.3;
            let aspect = w as f64 / h as f64;
            let r32 = |v: [f64; 3], s: f64| v.map(|x| (x * s) as f32);
            let base = params(Ray::new([0.0; 3], [0.0, 0.0, 1.0], 0.0, 1.0));
            launch.camera = Some(Camera {
                eye: r32(eye, 1.0),
                forward: r32(f, 1.0),
                right: r32(r, half * aspect),
                up: r32(u, half),
                width: w,
                height: h,
                tmin: base.tmin,
                tmax: base.tmax,
                flags: base.flags,
                cull_mask: base.cull_mask,
                sbt_offset: base.sbt_offset,
                sbt_stride: base.sbt_stride,
                miss_index: base.miss_index,
            });
        }
        // Random rays from a sphere around the scene towards points near its centre.
        2 => {
            for _ in 0..w * h {
                let o = rng.point(-1.0, 1.0).map(|x| x as f64);
                let on = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt().max(1e-3);
                let origin = o.map(|x| x / on * dist);
                let target = rng.point(-1.5, 1.5).map(|x| x as f64);
                let dir = [0, 1, 2].map(|k| (target[k] - origin[k]) as f32);
                launch
                    .rays
                    .push(params(Ray::new(origin.map(|x| x as f32), dir, 0.0, 1.0)));
            }
        }
        // Rays aimed exactly at shared edges and vertices (where the family has them), else random.
        _ => {
            let points = if aim_points.is_empty() {
                vec![[0.0f32; 3]]
            } else {
                aim_points
            };
            for k in 0..(w * h) as usize {
                let p = points[k % points.len()];
                let ray = if d.family % 6 == 1 {
                    // From outside the sphere straight at a vertex.
                    Ray::new(p.map(|x| 4.0 * x), p.map(|x| -3.0 * x), 0.0, 1.0)
                } else {
                    Ray::new([p[0], p[1], p[2] + 4.0], [0.0, 0.0, -1.0], 0.0, 1.0)
                };
                launch.rays.push(params(ray));
            }
        }
    }
    (launch, [w, h, 1])
}

/// Whether any instance of the scene could be hit at all (a mask overlapping the rays' cull mask):
/// for the distribution meta-tests.
pub fn reachable(launch: &Launch) -> bool {
    let cull = launch
        .camera
        .as_ref()
        .map(|c| c.cull_mask)
        .or(launch.rays.first().map(|r| r.cull_mask))
        .unwrap_or(0);
    launch
        .scene
        .instances
        .iter()
        .any(|i| i.bottom_level.is_some() && i.mask as u32 & cull != 0)
}
