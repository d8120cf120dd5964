//! The scene a trace case's rays see, as a plan: the bytes every bottom-level structure is built from
//! (geometry `g` of instance `i` is one triangle or box around (2g, 4i, 0), where the rays aim), one
//! bottom-level structure per instance with geometry, and the top-level structure's instance records.

use crate::error::HarnessError;
use model::world::{GeometryKind, Instance, PipelineApi};

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

impl ScenePlan {
    /// The scene of a launch's instances. An instance that mixes triangles and boxes is unsupported: one
    /// bottom-level structure holds one geometry type, so it cannot be built validly.
    pub fn of(instances: &[Instance], api: PipelineApi) -> Result<ScenePlan, HarnessError> {
        if let Some(i) = instances
            .iter()
            .position(|inst| inst.geometries.windows(2).any(|w| w[0] != w[1]))
        {
            return Err(HarnessError::NotRealised(format!(
                "instance {i} mixes triangle and AABB geometries; one acceleration structure holds one type"
            )));
        }
        let mut input: Vec<u8> = Vec::new();
        let mut bottoms = Vec::new();
        let mut plans = Vec::with_capacity(instances.len());
        for (i, inst) in instances.iter().enumerate() {
            let mut geometries = Vec::with_capacity(inst.geometries.len());
            for (g, kind) in inst.geometries.iter().enumerate() {
                let (cx, cy) = (2.0 * g as f32, 4.0 * i as f32);
                input.resize(input.len().next_multiple_of(16), 0);
                geometries.push(GeometryPlan {
                    kind: *kind,
                    offset: input.len() as u64,
                });
                let floats: &[f32] = match kind {
                    GeometryKind::Triangles => &[
                        cx - 0.5,
                        cy - 0.5,
                        0.0,
                        cx + 0.5,
                        cy - 0.5,
                        0.0,
                        cx,
                        cy + 0.5,
                        0.0,
                    ],
                    GeometryKind::Aabbs => &[cx - 0.5, cy - 0.5, -0.5, cx + 0.5, cy + 0.5, 0.5],
                };
                floats
                    .iter()
                    .for_each(|f| input.extend_from_slice(&f.to_le_bytes()));
            }
            // An instance without geometry is made inactive (reference 0): it keeps its place in the
            // instance numbering, and no bottom-level structure of zero geometries is built.
            let bottom = if geometries.is_empty() {
                None
            } else {
                bottoms.push(geometries);
                Some(bottoms.len() - 1)
            };
            plans.push(InstancePlan {
                mask: inst.mask,
                sbt_record_offset: inst.sbt_record_offset & 0xFF_FFFF,
                bottom,
            });
        }
        Ok(ScenePlan {
            api,
            input,
            bottoms,
            instances: plans,
        })
    }
}

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
    fn the_scene_places_each_geometry_where_the_rays_aim() {
        let inst = |g: Vec<GeometryKind>| Instance {
            geometries: g,
            sbt_record_offset: 0x1234_5678,
            mask: 0x0f,
            cluster: false,
        };
        let s = ScenePlan::of(
            &[
                inst(vec![GeometryKind::Triangles, GeometryKind::Triangles]),
                inst(vec![]),
                inst(vec![GeometryKind::Aabbs]),
            ],
            PipelineApi::Khr,
        )
        .unwrap();
        assert_eq!(s.bottoms.len(), 2);
        assert_eq!(
            s.instances.iter().map(|i| i.bottom).collect::<Vec<_>>(),
            vec![Some(0), None, Some(1)]
        );
        assert_eq!(s.instances[0].sbt_record_offset, 0x34_5678);
        let floats = |at: u64, n: usize| -> Vec<f32> {
            (0..n)
                .map(|k| {
                    let o = at as usize + 4 * k;
                    f32::from_le_bytes(s.input[o..o + 4].try_into().unwrap())
                })
                .collect()
        };
        // Geometry 1 of instance 0 is centred at (2, 0); the box of instance 2 at (0, 8).
        let g1 = s.bottoms[0][1];
        assert_eq!(g1.offset % 16, 0);
        assert_eq!(
            floats(g1.offset, 9),
            [1.5, -0.5, 0.0, 2.5, -0.5, 0.0, 2.0, 0.5, 0.0]
        );
        let b = s.bottoms[1][0];
        assert_eq!(floats(b.offset, 6), [-0.5, 7.5, -0.5, 0.5, 8.5, 0.5]);
        let mixed = ScenePlan::of(
            &[inst(vec![GeometryKind::Triangles, GeometryKind::Aabbs])],
            PipelineApi::Khr,
        );
        assert!(matches!(mixed, Err(HarnessError::NotRealised(_))));
        let r = instance_record(0xff, 3, 0xdead_beef);
        assert_eq!(&r[0..4], &1.0f32.to_le_bytes());
        assert_eq!(&r[48..56], &[0, 0, 0, 0xff, 3, 0, 0, 0]);
        assert_eq!(&r[56..64], &0xdead_beefu64.to_le_bytes());
    }
}
