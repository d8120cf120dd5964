//! A build case's plan: its buffers with the model's memory image (the bytes with no address in them,
//! and where each device address goes: a buffer's plus an offset, or a structure's), its acceleration
//! structures at their buffer ranges, the Vulkan form of its build infos with symbolic addresses, the
//! command buffer's steps and the indirect call's arguments.

use super::{step_text, Step};
use crate::error::HarnessError;
use ash::vk;
use model::accel::call::{BuildGeometryInfo, BuildMode, GeometryData, IndexType, VertexFormat};
use model::accel::world::{
    AddressResolver, BuildContents, InstanceReference, SparseImage, SyntheticAddresses,
};
use model::accel::{AsType, BuildWorld};
use model::call::Address;
use model::world::{CommandBufferLevel, CommandBufferLifecycle, MemoryBinding};
use model::AccelBody;

/// What a relocation writes: the device address of a buffer plus an offset, or of a structure.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub enum AddressOf {
    Buffer { name: String, offset: u64 },
    Structure { name: String },
}

/// A device address written into a memory image at `offset` (its first `len` bytes, little-endian:
/// fewer than 8 where the buffer ends).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Relocation {
    pub offset: u64,
    pub len: usize,
    pub target: AddressOf,
}

/// One buffer of a build case.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct BuildBufferPlan {
    pub name: String,
    pub size: u64,
    /// The case's usage with SHADER_DEVICE_ADDRESS added (every build buffer is read by address).
    pub usage: u32,
    pub flags: u32,
    pub memory: MemoryBinding,
    pub sparse: bool,
    /// An address of the call (range records, scratch, geometry data) lies in it.
    pub addressed: bool,
    /// The case writes contents into it.
    pub written: bool,
    /// The memory image with every device address left 0: the runs the case's contents write, by
    /// offset (the rest of the buffer is zero), never a copy sized by the buffer.
    pub image: Vec<ImageRun>,
    pub relocations: Vec<Relocation>,
}

/// Bytes a buffer's contents write at `offset`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ImageRun {
    pub offset: u64,
    pub bytes: Vec<u8>,
}

/// One acceleration structure of a build case.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct StructurePlan {
    pub name: String,
    pub buffer: String,
    pub offset: u64,
    pub size: u64,
    /// `VkAccelerationStructureTypeKHR`.
    pub ty: i32,
}

/// One geometry of a build info, in its Vulkan form.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum GeometryDataPlan {
    Triangles {
        vertex_format: i32,
        vertex_data: Address,
        vertex_stride: u64,
        max_vertex: u32,
        index_type: i32,
        index_data: Address,
        transform_data: Address,
    },
    Aabbs {
        data: Address,
        stride: u64,
    },
    Instances {
        array_of_pointers: bool,
        data: Address,
    },
}

/// A geometry with its flags.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BuildGeometryPlan {
    /// `VkGeometryTypeKHR`.
    pub ty: i32,
    pub flags: u32,
    pub data: GeometryDataPlan,
}

/// One `VkAccelerationStructureBuildGeometryInfoKHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BuildInfoPlan {
    pub ty: i32,
    pub flags: u32,
    pub mode: i32,
    pub src: Option<String>,
    pub dst: Option<String>,
    pub scratch: Address,
    /// None when a geometry is of a type the harness does not realise (motion, micromaps, spheres…).
    pub geometries: Option<Vec<BuildGeometryPlan>>,
}

/// A build case's plan.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BuildPlan {
    pub buffers: Vec<BuildBufferPlan>,
    pub structures: Vec<StructurePlan>,
    pub infos: Vec<BuildInfoPlan>,
    pub indirect_addresses: Vec<Address>,
    pub indirect_strides: Vec<u32>,
    pub max_primitive_counts: Vec<Vec<u32>>,
    pub level: CommandBufferLevel,
    pub in_render_pass: bool,
    /// Recording the command buffer's state and the call (never submitted).
    pub steps: Vec<Step>,
}

/// A resolver that knows no address: every one is 0.
struct NoAddresses;

