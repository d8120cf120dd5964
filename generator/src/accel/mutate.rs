//! One-VUID mutations of a valid build case: each edits the world or the call so the case breaks its
//! target rule, and is kept only when the model's verdict is the target plus what the device makes
//! unavoidable and the rules the edit cannot help breaking with it (declared in `also`).

use super::*;
use model::{AccelBody, Body};

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
pub fn mutate(case: &Case, tail: &str, profile: &DeviceProfile, rules: &RuleSet) -> Option<Case> {
    let base = case.as_accel()?;
    let mut c = base.clone();
    let w = &mut c.world;
    let call = &mut c.call;
    let tag = tail.rsplit('-').next()?;
    if let Some(two) = mutate_two_infos(base, tag) {
        return settle(two?, case, profile, rules, tail);
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
            if call.max_primitive_counts[0][0] == 0 || base.world.buffers.is_empty() {
                return None;
            }
            let mem = base.world.memory();
            let r = model::accel::indirect_ranges(&mem, &base.call, 0).ok()?;
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
            return finish_update(c, case, profile, rules, tail);
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
    settle(c, case, profile, rules, tail)
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
    c: AccelBody,
    base: &Case,
    profile: &DeviceProfile,
    rules: &RuleSet,
    tail: &str,
) -> Option<Case> {
    let c = record_last_build(c, 0, "dst")?;
    settle(c, base, profile, rules, tail)
}

/// Gives structure `name` the last build an update of info `i` expects: the info's type, flags and
/// geometries, with the ranges, indices and activity the info reads now.
fn record_last_build(mut c: AccelBody, i: usize, name: &str) -> Option<AccelBody> {
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
pub fn add_second_info(c: &mut AccelBody) {
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
fn make_update(c: AccelBody, i: usize, src: &str) -> Option<AccelBody> {
    let mut c = c;
    let info = &mut c.call.infos[i];
    info.flags = BuildFlags(info.flags.0 | BuildFlags::ALLOW_UPDATE);
    info.mode = BuildMode::Update;
    info.src = Some(src.into());
    record_last_build(c, i, src)
}

/// The mutations that need two build infos (`pInfos-03403`, `dstAccelerationStructure-03698`, …), on
/// the case with [`add_second_info`]; None when the tag is not one of them or the case has no place.
fn mutate_two_infos(case: &AccelBody, tag: &str) -> Option<Option<AccelBody>> {
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
    c: AccelBody,
    base: &Case,
    profile: &DeviceProfile,
    rules: &RuleSet,
    tail: &str,
) -> Option<Case> {
    let target = vuid(tail);
    let mut c = Case {
        body: Body::Accel(c),
        ..base.clone()
    };
    let got: std::collections::BTreeSet<String> = model::validate(rules, profile, &c)
        .violations
        .into_iter()
        .map(|v| v.vuid)
        .collect();
    if !got.contains(&target) {
        return None;
    }
    let tag = tail.rsplit('-').next().unwrap_or(tail);
    let allowed: Vec<String> = model::accel::unavoidable(profile)
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
