//! One ray through a prepared scene: candidates after culling (spec, "Ray Intersection Culling")
//! and confirmation ("Ray Intersection Confirmation"); `conclude.rs` turns them into the set of
//! committed hits, miss rule and invocation counts the traversal may produce.

use super::arith::{affine, map3, v3, BoundedF64, Dyadic, PlainF32, V3};
use super::band::triangle_band;
use super::conclude::conclude;
use super::outside::robustly_outside;
use super::prepare::{Item, PreparedScene, RayF64, WorldGeometry};
use super::sphere::{sphere_band, sphere_reports, sphere_signs, SphereSigns};
use super::triangle::{
    classify, triangle_intervals, triangle_signs, MissReason, PairClass, TriangleSigns,
    TriangleValues, VaryReason,
};
use super::watertight::{watertight_groups, TriangleHit};
use super::*;
use crate::scene::undefined::{ray_problems, EXCLUSIVE_RAY_FLAGS};
use crate::scene::{GeometryData, Problem, Ray, RayFlags, SceneInstance};
use std::cmp::Ordering;

/// The outcome of one (ray, triangle) pair.
#[derive(Clone, Copy)]
struct TriangleOutcome {
    class: PairClass,
    signs: Option<TriangleSigns>,
    values: Option<TriangleValues>,
    /// The t and barycentric intervals (`triangle_intervals`), where the pair is no miss.
    intervals: Option<(Interval, [Interval; 2])>,
    evaluation: Evaluation,
}

/// Which arithmetic decided a pair's signs (the counter it adds to).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Evaluation {
    /// Decided before any arithmetic (degenerate or in-plane).
    None,
    Filter,
    Exact,
    F32,
}

impl Evaluation {
    fn count(self, stats: &mut TracerStats) {
        match self {
            Evaluation::None => {}
            Evaluation::Filter => stats.filter_decided += 1,
            Evaluation::Exact => stats.exact_evaluations += 1,
            Evaluation::F32 => stats.f32_evaluations += 1,
        }
    }
}

fn dyadic_world(scene: &PreparedScene, w: &WorldGeometry, v: [f32; 3]) -> V3<Dyadic> {
    let inst = &scene.scene.instances[w.instance as usize];
    let GeometryData::Triangles(t) =
        &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize].data
    else {
        unreachable!("triangle geometry")
    };
    let obj = v3::<Dyadic>(v);
    let as_space = match &t.transform {
        Some(m) => affine(&m.0, &obj),
        None => obj,
    };
    affine(&inst.transform.0, &as_space)
}

fn f32_world(scene: &PreparedScene, w: &WorldGeometry, v: [f32; 3]) -> V3<PlainF32> {
    let inst = &scene.scene.instances[w.instance as usize];
    let GeometryData::Triangles(t) =
        &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize].data
    else {
        unreachable!("triangle geometry")
    };
    let obj = v3::<PlainF32>(v);
    let as_space = match &t.transform {
        Some(m) => affine(&m.0, &obj),
        None => obj,
    };
    affine(&inst.transform.0, &as_space)
}

