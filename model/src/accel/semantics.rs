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
                .map(|b| RangeInfo::from_bytes(&b))
                .ok_or_else(|| {
                    err(
                        format!("range record {j} of pInfos[{i}]"),
                        "lies outside every buffer of the world",
                    )
                })
        })
        .collect()
}

/// The YAML path (`world.buffers[1].contents[0].ranges[0]`) of the range record of info `i` that states
/// the most primitives, where a `ranges` write of the world put it.
pub fn largest_range_record(world: &BuildWorld, call: &BuildIndirect, i: usize) -> Option<String> {
    let n = call.infos.get(i).map_or(0, |g| g.geometries.len());
    let mem = world.memory();
    let largest = (0..n)
        .filter_map(|j| {
            let a = call.range_address(i, j)?;
            let count = mem
                .read(&a, RangeInfo::SIZE)
                .map(|b| RangeInfo::from_bytes(&b))?;
            Some((count.primitive_count, a))
        })
        .max_by_key(|(count, _)| *count)?;
    let (name, at) = largest.1.buffer()?;
    let b = world.buffers.iter().position(|b| b.name == name)?;
    world.buffers[b]
        .contents
        .iter()
        .enumerate()
        .rev()
        .find_map(|(c, w)| match w {
            super::world::BuildContents::Ranges {
                offset,
                stride,
                ranges,
            } => (0..ranges.len()).find_map(|k| {
                let start = (k as u64).checked_mul(*stride)?.checked_add(*offset)?;
                (start == at).then(|| format!("world.buffers[{b}].contents[{c}].ranges[{k}]"))
            }),
            _ => None,
        })
}

/// Where vertex `k` of primitive `p` of a triangle geometry is read: index (or 3p + k, without
/// indices) plus firstVertex, times the stride, from the vertex data (plus primitiveOffset without
/// indices).
fn vertex_address(
    vertex_data: &Address,
    stride: u64,
    index_type: IndexType,
    indices: &[u32],
    range: &RangeInfo,
    (p, k): (u32, usize),
    ctx: &str,
) -> Result<Address, ReadError> {
    Ok(if index_type == IndexType::None {
        let n = range.first_vertex as u64 + 3 * p as u64 + k as u64;
        offset(
            vertex_data,
            element(range.primitive_offset as u64, n, stride, ctx)?,
        )
    } else {
        let n = indices[3 * p as usize + k] as u64 + range.first_vertex as u64;
        offset(vertex_data, element(0, n, stride, ctx)?)
    })
}

/// Per built primitive, in [`build_primitives`]' order, the fourth component of each vertex of a
/// triangle read in a four-component format under a geometry transform; None for every other
/// primitive. The specification does not say what that component means: the model's position is the
/// first three (an affine transform of a point in 3D, as DirectX Raytracing states for the same
/// format), so a build may only read it otherwise, which `check::deviation` asks.
pub fn transformed_fourth_components(
    mem: &Memory,
    info: &BuildGeometryInfo,
    ranges: &[RangeInfo],
) -> Result<Vec<Option<[f32; 3]>>, ReadError> {
    let mut out = Vec::new();
    for (g, (geom, range)) in info.geometries.iter().zip(ranges).enumerate() {
        let format = match &geom.data {
            GeometryData::Triangles {
                vertex_format,
                transform_data,
                ..
            } if !transform_data.is_null() && vertex_format.has_fourth() => *vertex_format,
            _ => {
                out.extend((0..range.primitive_count).map(|_| None));
                continue;
            }
        };
        let ctx = format!("pGeometries[{g}]");
        let addresses = triangle_vertex_addresses(mem, &geom.data, range, &ctx)?;
        for corners in addresses.chunks_exact(3) {
            let mut w = [1.0f32; 3];
            for (x, a) in w.iter_mut().zip(corners) {
                let bytes = mem
                    .read(a, format.size())
                    .ok_or_else(|| err(ctx.clone(), "vertex lies outside every buffer"))?;
                *x = half_to_f32(u16::from_le_bytes([bytes[6], bytes[7]]));
            }
            out.push(Some(w));
        }
    }
    Ok(out)
}

