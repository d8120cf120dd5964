//! Strategies for `vkCmdBuildAccelerationStructuresIndirectKHR` cases: a [`BuildPlan`] (geometry kind,
//! per-geometry ranges, indirect stride and offset, boundary values drawn first) realised into a valid
//! [`BuildCase`], and one-VUID mutations of it, each checked against the model so that a case violates
//! exactly its VUID plus the co-violations the device makes unavoidable (declared in `also`).

use model::accel::call::{BuildFlags, GeometryFlags};
use model::accel::world::{identity, InstanceRecord, InstanceReference, LastBuild, LastGeometry};
use model::accel::{
    AccelerationStructure, AsType, BuildBuffer, BuildCase, BuildContents, BuildGeometryInfo,
    BuildIndirect, BuildMode, BuildRuleSet, BuildSizes, BuildWorld, Geometry, GeometryData,
    IndexType, RangeInfo, VertexFormat,
};
use model::call::Address;
use model::flags::{BufferUsage, QueueFlags};
use model::world::{CommandBufferLifecycle, CommandBufferState, DeviceState};
use model::{DeviceProfile, Intent};
use proptest::prelude::*;

/// The VUID of the command's feature rule.
pub const FEATURE_VUID: &str =
    "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650";

/// The full VUID of a tag of the command.
pub fn vuid(tail: &str) -> String {
    format!("VUID-vkCmdBuildAccelerationStructuresIndirectKHR-{tail}")
}

/// Geometry kind of a plan (one kind per build: one structure holds one type).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Triangles {
        index: IndexType,
        transform: bool,
        format: VertexFormat,
    },
    Aabbs,
    Instances {
        pointers: bool,
    },
}

/// One geometry's range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GeometryPlan {
    pub count: u32,
    /// `ppMaxPrimitiveCounts[0][j] - count`.
    pub slack: u32,
    /// primitiveOffset in units of the kind's alignment.
    pub offset_units: u32,
    pub first_vertex: u32,
    pub transform_units: u32,
    /// A primitive made inactive (NaN X / NaN minX / reference 0), if any.
    pub inactive: Option<u32>,
}

/// The knobs of a valid case.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BuildPlan {
    pub kind: Kind,
    pub geometries: Vec<GeometryPlan>,
    /// `pIndirectStrides[0] = 16 + 4 * stride_extra`.
    pub stride_extra: u32,
    /// `pIndirectDeviceAddresses[0]` offset in units of 4.
    pub address_units: u32,
}

/// Sizes assumed when a case is made without a device: generous upper bounds for the small builds the
/// plans make; the harness replaces them with what the device reports and judges again.
pub const ASSUMED: BuildSizes = BuildSizes {
    structure: 1 << 16,
    build_scratch: 1 << 16,
    update_scratch: 1 << 16,
};

fn boundary_first(max: u32) -> BoxedStrategy<u32> {
    prop_oneof![3 => Just(0u32), 2 => Just(max), 5 => 0..=max].boxed()
}

/// Plans, boundary values (0, the largest) drawn first.
pub fn plan_strategy() -> impl Strategy<Value = BuildPlan> {
    let kind = prop_oneof![
        (prop_oneof![Just(IndexType::None), Just(IndexType::Uint16), Just(IndexType::Uint32)], any::<bool>(),
            prop_oneof![3 => Just(VertexFormat::R32g32b32Sfloat), 1 => Just(VertexFormat::R32g32Sfloat), 1 => Just(VertexFormat::R16g16b16a16Sfloat)])
            .prop_map(|(index, transform, format)| Kind::Triangles { index, transform, format }),
        Just(Kind::Aabbs),
        any::<bool>().prop_map(|pointers| Kind::Instances { pointers }),
    ];
    let geometry = (
        boundary_first(4),
        boundary_first(2),
        boundary_first(3),
        boundary_first(2),
        boundary_first(2),
        proptest::option::weighted(0.3, 0u32..4),
    )
        .prop_map(
            |(count, slack, offset_units, first_vertex, transform_units, inactive)| GeometryPlan {
                count,
                slack,
                offset_units,
                first_vertex,
                transform_units,
                inactive: inactive.filter(|i| *i < count),
            },
        );
    (
        kind,
        proptest::collection::vec(geometry, 1..=3),
        boundary_first(4),
        boundary_first(3),
    )
        .prop_map(|(kind, mut geometries, stride_extra, address_units)| {
            if matches!(kind, Kind::Instances { .. }) {
                geometries.truncate(1); // a top-level build has exactly one instance geometry
            }
            BuildPlan {
                kind,
                geometries,
                stride_extra,
                address_units,
            }
        })
}

/// Byte alignment of primitiveOffset for a kind.
fn offset_alignment(kind: Kind) -> u32 {
    match kind {
        Kind::Triangles {
            index: IndexType::None,
            format,
            ..
        } => format.component_size() as u32,
        Kind::Triangles { index, .. } => index.size() as u32,
        Kind::Aabbs => 8,
        Kind::Instances { pointers: true } => 8,
        Kind::Instances { pointers: false } => 16,
    }
}

fn addr(buffer: &str, offset: u64) -> Address {
    Address::InBuffer {
        buffer: buffer.into(),
        offset,
    }
}

fn align_up(v: u64, a: u64) -> u64 {
    v.div_ceil(a) * a
}

/// Where primitive `p` of geometry `g` sits: every primitive has its own 3x3 cell in the plane z = 0.
pub fn cell(g: u32, p: u32) -> (f32, f32) {
    (3.0 * p as f32, 3.0 * g as f32)
}

/// The BLAS every instance of a top-level plan references: one triangle at the origin.
pub const BLAS: &str = "blas";