fn classify_triangle(
    scene: &PreparedScene,
    w: &WorldGeometry,
    primitive: u32,
    ray: &Ray,
    rf: &RayF64,
    precision: Precision,
) -> TriangleOutcome {
    let GeometryData::Triangles(t) =
        &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize].data
    else {
        unreachable!("triangle geometry")
    };
    let ids = t.vertex_indices(primitive as usize);
    let pos = map3(ids, |i| t.positions[i]);
    let miss = |reason| TriangleOutcome {
        class: PairClass::ReqMiss(reason),
        signs: None,
        values: None,
        intervals: None,
        evaluation: Evaluation::None,
    };
    // Spec, "Ray Face Culling": a zero ray-space area is culled. Two coincident vertices give zero
    // area in every implementation (identical inputs, identical arithmetic).
    if pos[0] == pos[1] || pos[1] == pos[2] || pos[2] == pos[0] {
        return miss(MissReason::Degenerate);
    }
    let inst = &scene.instances[w.instance as usize];
    let geometry_identity = t.transform.as_ref().is_none_or_identity();
    if inst.identity && geometry_identity {
        #[allow(clippy::needless_range_loop)] // one axis indexes positions and the ray
        for k in 0..3 {
            let plane = pos[0][k];
            if pos[1][k] == plane
                && pos[2][k] == plane
                && ray.direction[k] == 0.0
                && ray.origin[k] == plane
            {
                return miss(MissReason::InPlane);
            }
        }
    }
    let radius = map3(ids, |i| w.static_radius[i]);
    // The commonest miss, robustly outside two edges, certified before the band and the
    // error-tracked edge functions (see `outside.rs`); the full classification finds it too.
    if precision == Precision::F64WithExactFallback
        && robustly_outside(
            &inst.band,
            &map3(ids, |i| w.vertices[i]),
            &radius,
            rf.origin,
            rf.origin_norm,
            rf.direction,
        )
    {
        return TriangleOutcome {
            evaluation: Evaluation::Filter,
            ..miss(MissReason::Outside)
        };
    }
    let world_f64 = map3(ids, |i| map3(w.vertices[i], |x| x.value));
    let band = triangle_band(&inst.band, &world_f64, &radius, rf.origin, rf.direction);
    let evaluate_exact = || {
        let world = pos.map(|p| dyadic_world(scene, w, p));
        triangle_signs::<Dyadic>(
            &world,
            &v3(ray.origin),
            &v3(ray.direction),
            ray.tmin,
            ray.tmax,
            &band,
        )
        .expect("exact arithmetic decides every sign")
    };
    let ((signs, values), evaluation) = match precision {
        Precision::ExactOnly => (evaluate_exact(), Evaluation::Exact),
        Precision::F64WithExactFallback => {
            let world = map3(ids, |i| w.vertices[i]);
            match triangle_signs::<BoundedF64>(
                &world,
                &v3(ray.origin),
                &v3(ray.direction),
                ray.tmin,
                ray.tmax,
                &band,
            ) {
                Some(x) => (x, Evaluation::Filter),
                None => (evaluate_exact(), Evaluation::Exact),
            }
        }
        Precision::F32FilterOnly => {
            let world = pos.map(|p| f32_world(scene, w, p));
            let x = triangle_signs::<PlainF32>(
                &world,
                &v3(ray.origin),
                &v3(ray.direction),
                ray.tmin,
                ray.tmax,
                &band,
            )
            .expect("f32 signs are taken at face value");
            (x, Evaluation::F32)
        }
    };
    let class = classify(&signs);
    TriangleOutcome {
        class,
        signs: Some(signs),
        values: Some(values),
        intervals: (!matches!(class, PairClass::ReqMiss(_)))
            .then(|| triangle_intervals(&values, &band)),
        evaluation,
    }
}

trait OptionTransform {
    fn is_none_or_identity(&self) -> bool;
}

impl OptionTransform for Option<&crate::scene::Transform3x4> {
    fn is_none_or_identity(&self) -> bool {
        !matches!(self, Some(m) if !m.is_identity())
    }
}

/// Opacity of a candidate (spec, "Ray Opacity Culling"): ray flags beat the instance's FORCE_*
/// flags, which beat the geometry's OPAQUE bit.
pub fn opacity(ray: &Ray, inst: &SceneInstance, geometry_opaque: bool) -> bool {
    if ray.flags.contains(RayFlags::OPAQUE) {
        true
    } else if ray.flags.contains(RayFlags::NO_OPAQUE) {
        false
    } else if inst.flags.force_opaque {
        true
    } else if inst.flags.force_no_opaque {
        false
    } else {
        geometry_opaque
    }
}

/// Whether opacity culling drops the candidate (spec, "Ray Opacity Culling").
pub fn opacity_culled(ray: &Ray, opaque: bool) -> bool {
    (ray.flags.contains(RayFlags::CULL_OPAQUE) && opaque)
        || (ray.flags.contains(RayFlags::CULL_NO_OPAQUE) && !opaque)
}

