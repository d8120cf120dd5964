//! The checks of the build command's own predicates, each against the world's memory image.

use super::*;
use crate::flags::BufferUsage;

/// Checks one build predicate; every failure found is pushed.
pub(crate) fn check(p: &AccelPredicate, cx: &AccelContext, out: &mut Out) {
    use AccelPredicate as P;
    let w = cx.world;
    let call = cx.call;
    match p {
        P::IndirectAddressMultipleOf(m) => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                if a.alignment_value() % m != 0 {
                    push(
                        out,
                        format!("pIndirectDeviceAddresses[{i}]"),
                        format!("offset {} is not a multiple of {m}", a.alignment_value()),
                    );
                }
            }
        }
        P::IndirectStrideMultipleOf(m) => {
            for (i, s) in call.indirect_strides.iter().enumerate() {
                if *s as u64 % m != 0 {
                    push(
                        out,
                        format!("pIndirectStrides[{i}]"),
                        format!("{s} is not a multiple of {m}"),
                    );
                }
            }
        }
        P::InfoCountPositive => {
            if call.infos.is_empty() {
                push(out, "infoCount", "is 0");
            }
        }
        P::ModeValid => {
            for (i, info) in call.infos.iter().enumerate() {
                if let BuildMode::Other(v) = info.mode {
                    push(
                        out,
                        format!("pInfos[{i}].mode"),
                        format!("{v} is not a VkBuildAccelerationStructureModeKHR value"),
                    );
                }
            }
        }
        P::DstValid => {
            for (i, info) in call.infos.iter().enumerate() {
                match &info.dst {
                    None => push(
                        out,
                        format!("pInfos[{i}].dstAccelerationStructure"),
                        "is VK_NULL_HANDLE",
                    ),
                    Some(n) if w.structure(n).is_none() => push(
                        out,
                        format!("pInfos[{i}].dstAccelerationStructure"),
                        format!("`{n}` is not a structure of the world"),
                    ),
                    _ => {}
                }
            }
        }
        P::SrcValidIfNotNull => {
            for (i, info) in call.infos.iter().enumerate() {
                if let Some(n) = &info.src {
                    if w.structure(n).is_none() {
                        push(
                            out,
                            format!("pInfos[{i}].srcAccelerationStructure"),
                            format!("`{n}` is not a structure of the world"),
                        );
                    }
                }
            }
        }
        P::SrcNotNullIfUpdate => {
            for (i, info) in call.infos.iter().enumerate() {
                if is_update(info) && info.src.is_none() {
                    push(
                        out,
                        format!("pInfos[{i}].srcAccelerationStructure"),
                        "is VK_NULL_HANDLE in update mode",
                    );
                }
            }
        }
        P::DistinctDst => {
            for (i, a) in call.infos.iter().enumerate() {
                for (j, b) in call.infos.iter().enumerate().skip(i + 1) {
                    if a.dst.is_some() && a.dst == b.dst {
                        push(
                            out,
                            format!("pInfos[{j}].dstAccelerationStructure"),
                            format!("is also the destination of pInfos[{i}]"),
                        );
                    }
                }
            }
        }
        P::SrcNotOtherDst => {
            for (i, a) in call.infos.iter().enumerate() {
                for (j, b) in call.infos.iter().enumerate() {
                    if i != j && a.src.is_some() && a.src == b.dst {
                        push(
                            out,
                            format!("pInfos[{i}].srcAccelerationStructure"),
                            format!("is the destination of pInfos[{j}]"),
                        );
                    }
                }
            }
        }
        P::DstNotInstancedByOther => {
            for (i, a) in call.infos.iter().enumerate() {
                let Some(dst) = &a.dst else { continue };
                for j in (0..call.infos.len()).filter(|j| *j != i) {
                    for (ctx, n) in referenced_structures(cx, j) {
                        if &n == dst {
                            push(
                                out,
                                ctx,
                                format!("references `{dst}`, the destination of pInfos[{i}]"),
                            );
                        }
                    }
                }
            }
        }
        P::NoOverlap(kind) => update::check_overlap(*kind, cx, out),
        P::Keep(k) => update::check_keep(*k, cx, out),
        P::InputUsage => {
            for (i, info) in call.infos.iter().enumerate() {
                for f in [
                    Field::Vertex,
                    Field::Index,
                    Field::Transform,
                    Field::Aabbs,
                    Field::Instances,
                ] {
                    for (ctx, a) in field_addresses(info, i, f) {
                        if let Some(b) = buffer_of(w, a) {
                            if !b.usage.contains(
                                BufferUsage::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR,
                            ) {
                                push(out, ctx, format!("buffer `{}` lacks ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR", b.name));
                            }
                        }
                    }
                }
            }
        }
        P::IndirectContiguous => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                if let Some(b) = buffer_of(w, a) {
                    if not_contiguous(b) {
                        push(
                            out,
                            format!("pIndirectDeviceAddresses[{i}]"),
                            format!("buffer `{}` is not bound to one memory object", b.name),
                        );
                    }
                }
            }
        }
        P::IndirectRangeInOneBuffer => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                let n = call.infos.get(i).map_or(0, |g| g.geometries.len()) as u64;
                let len = n * *call.indirect_strides.get(i).unwrap_or(&0) as u64;
                if len == 0 {
                    continue;
                }
                let ctx = format!("pIndirectDeviceAddresses[{i}]");
                match a.buffer() {
                    Some((name, off)) => match w.buffer(name) {
                        Some(b) if off.saturating_add(len) <= b.size => {}
                        Some(b) => push(
                            out,
                            ctx,
                            format!(
                                "[{off}, {off}+{len}) passes the end of `{}` ({} bytes)",
                                b.name, b.size
                            ),
                        ),
                        None => push(out, ctx, format!("no buffer `{name}` in the world")),
                    },
                    None => push(out, ctx, "the address lies in no buffer of the world"),
                }
            }
        }
        P::IndirectUsage => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                if let Some(b) = buffer_of(w, a) {
                    if !b.usage.contains(BufferUsage::INDIRECT_BUFFER_BIT) {
                        push(
                            out,
                            format!("pIndirectDeviceAddresses[{i}]"),
                            format!("buffer `{}` lacks INDIRECT_BUFFER_BIT", b.name),
                        );
                    }
                }
            }
        }
        P::RangeRecordsValid => check_range_records(cx, out),
        P::DstSizeEnough => {
            for (i, info) in call.infos.iter().enumerate() {
                let (Some(s), Some(need)) = (
                    info.dst.as_ref().and_then(|d| w.structure(d)),
                    w.sizes.get(i),
                ) else {
                    continue;
                };
                if s.size < need.structure {
                    push(
                        out,
                        format!("pInfos[{i}].dstAccelerationStructure"),
                        format!(
                            "`{}` has size {} < {} required",
                            s.name, s.size, need.structure
                        ),
                    );
                }
            }
        }
        P::ScratchInOneBuffer { mode, skip_zero } => {
            for (i, info) in call.infos.iter().enumerate() {
                if info.mode != *mode {
                    continue;
                }
                let Some(n) = scratch_size(cx, i) else {
                    continue;
                };
                if n == 0 && *skip_zero {
                    continue;
                }
                let ctx = format!("pInfos[{i}].scratchData.deviceAddress");
                match info
                    .scratch
                    .buffer()
                    .and_then(|(b, o)| Some((w.buffer(b)?, o)))
                {
                    Some((b, o)) if o.saturating_add(n) <= b.size => {}
                    Some((b, o)) => push(
                        out,
                        ctx,
                        format!(
                            "[{o}, {o}+{n}) passes the end of `{}` ({} bytes)",
                            b.name, b.size
                        ),
                    ),
                    None if n == 0 => {}
                    None => push(out, ctx, "lies in no buffer of the world"),
                }
            }
        }
        P::ScratchUsage(mode) => {
            for (i, info) in call.infos.iter().enumerate() {
                if let Some(m) = mode {
                    if info.mode != *m || scratch_size(cx, i).unwrap_or(1) == 0 {
                        continue;
                    }
                }
                if let Some(b) = buffer_of(w, &info.scratch) {
                    if !b.usage.contains(BufferUsage::STORAGE_BUFFER_BIT) {
                        push(
                            out,
                            format!("pInfos[{i}].scratchData.deviceAddress"),
                            format!("buffer `{}` lacks STORAGE_BUFFER_BIT", b.name),
                        );
                    }
                } else if mode.is_some() {
                    if let Some(why) = invalid_address(w, &info.scratch) {
                        push(out, format!("pInfos[{i}].scratchData.deviceAddress"), why);
                    }
                }
            }
        }
        P::DstTypeMatches(t) => {
            for (i, info) in call.infos.iter().enumerate() {
                if info.ty != *t {
                    continue;
                }
                if let Some(s) = info.dst.as_ref().and_then(|d| w.structure(d)) {
                    if s.ty != *t && s.ty != AsType::Generic {
                        push(
                            out,
                            format!("pInfos[{i}].dstAccelerationStructure"),
                            format!("`{}` was created as {:?}", s.name, s.ty),
                        );
                    }
                }
            }
        }
        P::DstBound | P::SrcBoundIfUpdate => {
            for (i, info) in call.infos.iter().enumerate() {
                let (name, what) = match p {
                    P::DstBound => (info.dst.as_ref(), "dstAccelerationStructure"),
                    _ if is_update(info) => (info.src.as_ref(), "srcAccelerationStructure"),
                    _ => continue,
                };
                if let Some(b) = name
                    .and_then(|n| w.structure(n))
                    .and_then(|s| w.buffer(&s.buffer))
                {
                    if b.memory == MemoryBinding::Unbound {
                        push(
                            out,
                            format!("pInfos[{i}].{what}"),
                            format!("its buffer `{}` is not bound to memory", b.name),
                        );
                    }
                }
            }
        }
        P::InstancedBound => {
            for i in 0..call.infos.len() {
                for (ctx, n) in referenced_structures(cx, i) {
                    if let Some(b) = w.structure(&n).and_then(|s| w.buffer(&s.buffer)) {
                        if b.memory == MemoryBinding::Unbound {
                            push(
                                out,
                                ctx,
                                format!(
                                    "references `{n}` whose buffer `{}` is not bound to memory",
                                    b.name
                                ),
                            );
                        }
                    }
                }
            }
        }
        P::ScratchAligned => {
            let Some(m) = cx.profile.limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::minAccelerationStructureScratchOffsetAlignment") else { return };
            for (i, info) in call.infos.iter().enumerate() {
                let v = info.scratch.alignment_value();
                if m > 0 && v % m != 0 {
                    push(out, format!("pInfos[{i}].scratchData.deviceAddress"), format!("offset {v} is not a multiple of minAccelerationStructureScratchOffsetAlignment ({m})"));
                }
            }
        }
        P::AlignedTo(field, m) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (j, g) in info.geometries.iter().enumerate() {
                    let a = match (&g.data, field) {
                        (GeometryData::Aabbs { data, .. }, Field::Aabbs) => data,
                        (
                            GeometryData::Instances {
                                data,
                                array_of_pointers,
                            },
                            Field::Instances,
                        ) if (*m == 8) == *array_of_pointers => data,
                        (GeometryData::Triangles { transform_data, .. }, Field::Transform)
                            if !transform_data.is_null() =>
                        {
                            transform_data
                        }
                        _ => continue,
                    };
                    if a.alignment_value() % m != 0 {
                        push(
                            out,
                            format!("pInfos[{i}].pGeometries[{j}]"),
                            format!(
                                "address offset {} is not aligned to {m}",
                                a.alignment_value()
                            ),
                        );
                    }
                }
            }
        }
        P::VertexComponentAligned | P::IndexAligned => {
            for (i, info) in call.infos.iter().enumerate() {
                for (j, g) in info.geometries.iter().enumerate() {
                    if let GeometryData::Triangles {
                        vertex_format,
                        vertex_data,
                        index_type,
                        index_data,
                        ..
                    } = &g.data
                    {
                        let (a, m, what) = if matches!(p, P::VertexComponentAligned) {
                            (vertex_data, vertex_format.component_size(), "vertexData")
                        } else if *index_type != IndexType::None {
                            (index_data, index_type.size(), "indexData")
                        } else {
                            continue;
                        };
                        if a.alignment_value() % m != 0 {
                            push(
                                out,
                                format!("pInfos[{i}].pGeometries[{j}].geometry.triangles.{what}"),
                                format!("offset {} is not aligned to {m}", a.alignment_value()),
                            );
                        }
                    }
                }
            }
        }
        P::PointerElementsAligned(m) => {
            for (i, info) in call.infos.iter().enumerate() {
                let Some(rs) = ranges(cx, i) else { continue };
                for (j, (g, r)) in info.geometries.iter().zip(&rs).enumerate() {
                    if let GeometryData::Instances {
                        array_of_pointers: true,
                        data,
                    } = &g.data
                    {
                        for k in 0..r.primitive_count.min(1 << 16) {
                            let ctx = format!("pInfos[{i}].pGeometries[{j}] pointer {k}");
                            if let Ok(a) = instance_address(&cx.mem, data, true, r, k, &ctx) {
                                if a.alignment_value() % m != 0 {
                                    push(
                                        out,
                                        ctx,
                                        format!(
                                            "points at offset {} which is not aligned to {m}",
                                            a.alignment_value()
                                        ),
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
        P::MaxInstanceCount => {
            let Some(m) = cx
                .profile
                .limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount")
            else {
                return;
            };
            for (i, info) in call.infos.iter().enumerate() {
                for (j, g) in info.geometries.iter().enumerate() {
                    if g.data.geometry_type() == crate::accel::call::GeometryType::Instances {
                        let c = call
                            .max_primitive_counts
                            .get(i)
                            .and_then(|v| v.get(j))
                            .copied()
                            .unwrap_or(0) as u64;
                        if c > m {
                            push(
                                out,
                                format!("ppMaxPrimitiveCounts[{i}][{j}]"),
                                format!("{c} is greater than maxInstanceCount ({m})"),
                            );
                        }
                    }
                }
            }
        }
        P::ValidAddress(field) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (n, (ctx, a)) in field_addresses(info, i, *field).into_iter().enumerate() {
                    // Conditions: transform only when not 0; micromap and sphere index only when indexed.
                    if *field == Field::Transform && a.is_null() {
                        continue;
                    }
                    if matches!(field, Field::MicromapIndex | Field::SphereIndex(_)) {
                        let j = geometry_of(info, i, *field, n);
                        if field_index_type(info, j, *field) == Some(IndexType::None) {
                            continue;
                        }
                    }
                    if let Some(why) = invalid_address(w, a) {
                        push(out, ctx, why);
                    }
                }
            }
        }
        P::ZeroAddress(field) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (n, (ctx, a)) in field_addresses(info, i, *field).into_iter().enumerate() {
                    let j = geometry_of(info, i, *field, n);
                    if field_index_type(info, j, *field) == Some(IndexType::None) && !a.is_null() {
                        push(
                            out,
                            ctx,
                            "is not 0 although the index type is VK_INDEX_TYPE_NONE_KHR",
                        );
                    }
                }
            }
        }
        P::Contiguous(field) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (ctx, a) in field_addresses(info, i, *field) {
                    if let Some(b) = buffer_of(w, a) {
                        if not_contiguous(b) {
                            push(
                                out,
                                ctx,
                                format!("buffer `{}` is not bound to one memory object", b.name),
                            );
                        }
                    }
                }
            }
        }
        P::InstanceReferenceValid | P::InstanceReferenceBottomLevel => {
            for i in 0..call.infos.len() {
                for (ctx, rec) in instances_of(cx, i) {
                    match &rec.reference {
                        InstanceReference::Null => {}
                        InstanceReference::Raw(v) => push(
                            out,
                            ctx,
                            format!(
                                "accelerationStructureReference {v:#x} is no structure's address"
                            ),
                        ),
                        InstanceReference::Structure(n) => match w.structure(n) {
                            None => push(
                                out,
                                ctx,
                                format!("references `{n}`, not a structure of the world"),
                            ),
                            Some(s)
                                if matches!(p, P::InstanceReferenceBottomLevel)
                                    && s.ty == AsType::TopLevel =>
                            {
                                push(out, ctx, format!("references `{n}`, a top-level structure"))
                            }
                            _ => {}
                        },
                    }
                }
            }
        }
        P::OpacityMicromapsDisableAllowed => {
            for i in 0..call.infos.len() {
                for (ctx, rec) in instances_of(cx, i) {
                    if rec.flags & crate::accel::world::INSTANCE_DISABLE_OPACITY_MICROMAPS == 0 {
                        continue;
                    }
                    if let InstanceReference::Structure(n) = &rec.reference {
                        let allowed = w
                            .structure(n)
                            .and_then(|s| s.last_build.as_ref())
                            .is_some_and(|b| {
                                b.flags.has(
                                    crate::accel::call::BuildFlags::ALLOW_DISABLE_OPACITY_MICROMAPS_EXT,
                                )
                            });
                        if !allowed {
                            push(out, ctx, format!("sets DISABLE_OPACITY_MICROMAPS but `{n}` was not built with ALLOW_DISABLE_OPACITY_MICROMAPS"));
                        }
                    }
                }
            }
        }
        P::MaxCountsCoverRanges => {
            for i in 0..call.infos.len() {
                let Some(rs) = ranges(cx, i) else { continue };
                for (j, r) in rs.iter().enumerate() {
                    let m = call
                        .max_primitive_counts
                        .get(i)
                        .and_then(|v| v.get(j))
                        .copied()
                        .unwrap_or(0);
                    if r.primitive_count > m {
                        push(
                            out,
                            format!("ppMaxPrimitiveCounts[{i}][{j}]"),
                            format!(
                                "{m} is less than the primitiveCount {} in memory",
                                r.primitive_count
                            ),
                        );
                    }
                }
            }
        }
    }
}