/// Realises a plan as a case valid on `profile` (apart from the unavoidable co-violations).
pub fn realise(plan: &BuildPlan, profile: &DeviceProfile, name: &str) -> BuildCase {
    let input_usage = BufferUsage::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR
        | BufferUsage::SHADER_DEVICE_ADDRESS_BIT;
    let mut input: Vec<BuildContents> = Vec::new();
    let mut cursor: u64 = 0;
    let mut geometries = Vec::new();
    let mut max_counts = Vec::new();
    let mut ranges = Vec::new();
    let align = offset_alignment(plan.kind) as u64;
    for (g, gp) in plan.geometries.iter().enumerate() {
        let g32 = g as u32;
        let primitive_offset = gp.offset_units * align as u32;
        max_counts.push(gp.count + gp.slack);
        let mut range = RangeInfo {
            primitive_count: gp.count,
            primitive_offset,
            first_vertex: 0,
            transform_offset: 0,
        };
        let data = match plan.kind {
            Kind::Triangles {
                index,
                transform,
                format,
            } => {
                range.first_vertex = gp.first_vertex;
                let stride = align_up(format.size(), 4) + 4; // a gap between vertices
                                                             // Vertices: first_vertex unused ones, then 3 per primitive (max slack included).
                let n_prims = gp.count + gp.slack;
                let mut verts: Vec<[f32; 3]> = vec![[0.0; 3]; gp.first_vertex as usize];
                for p in 0..n_prims {
                    let (cx, cy) = cell(g32, p);
                    let x0 = if gp.inactive == Some(p) {
                        f32::NAN
                    } else {
                        cx - 0.5
                    };
                    verts.extend([
                        [x0, cy - 0.5, 0.0],
                        [cx + 0.5, cy - 0.5, 0.0],
                        [cx, cy + 0.5, 0.0],
                    ]);
                }
                // The transform moves the geometry by (0, 0, 0) plus a zero translation check value.
                let vbase = align_up(cursor, 16);
                let vstart = if index == IndexType::None {
                    vbase
                } else {
                    vbase
                };
                let voff = if index == IndexType::None {
                    primitive_offset as u64
                } else {
                    0
                };
                let mut floats_at = vstart + voff;
                for v in &verts {
                    let comps: Vec<f32> = v[..format.components()].to_vec();
                    let mut vals = comps.clone();
                    if format == VertexFormat::R16g16b16a16Sfloat {
                        vals.push(1.0);
                    }
                    input.push(if format.component_size() == 2 {
                        BuildContents::Halves {
                            offset: floats_at,
                            values: vals,
                        }
                    } else {
                        BuildContents::Floats {
                            offset: floats_at,
                            values: vals,
                        }
                    });
                    floats_at += stride;
                }
                cursor = floats_at;
                let max_vertex = verts.len() as u32;
                let mut index_data = Address::NULL;
                if index != IndexType::None {
                    let ibase = align_up(cursor, 16);
                    index_data = addr("input", ibase);
                    let idx: Vec<u32> = (0..n_prims)
                        .flat_map(|p| [3 * p + 1, 3 * p + 2, 3 * p])
                        .collect();
                    let at = ibase + primitive_offset as u64;
                    input.push(match index {
                        IndexType::Uint16 => BuildContents::U16s {
                            offset: at,
                            values: idx.iter().map(|v| *v as u16).collect(),
                        },
                        IndexType::Uint8 => BuildContents::U8s {
                            offset: at,
                            values: idx.iter().map(|v| *v as u8).collect(),
                        },
                        _ => BuildContents::U32s {
                            offset: at,
                            values: idx.clone(),
                        },
                    });
                    cursor = at + idx.len() as u64 * index.size();
                }
                let mut transform_data = Address::NULL;
                if transform {
                    let tbase = align_up(cursor, 16);
                    transform_data = addr("input", tbase);
                    range.transform_offset = 16 * gp.transform_units;
                    // A translation by (0, 0, 0.25): the built triangles sit at z = 0.25.
                    let mut m = identity();
                    m[11] = 0.25;
                    input.push(BuildContents::Floats {
                        offset: tbase + range.transform_offset as u64,
                        values: m.to_vec(),
                    });
                    cursor = tbase + range.transform_offset as u64 + 48;
                }
                GeometryData::Triangles {
                    vertex_format: format,
                    vertex_data: addr("input", vstart),
                    vertex_stride: stride,
                    max_vertex,
                    index_type: index,
                    index_data,
                    transform_data,
                    motion_vertex_data: None,
                    opacity_micromap: None,
                }
            }
            Kind::Aabbs => {
                let base = align_up(cursor, 16);
                let stride = 32u64;
                for p in 0..gp.count + gp.slack {
                    let (cx, cy) = cell(g32, p);
                    let minx = if gp.inactive == Some(p) {
                        f32::NAN
                    } else {
                        cx - 0.5
                    };
                    input.push(BuildContents::Floats {
                        offset: base + primitive_offset as u64 + p as u64 * stride,
                        values: vec![minx, cy - 0.5, -0.5, cx + 0.5, cy + 0.5, 0.5],
                    });
                }
                cursor = base + primitive_offset as u64 + (gp.count + gp.slack) as u64 * stride;
                GeometryData::Aabbs {
                    data: addr("input", base),
                    stride,
                }
            }
            Kind::Instances { pointers } => {
                let recs_base = align_up(cursor, 64);
                let n = gp.count + gp.slack;
                let instances: Vec<InstanceRecord> = (0..n)
                    .map(|k| {
                        let (cx, cy) = cell(g32, k);
                        let mut t = identity();
                        t[3] = cx;
                        t[7] = cy;
                        InstanceRecord {
                            transform: t,
                            custom_index: k,
                            mask: 0xff,
                            sbt_offset: 0,
                            flags: 0,
                            reference: if gp.inactive == Some(k) {
                                InstanceReference::Null
                            } else {
                                InstanceReference::Structure(BLAS.into())
                            },
                        }
                    })
                    .collect();
                if pointers {
                    // Records packed, in reverse order; the pointer array names them.
                    input.push(BuildContents::Instances {
                        offset: recs_base,
                        instances: instances.iter().rev().cloned().collect(),
                    });
                    let pbase = align_up(recs_base + 64 * n as u64, 16);
                    let targets = (0..n)
                        .map(|k| addr("input", recs_base + 64 * (n - 1 - k) as u64))
                        .collect();
                    input.push(BuildContents::Pointers {
                        offset: pbase + primitive_offset as u64,
                        targets,
                    });
                    cursor = pbase + primitive_offset as u64 + 8 * n as u64;
                    GeometryData::Instances {
                        array_of_pointers: true,
                        data: addr("input", pbase),
                    }
                } else {
                    input.push(BuildContents::Instances {
                        offset: recs_base + primitive_offset as u64,
                        instances,
                    });
                    cursor = recs_base + primitive_offset as u64 + 64 * n as u64;
                    GeometryData::Instances {
                        array_of_pointers: false,
                        data: addr("input", recs_base),
                    }
                }
            }
        };
        geometries.push(Geometry {
            flags: GeometryFlags(1),
            data,
        });
        ranges.push(range);
    }
    let stride = 16 + 4 * plan.stride_extra;
    let ind_off = 4 * plan.address_units as u64;
    let ind_size = ind_off + stride as u64 * ranges.len() as u64 + 16;
    let top = matches!(plan.kind, Kind::Instances { .. });
    let ty = if top {
        AsType::TopLevel
    } else {
        AsType::BottomLevel
    };
    let mut structures = vec![AccelerationStructure {
        name: "dst".into(),
        ty,
        buffer: "storage".into(),
        offset: 0,
        size: ASSUMED.structure,
        last_build: None,
    }];
    if top {
        structures.push(AccelerationStructure {
            name: BLAS.into(),
            ty: AsType::BottomLevel,
            buffer: "storage".into(),
            offset: ASSUMED.structure,
            size: ASSUMED.structure,
            last_build: Some(LastBuild {
                ty: AsType::BottomLevel,
                flags: BuildFlags::default(),
                geometries: vec![],
            }),
        });
    }
    let scratch_align = profile
        .limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::minAccelerationStructureScratchOffsetAlignment")
        .unwrap_or(256)
        .max(256);
    let buffers = vec![
        BuildBuffer {
            name: "input".into(),
            size: align_up(cursor.max(16), 16) + 64,
            usage: input_usage,
            flags: Default::default(),
            memory: Default::default(),
            contents: input,
        },
        BuildBuffer {
            name: "indirect".into(),
            size: ind_size,
            usage: BufferUsage::INDIRECT_BUFFER_BIT | BufferUsage::SHADER_DEVICE_ADDRESS_BIT,
            flags: Default::default(),
            memory: Default::default(),
            contents: vec![BuildContents::Ranges {
                offset: ind_off,
                stride: stride as u64,
                ranges,
            }],
        },
        BuildBuffer {
            name: "storage".into(),
            size: ASSUMED.structure * if top { 2 } else { 1 },
            usage: BufferUsage::ACCELERATION_STRUCTURE_STORAGE_BIT_KHR
                | BufferUsage::SHADER_DEVICE_ADDRESS_BIT,
            flags: Default::default(),
            memory: Default::default(),
            contents: vec![],
        },
        BuildBuffer {
            name: "scratch".into(),
            size: ASSUMED.build_scratch + 2 * scratch_align,
            usage: BufferUsage::STORAGE_BUFFER_BIT | BufferUsage::SHADER_DEVICE_ADDRESS_BIT,
            flags: Default::default(),
            memory: Default::default(),
            contents: vec![],
        },
    ];
    let mut features: std::collections::BTreeSet<String> =
        ["accelerationStructure", "bufferDeviceAddress"]
            .iter()
            .map(|s| s.to_string())
            .collect();
    if profile.has_feature("accelerationStructureIndirectBuild") {
        features.insert("accelerationStructureIndirectBuild".into());
    }
    let extensions = [
        "VK_KHR_acceleration_structure",
        "VK_KHR_deferred_host_operations",
        "VK_KHR_buffer_device_address",
    ]
    .iter()
    .filter(|e| profile.has_extension(e) || profile.api_major_minor() >= (1, 2))
    .map(|s| s.to_string())
    .collect();
    let world = BuildWorld {
        device: DeviceState {
            extensions,
            features,
        },
        buffers,
        structures,
        command_buffer: CommandBufferState::default(),
        between_suspended_render_passes: false,
        sizes: vec![ASSUMED],
    };
    let info = BuildGeometryInfo {
        ty,
        flags: BuildFlags(BuildFlags::PREFER_FAST_TRACE),
        mode: BuildMode::Build,
        src: None,
        dst: Some("dst".into()),
        geometries,
        geometries_by_pointer: false,
        scratch: addr("scratch", 0),
    };
    let call = BuildIndirect {
        infos: vec![info],
        indirect_addresses: vec![addr("indirect", ind_off)],
        indirect_strides: vec![stride],
        max_primitive_counts: vec![max_counts],
    };
    let unavoidable = unavoidable(profile);
    let intent = match unavoidable.split_first() {
        None => Intent::Valid,
        Some((v, rest)) => Intent::Violates {
            vuid: v.clone(),
            also: rest.to_vec(),
        },
    };
    BuildCase {
        name: name.into(),
        profile: profile.name.clone(),
        seed: None,
        intent,
        world,
        call,
    }
}

