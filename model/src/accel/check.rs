//! How a built acceleration structure is checked: one ray per built primitive with what it must report
//! ([`expected_rays`]), and the named ways a driver's build is known to depart from the model
//! ([`deviation`]), decided by casting the same rays on the CPU at the structure each deviation builds.
//! The harness traces the rays on the device; the session compares what came back with these.

use super::call::{GeometryData, IndexType};
use super::semantics::{build_primitives, indirect_ranges, BuiltPrimitive, Shape};
use super::world::{AsType, RangeInfo};
use crate::case::AccelBody;

/// One ray per built primitive: origin above the primitive, direction +z, and what it must report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ExpectedRay {
    pub origin: [f32; 3],
    /// (instance, geometry, primitive) when it must hit; None when it must miss.
    pub hit: Option<(u32, u32, u32)>,
}

/// The rays that check a built structure, from the model's primitives (top-level: instances of the
/// one-triangle BLAS the generator uses, whose triangle's centroid is (0, -1/6)).
pub fn expected_rays(prims: &[BuiltPrimitive], top: bool) -> Vec<ExpectedRay> {
    prims
        .iter()
        .filter_map(|p| {
            let (x, y) = match &p.shape {
                Shape::Triangle(v) if p.active => (
                    (v[0][0] + v[1][0] + v[2][0]) / 3.0,
                    (v[0][1] + v[1][1] + v[2][1]) / 3.0,
                ),
                Shape::Triangle(v) => ((v[1][0] + v[2][0]) / 2.0, (v[1][1] + v[2][1]) / 2.0),
                Shape::Aabb { min, max } => {
                    let x = if min[0].is_nan() {
                        max[0] - 0.5
                    } else {
                        (min[0] + max[0]) / 2.0
                    };
                    (x, (min[1] + max[1]) / 2.0)
                }
                Shape::Instance(rec) => (rec.transform[3], rec.transform[7] - 1.0 / 6.0),
            };
            if !x.is_finite() || !y.is_finite() {
                return None;
            }
            let hit = p.active.then_some({
                if top {
                    (p.primitive, 0, 0)
                } else {
                    (0, p.geometry, p.primitive)
                }
            });
            Some(ExpectedRay {
                origin: [x, y, -1.0],
                hit,
            })
        })
        .collect()
}

/// What each ray hit: `(instance, geometry, primitive)`, or None for a miss.
pub type Hits = Vec<Option<(u32, u32, u32)>>;

/// The rays that check a valid build case's structure: the case's first info as the model builds it
/// from the range records in memory. None when the model cannot read the build (no info, records
/// outside memory).
pub fn check_rays(body: &AccelBody) -> Option<Vec<ExpectedRay>> {
    let info = body.call.infos.first()?;
    let mem = body.world.memory();
    let ranges = indirect_ranges(&mem, &body.call, 0).ok()?;
    let prims = build_primitives(&mem, info, &ranges).ok()?;
    Some(expected_rays(&prims, info.ty == AsType::TopLevel))
}

/// How a deviation rewrites the ranges a build reads, per geometry.
type RangeRewrite = fn(&GeometryData, RangeInfo) -> RangeInfo;

/// Named ways a driver's build may depart from the model: each rewrites the ranges the build reads.
const DEVIATIONS: &[(&str, RangeRewrite)] = &[
    ("indexed-first-vertex-ignored", |g, r| match g {
        GeometryData::Triangles { index_type, .. } if *index_type != IndexType::None => RangeInfo {
            first_vertex: 0,
            ..r
        },
        _ => r,
    }),
    ("first-vertex-applied-twice", |g, r| match g {
        GeometryData::Triangles { .. } => RangeInfo {
            first_vertex: r.first_vertex.saturating_mul(2),
            ..r
        },
        _ => r,
    }),
];