fn confirmation(opaque: bool, shaders: &HitShaders, primitive: u32) -> Confirmation {
    if opaque {
        Confirmation::Opaque
    } else if !shaders.has_any_hit() {
        Confirmation::NoAnyHit
    } else {
        let rule = shaders.any_hit.expect("has any-hit");
        if rule.accepts(primitive) {
            Confirmation::AnyHitAccepts {
                terminates: rule == AnyHitRule::Terminate,
            }
        } else {
            Confirmation::AnyHitIgnores
        }
    }
}

/// Whether a cut behind a required hit is allowed for the ray with `shaders`: it may not end at its
/// first hit, and no primitive of the scene runs an any-hit shader for it (opaque, or a hit group
/// without one). The one way the shader table decides which triangles [`trace_ray`] keeps as candidates.
pub fn cut_allowed_for(scene: &PreparedScene, ray: &Ray, shaders: &ShaderTable<'_>) -> bool {
    if ray.flags.contains(RayFlags::TERMINATE_ON_FIRST_HIT) {
        return false;
    }
    // Every primitive opaque for this ray: none runs any-hit, whatever the shader table holds.
    if ray.flags.contains(RayFlags::OPAQUE)
        || (!ray.flags.contains(RayFlags::NO_OPAQUE) && scene.all_opaque)
    {
        return true;
    }
    scene.geometries.iter().all(|w| {
        let inst = &scene.scene.instances[w.instance as usize];
        let geometry =
            &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize];
        opacity(ray, inst, geometry.flags.opaque)
            || !(shaders.hit)(w.instance, w.geometry).has_any_hit()
    })
}

/// Whether a triangle of `w` survives mask, primitive and opacity culling for the ray (the pairs
/// [`required_hit_t`] asks about).
fn triangle_unculled(scene: &PreparedScene, w: &WorldGeometry, ray: &Ray) -> bool {
    let inst = &scene.scene.instances[w.instance as usize];
    if inst.mask as u32 & ray.cull_mask & 0xFF == 0 || ray.flags.contains(RayFlags::SKIP_TRIANGLES)
    {
        return false;
    }
    let geometry =
        &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize];
    !opacity_culled(ray, opacity(ray, inst, geometry.flags.opaque))
}

/// The upper t bound of a triangle that must be a candidate and is confirmed without any-hit
/// (REQ-hit, not culled — see [`triangle_unculled`] —, its facing certain where a facing is
/// culled), or None; `out` is its classification.
fn required_hit_t(
    scene: &PreparedScene,
    w: &WorldGeometry,
    ray: &Ray,
    out: &TriangleOutcome,
) -> Option<f64> {
    let inst = &scene.scene.instances[w.instance as usize];
    if out.class != PairClass::ReqHit {
        return None;
    }
    let (signs, (t, _)) = (out.signs?, out.intervals?);
    let culls_facing = !inst.flags.triangle_facing_cull_disable
        && (ray.flags.contains(RayFlags::CULL_BACK_FACING_TRIANGLES)
            || ray.flags.contains(RayFlags::CULL_FRONT_FACING_TRIANGLES));
    if culls_facing {
        let o = signs.orientation?;
        let front = ((o == Ordering::Less) != scene.instances[w.instance as usize].det_negative)
            != inst.flags.flip_facing;
        let culled = if front {
            ray.flags.contains(RayFlags::CULL_FRONT_FACING_TRIANGLES)
        } else {
            ray.flags.contains(RayFlags::CULL_BACK_FACING_TRIANGLES)
        };
        if culled {
            return None;
        }
    }
    t.hi.is_finite().then_some(t.hi)
}

/// A primitive the ray's padded box test kept, with its classification when the traversal made
/// one (an unculled triangle). Small, so the sort moves little.
struct NearItem {
    /// (instance, geometry, primitive): the order of the candidates.
    key: (u32, u32, u32),
    item: Item,
    /// Its index in the prepared scene's items.
    index: u32,
    /// Its classification's index in the scratch outcomes, or `u32::MAX`.
    outcome: u32,
    /// The cut it was kept at (its padded box met by the ray cut there): the final cut, if the
    /// same, would keep it again.
    kept_at: f64,
}

/// A procedural primitive the intersection shader must run for.
pub(super) struct MustRun {
    pub t_hi: f64,
    pub primitive: PrimitiveRef,
}