/// The VUIDs every build case violates on `profile` (the feature when the device lacks it).
pub fn unavoidable(profile: &DeviceProfile) -> Vec<String> {
    if profile.has_feature("accelerationStructureIndirectBuild") {
        vec![]
    } else {
        vec![FEATURE_VUID.into()]
    }
}

/// Whether a case is valid apart from the unavoidable co-violations.
pub fn valid_apart_from_device(case: &BuildCase, profile: &DeviceProfile) -> bool {
    let u = unavoidable(profile);
    case.expected_vuids().iter().all(|v| u.contains(v))
}

/// Shifts every content write of a buffer at or after `from` by `delta` bytes (keeping what is read).
fn shift_contents(b: &mut BuildBuffer, from: u64, delta: u64) {
    for c in &mut b.contents {
        let off = match c {
            BuildContents::Ranges { offset, .. }
            | BuildContents::Floats { offset, .. }
            | BuildContents::Halves { offset, .. }
            | BuildContents::U32s { offset, .. }
            | BuildContents::U16s { offset, .. }
            | BuildContents::U8s { offset, .. }
            | BuildContents::Instances { offset, .. }
            | BuildContents::Pointers { offset, .. } => offset,
        };
        if *off >= from {
            *off += delta;
        }
    }
    b.size += delta;
}

