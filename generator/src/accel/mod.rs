//! Strategies for `vkCmdBuildAccelerationStructuresIndirectKHR` cases: a [`BuildPlan`] (geometry kind,
//! per-geometry ranges, indirect stride and offset, boundary values drawn first) realised into a valid
//! build case, and one-VUID mutations of it ([`mutate`]), each judged with the rules it is given so
//! that a case violates exactly its VUID plus the co-violations the device makes unavoidable
//! (declared in `also`).

mod mutate;

pub use mutate::{add_second_info, mutate};

use model::accel::call::{BuildFlags, GeometryFlags};
use model::accel::world::{identity, InstanceRecord, InstanceReference, LastBuild, LastGeometry};
use model::accel::{
    AccelerationStructure, AsType, BuildBuffer, BuildContents, BuildGeometryInfo, BuildIndirect,
    BuildMode, BuildSizes, BuildWorld, Geometry, GeometryData, IndexType, RangeInfo, VertexFormat,
};
use model::call::Address;
use model::flags::{BufferUsage, QueueFlags};
use model::rules::RuleSet;
use model::world::{CommandBufferLifecycle, CommandBufferState, DeviceState};
use model::Case;
use model::{DeviceProfile, Intent};
use proptest::prelude::*;

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

/// The plan with each instance geometry's records (its count and slack) within the profile's
/// `maxInstanceCount`: a device reporting fewer than the specification's 2^24-1 (a conformance
/// finding the run prints) still gets valid cases that are valid on it.
fn within_instance_limit(plan: &BuildPlan, profile: &DeviceProfile) -> BuildPlan {
    let mut plan = plan.clone();
    let limit =
        profile.limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount");
    if let (Kind::Instances { .. }, Some(max)) = (plan.kind, limit) {
        let max = u32::try_from(max).unwrap_or(u32::MAX);
        for g in &mut plan.geometries {
            g.count = g.count.min(max);
            g.slack = g.slack.min(max - g.count);
            g.inactive = g.inactive.filter(|i| *i < g.count);
        }
    }
    plan
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
pub fn realise(plan: &BuildPlan, profile: &DeviceProfile, name: &str) -> Case {
    let plan = &within_instance_limit(plan, profile);
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
                let vstart = vbase;
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
    let unavoidable = model::accel::unavoidable(profile);
    let intent = match unavoidable.split_first() {
        None => Intent::Valid,
        Some((v, rest)) => Intent::Violates {
            vuid: v.clone(),
            also: rest.to_vec(),
        },
    };
    Case::accel(name, &profile.name, intent, world, call)
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
    "commandBuffer-09547",
    "infoCount-arraylength",
    "dstAccelerationStructure-03698",
    "dstAccelerationStructure-03702",
    "dstAccelerationStructure-03703",
    "scratchData-03704",
    "scratchData-03705",
    "pInfos-03403",
    "None-03407",
];

/// The executable build rows no mutation targets, each with why (by VUID tail): the coverage report
/// lists them as untested with the reason; a row with neither a mutation nor a reason is its error.
pub const UNMUTATED: &[(&str, &str)] = &[
    (
        "dstAccelerationStructure-03701",
        "drawn as a co-violation by the pInfos-03403 cases (an update whose source is another info's destination)",
    ),
    (
        "dstAccelerationStructure-03706",
        "needs a destination overlapping a structure an instance references; the build plans realise no such aliasing yet",
    ),
    (
        "pInfos-03663",
        "an update making inactive primitives active needs the source's earlier build on the device, which the harness does not realise",
    ),
    (
        "pInfos-03664",
        "an update making active primitives inactive needs the source's earlier build on the device, which the harness does not realise",
    ),
    (
        "pInfos-03668",
        "needs an update whose source and destination alias memory without being the same structure; no build plan places them so yet",
    ),
    (
        "pInfos-03672",
        "the update-scratch range needs an update the device can size; the build-scratch twin pInfos-03671 has its mutation",
    ),
    (
        "pInfos-03708",
        "a source structure on a buffer with no memory: the destination's twin pInfos-03707 has its mutation, the source's is not written yet",
    ),
    (
        "pInfos-03709",
        "needs a top-level build whose instances reference a structure on unbound memory; not written yet",
    ),
    (
        "pInfos-03717",
        "arrays of instance pointers are not planned by the build generator",
    ),
    (
        "pInfos-03758",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03759",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03760",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03761",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03762",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03763",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03764",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03765",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03766",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03767",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03768",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "primitiveCount-03769",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "firstVertex-03770",
        "a mismatch with the source's last build is judged by the model, but the layer sees the device, where the harness does not replay that build",
    ),
    (
        "pInfos-03803",
        "a non-sparse buffer is bound whole or not at all, and an unbound one's address is itself invalid to query (VUID-VkBufferDeviceAddressInfo-buffer-02600); the pIndirectDeviceAddresses-03645 cases show it is not realisable",
    ),
    (
        "pInfos-03805",
        "a non-sparse buffer is bound whole or not at all, and an unbound one's address is itself invalid to query (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
    ),
    (
        "pInfos-03807",
        "a non-sparse buffer is bound whole or not at all, and an unbound one's address is itself invalid to query (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
    ),
    (
        "pInfos-03809",
        "a non-sparse buffer is bound whole or not at all, and an unbound one's address is itself invalid to query (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
    ),
    (
        "pInfos-03812",
        "a non-sparse buffer is bound whole or not at all, and an unbound one's address is itself invalid to query (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
    ),
    (
        "pInfos-03814",
        "a non-sparse buffer is bound whole or not at all, and an unbound one's address is itself invalid to query (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
    ),
    (
        "srcAccelerationStructure-04629",
        "a non-null handle that is not a valid structure cannot be made without handing the driver a dangling handle",
    ),
];

/// Why no mutation targets a build VUID, if the generator says why.
pub fn unmutated(vuid_name: &str) -> Option<&'static str> {
    UNMUTATED
        .iter()
        .find(|(t, _)| vuid(t) == vuid_name)
        .map(|(_, why)| *why)
}

/// Deterministic cases: for each plan drawn from `seed`, the valid case and every mutation that fits,
/// each mutation judged with `rules`.
pub fn generate(profile: &DeviceProfile, rules: &RuleSet, seed: u64, plans: usize) -> Vec<Case> {
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
            if let Some(mut m) = mutate(&base, tail, profile, rules) {
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
    rules: &RuleSet,
    target: Option<&str>,
    seed: u64,
    range: std::ops::Range<usize>,
) -> Vec<Case> {
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
                Some(t) => mutate(&base, t, profile, rules).map(|mut m| {
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