/// Whether item `i` is far from the ray (its far box's test; with the BVH's shortcut `quick`, a
/// segment that meets its inner box first).
#[inline(always)]
fn far_item(scene: &PreparedScene, quick: bool, i: usize, ray: &RayF64) -> bool {
    !(quick && scene.item_bounds[i].meets_inner(ray)) && scene.item_boxes[i].is_far(ray)
}

/// Every flag some exclusive pair of [`EXCLUSIVE_RAY_FLAGS`] names.
const EXCLUSIVE_FLAGS: u32 = {
    let mut bits = 0;
    let mut i = 0;
    while i < EXCLUSIVE_RAY_FLAGS.len() {
        bits |= EXCLUSIVE_RAY_FLAGS[i].0 .0 | EXCLUSIVE_RAY_FLAGS[i].1 .0;
        i += 1;
    }
    bits
};

/// Whether the ray has none of [`ray_problems`]' problems, tested without building them: finite
/// origin and direction, a direction not zero, `0 ≤ tmin ≤ tmax` with tmin finite and tmax not NaN,
/// known flags, and at most one flag of the exclusive pairs (so no pair). False decides nothing:
/// `ray_problems` then says.
fn plainly_defined(ray: &Ray) -> bool {
    let finite3 = |v: &[f32; 3]| v[0].is_finite() && v[1].is_finite() && v[2].is_finite();
    finite3(&ray.origin)
        && finite3(&ray.direction)
        && ray.direction != [0.0; 3]
        && ray.tmin.is_finite()
        && ray.tmin >= 0.0
        && ray.tmin <= ray.tmax
        && ray.flags.0 & !RayFlags::KNOWN == 0
        && (ray.flags.0 & EXCLUSIVE_FLAGS).count_ones() <= 1
}