impl AddressResolver for NoAddresses {
    fn buffer(&self, _: &str) -> Option<u64> {
        None
    }
    fn structure(&self, _: &str) -> Option<u64> {
        None
    }
}

/// `VkIndexType` of an index type.
pub(crate) fn vk_index(t: IndexType) -> vk::IndexType {
    match t {
        IndexType::None => vk::IndexType::NONE_KHR,
        IndexType::Uint8 => vk::IndexType::UINT8_EXT,
        IndexType::Uint16 => vk::IndexType::UINT16,
        IndexType::Uint32 => vk::IndexType::UINT32,
    }
}

/// `VkFormat` of a vertex format.
pub(crate) fn vk_format(f: VertexFormat) -> vk::Format {
    match f {
        VertexFormat::R32g32b32Sfloat => vk::Format::R32G32B32_SFLOAT,
        VertexFormat::R32g32Sfloat => vk::Format::R32G32_SFLOAT,
        VertexFormat::R16g16b16a16Sfloat => vk::Format::R16G16B16A16_SFLOAT,
        VertexFormat::R16g16Sfloat => vk::Format::R16G16_SFLOAT,
    }
}

/// `VkAccelerationStructureTypeKHR` of a type.
pub fn vk_type(t: AsType) -> vk::AccelerationStructureTypeKHR {
    match t {
        AsType::TopLevel => vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        AsType::BottomLevel => vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
        AsType::Generic => vk::AccelerationStructureTypeKHR::GENERIC,
    }
}

/// The Vulkan form of one info (geometries None for a type the harness does not realise).
fn info_plan(info: &BuildGeometryInfo) -> BuildInfoPlan {
    let geometries = info
        .geometries
        .iter()
        .map(|g| {
            let (ty, data) = match &g.data {
                GeometryData::Triangles {
                    vertex_format,
                    vertex_data,
                    vertex_stride,
                    max_vertex,
                    index_type,
                    index_data,
                    transform_data,
                    motion_vertex_data: None,
                    opacity_micromap: None,
                } => (
                    vk::GeometryTypeKHR::TRIANGLES,
                    GeometryDataPlan::Triangles {
                        vertex_format: vk_format(*vertex_format).as_raw(),
                        vertex_data: vertex_data.clone(),
                        vertex_stride: *vertex_stride,
                        max_vertex: *max_vertex,
                        index_type: vk_index(*index_type).as_raw(),
                        index_data: index_data.clone(),
                        transform_data: transform_data.clone(),
                    },
                ),
                GeometryData::Aabbs { data, stride } => (
                    vk::GeometryTypeKHR::AABBS,
                    GeometryDataPlan::Aabbs {
                        data: data.clone(),
                        stride: *stride,
                    },
                ),
                GeometryData::Instances {
                    array_of_pointers,
                    data,
                } => (
                    vk::GeometryTypeKHR::INSTANCES,
                    GeometryDataPlan::Instances {
                        array_of_pointers: *array_of_pointers,
                        data: data.clone(),
                    },
                ),
                _ => return None,
            };
            Some(BuildGeometryPlan {
                ty: ty.as_raw(),
                flags: g.flags.0,
                data,
            })
        })
        .collect();
    let mode = match info.mode {
        BuildMode::Build => vk::BuildAccelerationStructureModeKHR::BUILD.as_raw(),
        BuildMode::Update => vk::BuildAccelerationStructureModeKHR::UPDATE.as_raw(),
        BuildMode::Other(v) => v as i32,
    };
    BuildInfoPlan {
        ty: vk_type(info.ty).as_raw(),
        flags: info.flags.0,
        mode,
        src: info.src.clone(),
        dst: info.dst.clone(),
        scratch: info.scratch.clone(),
        geometries,
    }
}