fn buffer_mut<'a>(w: &'a mut BuildWorld, name: &str) -> &'a mut BuildBuffer {
    w.buffers
        .iter_mut()
        .find(|b| b.name == name)
        .expect("generated buffer")
}

fn bump(a: &mut Address, delta: u64) {
    if let Address::InBuffer { offset, .. } = a {
        *offset += delta;
    }
}

/// Applies the mutation for `tail` (`pIndirectStrides-03787`); None when the case has no place for it.
pub fn mutate(case: &BuildCase, tail: &str, profile: &DeviceProfile) -> Option<BuildCase> {
    let mut c = case.clone();
    let w = &mut c.world;
    let call = &mut c.call;
    let tag = tail.rsplit('-').next()?;
    if let Some(two) = mutate_two_infos(case, tag) {
        return settle(two?, case, profile, tail);
    }
    let first_geom = call.infos[0].geometries[0].data.clone();
    match tag {
        "03650" => {
            w.device
                .features
                .remove("accelerationStructureIndirectBuild");
        }
        "03648" => {
            // The records move with the address, so what is read stays the same.
            let Address::InBuffer { offset, .. } = &call.indirect_addresses[0] else {
                return None;
            };
            let from = *offset;
            shift_contents(buffer_mut(w, "indirect"), from, 2);
            bump(&mut call.indirect_addresses[0], 2);
        }
        "03787" => {
            call.indirect_strides[0] += 2;
            let b = buffer_mut(w, "indirect");
            for ct in &mut b.contents {
                if let BuildContents::Ranges { stride, .. } = ct {
                    *stride += 2;
                }
            }
            b.size += 2 * call.infos[0].geometries.len() as u64;
        }
        "03647" => buffer_mut(w, "indirect")
            .usage
            .remove(BufferUsage::INDIRECT_BUFFER_BIT),
        "03645" => buffer_mut(w, "indirect").memory = model::world::MemoryBinding::Scattered,
        "03646" => {
            // Stride 32 leaves room to cut the buffer below n * stride while every record stays inside.
            let n = call.infos[0].geometries.len() as u64;
            call.indirect_strides[0] = 32;
            let off = call.indirect_addresses[0].alignment_value();
            let b = buffer_mut(w, "indirect");
            for ct in &mut b.contents {
                if let BuildContents::Ranges { stride, .. } = ct {
                    *stride = 32;
                }
            }
            b.size = off + n * 32 - 4;
        }
        "03651" => {
            let b = buffer_mut(w, "indirect");
            let BuildContents::Ranges { ranges, .. } = &mut b.contents[0] else {
                return None;
            };
            ranges[0].primitive_offset += 1;
            if matches!(
                first_geom,
                GeometryData::Triangles {
                    index_type: IndexType::None,
                    ..
                }
            ) {
                // non-indexed offsets need only the component size; 1 byte breaks that too
            }
        }
        "03653" => {
            // The maximum drops below the count the record in memory holds.
            if call.max_primitive_counts[0][0] == 0 || case.world.buffers.is_empty() {
                return None;
            }
            let mem = case.world.memory();
            let r = model::accel::indirect_ranges(&mem, &case.call, 0).ok()?;
            if r[0].primitive_count == 0 {
                return None;
            }
            call.max_primitive_counts[0][0] = r[0].primitive_count - 1;
        }
        "03801" => {
            if !matches!(first_geom, GeometryData::Instances { .. }) {
                return None;
            }
            let m = profile
                .limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount")?;
            call.max_primitive_counts[0][0] = u32::try_from(m + 1).ok()?;
        }
        "03674" => buffer_mut(w, "scratch")
            .usage
            .remove(BufferUsage::STORAGE_BUFFER_BIT),
        "03710" => {
            let m = profile.limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::minAccelerationStructureScratchOffsetAlignment")?;
            if m < 2 {
                return None;
            }
            bump(&mut call.infos[0].scratch, m / 2);
        }
        "03671" | "12258" => {
            // Far below what any device asks (the harness judges again with the device's sizes).
            buffer_mut(w, "scratch").size = 8;
        }
        "03802" => call.infos[0].scratch = Address::Raw(0x10_0000),
        // Far below what any device asks (the harness judges again with the device's sizes).
        "03652" => w.structures[0].size = 16,
        "03699" | "03700" => {
            let want = if tag == "03699" {
                AsType::TopLevel
            } else {
                AsType::BottomLevel
            };
            if call.infos[0].ty != want {
                return None;
            }
            w.structures[0].ty = if want == AsType::TopLevel {
                AsType::BottomLevel
            } else {
                AsType::TopLevel
            };
        }
        "03707" => buffer_mut(w, "storage").memory = model::world::MemoryBinding::Unbound,
        "03800" => call.infos[0].dst = None,
        "04628" => call.infos[0].mode = BuildMode::Other(7),
        "04630" => {
            call.infos[0].mode = BuildMode::Update;
            call.infos[0].src = None;
        }
        "03667" => {
            // Update in place from a structure last built without ALLOW_UPDATE, with the same shape.
            let info = &call.infos[0];
            let geometries = info
                .geometries
                .iter()
                .map(|g| last_geometry(&g.data))
                .collect();
            w.structures[0].last_build = Some(LastBuild {
                ty: info.ty,
                flags: info.flags,
                geometries,
            });
            call.infos[0].mode = BuildMode::Update;
            call.infos[0].src = Some("dst".into());
            return finish_update(c, case, profile, tail);
        }
        "03673" => buffer_mut(w, "input")
            .usage
            .remove(BufferUsage::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR),
        "03711" | "03712" | "03714" | "03715" | "03716" | "03810" | "03804" | "03811" | "03813"
        | "03806" | "03808" => {
            let g = &mut call.infos[0].geometries[0].data;
            match (tag, g) {
                (
                    "03711",
                    GeometryData::Triangles {
                        vertex_format: VertexFormat::R32g32b32Sfloat | VertexFormat::R32g32Sfloat,
                        vertex_data,
                        ..
                    },
                ) => {
                    let from = vertex_data.alignment_value();
                    bump(vertex_data, 2);
                    shift_from(w, from, 2, &mut call.infos[0]);
                }
                (
                    "03712",
                    GeometryData::Triangles {
                        index_type: IndexType::Uint16 | IndexType::Uint32,
                        index_data,
                        ..
                    },
                ) => {
                    let from = index_data.alignment_value();
                    bump(index_data, 1);
                    shift_from(w, from, 1, &mut call.infos[0]);
                }
                ("03714", GeometryData::Aabbs { data, .. }) => {
                    let from = data.alignment_value();
                    bump(data, 4);
                    shift_from(w, from, 4, &mut call.infos[0]);
                }
                (
                    "03715",
                    GeometryData::Instances {
                        array_of_pointers: false,
                        data,
                    },
                ) => {
                    let from = data.alignment_value();
                    bump(data, 8);
                    shift_from(w, from, 8, &mut call.infos[0]);
                }
                (
                    "03716",
                    GeometryData::Instances {
                        array_of_pointers: true,
                        data,
                    },
                ) => {
                    let from = data.alignment_value();
                    bump(data, 4);
                    shift_from(w, from, 4, &mut call.infos[0]);
                }
                ("03810", GeometryData::Triangles { transform_data, .. })
                    if !transform_data.is_null() =>
                {
                    let from = transform_data.alignment_value();
                    bump(transform_data, 8);
                    shift_from(w, from, 8, &mut call.infos[0]);
                }
                ("03804", GeometryData::Triangles { vertex_data, .. }) => {
                    *vertex_data = Address::Raw(0x4_0000_0000_0000)
                }
                (
                    "03806",
                    GeometryData::Triangles {
                        index_type: IndexType::Uint16 | IndexType::Uint32,
                        index_data,
                        ..
                    },
                ) => *index_data = Address::Raw(0x4_0000_0000_0000),
                ("03808", GeometryData::Triangles { transform_data, .. })
                    if !transform_data.is_null() =>
                {
                    *transform_data = Address::Raw(0x4_0000_0000_0000)
                }
                ("03811", GeometryData::Aabbs { data, .. }) => {
                    *data = Address::Raw(0x4_0000_0000_0000)
                }
                ("03813", GeometryData::Instances { data, .. }) => {
                    *data = Address::Raw(0x4_0000_0000_0000)
                }
                _ => return None,
            }
            // shift_from moved the bumped target a second time (it lies past `from`): undo that once.
            let delta = match tag {
                "03711" => 2,
                "03712" => 1,
                "03714" | "03716" => 4,
                "03715" | "03810" => 8,
                _ => 0,
            };
            if delta > 0 {
                let target = match (tag, &mut call.infos[0].geometries[0].data) {
                    ("03711", GeometryData::Triangles { vertex_data, .. }) => vertex_data,
                    ("03712", GeometryData::Triangles { index_data, .. }) => index_data,
                    ("03810", GeometryData::Triangles { transform_data, .. }) => transform_data,
                    (
                        _,
                        GeometryData::Aabbs { data, .. } | GeometryData::Instances { data, .. },
                    ) => data,
                    _ => return None,
                };
                if let Address::InBuffer { offset, .. } = target {
                    *offset -= delta;
                }
            }
        }
        "06707" | "12281" => {
            if !matches!(first_geom, GeometryData::Instances { .. }) {
                return None;
            }
            let b = buffer_mut(w, "input");
            let target = if tag == "06707" {
                InstanceReference::Raw(0xdead_0000)
            } else {
                InstanceReference::Structure("dst".into())
            };
            let mut done = false;
            for ct in &mut b.contents {
                if let BuildContents::Instances { instances, .. } = ct {
                    for r in instances.iter_mut() {
                        if r.reference != InstanceReference::Null && !done {
                            r.reference = target.clone();
                            done = true;
                        }
                    }
                }
            }
            if !done {
                return None;
            }
        }
        "recording" => w.command_buffer.lifecycle = CommandBufferLifecycle::Executable,
        "cmdpool" => w.command_buffer.pool_queue = QueueFlags::TRANSFER_BIT,
        "renderpass" => w.command_buffer.in_render_pass = true,
        "videocoding" => w.command_buffer.in_video_coding = true,
        "03649" | "09547" => w.command_buffer.protected = true,
        "arraylength" => {
            call.infos.clear();
            call.indirect_addresses.clear();
            call.indirect_strides.clear();
            call.max_primitive_counts.clear();
        }
        _ => return None,
    }
    settle(c, case, profile, tail)
}