/// A relaxation that may follow a range deviation (or none), for structures holding an inactive triangle
/// (a vertex whose X is NaN): lavapipe (Mesa 25.0.7) keeps such a triangle in its BVH, and its NaN bounds
/// make primitives elsewhere in the tree unreachable (which ones depends on the tree, so a CPU cast
/// cannot name them). Under it every ray the device reports as a hit must hit what the cast says; rays
/// the cast says hit may miss. Only named when the exact casts fail.
pub const INACTIVE_TRIANGLE_DROPS: &str = "inactive-triangle-drops-primitives";

/// The twin of [`INACTIVE_TRIANGLE_DROPS`] for AABB geometry: lavapipe (Mesa 25.0.7) keeps a box whose
/// minimum X is NaN (inactive) in its BVH, and an active box before it in the same geometry becomes
/// unreachable (`cases/build/lavapipe-inactive-aabb-drops-box.yaml`). The same relaxation: every device
/// hit must be the cast's; rays the cast says hit may miss. Named where the structure holds an inactive
/// AABB (and no inactive triangle) and the exact casts fail.
pub const INACTIVE_AABB_DROPS: &str = "inactive-aabb-drops-primitives";

/// The names (see [`DEVIATIONS`], joined by `|` when several fit) of the deviations that explain a valid
/// case's ray mismatches exactly: the same rays cast on the CPU at the structure built under the
/// deviation report precisely what the device reported. Where no deviation explains them exactly and the
/// built structure holds an inactive triangle, the deviations (none included) that explain them up to
/// the fewest dropped primitives are named with `+` [`INACTIVE_TRIANGLE_DROPS`] (`inactive-triangle-drops-primitives`
/// alone for none; [`INACTIVE_AABB_DROPS`] where the inactive primitive is a box). None when no
/// deviation explains them, or when a CPU cast cannot decide (a ray grazing an edge or a box's side,
/// two boxes entered at one t, a top-level build).
pub fn deviation(case: &AccelBody, device_hits: &Hits) -> Option<String> {
    let info = case.call.infos.first()?;
    if device_hits.is_empty() || case.call.infos.len() != 1 || info.ty != AsType::BottomLevel {
        return None;
    }
    let mem = case.world.memory();
    let ranges = indirect_ranges(&mem, &case.call, 0).ok()?;
    let prims = build_primitives(&mem, info, &ranges).ok()?;
    let rays = expected_rays(&prims, false);
    if rays.len() != device_hits.len() {
        return None;
    }
    // A deviating build may read past the end of a buffer: the harness's buffers lie in zeroed
    // allocations, so the cast reads zeros there (degenerate triangles that nothing hits).
    let mut padded = case.world.clone();
    for b in &mut padded.buffers {
        b.size = b.size.saturating_add(4096);
    }
    let padded_mem = padded.memory();
    // Each candidate: its name and what the cast reports per ray at the structure it builds (with
    // whether that structure holds an inactive triangle). "none" is the model's own build.
    let identity: RangeRewrite = |_, r| r;
    let candidates: Vec<(&str, Hits, Option<&str>)> = std::iter::once(("none", identity))
        .chain(DEVIATIONS.iter().copied())
        .filter_map(|(name, f)| {
            let alt: Vec<RangeInfo> = info
                .geometries
                .iter()
                .zip(&ranges)
                .map(|(g, r)| f(&g.data, *r))
                .collect();
            if name != "none" && alt == ranges {
                return None;
            }
            let alt_prims = build_primitives(&padded_mem, info, &alt).ok()?;
            let inactive_of = |aabb: bool| {
                alt_prims.iter().any(|p| {
                    !p.active
                        && match p.shape {
                            Shape::Triangle(_) => !aabb,
                            Shape::Aabb { .. } => aabb,
                            Shape::Instance(_) => false,
                        }
                })
            };
            let inactive = if inactive_of(false) {
                Some(INACTIVE_TRIANGLE_DROPS)
            } else if inactive_of(true) {
                Some(INACTIVE_AABB_DROPS)
            } else {
                None
            };
            let hits: Option<Hits> = rays.iter().map(|r| cast(&alt_prims, r.origin)).collect();
            Some((name, hits?, inactive))
        })
        .collect();
    let exact: Vec<&str> = candidates
        .iter()
        .filter(|(name, hits, _)| *name != "none" && hits == device_hits)
        .map(|c| c.0)
        .collect();
    if !exact.is_empty() {
        return Some(exact.join("|"));
    }
    // Up to dropped primitives: the candidates whose every device hit is the cast's, fewest drops first.
    let drops = |hits: &Hits| -> Option<usize> {
        let mut n = 0;
        for (want, got) in hits.iter().zip(device_hits) {
            match got {
                None if want.is_some() => n += 1,
                _ if got != want => return None,
                _ => {}
            }
        }
        Some(n)
    };
    let relaxed: Vec<(&str, usize, &str)> = candidates
        .iter()
        .filter_map(|(name, hits, inactive)| Some((*name, drops(hits)?, (*inactive)?)))
        .collect();
    let fewest = relaxed.iter().map(|r| r.1).min();
    let dropped: Vec<String> = relaxed
        .iter()
        .filter(|r| Some(r.1) == fewest)
        .map(|(name, _, relaxation)| match *name {
            "none" => relaxation.to_string(),
            n => format!("{n}+{relaxation}"),
        })
        .collect();
    (!dropped.is_empty()).then(|| dropped.join("|"))
}