/// Whether any address of the call (indirect records, scratch, geometry data) lies in buffer `name`.
fn addressed(case: &AccelBody, name: &str) -> bool {
    let is = |a: &Address| a.buffer().is_some_and(|(b, _)| b == name);
    case.call.indirect_addresses.iter().any(is)
        || case.call.infos.iter().any(|i| {
            is(&i.scratch)
                || i.geometries.iter().any(|g| match &g.data {
                    GeometryData::Triangles {
                        vertex_data,
                        index_data,
                        transform_data,
                        ..
                    } => is(vertex_data) || is(index_data) || is(transform_data),
                    GeometryData::Aabbs { data, .. } => is(data),
                    GeometryData::Instances { data, .. } => is(data),
                    _ => false,
                })
        })
}

/// The device addresses a buffer's memory image holds, where no later write covers them: the model's
/// image laid out with synthetic addresses must hold each one's synthetic value.
fn relocations(world: &BuildWorld, name: &str) -> Vec<Relocation> {
    let Some(b) = world.buffer(name) else {
        return vec![];
    };
    let synthetic = SyntheticAddresses(world);
    let Some(image) = world.image(name, &synthetic) else {
        return vec![];
    };
    let mut candidates: Vec<(u64, AddressOf)> = Vec::new();
    for c in &b.contents {
        match c {
            BuildContents::Instances { offset, instances } => {
                for (k, inst) in instances.iter().enumerate() {
                    if let InstanceReference::Structure(n) = &inst.reference {
                        candidates.push((
                            offset + 64 * k as u64 + 56,
                            AddressOf::Structure { name: n.clone() },
                        ));
                    }
                }
            }
            BuildContents::Pointers { offset, targets } => {
                for (k, a) in targets.iter().enumerate() {
                    if let Address::InBuffer { buffer, offset: o } = a {
                        candidates.push((
                            offset + 8 * k as u64,
                            AddressOf::Buffer {
                                name: buffer.clone(),
                                offset: *o,
                            },
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    let mut out: Vec<Relocation> = Vec::new();
    for (offset, target) in candidates {
        let value = resolve(&target, &synthetic);
        if value == 0 || offset >= image.size() {
            continue;
        }
        let len = (image.size() - offset).min(8) as usize;
        if image.read(offset, len as u64).as_deref() != Some(&value.to_le_bytes()[..len]) {
            continue; // a later write covers it
        }
        out.retain(|r| r.offset != offset);
        out.push(Relocation {
            offset,
            len,
            target,
        });
    }
    out
}

fn resolve(target: &AddressOf, r: &dyn AddressResolver) -> u64 {
    match target {
        AddressOf::Buffer { name, offset } => r.buffer(name).map_or(0, |b| b + offset),
        AddressOf::Structure { name } => r.structure(name).unwrap_or(0),
    }
}

impl BuildBufferPlan {
    /// The memory image with the addresses of `resolver` written in.
    pub fn image_at(&self, resolver: &dyn AddressResolver) -> SparseImage {
        let mut image = SparseImage::new(self.size);
        for run in &self.image {
            image.write(run.offset, &run.bytes);
        }
        for r in &self.relocations {
            let v = resolve(&r.target, resolver).to_le_bytes();
            image.write(r.offset, &v[..r.len]);
        }
        image
    }

    /// Bytes of the memory image the case writes (the rest is zero).
    pub fn image_bytes(&self) -> usize {
        self.image.iter().map(|r| r.bytes.len()).sum()
    }
}

impl BuildPlan {
    /// The plan of a build case, or why the harness cannot realise its command buffer state.
    pub fn of(case: &AccelBody) -> Result<BuildPlan, HarnessError> {
        let world = &case.world;
        let cbs = &world.command_buffer;
        if cbs.protected
            || cbs.in_video_coding
            || cbs.between_suspended_render_passes
            || !cbs
                .pool_queue
                .contains(model::flags::QueueFlags::COMPUTE_BIT)
        {
            return Err(HarnessError::NotRealised(
                "protected command buffers, video coding scopes, pools without compute and recording between suspended render passes are not realised for builds".into(),
            ));
        }
        let buffers = world
            .buffers
            .iter()
            .map(|b| BuildBufferPlan {
                name: b.name.clone(),
                size: b.size,
                usage: (b.usage.0 as u32) | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
                flags: b.flags.0 as u32,
                memory: b.memory,
                sparse: b.is_sparse(),
                addressed: addressed(case, &b.name),
                written: !b.contents.is_empty(),
                image: world
                    .image(&b.name, &NoAddresses)
                    .map(|i| {
                        i.runs()
                            .map(|(offset, bytes)| ImageRun {
                                offset,
                                bytes: bytes.to_vec(),
                            })
                            .collect()
                    })
                    .unwrap_or_default(),
                relocations: relocations(world, &b.name),
            })
            .collect();
        let structures = world
            .structures
            .iter()
            .map(|s| StructurePlan {
                name: s.name.clone(),
                buffer: s.buffer.clone(),
                offset: s.offset,
                size: s.size,
                ty: vk_type(s.ty).as_raw(),
            })
            .collect();
        let secondary = cbs.level == CommandBufferLevel::Secondary;
        let primary_pass = cbs.in_render_pass && !secondary;
        super::refuse_ended_inside_render_pass(cbs)?;
        let mut steps = vec![Step::Reset { level: cbs.level }];
        if cbs.lifecycle != CommandBufferLifecycle::Initial {
            steps.push(Step::Begin {
                level: cbs.level,
                continue_render_pass: secondary && cbs.in_render_pass,
            });
            if primary_pass {
                steps.push(Step::BeginRenderPass);
            }
            if matches!(
                cbs.lifecycle,
                CommandBufferLifecycle::Executable | CommandBufferLifecycle::Invalid
            ) {
                steps.push(Step::End);
            }
            if cbs.lifecycle == CommandBufferLifecycle::Invalid {
                steps.push(Step::SubmitToInvalidate);
            }
        }
        steps.push(Step::Call { dropped: true });
        if cbs.lifecycle == CommandBufferLifecycle::Recording {
            if primary_pass {
                steps.push(Step::EndRenderPass);
            }
            steps.push(Step::End);
        }
        Ok(BuildPlan {
            buffers,
            structures,
            infos: case.call.infos.iter().map(info_plan).collect(),
            indirect_addresses: case.call.indirect_addresses.clone(),
            indirect_strides: case.call.indirect_strides.clone(),
            max_primitive_counts: case.call.max_primitive_counts.clone(),
            level: cbs.level,
            in_render_pass: cbs.in_render_pass,
            steps,
        })
    }

    /// Appends the plan's call sequence, as a person reads it.
    pub(crate) fn describe(&self, out: &mut Vec<String>) {
        for b in &self.buffers {
            out.push(format!(
                "vkCreateBuffer `{}`: {} bytes{}{}; {} bytes of memory image, {} device address(es) written in",
                b.name,
                b.size,
                if b.sparse { ", sparse" } else { "" },
                match b.memory {
                    MemoryBinding::Whole => "",
                    MemoryBinding::Unbound => ", no memory bound",
                    MemoryBinding::Scattered => ", bound to two memory objects",
                },
                b.image_bytes(),
                b.relocations.len()
            ));
        }
        for s in &self.structures {
            out.push(format!(
                "vkCreateAccelerationStructureKHR `{}`: `{}`+{}, {} bytes",
                s.name, s.buffer, s.offset, s.size
            ));
        }
        out.push(format!(
            "vkGetAccelerationStructureBuildSizesKHR for each of {} info(s) with its maxima",
            self.infos.len()
        ));
        let addr = |a: &Address| match a {
            Address::Raw(v) => format!("{v:#x}"),
            Address::InBuffer { buffer, offset } => format!("`{buffer}`+{offset}"),
        };
        for s in &self.steps {
            if let Step::Call { .. } = s {
                out.push(format!(
                    "{}: vkCmdBuildAccelerationStructuresIndirectKHR({} info(s), indirect [{}], strides {:?}, maxima {:?})",
                    step_text(s),
                    self.infos.len(),
                    self.indirect_addresses.iter().map(addr).collect::<Vec<_>>().join(", "),
                    self.indirect_strides,
                    self.max_primitive_counts
                ));
            } else {
                out.push(step_text(s));
            }
        }
    }
}
