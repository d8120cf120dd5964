//! The overlap rules between the infos of one call and the rules an update-mode build keeps from the
//! last build of its source.

use super::*;
use crate::accel::semantics::{build_primitives, range_indices};

pub(super) fn check_overlap(kind: Overlap, cx: &AccelContext, out: &mut Out) {
    let infos = &cx.call.infos;
    for (i, a) in infos.iter().enumerate() {
        for (j, b) in infos.iter().enumerate() {
            let other = i != j;
            let (x, y, what) = match kind {
                Overlap::DstSrcUpdateOther if other && is_update(b) => (
                    structure_span(cx, a.dst.as_ref()),
                    structure_span(cx, b.src.as_ref()),
                    "the source of update pInfos",
                ),
                Overlap::DstDstOther if other && i < j => (
                    structure_span(cx, a.dst.as_ref()),
                    structure_span(cx, b.dst.as_ref()),
                    "the destination of pInfos",
                ),
                Overlap::DstScratchAny => (
                    structure_span(cx, a.dst.as_ref()),
                    scratch_span(cx, j),
                    "the scratch of pInfos",
                ),
                Overlap::ScratchScratchOther if other && i < j => (
                    scratch_span(cx, i),
                    scratch_span(cx, j),
                    "the scratch of pInfos",
                ),
                Overlap::ScratchSrcUpdateAny if is_update(b) => (
                    scratch_span(cx, i),
                    structure_span(cx, b.src.as_ref()),
                    "the source of update pInfos",
                ),
                Overlap::SrcDstUpdateSame if i == j && is_update(a) && a.src != a.dst => (
                    structure_span(cx, a.src.as_ref()),
                    structure_span(cx, a.dst.as_ref()),
                    "its own destination, pInfos",
                ),
                Overlap::DstInstancedOther if other => {
                    let Some(x) = structure_span(cx, a.dst.as_ref()) else {
                        continue;
                    };
                    for (ctx, n) in referenced_structures(cx, j) {
                        if let Some(y) = cx.world.backing(&n) {
                            if overlaps(x, y) && a.dst.as_deref() != Some(n.as_str()) {
                                push(
                                    out,
                                    format!("pInfos[{i}].dstAccelerationStructure"),
                                    format!("overlaps `{n}`, referenced by {ctx}"),
                                );
                            }
                        }
                    }
                    continue;
                }
                _ => continue,
            };
            if let (Some(x), Some(y)) = (x, y) {
                if overlaps(x, y) {
                    let ctx = match kind {
                        Overlap::ScratchScratchOther | Overlap::ScratchSrcUpdateAny => {
                            format!("pInfos[{i}].scratchData")
                        }
                        Overlap::SrcDstUpdateSame => {
                            format!("pInfos[{i}].srcAccelerationStructure")
                        }
                        _ => format!("pInfos[{i}].dstAccelerationStructure"),
                    };
                    push(
                        out,
                        ctx,
                        format!(
                            "[{}+{}, +{}) overlaps {what}[{j}] [{}+{}, +{})",
                            x.0, x.1, x.2, y.0, y.1, y.2
                        ),
                    );
                }
            }
        }
    }
}

