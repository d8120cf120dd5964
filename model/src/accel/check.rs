//! How a built acceleration structure is checked: the model's primitives of the build as the reference
//! tracer's scene (`super::scene`), rays through every primitive plus random rays, and the outcomes the
//! tracer allows per ray ([`BuildCheck`]); the device's records of those rays judged with
//! `crate::tracer::judge` ([`judge_build`]); and the named ways a driver's build is known to depart
//! from the model ([`deviation`]), decided by judging the same records against the structure each
//! deviation builds. The harness traces the rays on the device; the session judges what came back.

use super::call::{BuildGeometryInfo, GeometryData, IndexType};
use super::scene::{build_scene, check_hit_shaders, check_rays as rays_through, CHECK_MISS};
use super::semantics::{build_primitives, indirect_ranges, BuiltPrimitive, Shape};
use super::world::{AsType, Memory, RangeInfo};
use crate::case::AccelBody;
use crate::rendered::RenderedResult;
use crate::scene::{Ray, Scene};
use crate::tracer::judge::{judge, RayVerdict};
use crate::tracer::record::{RayRecord, RecordOutcome};
use crate::tracer::{
    trace_ray, AllowedOutcomes, PreparedScene, PrimitiveRef, ShaderTable, TracerConfig, TracerStats,
};

/// What each ray hit: `(instance, geometry, primitive)`, or None for a miss.
pub type Hits = Vec<Option<(u32, u32, u32)>>;

/// How many failures a judgement keeps in words.
const KEPT: usize = 5;

/// The check of a build case's first info: the scene the model builds, the rays, and the outcomes the
/// tracer allows for each.
#[derive(Debug, Clone)]
pub struct BuildCheck {
    pub scene: Scene,
    pub rays: Vec<Ray>,
    pub allowed: Vec<AllowedOutcomes>,
    pub stats: TracerStats,
}

/// The ranges the case's first info reads from memory and the primitives the model builds from them.
pub fn first_build(body: &AccelBody) -> Result<(Vec<RangeInfo>, Vec<BuiltPrimitive>), String> {
    let info = body.call.infos.first().ok_or("the build has no info")?;
    let mem = body.world.memory();
    let ranges = indirect_ranges(&mem, &body.call, 0).map_err(|e| e.to_string())?;
    let prims = build_primitives(&mem, info, &ranges).map_err(|e| e.to_string())?;
    Ok((ranges, prims))
}

/// The rays that check a valid build case's structure (see `super::scene::check_rays`). None when
/// the model cannot read the build (no info, records outside memory).
pub fn check_rays(body: &AccelBody) -> Option<Vec<Ray>> {
    let (_, prims) = first_build(body).ok()?;
    Some(rays_through(&prims))
}