/// The geometry index of the n-th address `field_addresses` returned for a field.
fn geometry_of(info: &BuildGeometryInfo, i: usize, field: Field, n: usize) -> usize {
    let mut seen = 0;
    for j in 0..info.geometries.len() {
        let one = BuildGeometryInfo {
            geometries: vec![info.geometries[j].clone()],
            ..info.clone()
        };
        let k = field_addresses(&one, i, field).len();
        if n < seen + k {
            return j;
        }
        seen += k;
    }
    0
}

/// 03651: every range record the command reads lies in memory and is a valid
/// `VkAccelerationStructureBuildRangeInfoKHR` for its geometry (offset alignments by geometry kind).
fn check_range_records(cx: &AccelContext, out: &mut Out) {
    for (i, info) in cx.call.infos.iter().enumerate() {
        for (j, g) in info.geometries.iter().enumerate() {
            let ctx = format!("range record {j} of pInfos[{i}]");
            let Some(a) = cx.call.range_address(i, j) else {
                continue;
            };
            let Some(bytes) = cx.mem.read(&a, RangeInfo::SIZE) else {
                push(out, ctx, "lies outside every buffer of the world");
                continue;
            };
            let r = RangeInfo::from_bytes(&bytes);
            let (what, m) = match &g.data {
                GeometryData::Triangles {
                    index_type: IndexType::None,
                    vertex_format,
                    ..
                } => ("primitiveOffset", vertex_format.component_size()),
                GeometryData::Triangles { index_type, .. } => {
                    ("primitiveOffset", index_type.size())
                }
                GeometryData::Aabbs { .. } => ("primitiveOffset", 8),
                GeometryData::Instances {
                    array_of_pointers: true,
                    ..
                } => ("primitiveOffset", 8),
                GeometryData::Instances { .. } => ("primitiveOffset", 16),
                _ => continue,
            };
            if r.primitive_offset as u64 % m != 0 {
                push(
                    out,
                    ctx.clone(),
                    format!("{what} {} is not a multiple of {m}", r.primitive_offset),
                );
            }
            if let GeometryData::Triangles { transform_data, .. } = &g.data {
                if !transform_data.is_null() && r.transform_offset % 16 != 0 {
                    push(
                        out,
                        ctx,
                        format!(
                            "transformOffset {} is not a multiple of 16",
                            r.transform_offset
                        ),
                    );
                }
            }
        }
    }
}
