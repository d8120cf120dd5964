//! Aimed scene parts: one small triangle or box per geometry at a fixed spot, and rays aimed straight
//! at one of them, for cases that must reach chosen shader binding table records. Geometry `g` of the
//! aimed instance at index `i` sits at (2g, 4i, 0); aimed instances carry only mask bit
//! [`AIMED_MASK`] and aimed rays cull with that bit alone, so rendered scenes (which never use it) and
//! aimed parts never see each other. Mutations that add a ray for one record use [`PROBE_MASK`] the
//! same way, so no other ray reaches what they add.

use model::scene::{
    Aabb, Aabbs, BottomLevel, Geometry, GeometryData, GeometryFlags, Ray, SceneInstance, Sphere,
    Transform3x4, Triangles,
};
use model::world::{GeometryKind, Launch};

/// The mask bit of aimed instances and the cull mask of aimed rays.
pub const AIMED_MASK: u8 = 0x80;
/// The mask bit of the instance and ray a mutation adds to reach one record.
pub const PROBE_MASK: u8 = 0x40;
/// The mask bits rendered scenes and their rays may use.
pub const RENDERED_MASKS: u8 = 0x3F;

fn spot(instance: u32, geometry: u32) -> (f32, f32) {
    (2.0 * geometry as f32, 4.0 * instance as f32)
}

/// The geometry of kind `kind` at (2g, 4i, 0): a triangle around the spot in z = 0, or a unit box
/// around it holding the sphere of radius ½ at the spot.
fn aimed_geometry(kind: GeometryKind, instance: u32, g: u32) -> Geometry {
    let (cx, cy) = spot(instance, g);
    let data = match kind {
        GeometryKind::Triangles => GeometryData::Triangles(Triangles {
            positions: vec![
                [cx - 0.5, cy - 0.5, 0.0],
                [cx + 0.5, cy - 0.5, 0.0],
                [cx, cy + 0.5, 0.0],
            ],
            indices: None,
            transform: None,
        }),
        GeometryKind::Aabbs => GeometryData::Aabbs(Aabbs {
            boxes: vec![Aabb {
                min: [cx - 0.5, cy - 0.5, -0.5],
                max: [cx + 0.5, cy + 0.5, 0.5],
            }],
            spheres: vec![Sphere {
                center: [cx, cy, 0.0],
                radius: 0.5,
            }],
        }),
    };
    Geometry {
        flags: GeometryFlags::default(),
        data,
    }
}

/// Appends an instance (mask `mask`) of a new bottom level with one aimed geometry per entry of
/// `kinds`; returns its instance index.
pub fn add_instance(
    launch: &mut Launch,
    kinds: &[GeometryKind],
    sbt_record_offset: u32,
    mask: u8,
) -> u32 {
    let scene = &mut launch.scene;
    let instance = scene.instances.len() as u32;
    let bottom_level = scene.bottom_levels.len() as u32;
    scene.bottom_levels.push(BottomLevel {
        geometries: kinds
            .iter()
            .enumerate()
            .map(|(g, &k)| aimed_geometry(k, instance, g as u32))
            .collect(),
    });
    scene.instances.push(SceneInstance {
        bottom_level: Some(bottom_level),
        transform: Transform3x4::IDENTITY,
        custom_index: instance,
        mask,
        sbt_record_offset,
        flags: Default::default(),
    });
    instance
}

/// The ray (+z from z = −1, t in [0, 100]) aimed at geometry `g` of the aimed instance `instance`,
/// culling with `mask`.
pub fn ray_at(instance: u32, g: u32, mask: u8) -> Ray {
    let (cx, cy) = spot(instance, g);
    Ray {
        cull_mask: mask as u32,
        ..Ray::new([cx, cy, -1.0], [0.0, 0.0, 1.0], 0.0, 100.0)
    }
}

/// A ray that misses every aimed geometry (it passes far beside them), culling with `mask`.
pub fn ray_beside(mask: u8) -> Ray {
    Ray {
        cull_mask: mask as u32,
        ..Ray::new([-1000.0, -1000.0, -1.0], [0.0, 0.0, 1.0], 0.0, 100.0)
    }
}
