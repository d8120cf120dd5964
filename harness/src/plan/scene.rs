//! The scene of a trace case as a plan, made from the case's rendered scene (`model::scene::Scene`):
//! the one input buffer every bottom-level structure is built from (f32 positions, u16/u32 indices,
//! row-major 3x4 geometry transforms, AABBs, each 16-aligned), per bottom level its geometries with
//! their flags, offsets and primitive counts, the top-level structure's instance records (row-major
//! 3x4 transform, custom index, mask, SBT record offset, instance flags, the bottom level referenced
//! or none) and the spheres buffer the intersection shader reads. `realise::scene` builds the
//! structures from exactly these bytes (KHR or NV), and the C export embeds them.

use ash::vk;
use model::scene::{GeometryData, GeometryFlags, Indices, InstanceFlags, Scene, SceneInstance};
use model::world::PipelineApi;

/// Bytes of a vertex (three f32) and of a box (min, max as six f32).
pub const VERTEX_STRIDE: u64 = 12;
pub const AABB_STRIDE: u64 = 24;
/// Bytes of one instance record (`VkAccelerationStructureInstanceKHR`, which the NV record shares).
pub const INSTANCE_SIZE: usize = 64;

/// The data of one geometry, as offsets into [`ScenePlan::input`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum GeometryDataPlan {
    Triangles {
        /// f32 positions at [`VERTEX_STRIDE`].
        vertices: u64,
        vertex_count: u32,
        /// `(offset, count, 16 or 32 bits)`, or none (non-indexed).
        indices: Option<(u64, u32, u8)>,
        /// A row-major 3x4 f32 matrix.
        transform: Option<u64>,
    },
    Aabbs {
        /// Boxes at [`AABB_STRIDE`].
        boxes: u64,
        count: u32,
    },
}

/// One geometry of a bottom-level structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct GeometryPlan {
    /// `VkGeometryFlagsKHR` (OPAQUE, NO_DUPLICATE_ANY_HIT_INVOCATION; the NV bits are the same).
    pub flags: u32,
    pub data: GeometryDataPlan,
    pub primitive_count: u32,
}

/// One bottom level of the scene. One without geometries is not built: instances referencing it
/// reference 0 (inactive), which no ray can tell from an empty structure and no driver has to size.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct BottomPlan {
    pub geometries: Vec<GeometryPlan>,
}

impl BottomPlan {
    pub fn built(&self) -> bool {
        !self.geometries.is_empty()
    }
}

/// One instance of the top-level structure.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct InstancePlan {
    /// Row-major 3x4.
    pub transform: [f32; 12],
    /// 24 bits.
    pub custom_index: u32,
    pub mask: u8,
    /// `instanceShaderBindingTableRecordOffset` (24 bits).
    pub sbt_record_offset: u32,
    /// `VkGeometryInstanceFlagsKHR` (the NV bits are the same).
    pub flags: u8,
    /// The built bottom level it references; None: reference 0, an inactive instance.
    pub bottom: Option<usize>,
}

impl InstancePlan {
    /// The record of a scene's instance referencing built bottom level `bottom` (None: inactive).
    pub fn of(inst: &SceneInstance, bottom: Option<usize>) -> InstancePlan {
        let mut transform = [0f32; 12];
        for (k, x) in inst.transform.0.iter().flatten().enumerate() {
            transform[k] = *x;
        }
        InstancePlan {
            transform,
            custom_index: inst.custom_index & 0xFF_FFFF,
            mask: inst.mask,
            sbt_record_offset: inst.sbt_record_offset & 0xFF_FFFF,
            flags: instance_flags(inst.flags),
            bottom,
        }
    }
}

/// The scene of a trace case.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ScenePlan {
    /// KHR structures (device addresses) or NV ones (buffers and offsets, handles).
    pub api: PipelineApi,
    /// Every bottom level's input (at least 16 bytes).
    pub input: Vec<u8>,
    pub bottoms: Vec<BottomPlan>,
    pub instances: Vec<InstancePlan>,
    /// The words of the spheres buffer (binding 4, see `shaders/intersection.rint`).
    pub spheres: Vec<u32>,
}

