//! The traced check of a build run as valid, as a plan: the ranges the model reads from memory (what
//! the direct build is given), one ray per built primitive with the hit the model expects, and the box
//! table from which the check's shaders generate AABB hits. A top-level case's instances reference the
//! generator's one-triangle bottom-level structure, built first.

use crate::error::HarnessError;
use model::accel::call::BuildGeometryInfo;
use model::accel::check::{expected_rays, ExpectedRay};
use model::accel::semantics::Shape;
use model::accel::{AsType, BuiltPrimitive, RangeInfo};
use model::AccelBody;

/// The structure a top-level case's instances reference.
pub const TOP_LEVEL_BLAS: &str = "blas";

/// The triangle of [`TOP_LEVEL_BLAS`]: three vertices around the origin (centroid (0, -1/6)).
pub const BLAS_TRIANGLE: [f32; 9] = [-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.0, 0.5, 0.0];

/// Slots of the box table's per-geometry base indices.
const BOX_TABLE_GEOMETRIES: usize = 8;

/// The check of a build case's first info.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CheckPlan {
    /// The range records the model reads from memory: the direct build's ranges.
    pub ranges: Vec<RangeInfo>,
    /// The case builds a top-level structure (traced as is); otherwise its result is traced through
    /// a one-instance top-level structure.
    pub top: bool,
    /// The structure holds AABBs (a ray tracing pipeline needs an intersection shader).
    pub procedural: bool,
    /// One ray per built primitive (+z from its origin, t in [0, 100]) and the hit the model expects.
    pub rays: Vec<ExpectedRay>,
    /// Per-geometry base indices (8 slots of u32), then every AABB primitive's box as min and max vec4.
    pub boxes: Vec<u8>,
}

impl CheckPlan {
    /// The check of `case`'s first info, from the model's reading of its memory.
    pub fn of(case: &AccelBody) -> Result<CheckPlan, HarnessError> {
        let (ranges, prims) = first_build(case)?;
        let info = &case.call.infos[0];
        let top = info.ty == AsType::TopLevel;
        Ok(CheckPlan {
            rays: expected_rays(&prims, top),
            boxes: box_table(info, &prims),
            procedural: info
                .geometries
                .iter()
                .any(|g| matches!(g.data, model::accel::call::GeometryData::Aabbs { .. })),
            ranges,
            top,
        })
    }

    /// Rays from `origins` with no expectation, through the box table of `case`'s first info: for
    /// probing what a driver built.
    pub fn probe(case: &AccelBody, origins: &[[f32; 3]]) -> Result<CheckPlan, HarnessError> {
        let mut plan = CheckPlan::of(case)?;
        plan.rays = origins
            .iter()
            .map(|o| ExpectedRay {
                origin: *o,
                hit: None,
            })
            .collect();
        Ok(plan)
    }
}

/// Per-geometry base indices (8 slots) and the boxes of every AABB primitive, as floats.
fn box_table(info: &BuildGeometryInfo, prims: &[BuiltPrimitive]) -> Vec<u8> {
    let mut base = [0u32; BOX_TABLE_GEOMETRIES];
    let mut boxes: Vec<f32> = Vec::new();
    let mut n = 0u32;
    for (g, slot) in base.iter_mut().enumerate().take(info.geometries.len()) {
        *slot = n;
        for p in prims.iter().filter(|p| p.geometry == g as u32) {
            if let Shape::Aabb { min, max } = &p.shape {
                boxes.extend([min[0], min[1], min[2], 0.0, max[0], max[1], max[2], 0.0]);
                n += 1;
            }
        }
    }
    let mut bytes: Vec<u8> = base.iter().flat_map(|b| b.to_le_bytes()).collect();
    bytes.extend(boxes.iter().flat_map(|f| f.to_le_bytes()));
    bytes.resize(bytes.len().max(64), 0);
    bytes
}

/// The ranges the case's first info reads from memory and the primitives the model builds from them.
fn first_build(case: &AccelBody) -> Result<(Vec<RangeInfo>, Vec<BuiltPrimitive>), HarnessError> {
    let info = case
        .call
        .infos
        .first()
        .ok_or_else(|| HarnessError::Failed("no build info".into()))?;
    let mem = case.world.memory();
    let ranges =
        model::accel::indirect_ranges(&mem, &case.call, 0).map_err(HarnessError::failed)?;
    let prims =
        model::accel::build_primitives(&mem, info, &ranges).map_err(HarnessError::failed)?;
    Ok((ranges, prims))
}

/// The SPIR-V of the ray query check's compute shader.
pub fn ray_query_spirv() -> Result<Vec<u32>, HarnessError> {
    crate::accel_check::ray_query_spirv()
}
