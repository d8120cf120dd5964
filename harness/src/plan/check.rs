//! The traced check of a build run as valid, as a plan: the ranges the model reads from memory (what
//! the direct build is given), the check's rays (`model::accel::check::check_rays`: through every
//! built primitive plus random rays), and the sphere table from which the check's shaders report AABB
//! hits. A top-level case's instances reference the model's one-triangle bottom-level structure, built
//! first.

use crate::error::HarnessError;
use model::accel::call::BuildGeometryInfo;
use model::accel::scene::{check_rays, inscribed, CHECK_TMAX, TOP_LEVEL_TRIANGLE};
use model::accel::semantics::Shape;
use model::accel::{AsType, BuiltPrimitive, RangeInfo};
use model::scene::Ray;
use model::AccelBody;

/// The structure a top-level case's instances reference.
pub const TOP_LEVEL_BLAS: &str = "blas";

/// The triangle of [`TOP_LEVEL_BLAS`] as floats (`model::accel::scene::TOP_LEVEL_TRIANGLE`).
pub const BLAS_TRIANGLE: [f32; 9] = {
    let t = TOP_LEVEL_TRIANGLE;
    [
        t[0][0], t[0][1], t[0][2], t[1][0], t[1][1], t[1][2], t[2][0], t[2][1], t[2][2],
    ]
};

/// Slots of the sphere table's per-geometry base indices.
const SPHERE_TABLE_GEOMETRIES: usize = 8;

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
    /// The check's rays, in the order their records are written.
    pub rays: Vec<Ray>,
    /// Per-geometry base indices (8 slots of u32), then every AABB primitive's sphere as a vec4
    /// (centre, radius).
    pub spheres: Vec<u8>,
}

impl CheckPlan {
    /// The check of `case`'s first info, from the model's reading of its memory.
    pub fn of(case: &AccelBody) -> Result<CheckPlan, HarnessError> {
        let (ranges, prims) = first_build(case)?;
        let info = &case.call.infos[0];
        let top = info.ty == AsType::TopLevel;
        Ok(CheckPlan {
            rays: check_rays(&prims),
            spheres: sphere_table(info, &prims),
            procedural: info
                .geometries
                .iter()
                .any(|g| matches!(g.data, model::accel::call::GeometryData::Aabbs { .. })),
            ranges,
            top,
        })
    }

    /// Rays from `origins` along +z (t in [0, 100]) with no expectation, through the sphere table of
    /// `case`'s first info: for probing what a driver built.
    pub fn probe(case: &AccelBody, origins: &[[f32; 3]]) -> Result<CheckPlan, HarnessError> {
        let mut plan = CheckPlan::of(case)?;
        plan.rays = origins
            .iter()
            .map(|o| Ray::new(*o, [0.0, 0.0, 1.0], 0.0, CHECK_TMAX))
            .collect();
        Ok(plan)
    }

    /// The rays as the shaders read them: per ray (origin, tmin) and (direction, tmax) as vec4s.
    pub fn ray_bytes(&self) -> Vec<u8> {
        self.rays
            .iter()
            .flat_map(|r| {
                let (o, d) = (r.origin, r.direction);
                [o[0], o[1], o[2], r.tmin, d[0], d[1], d[2], r.tmax]
            })
            .flat_map(f32::to_le_bytes)
            .collect()
    }
}

/// Per-geometry base indices (8 slots) and the sphere of every AABB primitive, as floats.
fn sphere_table(info: &BuildGeometryInfo, prims: &[BuiltPrimitive]) -> Vec<u8> {
    let mut base = [0u32; SPHERE_TABLE_GEOMETRIES];
    let mut spheres: Vec<f32> = Vec::new();
    let mut n = 0u32;
    for (g, slot) in base.iter_mut().enumerate().take(info.geometries.len()) {
        *slot = n;
        for p in prims.iter().filter(|p| p.geometry == g as u32) {
            if let Shape::Aabb { min, max } = &p.shape {
                let s = inscribed(min, max);
                spheres.extend([s.center[0], s.center[1], s.center[2], s.radius]);
                n += 1;
            }
        }
    }
    let mut bytes: Vec<u8> = base.iter().flat_map(|b| b.to_le_bytes()).collect();
    bytes.extend(spheres.iter().flat_map(|f| f.to_le_bytes()));
    bytes.resize(bytes.len().max(64), 0);
    bytes
}

/// The ranges the case's first info reads from memory and the primitives the model builds from them.
fn first_build(case: &AccelBody) -> Result<(Vec<RangeInfo>, Vec<BuiltPrimitive>), HarnessError> {
    model::accel::check::first_build(case).map_err(HarnessError::failed)
}

/// The SPIR-V of the ray query check's compute shader.
pub fn ray_query_spirv() -> Result<Vec<u32>, HarnessError> {
    crate::accel_check::ray_query_spirv()
}

/// The SPIR-V of the pipeline check's shaders, for devices without ray query: raygen, miss,
/// closest-hit (both hit groups) and intersection (`shaders/check.*`).
pub fn pipeline_spirv() -> Result<[Vec<u32>; 4], HarnessError> {
    crate::accel_check::pipeline_spirv()
}