fn geometry_flags(f: GeometryFlags) -> u32 {
    let mut out = vk::GeometryFlagsKHR::empty();
    if f.opaque {
        out |= vk::GeometryFlagsKHR::OPAQUE;
    }
    if f.no_duplicate_any_hit {
        out |= vk::GeometryFlagsKHR::NO_DUPLICATE_ANY_HIT_INVOCATION;
    }
    out.as_raw()
}

/// The instance flags byte (KHR and NV share the bits).
fn instance_flags(f: InstanceFlags) -> u8 {
    let mut out = vk::GeometryInstanceFlagsKHR::empty();
    if f.triangle_facing_cull_disable {
        out |= vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE;
    }
    if f.flip_facing {
        out |= vk::GeometryInstanceFlagsKHR::TRIANGLE_FLIP_FACING;
    }
    if f.force_opaque {
        out |= vk::GeometryInstanceFlagsKHR::FORCE_OPAQUE;
    }
    if f.force_no_opaque {
        out |= vk::GeometryInstanceFlagsKHR::FORCE_NO_OPAQUE;
    }
    out.as_raw() as u8
}

/// The words of the spheres buffer: per instance the start of its bottom level's geometry table, per
/// geometry the start of its spheres, per sphere its centre and radius as f32 bits (at least 4 words).
fn sphere_words(scene: &Scene) -> Vec<u32> {
    let n = scene.instances.len();
    let mut words = vec![0u32; n];
    let mut tables = Vec::with_capacity(scene.bottom_levels.len());
    for bl in &scene.bottom_levels {
        tables.push(words.len() as u32);
        words.extend(std::iter::repeat_n(0, bl.geometries.len()));
    }
    for (b, bl) in scene.bottom_levels.iter().enumerate() {
        for (g, geometry) in bl.geometries.iter().enumerate() {
            if let GeometryData::Aabbs(a) = &geometry.data {
                words[tables[b] as usize + g] = words.len() as u32;
                for s in &a.spheres {
                    words.extend(s.center.map(f32::to_bits));
                    words.push(s.radius.to_bits());
                }
            }
        }
    }
    for (i, inst) in scene.instances.iter().enumerate() {
        if let Some(b) = inst.bottom_level {
            words[i] = tables.get(b as usize).copied().unwrap_or(0);
        }
    }
    words.resize(words.len().max(4), 0);
    words
}

impl ScenePlan {
    /// The plan of a case's scene for structures of `api`.
    pub fn of(scene: &Scene, api: PipelineApi) -> ScenePlan {
        let mut input: Vec<u8> = Vec::new();
        let at = |input: &mut Vec<u8>, bytes: &[u8]| -> u64 {
            input.resize(input.len().next_multiple_of(16), 0);
            let offset = input.len() as u64;
            input.extend_from_slice(bytes);
            // At least one byte, so an empty array still has an address inside the buffer.
            if bytes.is_empty() {
                input.push(0);
            }
            offset
        };
        let f32s = |v: &mut dyn Iterator<Item = f32>| -> Vec<u8> {
            v.flat_map(|x| x.to_le_bytes()).collect()
        };
        let mut bottoms = Vec::with_capacity(scene.bottom_levels.len());
        for bl in &scene.bottom_levels {
            let mut geometries = Vec::with_capacity(bl.geometries.len());
            for g in &bl.geometries {
                let (data, primitive_count) = match &g.data {
                    GeometryData::Triangles(t) => {
                        let vertices = at(
                            &mut input,
                            &f32s(&mut t.positions.iter().flatten().copied()),
                        );
                        let indices = t.indices.as_ref().map(|ix| {
                            let (bytes, bits): (Vec<u8>, u8) = match ix {
                                Indices::U16(v) => {
                                    (v.iter().flat_map(|x| x.to_le_bytes()).collect(), 16)
                                }
                                Indices::U32(v) => {
                                    (v.iter().flat_map(|x| x.to_le_bytes()).collect(), 32)
                                }
                            };
                            (at(&mut input, &bytes), ix.len() as u32, bits)
                        });
                        let transform = t
                            .transform
                            .as_ref()
                            .map(|m| at(&mut input, &f32s(&mut m.0.iter().flatten().copied())));
                        (
                            GeometryDataPlan::Triangles {
                                vertices,
                                vertex_count: t.positions.len() as u32,
                                indices,
                                transform,
                            },
                            t.primitive_count() as u32,
                        )
                    }
                    GeometryData::Aabbs(a) => (
                        GeometryDataPlan::Aabbs {
                            boxes: at(
                                &mut input,
                                &f32s(
                                    &mut a
                                        .boxes
                                        .iter()
                                        .flat_map(|b| b.min.into_iter().chain(b.max)),
                                ),
                            ),
                            count: a.boxes.len() as u32,
                        },
                        a.boxes.len() as u32,
                    ),
                };
                geometries.push(GeometryPlan {
                    flags: geometry_flags(g.flags),
                    data,
                    primitive_count,
                });
            }
            bottoms.push(BottomPlan { geometries });
        }
        input.resize(input.len().max(16), 0);
        let instances = scene
            .instances
            .iter()
            .map(|inst| {
                let bottom = inst
                    .bottom_level
                    .map(|b| b as usize)
                    .filter(|&b| bottoms.get(b).is_some_and(BottomPlan::built));
                InstancePlan::of(inst, bottom)
            })
            .collect();
        ScenePlan {
            api,
            input,
            bottoms,
            instances,
            spheres: sphere_words(scene),
        }
    }