/// The last-build record a geometry would leave (the shape only; ranges filled by the caller).
fn last_geometry(d: &GeometryData) -> LastGeometry {
    let (vertex_format, max_vertex, index_type, has_transform) = match d {
        GeometryData::Triangles {
            vertex_format,
            max_vertex,
            index_type,
            transform_data,
            ..
        } => (
            Some(*vertex_format),
            *max_vertex,
            Some(*index_type),
            !transform_data.is_null(),
        ),
        _ => (None, 0, None, false),
    };
    LastGeometry {
        geometry_type: d.geometry_type(),
        flags: GeometryFlags(1),
        vertex_format,
        max_vertex,
        index_type,
        has_transform,
        dense: None,
        range: RangeInfo::default(),
        indices: vec![],
        active: vec![],
    }
}

/// Completes an update-mode mutation: the last build's ranges, indices and activity are the current ones.
fn finish_update(
    c: BuildCase,
    base: &BuildCase,
    profile: &DeviceProfile,
    tail: &str,
) -> Option<BuildCase> {
    let c = record_last_build(c, 0, "dst")?;
    settle(c, base, profile, tail)
}

/// Gives structure `name` the last build an update of info `i` expects: the info's type, flags and
/// geometries, with the ranges, indices and activity the info reads now.
fn record_last_build(mut c: BuildCase, i: usize, name: &str) -> Option<BuildCase> {
    let mem = c.world.memory();
    let ranges = model::accel::indirect_ranges(&mem, &c.call, i).ok()?;
    let info = &c.call.infos[i];
    let prims = model::accel::build_primitives(&mem, info, &ranges).ok()?;
    let mut geoms = Vec::new();
    for (j, (g, r)) in info.geometries.iter().zip(&ranges).enumerate() {
        let mut lg = last_geometry(&g.data);
        lg.flags = g.flags;
        lg.range = *r;
        lg.indices = model::accel::semantics::range_indices(&mem, &g.data, r, "").ok()?;
        lg.active = prims
            .iter()
            .filter(|p| p.geometry == j as u32)
            .map(|p| p.active)
            .collect();
        geoms.push(lg);
    }
    drop(mem);
    let (ty, flags) = (info.ty, info.flags);
    let s = c.world.structures.iter_mut().find(|s| s.name == name)?;
    match &mut s.last_build {
        // 03667's base: the structure already carries the last build's type and flags.
        Some(lb) if name == "dst" && i == 0 => lb.geometries = geoms,
        lb => {
            *lb = Some(LastBuild {
                ty,
                flags,
                geometries: geoms,
            })
        }
    }
    Some(c)
}

