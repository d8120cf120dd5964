//! The meaning of a valid build (semantics.md §4, §8): from the range records to the exact primitives
//! built — triangle positions after index, firstVertex and transform; AABBs; instance records — with
//! inactive primitives marked and PrimitiveId counted from the start of each range.
//!
//! [`build_primitives`] takes the ranges as values, so a direct build and an indirect build whose
//! records in memory hold the same ranges have one meaning by construction; [`indirect_ranges`] reads
//! the records of an indirect call from the memory image.

use super::call::{BuildGeometryInfo, BuildIndirect, GeometryData, IndexType, VertexFormat};
use super::world::{half_to_f32, offset, BuildWorld, InstanceRecord, Memory, RangeInfo};
use crate::call::Address;

/// What one built primitive is.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Shape {
    /// Three positions in the structure's space (transform applied).
    Triangle([[f32; 3]; 3]),
    Aabb {
        min: [f32; 3],
        max: [f32; 3],
    },
    Instance(InstanceRecord),
}

/// One primitive of a build.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BuiltPrimitive {
    /// Index of the geometry in the info (`GeometryIndex`).
    pub geometry: u32,
    /// `PrimitiveId` (for instances: the instance index within the geometry's range).
    pub primitive: u32,
    pub active: bool,
    pub shape: Shape,
}

/// Why a build has no meaning: it reads memory no buffer of the world holds (undefined behaviour).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{context}: {problem}")]
pub struct ReadError {
    pub context: String,
    pub problem: String,
}

fn err(context: String, problem: &str) -> ReadError {
    ReadError {
        context,
        problem: problem.into(),
    }
}

/// The range records of info `i` of an indirect call, read from memory.
pub fn indirect_ranges(
    mem: &Memory,
    call: &BuildIndirect,
    i: usize,
) -> Result<Vec<RangeInfo>, ReadError> {
    let n = call.infos.get(i).map_or(0, |g| g.geometries.len());
    (0..n)
        .map(|j| {
            let a = call
                .range_address(i, j)
                .ok_or_else(|| err(format!("pIndirectDeviceAddresses[{i}]"), "missing"))?;
            mem.read(&a, RangeInfo::SIZE)
                .map(RangeInfo::from_bytes)
                .ok_or_else(|| {
                    err(
                        format!("range record {j} of pInfos[{i}]"),
                        "lies outside every buffer of the world",
                    )
                })
        })
        .collect()
}

fn read_vertex(
    mem: &Memory,
    fmt: VertexFormat,
    a: &Address,
    ctx: &str,
) -> Result<[f32; 3], ReadError> {
    let bytes = mem
        .read(a, fmt.size())
        .ok_or_else(|| err(ctx.into(), "vertex lies outside every buffer"))?;
    let mut v = [0.0f32; 3];
    for (c, out) in v.iter_mut().enumerate().take(fmt.components()) {
        *out = match fmt.component_size() {
            4 => f32::from_le_bytes(bytes[c * 4..c * 4 + 4].try_into().expect("4 bytes")),
            _ => half_to_f32(u16::from_le_bytes([bytes[c * 2], bytes[c * 2 + 1]])),
        };
    }
    Ok(v)
}

fn read_index(mem: &Memory, ty: IndexType, a: &Address, ctx: &str) -> Result<u32, ReadError> {
    let b = mem
        .read(a, ty.size())
        .ok_or_else(|| err(ctx.into(), "index lies outside every buffer"))?;
    Ok(match ty {
        IndexType::Uint8 => b[0] as u32,
        IndexType::Uint16 => u16::from_le_bytes([b[0], b[1]]) as u32,
        IndexType::Uint32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        IndexType::None => 0,
    })
}

/// Applies a row-major 3x4 transform.
pub fn transform_point(m: &[f32; 12], p: [f32; 3]) -> [f32; 3] {
    let r = |k: usize| m[4 * k] * p[0] + m[4 * k + 1] * p[1] + m[4 * k + 2] * p[2] + m[4 * k + 3];
    [r(0), r(1), r(2)]
}

/// Reads one instance record.
pub fn read_instance(mem: &Memory, a: &Address, ctx: &str) -> Result<InstanceRecord, ReadError> {
    let b = mem
        .read(a, 64)
        .ok_or_else(|| err(ctx.into(), "instance record lies outside every buffer"))?;
    let w = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
    let mut transform = [0.0f32; 12];
    for (k, t) in transform.iter_mut().enumerate() {
        *t = f32::from_bits(w(4 * k));
    }
    let (w0, w1) = (w(48), w(52));
    let r = u64::from_le_bytes(b[56..64].try_into().expect("8 bytes"));
    Ok(InstanceRecord {
        transform,
        custom_index: w0 & 0xff_ffff,
        mask: (w0 >> 24) as u8,
        sbt_offset: w1 & 0xff_ffff,
        flags: (w1 >> 24) as u8,
        reference: mem.decode_structure(r),
    })
}

/// The address of instance `k` of a range (through the pointer array when `array_of_pointers`).
pub fn instance_address(
    mem: &Memory,
    data: &Address,
    array_of_pointers: bool,
    range: &RangeInfo,
    k: u32,
    ctx: &str,
) -> Result<Address, ReadError> {
    let base = offset(data, range.primitive_offset as u64);
    if array_of_pointers {
        let p = offset(&base, 8 * k as u64);
        mem.pointer_at(&p)
            .ok_or_else(|| err(ctx.into(), "instance pointer lies outside every buffer"))
    } else {
        Ok(offset(&base, 64 * k as u64))
    }
}