/// Traces one ray: the set of outcomes the spec allows. Fails with the ray's undefined things.
pub fn trace_ray(
    scene: &PreparedScene,
    ray: &Ray,
    shaders: &ShaderTable<'_>,
    config: &TracerConfig,
    stats: &mut TracerStats,
) -> Result<AllowedOutcomes, Vec<Problem>> {
    if !plainly_defined(ray) {
        let problems = ray_problems(ray, "ray");
        if !problems.is_empty() {
            return Err(problems);
        }
    }
    stats.rays += 1;
    let rf = RayF64::of(ray);
    // The cut: the least upper t bound of a triangle that must be a candidate and must be confirmed
    // (so the committed hit is at most there). Behind it an opaque triangle, or one without any-hit,
    // is unobservable: where no primitive of the scene runs any-hit for this ray and the trace may
    // not end at its first hit, a triangle whose padded box the ray cut at the cut misses is left
    // out — in every mode alike (the BVH skips whole nodes of such triangles as the cut falls).
    let cut = std::cell::Cell::new(f64::INFINITY);
    let mut may_cut: Option<bool> = None;
    let mut scratch = SCRATCH.with(|s| std::mem::take(&mut *s.borrow_mut()));
    let Scratch {
        near,
        hits,
        outcomes,
    } = &mut scratch;
    let mut far_count = 0u64;
    let far_test = config.far_test;
    // The BVH's shortcuts (brute force, the reference, goes without): a segment that meets an
    // item's inner box is not far from it.
    let quick = config.use_bvh && far_test;
    let far = |i: usize, ray: &RayF64| far_item(scene, quick, i, ray);
    let mut visit = |i: usize| {
        let item = scene.items[i];
        if far_test && far(i, &rf) {
            far_count += 1;
            return;
        }
        let w = &scene.geometries[item.geometry as usize];
        if w.kind != PrimitiveKind::Triangle {
            near.push(NearItem {
                key: (w.instance, w.geometry, item.primitive),
                item,
                index: i as u32,
                outcome: u32::MAX,
                kept_at: f64::INFINITY,
            });
            return;
        }
        // Behind the cut already: the final cut, never above it, leaves it out too.
        let c = cut.get();
        if c < rf.tmax {
            let mut cut_ray = rf;
            cut_ray.tmax = c;
            if far(i, &cut_ray) {
                return;
            }
        }
        let outcome = triangle_unculled(scene, w, ray)
            .then(|| classify_triangle(scene, w, item.primitive, ray, &rf, config.precision));
        if let Some(t_hi) = outcome
            .as_ref()
            .and_then(|out| required_hit_t(scene, w, ray, out))
        {
            if t_hi < cut.get()
                && *may_cut.get_or_insert_with(|| cut_allowed_for(scene, ray, shaders))
            {
                cut.set(t_hi);
            }
        }
        near.push(NearItem {
            key: (w.instance, w.geometry, item.primitive),
            item,
            index: i as u32,
            outcome: outcome.map_or(u32::MAX, |o| {
                outcomes.push(o);
                outcomes.len() as u32 - 1
            }),
            kept_at: c,
        });
    };
    if quick {
        let (mut nodes, mut far) = (0, 0);
        scene.for_each_near(&rf, &mut nodes, &mut far, &cut, &mut visit);
        stats.nodes_visited += nodes;
        stats.far_rejections += far;
    } else {
        (0..scene.items.len()).for_each(&mut visit);
    }
    stats.far_rejections += far_count;
    // What the cut leaves out of what was kept before it fell.
    let cut_at = cut.get();
    if cut_at < rf.tmax {
        let mut cut_ray = rf;
        cut_ray.tmax = cut_at;
        near.retain(|n| {
            scene.geometries[n.item.geometry as usize].kind != PrimitiveKind::Triangle
                || n.kept_at == cut_at
                || !far(n.index as usize, &cut_ray)
        });
    }
    // A deterministic order, independent of the BVH.
    // (instance, geometry, primitive) is unique per item: an unstable sort gives the same order.
    near.sort_unstable_by_key(|n| n.key);

    // Allocated by the first candidate (most near pairs are misses), for one only: most rays that
    // have any have one, and a launch keeps every ray's candidates (a Vec's first push would make
    // room for four).
    let mut candidates: Vec<Candidate> = Vec::new();
    let push_candidate = |candidates: &mut Vec<Candidate>, c: Candidate| {
        if candidates.capacity() == 0 {
            candidates.reserve_exact(1);
        }
        candidates.push(c);
    };
    let mut must_run: Vec<MustRun> = Vec::new();
    for NearItem { item, outcome, .. } in near.drain(..) {
        let outcome = outcomes.get(outcome as usize);
        let w = &scene.geometries[item.geometry as usize];
        let inst = &scene.scene.instances[w.instance as usize];
        // Spec, "Ray Mask Culling".
        if inst.mask as u32 & ray.cull_mask & 0xFF == 0 {
            continue;
        }
        // Spec, "Ray Primitive Culling".
        let skip = match w.kind {
            PrimitiveKind::Triangle => RayFlags::SKIP_TRIANGLES,
            PrimitiveKind::Aabb => RayFlags::SKIP_AABBS,
        };
        if ray.flags.contains(skip) {
            continue;
        }
        let geometry =
            &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize];
        let prim = PrimitiveRef {
            instance: w.instance,
            geometry: w.geometry,
            primitive: item.primitive,
        };
        let opaque = opacity(ray, inst, geometry.flags.opaque);
        // Resolved where a candidate needs it (most near pairs are misses).
        let hit_shaders = || (shaders.hit)(w.instance, w.geometry);
        stats.pair_tests += 1;
        match w.kind {
            PrimitiveKind::Triangle => {
                // Classified while traversing, or now (read in place, not copied).
                let computed;
                let out = match outcome {
                    Some(o) => o,
                    None => {
                        computed =
                            classify_triangle(scene, w, item.primitive, ray, &rf, config.precision);
                        &computed
                    }
                };
                out.evaluation.count(stats);
                let (presence, reason) = match out.class {
                    PairClass::ReqHit => {
                        stats.req_hit += 1;
                        (Presence::Required, None)
                    }
                    PairClass::Vary(r) => {
                        stats.vary += 1;
                        (Presence::Possible, Some(r))
                    }
                    PairClass::ReqMiss(_) => {
                        stats.req_miss += 1;
                        continue;
                    }
                };
                let signs = out.signs.expect("classified");
                let values = out.values.expect("classified");
                if opacity_culled(ray, opaque) {
                    continue;
                }
                // Spec, "Ray Face Culling": facing in the bottom level's space, from the sign of
                // S and of det(A); FLIP_FACING reverses it.
                let front = signs.orientation.map(|o| {
                    let world_negative = o == Ordering::Less;
                    (world_negative != scene.instances[w.instance as usize].det_negative)
                        != inst.flags.flip_facing
                });
                const BOTH: [u32; 2] = [0xFE, 0xFF];
                let facings: &[u32] = match front {
                    Some(true) => &BOTH[..1],
                    Some(false) => &BOTH[1..],
                    None => &BOTH,
                };
                let culls = !inst.flags.triangle_facing_cull_disable;
                let mut kept = [0u32; 2];
                let mut count = 0;
                for &k in facings {
                    let culled = culls
                        && ((k == 0xFF
                            && ray.flags.contains(RayFlags::CULL_BACK_FACING_TRIANGLES))
                            || (k == 0xFE
                                && ray.flags.contains(RayFlags::CULL_FRONT_FACING_TRIANGLES)));
                    if !culled {
                        kept[count] = k;
                        count += 1;
                    }
                }
                let kinds = &kept[..count];
                let facing_vary = count < facings.len() && front.is_none();
                if kinds.is_empty() {
                    continue;
                }
                let presence = if facing_vary {
                    Presence::Possible
                } else {
                    presence
                };
                let reason = if facing_vary {
                    Some(VaryReason::Facing)
                } else {
                    reason
                };
                let (t, bary) = out.intervals.expect("classified, no miss");
                let (s, _) = values.sum;
                let t_exact = values.plane.0 / s;
                let bary_exact = [values.edge[1].0 / s, values.edge[2].0 / s];
                let single = kinds.len() == 1;
                let reports = kinds
                    .iter()
                    .map(|&k| AllowedReport {
                        hit_kind: k,
                        t,
                        barycentrics: Some(bary),
                        t_exact,
                        barycentrics_exact: Some(bary_exact),
                        required: presence == Presence::Required && single,
                    })
                    .collect();
                let GeometryData::Triangles(tri) = &geometry.data else {
                    unreachable!()
                };
                hits.push(TriangleHit {
                    candidate: candidates.len(),
                    bottom_level: w.bottom_level,
                    class: w.transform_class,
                    vertices: tri.vertices(item.primitive as usize),
                    world: tri
                        .vertex_indices(item.primitive as usize)
                        .map(|i| map3(w.vertices[i], |x| x.value)),
                    signs,
                });
                let hit_shaders = hit_shaders();
                push_candidate(
                    &mut candidates,
                    Candidate {
                        primitive: prim,
                        kind: PrimitiveKind::Triangle,
                        custom_index: inst.custom_index,
                        presence,
                        vary_reason: reason,
                        opaque,
                        confirmation: confirmation(opaque, &hit_shaders, item.primitive),
                        shaders: hit_shaders,
                        no_duplicate_any_hit: geometry.flags.no_duplicate_any_hit,
                        reports,
                    },
                );
            }
            PrimitiveKind::Aabb => {
                let hit_shaders = hit_shaders();
                if opacity_culled(ray, opaque) || !hit_shaders.has_intersection() {
                    stats.req_miss += 1;
                    continue;
                }
                let GeometryData::Aabbs(a) = &geometry.data else {
                    unreachable!()
                };
                let sphere = a.spheres[item.primitive as usize];
                let band = sphere_band(
                    &scene.instances[w.instance as usize].band,
                    &sphere,
                    rf.origin,
                    rf.direction,
                );
                let m = &inst.transform.0;
                let exact = |stats: &mut TracerStats| -> SphereSigns {
                    stats.exact_evaluations += 1;
                    sphere_signs::<Dyadic>(
                        m,
                        &sphere,
                        ray.origin,
                        ray.direction,
                        ray.tmin,
                        ray.tmax,
                        &band,
                    )
                    .expect("exact arithmetic decides every sign")
                };
                let signs = match config.precision {
                    Precision::ExactOnly => exact(stats),
                    Precision::F64WithExactFallback => {
                        match sphere_signs::<BoundedF64>(
                            m,
                            &sphere,
                            ray.origin,
                            ray.direction,
                            ray.tmin,
                            ray.tmax,
                            &band,
                        ) {
                            Some(s) => {
                                stats.filter_decided += 1;
                                s
                            }
                            None => exact(stats),
                        }
                    }
                    Precision::F32FilterOnly => {
                        stats.f32_evaluations += 1;
                        sphere_signs::<PlainF32>(
                            m,
                            &sphere,
                            ray.origin,
                            ray.direction,
                            ray.tmin,
                            ray.tmax,
                            &band,
                        )
                        .expect("f32 signs are taken at face value")
                    }
                };
                if signs.must_run {
                    must_run.push(MustRun {
                        t_hi: band.t0.hi.max(band.t1.lo),
                        primitive: prim,
                    });
                }
                let reports: few::Few<AllowedReport, 2> = sphere_reports(&signs, &band)
                    .into_iter()
                    .map(|r| AllowedReport {
                        hit_kind: r.hit_kind,
                        t: r.t,
                        barycentrics: None,
                        t_exact: r.t.mid(),
                        barycentrics_exact: None,
                        required: r.required && signs.must_run,
                    })
                    .collect();
                if reports.is_empty() {
                    stats.req_miss += 1;
                    continue;
                }
                let required = reports.iter().any(|r| r.required);
                if required {
                    stats.req_hit += 1;
                } else {
                    stats.vary += 1;
                }
                push_candidate(
                    &mut candidates,
                    Candidate {
                        primitive: prim,
                        kind: PrimitiveKind::Aabb,
                        custom_index: inst.custom_index,
                        presence: if required {
                            Presence::Required
                        } else {
                            Presence::Possible
                        },
                        vary_reason: if required {
                            None
                        } else {
                            Some(VaryReason::Procedural)
                        },
                        opaque,
                        confirmation: confirmation(opaque, &hit_shaders, item.primitive),
                        shaders: hit_shaders,
                        no_duplicate_any_hit: geometry.flags.no_duplicate_any_hit,
                        reports,
                    },
                );
            }
        }
    }
    let watertight = watertight_groups(scene, ray, &candidates, hits);
    hits.clear();
    outcomes.clear();
    SCRATCH.with(|s| *s.borrow_mut() = scratch);
    Ok(conclude(
        scene, ray, shaders, candidates, must_run, watertight,
    ))
}