    /// The instance records, each referencing `reference(bottom)` (a KHR device address or an NV
    /// handle) or 0.
    pub fn instance_bytes(&self, reference: &dyn Fn(usize) -> u64) -> Vec<u8> {
        self.instances
            .iter()
            .flat_map(|i| instance_record(i, i.bottom.map_or(0, reference)))
            .collect()
    }

    /// The spheres buffer's bytes.
    pub fn sphere_bytes(&self) -> Vec<u8> {
        self.spheres.iter().flat_map(|w| w.to_le_bytes()).collect()
    }

    /// The bottom levels that are built.
    pub fn built_bottoms(&self) -> usize {
        self.bottoms.iter().filter(|b| b.built()).count()
    }
}

/// The 64 bytes of a `VkAccelerationStructureInstanceKHR` (and the NV record, which has one layout):
/// the row-major transform, custom index (24 bits) and mask, SBT record offset (24 bits) and flags,
/// and `reference`.
pub fn instance_record(i: &InstancePlan, reference: u64) -> [u8; INSTANCE_SIZE] {
    let mut b = [0u8; INSTANCE_SIZE];
    for (k, v) in i.transform.iter().enumerate() {
        b[k * 4..k * 4 + 4].copy_from_slice(&v.to_le_bytes());
    }
    b[48..52]
        .copy_from_slice(&((i.custom_index & 0xFF_FFFF) | (i.mask as u32) << 24).to_le_bytes());
    b[52..56].copy_from_slice(
        &((i.sbt_record_offset & 0xFF_FFFF) | (i.flags as u32) << 24).to_le_bytes(),
    );
    b[56..64].copy_from_slice(&reference.to_le_bytes());
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_instance_record_is_the_vulkan_layout() {
        let i = InstancePlan {
            transform: [1.0, 0.0, 0.0, 5.0, 0.0, 1.0, 0.0, 6.0, 0.0, 0.0, 1.0, 7.0],
            custom_index: 0x12_3456,
            mask: 0xfe,
            sbt_record_offset: 3,
            flags: 0x5,
            bottom: Some(0),
        };
        let r = instance_record(&i, 0xdead_beef);
        let record = vk::AccelerationStructureInstanceKHR {
            transform: vk::TransformMatrixKHR {
                matrix: i.transform,
            },
            instance_custom_index_and_mask: vk::Packed24_8::new(0x12_3456, 0xfe),
            instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(3, 0x5),
            acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                device_handle: 0xdead_beef,
            },
        };
        // SAFETY: a plain C struct of 64 bytes.
        let want: [u8; 64] = unsafe { std::mem::transmute(record) };
        assert_eq!(r, want);
    }
}