/// A second build info, so rules between infos have a place: the first info's geometries again, building
/// `dst2` (on its own buffer `storage2`) with its own scratch buffer `scratch2`, reading the same range
/// records (a second `pIndirectDeviceAddresses` entry with the first's address and stride) with the same
/// maxima. Valid when the one-info case is: nothing of one info overlaps or names the other's.
pub fn add_second_info(c: &mut BuildCase) {
    let w = &mut c.world;
    let call = &mut c.call;
    let storage = w
        .buffers
        .iter()
        .find(|b| b.name == "storage")
        .expect("generated buffer")
        .clone();
    let scratch = w
        .buffers
        .iter()
        .find(|b| b.name == "scratch")
        .expect("generated buffer")
        .clone();
    w.buffers.push(BuildBuffer {
        name: "storage2".into(),
        size: ASSUMED.structure,
        ..storage
    });
    w.buffers.push(BuildBuffer {
        name: "scratch2".into(),
        ..scratch
    });
    let ty = call.infos[0].ty;
    w.structures.push(AccelerationStructure {
        name: "dst2".into(),
        ty,
        buffer: "storage2".into(),
        offset: 0,
        size: ASSUMED.structure,
        last_build: None,
    });
    w.sizes.push(ASSUMED);
    let mut second = call.infos[0].clone();
    second.dst = Some("dst2".into());
    second.scratch = addr("scratch2", 0);
    call.infos.push(second);
    call.indirect_addresses
        .push(call.indirect_addresses[0].clone());
    call.indirect_strides.push(call.indirect_strides[0]);
    call.max_primitive_counts
        .push(call.max_primitive_counts[0].clone());
}

/// Turns info `i` into an update of `dst` from `src` (ALLOW_UPDATE on the info and on the last build
/// `src` records, with the shape the info reads).
fn make_update(c: BuildCase, i: usize, src: &str) -> Option<BuildCase> {
    let mut c = c;
    let info = &mut c.call.infos[i];
    info.flags = BuildFlags(info.flags.0 | BuildFlags::ALLOW_UPDATE);
    info.mode = BuildMode::Update;
    info.src = Some(src.into());
    record_last_build(c, i, src)
}