/// Buffers one ray's trace needs and none keeps, reused by the next ray of the thread.
#[derive(Default)]
struct Scratch {
    near: Vec<NearItem>,
    hits: Vec<TriangleHit>,
    /// The near items' classifications.
    outcomes: Vec<TriangleOutcome>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Traces every ray of a launch (one shader table for all, e.g. uniform SBT parameters).
pub fn trace_launch(
    scene: &PreparedScene,
    rays: &[Ray],
    shaders: &ShaderTable<'_>,
    config: &TracerConfig,
    stats: &mut TracerStats,
) -> Result<Vec<AllowedOutcomes>, Vec<Problem>> {
    rays.iter()
        .map(|r| trace_ray(scene, r, shaders, config, stats))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plainly_defined_ray_has_no_problem() {
        let values = [
            0.0,
            -0.0,
            1.0,
            -2.5,
            1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let flags = [0, 1, 2, 3, 0x41, 0x100, 0x300, 0x400, 0x3FF];
        let (mut plain, mut rays) = (0, 0);
        for (i, &x) in values.iter().enumerate() {
            for &y in &values {
                for &f in &flags {
                    let z = values[(i + 3) % values.len()];
                    let mut ray = Ray::new([x, 1.0, z], [y, 0.0, 0.0], x.abs(), y);
                    ray.flags = RayFlags(f);
                    rays += 1;
                    if plainly_defined(&ray) {
                        plain += 1;
                        assert!(ray_problems(&ray, "ray").is_empty(), "{ray:?}");
                    }
                }
            }
        }
        assert!(plain > 0 && plain < rays, "{plain} of {rays}");
    }
}