/// Where each vertex of each primitive of a triangle geometry's range is read, three per primitive in
/// order ([`vertex_address`]); none for other geometry.
fn triangle_vertex_addresses(
    mem: &Memory,
    data: &GeometryData,
    range: &RangeInfo,
    ctx: &str,
) -> Result<Vec<Address>, ReadError> {
    let GeometryData::Triangles {
        vertex_data,
        vertex_stride,
        index_type,
        ..
    } = data
    else {
        return Ok(vec![]);
    };
    let indices = range_indices(mem, data, range, ctx)?;
    let mut out = Vec::new();
    for p in 0..range.primitive_count {
        for k in 0..3 {
            out.push(vertex_address(
                vertex_data,
                *vertex_stride,
                *index_type,
                &indices,
                range,
                (p, k),
                ctx,
            )?);
        }
    }
    Ok(out)
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
    let r = u64::from_le_bytes([b[56], b[57], b[58], b[59], b[60], b[61], b[62], b[63]]);
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
    if range.primitive_count as u64 > MOST_PRIMITIVES_BUILT {
        return Err(err(
            ctx.into(),
            "states more primitives than the model reads indices of",
        ));
    }
    let base = offset(index_data, range.primitive_offset as u64);
    (0..3 * range.primitive_count as u64)
        .map(|k| read_index(mem, *index_type, &offset(&base, k * index_type.size()), ctx))
        .collect()
}

/// The most primitives the model builds for one info: a range states its count (up to u32::MAX, and
/// at stride 0 every primitive reads the same bytes), and the model never allocates from a stated count.
/// A build of more has no meaning in the model (a [`ReadError`]: no traced check, no update comparison)
/// and is judged by its rules alone; the checks trace a ray per primitive, far fewer than this.
pub const MOST_PRIMITIVES_BUILT: u64 = 1 << 20;

/// `base + index * stride` in bytes, or an error when it passes u64::MAX (no buffer reaches there).
fn element(base: u64, index: u64, stride: u64, ctx: &str) -> Result<u64, ReadError> {
    index
        .checked_mul(stride)
        .and_then(|d| d.checked_add(base))
        .ok_or_else(|| err(ctx.into(), "lies past the end of the address space"))
}

/// The primitives one build info builds from its ranges (one per geometry, in geometry order).
pub fn build_primitives(
    mem: &Memory,
    info: &BuildGeometryInfo,
    ranges: &[RangeInfo],
) -> Result<Vec<BuiltPrimitive>, ReadError> {
    let stated: u64 = info
        .geometries
        .iter()
        .zip(ranges)
        .map(|(_, r)| r.primitive_count as u64)
        .sum();
    if stated > MOST_PRIMITIVES_BUILT {
        return Err(err(
            "pInfos".into(),
            &format!(
                "the ranges state {stated} primitives, more than the model builds ({MOST_PRIMITIVES_BUILT})"
            ),
        ));
    }
    let mut out = Vec::new();
    for (g, (geom, range)) in info.geometries.iter().zip(ranges).enumerate() {
        let ctx = format!("pGeometries[{g}]");
        match &geom.data {
            GeometryData::Triangles {
                vertex_format,
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
                let addresses = triangle_vertex_addresses(mem, &geom.data, range, &ctx)?;
                for (p, corners) in (0..range.primitive_count).zip(addresses.chunks_exact(3)) {
                    let mut tri = [[0.0f32; 3]; 3];
                    let mut active = true;
                    for (v, a) in tri.iter_mut().zip(corners) {
                        let raw = read_vertex(mem, *vertex_format, a, &ctx)?;
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
                    let at = element(range.primitive_offset as u64, p as u64, *stride, &ctx)?;
                    let a = offset(data, at);
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
