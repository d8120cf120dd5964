//! Named shapes of a launch: facts of its world and call alone, never of what a device did, so that a
//! triage entry can say a driver fails every launch of a shape (a `crash:` entry, keyed
//! `<command>:<shape>`) and the model, not a case's name, decides which launches those are.

use super::{procedural_geometries, traced_rays};
use crate::call::{Call, Table};
use crate::world::World;

/// A launch whose hit shader binding table is null (KHR: the region's address is 0; NV: no buffer)
/// while one of its rays meets an active AABB, in an instance its cull mask admits and without
/// SkipAABBs, that the ray's opacity flags cull (CullOpaque on a box that is opaque for it,
/// CullNoOpaque on one that is not). A culled box runs no intersection shader and reads no hit
/// record (spec, "Ray Opacity Culling"), so such a launch may be valid.
pub const CULLED_AABB_NULL_HIT_TABLE: &str = "culled-aabb-null-hit-table";

/// The shapes `call` has in `world`, in a fixed order.
pub fn shapes(world: &World, call: &Call) -> Vec<&'static str> {
    let mut out = Vec::new();
    if hit_table_is_null(call) && culls_an_aabb(world, call) {
        out.push(CULLED_AABB_NULL_HIT_TABLE);
    }
    out
}

fn hit_table_is_null(call: &Call) -> bool {
    match call {
        Call::TraceRaysNv(_) => call
            .nv_table(Table::Hit)
            .is_some_and(|t| t.buffer.is_none()),
        _ => call.region(Table::Hit).is_some_and(|r| r.address.is_null()),
    }
}

fn culls_an_aabb(world: &World, call: &Call) -> bool {
    let scene = &world.launch.scene;
    traced_rays(world, call)
        .iter()
        .any(|ray| procedural_geometries(scene, ray).any(|(_, _, culled)| culled))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::Case;

    fn committed(path: &str) -> Case {
        let full = format!("{}/../cases/{path}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&full).expect("a committed case");
        Case::from_yaml(&full, &text).expect("the case reads")
    }

    fn shapes_of(case: &Case) -> Vec<&'static str> {
        let t = case.as_trace().expect("a trace case");
        shapes(&t.world, &t.call)
    }

    #[test]
    fn the_nvidia_device_lost_cases_have_the_culled_aabb_shape_and_their_controls_do_not() {
        // The hit region set, or a triangle in the box's place: NVIDIA passes both.
        let controls = [
            "device-lost-b-control-hit-region-set.yaml",
            "device-lost-g-one-triangle-cull-opaque.yaml",
        ];
        let dir = format!(
            "{}/../cases/nvidia-h200/device-lost",
            env!("CARGO_MANIFEST_DIR")
        );
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .expect("the device-lost cases")
            .map(|e| {
                e.expect("an entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .filter(|n| n.ends_with(".yaml"))
            .collect();
        names.sort();
        assert!(names.len() >= 10, "{names:?}");
        for name in &names {
            let case = committed(&format!("nvidia-h200/device-lost/{name}"));
            if controls.contains(&name.as_str()) {
                assert!(shapes_of(&case).is_empty(), "{name}");
            } else {
                assert_eq!(shapes_of(&case), [CULLED_AABB_NULL_HIT_TABLE], "{name}");
            }
        }
    }

    #[test]
    fn the_shape_needs_a_ray_whose_opacity_flags_cull_the_box() {
        use crate::scene::RayFlags;
        let case =
            committed("nvidia-h200/device-lost/device-lost-a-one-aabb-cull-opaque-null-hit.yaml");
        let with = |flags: RayFlags, cull_mask: u32| {
            let mut c = case.clone();
            let t = c.as_trace_mut().expect("a trace case");
            let camera = t.world.launch.camera.as_mut().expect("the case's one ray");
            (camera.flags, camera.cull_mask) = (flags, cull_mask);
            shapes(&t.world, &t.call)
        };
        assert!(with(RayFlags(0), 0xFF).is_empty(), "no culling flag");
        assert!(
            with(RayFlags::CULL_OPAQUE | RayFlags::SKIP_AABBS, 0xFF).is_empty(),
            "the ray skips AABBs"
        );
        assert!(
            with(RayFlags::CULL_NO_OPAQUE, 0xFF).is_empty(),
            "an opaque box under CullNoOpaque"
        );
        assert!(
            with(RayFlags::CULL_OPAQUE, 0).is_empty(),
            "the mask admits no instance"
        );
        assert_eq!(
            with(RayFlags::CULL_OPAQUE, 0xFF),
            [CULLED_AABB_NULL_HIT_TABLE]
        );
    }
}
