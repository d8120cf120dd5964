//! The scene of a trace case as a plan: the bytes bottom-level structures are built from, the
//! geometries of each, and the top-level structure's instance records. Not yet made from a case's
//! rendered scene (the call plan refuses trace cases, [`super::trace::NOT_DESCRIBED`]); the instance
//! record layout serves the export's C runtime.

use model::world::{GeometryKind, PipelineApi};

/// One geometry of a bottom-level structure: its kind and where its data starts in the input bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct GeometryPlan {
    pub kind: GeometryKind,
    pub offset: u64,
}

/// One instance of the top-level structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct InstancePlan {
    pub mask: u8,
    /// `instanceShaderBindingTableRecordOffset` (24 bits).
    pub sbt_record_offset: u32,
    /// The bottom-level structure it references; None: reference 0, an inactive instance.
    pub bottom: Option<usize>,
}

/// The scene of a trace case.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ScenePlan {
    pub api: PipelineApi,
    /// Vertices (3 × vec3) and boxes (min, max), each at a 16-aligned offset.
    pub input: Vec<u8>,
    /// The geometries of each bottom-level structure.
    pub bottoms: Vec<Vec<GeometryPlan>>,
    pub instances: Vec<InstancePlan>,
}

/// Bytes of a triangle's three vertices and of a box, as the scene lays them out.
pub const TRIANGLE_VERTICES: u32 = 3;
pub const VERTEX_STRIDE: u64 = 12;
pub const AABB_STRIDE: u64 = 24;

/// The 64 bytes of a `VkAccelerationStructureInstanceKHR` (and the NV record, which has one layout):
/// the identity transform, custom index 0, `mask`, `sbt_record_offset`, no flags, and `reference` (a
/// device address or an NV handle).
pub fn instance_record(mask: u8, sbt_record_offset: u32, reference: u64) -> [u8; 64] {
    let mut b = [0u8; 64];
    let identity: [f32; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    for (i, v) in identity.iter().enumerate() {
        b[i * 4..i * 4 + 4].copy_from_slice(&v.to_le_bytes());
    }
    b[48..52].copy_from_slice(&((mask as u32) << 24).to_le_bytes());
    b[52..56].copy_from_slice(&(sbt_record_offset & 0xFF_FFFF).to_le_bytes());
    b[56..64].copy_from_slice(&reference.to_le_bytes());
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_instance_record_holds_the_identity_mask_offset_and_reference() {
        let r = instance_record(0xff, 3, 0xdead_beef);
        assert_eq!(&r[0..4], &1.0f32.to_le_bytes());
        assert_eq!(&r[48..56], &[0, 0, 0, 0xff, 3, 0, 0, 0]);
        assert_eq!(&r[56..64], &0xdead_beefu64.to_le_bytes());
    }
}