/// The mutations that need two build infos (`pInfos-03403`, `dstAccelerationStructure-03698`, …), on
/// the case with [`add_second_info`]; None when the tag is not one of them or the case has no place.
fn mutate_two_infos(case: &BuildCase, tag: &str) -> Option<Option<BuildCase>> {
    let mut c = case.clone();
    if !matches!(
        tag,
        "03698" | "03702" | "03703" | "03704" | "03705" | "03403" | "03407"
    ) {
        return None;
    }
    if c.call.infos.len() != 1 {
        return Some(None);
    }
    add_second_info(&mut c);
    let storage_usage = BufferUsage::ACCELERATION_STRUCTURE_STORAGE_BIT_KHR
        | BufferUsage::SHADER_DEVICE_ADDRESS_BIT
        | BufferUsage::STORAGE_BUFFER_BIT;
    let c = match tag {
        // The same destination twice (its memory then overlaps itself: 03702 too).
        "03698" => {
            c.call.infos[1].dst = Some("dst".into());
            Some(c)
        }
        // Two destinations whose memory overlaps: dst2 256 bytes into dst's buffer.
        "03702" => {
            let s = c.world.structures.iter_mut().find(|s| s.name == "dst2")?;
            s.buffer = "storage".into();
            s.offset = 256;
            let b = buffer_mut(&mut c.world, "storage");
            b.size = b.size.max(256 + ASSUMED.structure);
            Some(c)
        }
        // The second info's scratch lies in the memory backing the first info's destination.
        "03703" => {
            buffer_mut(&mut c.world, "storage").usage = storage_usage;
            c.call.infos[1].scratch = addr("storage", 0);
            Some(c)
        }
        // Both infos use the same scratch memory.
        "03704" => {
            c.call.infos[1].scratch = addr("scratch", 0);
            Some(c)
        }
        // The first info's scratch lies in the memory of the second's update source `old` (its own
        // buffer `storage3`, so nothing else overlaps).
        "03705" => {
            let storage = c
                .world
                .buffers
                .iter()
                .find(|b| b.name == "storage2")?
                .clone();
            c.world.buffers.push(BuildBuffer {
                name: "storage3".into(),
                usage: storage_usage,
                ..storage
            });
            let ty = c.call.infos[1].ty;
            c.world.structures.push(AccelerationStructure {
                name: "old".into(),
                ty,
                buffer: "storage3".into(),
                offset: 0,
                size: ASSUMED.structure,
                last_build: None,
            });
            let mut c = make_update(c, 1, "old")?;
            c.call.infos[0].scratch = addr("storage3", 0);
            Some(c)
        }
        // The second info updates from the first info's destination (whose memory it then reads while
        // the first writes it: 03701 too).
        "03403" => make_update(c, 1, "dst"),
        // A top-level build whose instances reference `blas`, built by the second info in the same call
        // (one triangle).
        "03407" => {
            if c.call.infos[0].ty != AsType::TopLevel {
                return Some(None);
            }
            let input = buffer_mut(&mut c.world, "input");
            let vbase = align_up(input.size, 16);
            input.contents.push(BuildContents::Floats {
                offset: vbase,
                values: vec![-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.0, 0.5, 0.0],
            });
            input.size = vbase + 48;
            let indirect = buffer_mut(&mut c.world, "indirect");
            let rbase = align_up(indirect.size, 16);
            indirect.contents.push(BuildContents::Ranges {
                offset: rbase,
                stride: 16,
                ranges: vec![RangeInfo {
                    primitive_count: 1,
                    ..RangeInfo::default()
                }],
            });
            indirect.size = rbase + 16;
            let info = &mut c.call.infos[1];
            info.ty = AsType::BottomLevel;
            info.dst = Some(BLAS.into());
            info.geometries = vec![Geometry {
                flags: GeometryFlags(1),
                data: GeometryData::Triangles {
                    vertex_format: VertexFormat::R32g32b32Sfloat,
                    vertex_data: addr("input", vbase),
                    vertex_stride: 12,
                    max_vertex: 2,
                    index_type: IndexType::None,
                    index_data: Address::NULL,
                    transform_data: Address::NULL,
                    motion_vertex_data: None,
                    opacity_micromap: None,
                },
            }];
            c.call.indirect_addresses[1] = addr("indirect", rbase);
            c.call.indirect_strides[1] = 16;
            c.call.max_primitive_counts[1] = vec![1];
            c.world.structures.retain(|s| s.name != "dst2");
            c.world.buffers.retain(|b| b.name != "storage2");
            Some(c)
        }
        _ => None,
    };
    Some(c)
}

/// Moves the input contents at or after `from` by `delta`, and every address into `input` at or
/// after `from` with them, so the geometry read is unchanged.
fn shift_from(w: &mut BuildWorld, from: u64, delta: u64, info: &mut BuildGeometryInfo) {
    shift_contents(buffer_mut(w, "input"), from, delta);
    let b = buffer_mut(w, "input");
    for ct in &mut b.contents {
        if let BuildContents::Pointers { targets, .. } = ct {
            for t in targets {
                if t.alignment_value() >= from {
                    bump(t, delta);
                }
            }
        }
    }
    for g in &mut info.geometries {
        let addrs: Vec<&mut Address> = match &mut g.data {
            GeometryData::Triangles {
                vertex_data,
                index_data,
                transform_data,
                ..
            } => vec![vertex_data, index_data, transform_data],
            GeometryData::Aabbs { data, .. } | GeometryData::Instances { data, .. } => vec![data],
            _ => vec![],
        };
        for a in addrs {
            if !a.is_null() && a.alignment_value() > from {
                bump(a, delta);
            }
        }
    }
}

/// Sibling VUIDs that one change violates together in some registry versions (the same rule split by
/// mode or by later text), accepted as declared co-violations.
fn siblings(tag: &str) -> &'static [&'static str] {
    match tag {
        "03674" => &["12261"],
        "03671" => &["12258"],
        "12258" => &["03671"],
        "03802" => &["03671", "12258", "12261"],
        "03649" => &["09547"],
        "09547" => &["03649"],
        "06707" => &["12281"],
        "03800" => &["03652"],
        "03646" => &["03651"],
        "03698" => &["03702"],
        "03403" => &["03701"],
        _ => &[],
    }
}

/// Judges the mutated case; keeps it only when the model's verdict is the target plus the unavoidable
/// and sibling VUIDs, which become its declared `also`.
fn settle(
    mut c: BuildCase,
    _base: &BuildCase,
    profile: &DeviceProfile,
    tail: &str,
) -> Option<BuildCase> {
    let rules = rules_for_settle();
    let target = vuid(tail);
    let got: std::collections::BTreeSet<String> = rules
        .validate(profile, &c.world, &c.call)
        .violations
        .into_iter()
        .map(|v| v.vuid)
        .collect();
    if !got.contains(&target) {
        return None;
    }
    let tag = tail.rsplit('-').next().unwrap_or(tail);
    let allowed: Vec<String> = unavoidable(profile)
        .into_iter()
        .chain(siblings(tag).iter().map(|s| s.to_string()))
        .collect();
    let also: Vec<String> = got.iter().filter(|v| **v != target).cloned().collect();
    if also.iter().any(|v| {
        !allowed
            .iter()
            .any(|a| v == a || v.ends_with(&format!("-{a}")))
    }) {
        return None;
    }
    c.intent = Intent::Violates { vuid: target, also };
    Some(c)
}