pub(super) fn check_keep(k: Keep, cx: &AccelContext, out: &mut Out) {
    use crate::accel::call::BuildFlags;
    for (i, info) in cx.call.infos.iter().enumerate() {
        if !is_update(info) {
            continue;
        }
        let Some(src) = info.src.as_ref().and_then(|n| cx.world.structure(n)) else {
            continue;
        };
        let ctx = format!("pInfos[{i}]");
        let Some(last) = &src.last_build else {
            if k == Keep::AllowUpdateBuilt {
                push(out, ctx, format!("`{}` was never built", src.name));
            }
            continue;
        };
        match k {
            Keep::AllowUpdateBuilt => {
                if !last.flags.has(BuildFlags::ALLOW_UPDATE) {
                    push(
                        out,
                        ctx,
                        format!("`{}` was not built with ALLOW_UPDATE", src.name),
                    );
                }
                continue;
            }
            Keep::GeometryCount => {
                if last.geometries.len() != info.geometries.len() {
                    push(
                        out,
                        format!("{ctx}.geometryCount"),
                        format!(
                            "{} differs from the last build's {}",
                            info.geometries.len(),
                            last.geometries.len()
                        ),
                    );
                }
                continue;
            }
            Keep::StructureType => {
                if last.ty != info.ty {
                    push(
                        out,
                        format!("{ctx}.type"),
                        format!("{:?} differs from the last build's {:?}", info.ty, last.ty),
                    );
                }
                continue;
            }
            Keep::Flags => {
                if last.flags != info.flags {
                    push(
                        out,
                        format!("{ctx}.flags"),
                        format!(
                            "{:#x} differs from the last build's {:#x}",
                            info.flags.0, last.flags.0
                        ),
                    );
                }
                continue;
            }
            _ => {}
        }
        let rs = ranges(cx, i);
        let now_prims = rs
            .as_ref()
            .and_then(|r| build_primitives(&cx.mem, info, r).ok());
        for (j, (g, l)) in info.geometries.iter().zip(&last.geometries).enumerate() {
            let gctx = format!("{ctx}.pGeometries[{j}]");
            let range = rs.as_ref().and_then(|r| r.get(j));
            let tri = match &g.data {
                GeometryData::Triangles {
                    vertex_format,
                    max_vertex,
                    index_type,
                    transform_data,
                    ..
                } => Some((
                    *vertex_format,
                    *max_vertex,
                    *index_type,
                    !transform_data.is_null(),
                )),
                _ => None,
            };
            let bad: Option<String> = match k {
                Keep::GeometryType => (g.data.geometry_type() != l.geometry_type)
                    .then(|| "geometryType changed".into()),
                Keep::GeometryFlags => (g.flags != l.flags).then(|| "flags changed".into()),
                Keep::VertexFormat => tri
                    .filter(|t| Some(t.0) != l.vertex_format)
                    .map(|_| "vertexFormat changed".into()),
                Keep::MaxVertex => tri
                    .filter(|t| t.1 != l.max_vertex)
                    .map(|_| "maxVertex changed".into()),
                Keep::IndexType => tri
                    .filter(|t| Some(t.2) != l.index_type)
                    .map(|_| "indexType changed".into()),
                Keep::TransformNull => tri
                    .filter(|t| !l.has_transform && t.3)
                    .map(|_| "transformData was NULL and is not".into()),
                Keep::TransformNotNull => tri
                    .filter(|t| l.has_transform && !t.3)
                    .map(|_| "transformData was not NULL and is".into()),
                Keep::IndexValues => match (tri, range) {
                    (Some(t), Some(r)) if t.2 != IndexType::None => {
                        let now = range_indices(&cx.mem, &g.data, r, &gctx).unwrap_or_default();
                        (now != l.indices).then(|| "index values differ from the last build".into())
                    }
                    _ => None,
                },
                Keep::PrimitiveCount => range
                    .filter(|r| r.primitive_count != l.range.primitive_count)
                    .map(|r| {
                        format!(
                            "primitiveCount {} differs from the last build's {}",
                            r.primitive_count, l.range.primitive_count
                        )
                    }),
                Keep::FirstVertex => match (tri, range) {
                    (Some(t), Some(r))
                        if t.2 != IndexType::None && r.first_vertex != l.range.first_vertex =>
                    {
                        Some(format!(
                            "firstVertex {} differs from the last build's {}",
                            r.first_vertex, l.range.first_vertex
                        ))
                    }
                    _ => None,
                },
                Keep::InactiveStayInactive | Keep::ActiveStayActive => {
                    let Some(prims) = &now_prims else { continue };
                    let now: Vec<bool> = prims
                        .iter()
                        .filter(|p| p.geometry == j as u32)
                        .map(|p| p.active)
                        .collect();
                    let flip = now.iter().zip(&l.active).position(|(n, was)| {
                        if k == Keep::InactiveStayInactive {
                            *n && !*was
                        } else {
                            !*n && *was
                        }
                    });
                    flip.map(|p| {
                        format!(
                            "primitive {p} was {} and is now {}",
                            if k == Keep::InactiveStayInactive {
                                "inactive"
                            } else {
                                "active"
                            },
                            if k == Keep::InactiveStayInactive {
                                "active"
                            } else {
                                "inactive"
                            }
                        )
                    })
                }
                Keep::Dense(m) => match (&g.data, &l.dense) {
                    (GeometryData::DenseTrianglesAmdx(d), Some(ld)) => {
                        let f = |x: &crate::accel::call::DenseTriangles| match m {
                            0 => x.num_triangles as u64,
                            1 => x.num_vertices as u64,
                            2 => x.max_primitive_index as u64,
                            3 => x.max_geometry_index as u64,
                            4 => x.format as u64,
                            _ => x.data_size,
                        };
                        (f(d) != f(ld))
                            .then(|| "dense geometry member differs from the last build".into())
                    }
                    _ => None,
                },
                Keep::AllowUpdateBuilt
                | Keep::GeometryCount
                | Keep::Flags
                | Keep::StructureType => None,
            };
            if let Some(problem) = bad {
                push(out, gctx, problem);
            }
        }
    }
}