/// The index values a triangle range reads (empty when not indexed).
pub fn range_indices(
    mem: &Memory,
    data: &GeometryData,
    range: &RangeInfo,
    ctx: &str,
) -> Result<Vec<u32>, ReadError> {
    let GeometryData::Triangles {
        index_type,
        index_data,
        ..
    } = data
    else {
        return Ok(vec![]);
    };
    if *index_type == IndexType::None {
        return Ok(vec![]);
    }
    let base = offset(index_data, range.primitive_offset as u64);
    (0..3 * range.primitive_count as u64)
        .map(|k| read_index(mem, *index_type, &offset(&base, k * index_type.size()), ctx))
        .collect()
}

/// The primitives one build info builds from its ranges (one per geometry, in geometry order).
pub fn build_primitives(
    mem: &Memory,
    info: &BuildGeometryInfo,
    ranges: &[RangeInfo],
) -> Result<Vec<BuiltPrimitive>, ReadError> {
    let mut out = Vec::new();
    for (g, (geom, range)) in info.geometries.iter().zip(ranges).enumerate() {
        let ctx = format!("pGeometries[{g}]");
        match &geom.data {
            GeometryData::Triangles {
                vertex_format,
                vertex_data,
                vertex_stride,
                index_type,
                transform_data,
                ..
            } => {
                let transform = if transform_data.is_null() {
                    None
                } else {
                    let a = offset(transform_data, range.transform_offset as u64);
                    let mut m = [0.0f32; 12];
                    for (k, v) in m.iter_mut().enumerate() {
                        *v = mem.f32_at(&offset(&a, 4 * k as u64)).ok_or_else(|| {
                            err(ctx.clone(), "transform lies outside every buffer")
                        })?;
                    }
                    Some(m)
                };
                let indices = range_indices(mem, &geom.data, range, &ctx)?;
                for p in 0..range.primitive_count {
                    let mut tri = [[0.0f32; 3]; 3];
                    let mut active = true;
                    for (k, v) in tri.iter_mut().enumerate() {
                        let a = if *index_type == IndexType::None {
                            let n = range.first_vertex as u64 + 3 * p as u64 + k as u64;
                            offset(
                                vertex_data,
                                range.primitive_offset as u64 + n * vertex_stride,
                            )
                        } else {
                            let n = indices[3 * p as usize + k] as u64 + range.first_vertex as u64;
                            offset(vertex_data, n * vertex_stride)
                        };
                        let raw = read_vertex(mem, *vertex_format, &a, &ctx)?;
                        active &= !raw[0].is_nan();
                        *v = transform.as_ref().map_or(raw, |m| transform_point(m, raw));
                    }
                    out.push(BuiltPrimitive {
                        geometry: g as u32,
                        primitive: p,
                        active,
                        shape: Shape::Triangle(tri),
                    });
                }
            }
            GeometryData::Aabbs { data, stride } => {
                for p in 0..range.primitive_count {
                    let a = offset(data, range.primitive_offset as u64 + p as u64 * stride);
                    let mut f = [0.0f32; 6];
                    for (k, v) in f.iter_mut().enumerate() {
                        *v = mem
                            .f32_at(&offset(&a, 4 * k as u64))
                            .ok_or_else(|| err(ctx.clone(), "AABB lies outside every buffer"))?;
                    }
                    out.push(BuiltPrimitive {
                        geometry: g as u32,
                        primitive: p,
                        active: !f[0].is_nan(),
                        shape: Shape::Aabb {
                            min: [f[0], f[1], f[2]],
                            max: [f[3], f[4], f[5]],
                        },
                    });
                }
            }
            GeometryData::Instances {
                array_of_pointers,
                data,
            } => {
                for p in 0..range.primitive_count {
                    let a = instance_address(mem, data, *array_of_pointers, range, p, &ctx)?;
                    let rec = read_instance(mem, &a, &ctx)?;
                    let active = rec.reference != super::world::InstanceReference::Null;
                    out.push(BuiltPrimitive {
                        geometry: g as u32,
                        primitive: p,
                        active,
                        shape: Shape::Instance(rec),
                    });
                }
            }
            _ => return Err(err(ctx, "the model gives no meaning to this geometry type")),
        }
    }
    Ok(out)
}

/// The primitives each info of an indirect call builds, read through its range records.
pub fn indirect_build(
    world: &BuildWorld,
    call: &BuildIndirect,
) -> Result<Vec<Vec<BuiltPrimitive>>, ReadError> {
    let mem = world.memory();
    (0..call.infos.len())
        .map(|i| {
            let ranges = indirect_ranges(&mem, call, i)?;
            build_primitives(&mem, &call.infos[i], &ranges)
        })
        .collect()
}

/// The primitives a direct build (`vkCmdBuildAccelerationStructuresKHR`) with these ranges builds.
pub fn direct_build(
    world: &BuildWorld,
    infos: &[BuildGeometryInfo],
    ranges: &[Vec<RangeInfo>],
) -> Result<Vec<Vec<BuiltPrimitive>>, ReadError> {
    let mem = world.memory();
    infos
        .iter()
        .zip(ranges)
        .map(|(info, r)| build_primitives(&mem, info, r))
        .collect()
}