thread_local! {
    static RULES: std::cell::RefCell<Option<BuildRuleSet>> = const { std::cell::RefCell::new(None) };
}

/// Sets the rule set mutations are judged with (the registry version the cases are for).
pub fn use_rules(rules: BuildRuleSet) {
    RULES.with(|r| *r.borrow_mut() = Some(rules));
}

fn rules_for_settle() -> BuildRuleSet {
    RULES.with(|r| {
        r.borrow_mut()
            .get_or_insert_with(|| {
                vk_registry::source::load_vuids(std::path::Path::new(
                    vk_registry::source::DEFAULT_REGISTRY_DIR,
                ))
                .map(|set| BuildRuleSet::from_vuids(&set))
                .unwrap_or_default()
            })
            .clone()
    })
}

/// The tails (`pInfos-03710`) the generator has a mutation for.
pub const MUTATIONS: &[&str] = &[
    "accelerationStructureIndirectBuild-03650",
    "pIndirectDeviceAddresses-03648",
    "pIndirectStrides-03787",
    "pIndirectDeviceAddresses-03647",
    "pIndirectDeviceAddresses-03645",
    "pIndirectDeviceAddresses-03646",
    "pIndirectDeviceAddresses-03651",
    "ppMaxPrimitiveCounts-03653",
    "pInfos-03801",
    "pInfos-03674",
    "pInfos-03710",
    "pInfos-03671",
    "pInfos-12258",
    "pInfos-03802",
    "pInfos-03652",
    "pInfos-03699",
    "pInfos-03700",
    "pInfos-03707",
    "dstAccelerationStructure-03800",
    "mode-04628",
    "pInfos-04630",
    "pInfos-03667",
    "geometry-03673",
    "pInfos-03711",
    "pInfos-03712",
    "pInfos-03714",
    "pInfos-03715",
    "pInfos-03716",
    "pInfos-03810",
    "pInfos-03804",
    "pInfos-03806",
    "pInfos-03808",
    "pInfos-03811",
    "pInfos-03813",
    "pInfos-06707",
    "pInfos-12281",
    "commandBuffer-recording",
    "commandBuffer-cmdpool",
    "renderpass",
    "videocoding",
    "commandBuffer-03649",
    "infoCount-arraylength",
    "dstAccelerationStructure-03698",
    "dstAccelerationStructure-03702",
    "dstAccelerationStructure-03703",
    "scratchData-03704",
    "scratchData-03705",
    "pInfos-03403",
    "None-03407",
];

/// Deterministic cases: for each plan drawn from `seed`, the valid case and every mutation that fits.
pub fn generate(profile: &DeviceProfile, seed: u64, plans: usize) -> Vec<BuildCase> {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &bytes),
    );
    let strat = plan_strategy();
    let mut out = Vec::new();
    for k in 0..plans {
        let Ok(tree) = strat.new_tree(&mut runner) else {
            continue;
        };
        let plan = tree.current();
        let mut base = realise(&plan, profile, &format!("build-{seed}-{k}-valid"));
        base.seed = Some(format!("{seed}/{k}"));
        for tail in MUTATIONS {
            if let Some(mut m) = mutate(&base, tail, profile) {
                m.name = format!("build-{seed}-{k}-{tail}");
                out.push(m);
            }
        }
        out.push(base);
    }
    out
}

/// The plan at `(seed, index, attempt)`: each drawn from its own generator, so any index range of a
/// spec can be generated alone (chunked runs) and gives the same cases.
fn plan_at(seed: u64, index: usize, attempt: u32) -> Option<BuildPlan> {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    bytes[8..16].copy_from_slice(&(index as u64).to_le_bytes());
    bytes[16..20].copy_from_slice(&attempt.to_le_bytes());
    bytes[20] = 0xb1; // distinct from `generate`'s streams
    let mut runner = TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &bytes),
    );
    plan_strategy()
        .new_tree(&mut runner)
        .ok()
        .map(|t| t.current())
}

/// The mutation tail of a full VUID of the command, if the generator has one.
pub fn mutation_for(vuid_name: &str) -> Option<&'static str> {
    MUTATIONS.iter().copied().find(|t| vuid(t) == vuid_name)
}

/// Cases `range` of one spec: valid cases (`target` None) or cases violating `target` (a full VUID with
/// a mutation). Case `k` is the first of up to 64 plans drawn for `(seed, k)` that the mutation fits;
/// an index no plan fits gives no case. Names are `build-<seed>-<k>-valid` / `build-<seed>-<k>-<tail>`.
pub fn generate_range(
    profile: &DeviceProfile,
    target: Option<&str>,
    seed: u64,
    range: std::ops::Range<usize>,
) -> Vec<BuildCase> {
    let tail = match target {
        None => None,
        Some(v) => match mutation_for(v) {
            Some(t) => Some(t),
            None => return vec![],
        },
    };
    let mut out = Vec::new();
    for k in range {
        for attempt in 0..64u32 {
            let Some(plan) = plan_at(seed, k, attempt) else {
                continue;
            };
            let mut base = realise(&plan, profile, &format!("build-{seed}-{k}-valid"));
            base.seed = Some(format!("{seed}/{k}/{attempt}"));
            let case = match tail {
                None => Some(base),
                Some(t) => mutate(&base, t, profile).map(|mut m| {
                    m.name = format!("build-{seed}-{k}-{t}");
                    m
                }),
            };
            if let Some(c) = case {
                out.push(c);
                break;
            }
        }
    }
    out
}