/// The outcomes the tracer allows for each ray against `scene`.
pub fn allowed_outcomes(
    scene: &Scene,
    rays: &[Ray],
) -> Result<(Vec<AllowedOutcomes>, TracerStats), String> {
    let prepared = PreparedScene::new(scene).map_err(|p| {
        let first: Vec<String> = p.iter().take(3).map(|x| x.to_string()).collect();
        format!(
            "the built structure is no scene the tracer judges: {}",
            first.join("; ")
        )
    })?;
    let hit = |_: u32, g: u32| check_hit_shaders(scene, g);
    let table = ShaderTable {
        hit: &hit,
        miss: CHECK_MISS,
    };
    let config = TracerConfig::default();
    let mut stats = TracerStats::default();
    let allowed = rays
        .iter()
        .enumerate()
        .map(|(k, r)| {
            trace_ray(&prepared, r, &table, &config, &mut stats).map_err(|p| {
                format!(
                    "check ray {k}: {}",
                    p.first().map(|x| x.to_string()).unwrap_or_default()
                )
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok((allowed, stats))
}

fn scene_of(
    mem: &Memory,
    info: &BuildGeometryInfo,
    ranges: &[RangeInfo],
) -> Result<(Scene, Vec<BuiltPrimitive>), String> {
    let prims = build_primitives(mem, info, ranges).map_err(|e| e.to_string())?;
    let scene = build_scene(mem, info, ranges, &prims, info.ty == AsType::TopLevel)?;
    Ok((scene, prims))
}

impl BuildCheck {
    /// The check of `body`'s first info, from the model's reading of its memory.
    pub fn of(body: &AccelBody) -> Result<BuildCheck, String> {
        let info = body.call.infos.first().ok_or("the build has no info")?;
        let mem = body.world.memory();
        let ranges = indirect_ranges(&mem, &body.call, 0).map_err(|e| e.to_string())?;
        let (scene, prims) = scene_of(&mem, info, &ranges)?;
        let rays = rays_through(&prims);
        let (allowed, stats) = allowed_outcomes(&scene, &rays)?;
        Ok(BuildCheck {
            scene,
            rays,
            allowed,
            stats,
        })
    }
}

/// What each record names: the committed `(instance, geometry, primitive)`, None for anything else.
pub fn hits_of(words: &[u32]) -> Hits {
    words
        .chunks_exact(RayRecord::WORDS)
        .map(|w| {
            (w[RayRecord::OUTCOME] == RayRecord::HIT).then_some((
                w[RayRecord::INSTANCE_ID],
                w[RayRecord::GEOMETRY_INDEX],
                w[RayRecord::PRIMITIVE_ID],
            ))
        })
        .collect()
}

/// A build's records judged ray by ray.
#[derive(Debug, Clone)]
pub struct BuildJudgement {
    /// The numbers a rendered case reports (rays, REQ/VARY, worst errors, histograms, failures).
    pub result: RenderedResult,
    /// Each ray's verdict.
    pub verdicts: Vec<RayVerdict>,
}

/// Judges `words` ([`RayRecord::WORDS`] per ray) against the allowed outcomes of each ray.
pub fn judge_against(
    rays: &[Ray],
    allowed: &[AllowedOutcomes],
    stats: &TracerStats,
    words: &[u32],
) -> Result<BuildJudgement, String> {
    if words.len() != allowed.len() * RayRecord::WORDS {
        return Err(format!(
            "{} record words read back for {} check rays of {} words",
            words.len(),
            allowed.len(),
            RayRecord::WORDS
        ));
    }
    let mut result = RenderedResult {
        distinct_rays: rays.len() as u64,
        pair_tests: stats.pair_tests,
        exact_evaluations: stats.exact_evaluations,
        ..RenderedResult::default()
    };
    let mut verdicts = Vec::with_capacity(allowed.len());
    for (k, (a, w)) in allowed
        .iter()
        .zip(words.chunks_exact(RayRecord::WORDS))
        .enumerate()
    {
        result.rays += 1;
        let (outcome, verdict) = match RayRecord::from_words(w) {
            Ok(r) => {
                let j = judge(a, &r);
                result.summary.add(&j);
                if j.t_error_rel.is_some() && j.t_error_rel >= result.worst_t_rel {
                    result.worst_t_rel = j.t_error_rel;
                    result.worst_t_ulps = j.t_error_ulps;
                    result.worst_t_bound = j.t_bound;
                }
                if j.bary_error_abs.is_some() && j.bary_error_abs >= result.worst_bary_abs {
                    result.worst_bary_abs = j.bary_error_abs;
                    result.worst_bary_bound = j.bary_bound;
                }
                (Some(r.outcome), j.verdict)
            }
            Err(e) => (None, RayVerdict::Fail(format!("unreadable record: {e}"))),
        };
        if a.vary {
            result.vary += 1;
            match outcome {
                Some(RecordOutcome::Hit) => result.vary_hit += 1,
                Some(_) => result.vary_miss += 1,
                None => {}
            }
        } else {
            result.req += 1;
        }
        result.shader_required += u64::from(a.intersection.min > 0);
        let at = || {
            let r = &rays[k];
            format!(
                "ray {k} (origin {:?} direction {:?} t [{}, {}])",
                r.origin, r.direction, r.tmin, r.tmax
            )
        };
        match &verdict {
            RayVerdict::Pass => {}
            RayVerdict::Warn(w) => {
                result.warnings += 1;
                if result.first_warnings.len() < KEPT {
                    result.first_warnings.push(format!("{}: {w}", at()));
                }
            }
            RayVerdict::Fail(f) => {
                result.failures += 1;
                if result.first_failures.len() < KEPT {
                    result.first_failures.push(format!("{}: {f}", at()));
                }
            }
        }
        verdicts.push(verdict);
    }
    Ok(BuildJudgement { result, verdicts })
}

/// Judges a valid build case's records (from the check's rays, in order) with the tracer.
pub fn judge_build(body: &AccelBody, words: &[u32]) -> Result<BuildJudgement, String> {
    let check = BuildCheck::of(body)?;
    judge_against(&check.rays, &check.allowed, &check.stats, words)
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

/// A deviation in how a vertex is read rather than where: the geometry transform applied to (x, y, z, A)
/// for a four-component vertex format, A its fourth component, with no divide — the transform's
/// translation weighted by A — where the model reads the position as the first three components and
/// transforms that point (lavapipe, Mesa 25.0.7: src/gallium/frontends/lavapipe/
/// lvp_acceleration_structure.c sums `matrix[comp][col] × coords[col]` over four columns, `coords[3]` the
/// format's fourth component). The specification gives that component no meaning; no reading of it
/// as part of the position (ignored, or a homogeneous coordinate) gives this.
pub const FOURTH_COMPONENT_WEIGHTS_TRANSLATION: &str = "fourth-component-weights-translation";

/// The structure `scene` (the model's, of `info` and `ranges`) as built under
/// [`FOURTH_COMPONENT_WEIGHTS_TRANSLATION`]: each transformed triangle of a four-component format
/// placed in the transform's space, its positions summed over the four columns in f32 as that build
/// does, with no transform left. None where no vertex's fourth component is other than 1 (both
/// readings agree).
fn fourth_component_weighted(
    mem: &Memory,
    info: &BuildGeometryInfo,
    ranges: &[RangeInfo],
    scene: &Scene,
) -> Option<Scene> {
    let fourth = super::semantics::transformed_fourth_components(mem, info, ranges).ok()?;
    if !fourth.iter().flatten().flatten().any(|w| *w != 1.0) {
        return None;
    }
    let mut alt = scene.clone();
    let geometries = &mut alt.bottom_levels.first_mut()?.geometries;
    let mut at = 0;
    for (geometry, range) in geometries.iter_mut().zip(ranges) {
        let count = range.primitive_count as usize;
        let weights = fourth.get(at..at + count)?;
        at += count;
        let crate::scene::GeometryData::Triangles(t) = &mut geometry.data else {
            continue;
        };
        let (Some(m), true) = (t.transform, weights.iter().all(Option::is_some)) else {
            continue;
        };
        let m = m.0;
        for (p, w) in weights.iter().enumerate() {
            let w = (*w)?;
            for (k, a) in w.iter().enumerate() {
                let v = t.positions.get_mut(3 * p + k)?;
                // An inactive vertex (X NaN) stays inactive, its other coordinates finite as the
                // scene keeps them: the NaN is not carried into them.
                let inactive = v[0].is_nan();
                let c = [if inactive { 0.0 } else { v[0] }, v[1], v[2], *a];
                let placed = [0, 1, 2].map(|r| {
                    let mut sum = 0.0f32;
                    for (col, x) in c.iter().enumerate() {
                        sum += m[r][col] * x;
                    }
                    sum
                });
                *v = if inactive {
                    let finite = |x: f32| if x.is_finite() { x } else { 0.0 };
                    [f32::NAN, finite(placed[1]), finite(placed[2])]
                } else {
                    placed
                };
            }
        }
        t.transform = None;
    }
    Some(alt)
}

/// A relaxation that may follow a range deviation (or none), for structures holding an inactive triangle
/// (a vertex whose X is NaN): lavapipe (Mesa 25.0.7) keeps such a triangle in its BVH, and its NaN bounds
/// make primitives elsewhere in the tree unreachable (which ones depends on the tree, so the model cannot
/// name them). Under it the device's records must pass the judgement against the structure with some
/// primitives dropped, the fewest that explain them — one set for every ray, or where none explains
/// them all, a set per failing ray (`drops_per_ray`). Only named when the exact judgements fail.
pub const INACTIVE_TRIANGLE_DROPS: &str = "inactive-triangle-drops-primitives";

/// The twin of [`INACTIVE_TRIANGLE_DROPS`] for AABB geometry: lavapipe (Mesa 25.0.7) keeps a box whose
/// minimum X is NaN (inactive) in its BVH, and an active box before it in the same geometry becomes
/// unreachable (`cases/build/lavapipe-inactive-aabb-drops-box.yaml`). The same relaxation. Named where
/// the structure holds an inactive AABB (and no inactive triangle) and the exact judgements fail.
pub const INACTIVE_AABB_DROPS: &str = "inactive-aabb-drops-primitives";

/// How many rounds of dropping a relaxation tries before it gives up.
const DROP_ROUNDS: usize = 8;

/// Whether every record passes against `allowed` (warnings pass).
fn all_pass(allowed: &[AllowedOutcomes], records: &[RayRecord]) -> Vec<bool> {
    allowed
        .iter()
        .zip(records)
        .map(|(a, r)| !matches!(judge(a, r).verdict, RayVerdict::Fail(_)))
        .collect()
}

/// The fewest primitives whose removal from `scene` makes every record pass, found greedily: each
/// round drops the candidates a failing ray's record passed over (nearer than its hit, or every one
/// when it missed): those that may be its committed hit, and the boxes whose intersection shader
/// must run for it (a box the ray enters, the sphere inside missed, is no committable hit, yet its
/// invocation count fails the record alike). None when a round drops nothing new (a record no
/// dropping explains).
fn fewest_drops(scene: &Scene, rays: &[Ray], records: &[RayRecord]) -> Option<usize> {
    let mut dropped: Vec<PrimitiveRef> = Vec::new();
    for _ in 0..DROP_ROUNDS {
        let mut alt = scene.clone();
        for p in &dropped {
            drop_primitive(&mut alt, p);
        }
        let (allowed, _) = allowed_outcomes(&alt, rays).ok()?;
        let pass = all_pass(&allowed, records);
        if pass.iter().all(|p| *p) {
            return Some(dropped.len());
        }
        let before = dropped.len();
        for ((a, r), ok) in allowed.iter().zip(records).zip(&pass) {
            if *ok {
                continue;
            }
            let reach = match r.outcome {
                RecordOutcome::Hit => r.t as f64,
                _ => f64::INFINITY,
            };
            let chosen = |p: &PrimitiveRef| {
                r.outcome == RecordOutcome::Hit
                    && *p
                        == (PrimitiveRef {
                            instance: r.instance_id,
                            geometry: r.geometry_index,
                            primitive: r.primitive_id,
                        })
            };
            for &i in a.committable.iter() {
                let c = &a.candidates[i];
                if !chosen(&c.primitive) && c.t_hull().lo < reach && !dropped.contains(&c.primitive)
                {
                    dropped.push(c.primitive);
                }
            }
            // Every box whose shader must run lies before anything that may end the trace or
            // shrink tmax, so before the record's hit too.
            for p in &a.must_run {
                if !chosen(p) && !dropped.contains(p) {
                    dropped.push(*p);
                }
            }
        }
        if dropped.len() == before {
            return None;
        }
    }
    None
}

/// [`fewest_drops`] ray by ray, where no one set of dropped primitives explains every record: each
/// failing record explained by the fewest drops from the structure as that ray alone meets it. An
/// inactive primitive's NaN bounds in a driver's tree hide a subtree from the rays whose slab tests
/// meet the NaN and not from the others (`cases/build/lavapipe-inactive-aabb-ray-dependent.yaml`:
/// one ray through a box misses it, another hits it), so which primitives a ray cannot reach depends
/// on the ray. Every record must still pass once its own drops are made: a hit is the cast's, only
/// misses differ. The drops summed over the rays, or None when a record no dropping explains.
fn drops_per_ray(scene: &Scene, rays: &[Ray], records: &[RayRecord]) -> Option<usize> {
    let (allowed, _) = allowed_outcomes(scene, rays).ok()?;
    let pass = all_pass(&allowed, records);
    let mut total = 0;
    for (k, ok) in pass.iter().enumerate() {
        if !ok {
            total += fewest_drops(scene, &rays[k..=k], &records[k..=k])?;
        }
    }
    Some(total)
}

/// Makes one primitive of a scene inactive (NaN X), keeping every PrimitiveId.
fn drop_primitive(scene: &mut Scene, p: &PrimitiveRef) {
    use crate::scene::GeometryData as G;
    if scene.bottom_levels.len() == 1 && scene.instances.len() > 1 {
        if let Some(i) = scene.instances.get_mut(p.instance as usize) {
            i.bottom_level = None;
        }
        return;
    }
    let Some(g) = scene
        .bottom_levels
        .first_mut()
        .and_then(|b| b.geometries.get_mut(p.geometry as usize))
    else {
        return;
    };
    let k = p.primitive as usize;
    match &mut g.data {
        G::Triangles(t) => {
            if let Some(v) = t.positions.get_mut(3 * k) {
                v[0] = f32::NAN;
            }
        }
        G::Aabbs(a) => {
            if let Some(b) = a.boxes.get_mut(k) {
                b.min[0] = f32::NAN;
            }
        }
    }
}

/// The names, joined by `|` (each alternative explains the records on its own), of the deviations
/// that explain a valid case's failing records: first those (see `DEVIATIONS`, each also read as
/// [`FOURTH_COMPONENT_WEIGHTS_TRANSLATION`] where that differs, named `X+fourth-component-weights-
/// translation`) that explain them exactly — the same rays judged against the structure built under
/// the deviation all pass —, then,
/// where the structure built holds an inactive triangle, the deviations (none included) that explain
/// them up to the fewest dropped primitives, named with `+` [`INACTIVE_TRIANGLE_DROPS`]
/// (`inactive-triangle-drops-primitives` alone for none; [`INACTIVE_AABB_DROPS`] where the inactive
/// primitive is a box). Both kinds are named because an exact fit may be a coincidence: a structure
/// whose inactive primitive hides a whole geometry misses every ray through it, which a deviation
/// that moves that geometry away from the rays fits exactly as well
/// (`cases/build/lavapipe-first-vertex-twice-hidden-geometry.yaml`). None when no deviation explains
/// them, or for a top-level build or several infos.
pub fn deviation(case: &AccelBody, words: &[u32]) -> Option<String> {
    let info = case.call.infos.first()?;
    if words.is_empty() || case.call.infos.len() != 1 || info.ty != AsType::BottomLevel {
        return None;
    }
    let records: Vec<RayRecord> = words
        .chunks_exact(RayRecord::WORDS)
        .map(RayRecord::from_words)
        .collect::<Result<_, _>>()
        .ok()?;
    let mem = case.world.memory();
    let ranges = indirect_ranges(&mem, &case.call, 0).ok()?;
    let prims = build_primitives(&mem, info, &ranges).ok()?;
    let rays = rays_through(&prims);
    if rays.len() != records.len() {
        return None;
    }
    // A deviating build may read past the end of a buffer: the harness's buffers lie in zeroed
    // allocations, so the model reads zeros there (degenerate triangles that nothing hits).
    let mut padded = case.world.clone();
    for b in &mut padded.buffers {
        b.size = b.size.saturating_add(4096);
    }
    let padded_mem = padded.memory();
    // Each candidate: its name, the scene it builds and the relaxation its inactive primitives allow;
    // each range deviation (none included) also with its vertices read as
    // FOURTH_COMPONENT_WEIGHTS_TRANSLATION reads them, where that differs.
    let identity: RangeRewrite = |_, r| r;
    let candidates: Vec<(String, Scene, Option<&str>)> = std::iter::once(("none", identity))
        .chain(DEVIATIONS.iter().copied())
        .flat_map(|(name, f)| {
            let alt: Vec<RangeInfo> = info
                .geometries
                .iter()
                .zip(&ranges)
                .map(|(g, r)| f(&g.data, *r))
                .collect();
            if name != "none" && alt == ranges {
                return vec![];
            }
            let Ok((scene, alt_prims)) = scene_of(&padded_mem, info, &alt) else {
                return vec![];
            };
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
            let weighted = fourth_component_weighted(&padded_mem, info, &alt, &scene).map(|w| {
                let named = match name {
                    "none" => FOURTH_COMPONENT_WEIGHTS_TRANSLATION.to_string(),
                    n => format!("{n}+{FOURTH_COMPONENT_WEIGHTS_TRANSLATION}"),
                };
                (named, w, inactive)
            });
            std::iter::once((name.to_string(), scene, inactive))
                .chain(weighted)
                .collect()
        })
        .collect();
    let exact: Vec<&str> = candidates
        .iter()
        .filter(|(name, scene, _)| {
            name != "none"
                && allowed_outcomes(scene, &rays)
                    .is_ok_and(|(a, _)| all_pass(&a, &records).iter().all(|p| *p))
        })
        .map(|c| c.0.as_str())
        .collect();
    let relaxed: Vec<(&str, usize, &str)> = candidates
        .iter()
        .filter(|(name, _, _)| !exact.contains(&name.as_str()))
        .filter_map(|(name, scene, inactive)| {
            let relaxation = (*inactive)?;
            let drops = fewest_drops(scene, &rays, &records)
                .or_else(|| drops_per_ray(scene, &rays, &records))?;
            Some((name.as_str(), drops, relaxation))
        })
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
    let names: Vec<String> = exact.iter().map(|n| n.to_string()).chain(dropped).collect();
    (!names.is_empty()).then(|| names.join("|"))
}