/// What a ray from `origin` along +z (t in [0, 100]) hits among triangle and AABB primitives, on the
/// CPU; the outer None when it cannot be decided (a ray within 1e-4 of an edge or a box's side, two
/// boxes entered at one t, an instance). A box is hit as the check's intersection shaders report it:
/// where the ray's x and y lie in the box, at t = max(min z - origin z, 0).
fn cast(prims: &[BuiltPrimitive], origin: [f32; 3]) -> Option<Option<(u32, u32, u32)>> {
    let mut best: Option<(f32, (u32, u32, u32))> = None;
    let mut box_ts: Vec<f32> = Vec::new();
    for p in prims.iter().filter(|p| p.active) {
        let v = match &p.shape {
            Shape::Triangle(v) => v,
            Shape::Aabb { min, max } => {
                let inside = |a: usize| {
                    let (o, lo, hi) = (origin[a] as f64, min[a] as f64, max[a] as f64);
                    if o > lo + 1e-4 && o < hi - 1e-4 {
                        Some(true)
                    } else if o < lo - 1e-4 || o > hi + 1e-4 {
                        Some(false)
                    } else {
                        None
                    }
                };
                let (in_x, in_y) = (inside(0)?, inside(1)?);
                if in_x && in_y {
                    let t = (min[2] - origin[2]).max(0.0);
                    if box_ts.iter().any(|u| (u - t).abs() < 1e-4) {
                        return None;
                    }
                    box_ts.push(t);
                    if t <= 100.0 && best.is_none_or(|(bt, _)| t < bt) {
                        best = Some((t, (0, p.geometry, p.primitive)));
                    }
                }
                continue;
            }
            Shape::Instance(_) => return None,
        };
        let (ox, oy) = (origin[0] as f64, origin[1] as f64);
        let x = |i: usize| v[i][0] as f64;
        let y = |i: usize| v[i][1] as f64;
        let area = (x(1) - x(0)) * (y(2) - y(0)) - (x(2) - x(0)) * (y(1) - y(0));
        if !area.is_finite() || area.abs() < 1e-9 {
            continue;
        }
        let edge =
            |a: usize, b: usize| ((x(b) - x(a)) * (oy - y(a)) - (ox - x(a)) * (y(b) - y(a))) / area;
        let w = [edge(1, 2), edge(2, 0), edge(0, 1)];
        if w.iter().all(|c| *c > 1e-4) {
            let z = w[0] * v[0][2] as f64 + w[1] * v[1][2] as f64 + w[2] * v[2][2] as f64;
            let t = (z - origin[2] as f64) as f32;
            if (0.0..=100.0).contains(&t) && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, (0, p.geometry, p.primitive)));
            }
        } else if w.iter().all(|c| *c > -1e-4) {
            return None;
        }
    }
    Some(best.map(|b| b.1))
}
