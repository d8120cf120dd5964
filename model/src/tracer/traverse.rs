//! Rays through a prepared scene: each ray's walk through the BVH (several rays' walks in turn),
//! the pairs it keeps classified (spec, "Ray Intersection Culling", "Ray Intersection
//! Confirmation"); `candidates.rs` turns what a walk kept into the ray's candidates and
//! `conclude.rs` those into the committed hits, miss rule and invocation counts it may produce.

use super::arith::{affine, map3, v3, BoundedF64, Dyadic, Num, PlainF32, V3};
use super::band::{cross_f64, triangle_band, within_f32_range};
use super::candidates::outcomes_of_near;
use super::outside::{pre_test, PreTest};
use super::prepare::{FarEntry, Item, PreparedScene, RayF64, WorldGeometry};
use super::triangle::{
    classify, triangle_intervals, triangle_signs, EdgeSide, MissReason, PairClass, TriangleSigns,
    TriangleValues, WindowSide,
};
use super::watertight::TriangleHit;
use super::*;
use crate::scene::undefined::{ray_problems, EXCLUSIVE_RAY_FLAGS};
use crate::scene::{GeometryData, Problem, Ray, RayFlags, SceneInstance};
use std::cmp::Ordering;

/// The outcome of one (ray, triangle) pair.
#[derive(Clone, Copy)]
pub(super) struct TriangleOutcome {
    pub(super) class: PairClass,
    pub(super) signs: Option<TriangleSigns>,
    pub(super) values: Option<TriangleValues>,
    /// The t and barycentric intervals (`triangle_intervals`), where the pair is no miss.
    pub(super) intervals: Option<(Interval, [Interval; 2])>,
    pub(super) evaluation: Evaluation,
}

/// Which arithmetic decided a pair's signs (the counter it adds to).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Evaluation {
    /// Decided before any arithmetic (degenerate or in-plane).
    None,
    Filter,
    Exact,
    F32,
}

impl Evaluation {
    pub(super) fn count(self, stats: &mut TracerStats) {
        match self {
            Evaluation::None => {}
            Evaluation::Filter => stats.filter_decided += 1,
            Evaluation::Exact => stats.exact_evaluations += 1,
            Evaluation::F32 => stats.f32_evaluations += 1,
        }
    }
}

/// A vertex of `w` in world space in the arithmetic `T` (exact in [`Dyadic`], each step rounded in
/// [`PlainF32`]): its geometry transform, then its instance's.
fn world_in<T: Num>(scene: &PreparedScene, w: &WorldGeometry, v: [f32; 3]) -> V3<T> {
    let inst = &scene.scene.instances[w.instance as usize];
    let GeometryData::Triangles(t) =
        &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize].data
    else {
        unreachable!("triangle geometry")
    };
    let obj = v3::<T>(v);
    let as_space = match &t.transform {
        Some(m) => affine(&m.0, &obj),
        None => obj,
    };
    affine(&inst.transform.0, &as_space)
}

pub(super) fn classify_triangle(
    scene: &PreparedScene,
    w: &WorldGeometry,
    item: &Item,
    ray: &Ray,
    rf: &RayF64,
    precision: Precision,
) -> TriangleOutcome {
    // The object-space triangles, read only where a test needs them (an axis-aligned ray, the
    // exact fallback, the f32 filter).
    let triangles = || {
        let GeometryData::Triangles(t) = &scene.scene.bottom_levels[w.bottom_level as usize]
            .geometries[w.geometry as usize]
            .data
        else {
            unreachable!("triangle geometry")
        };
        t
    };
    let ids = item.vertices.map(|v| v as usize);
    let pos = || {
        let t = triangles();
        map3(ids, |i| t.positions[i])
    };
    let miss = |reason| TriangleOutcome {
        class: PairClass::ReqMiss(reason),
        signs: None,
        values: None,
        intervals: None,
        evaluation: Evaluation::None,
    };
    // Spec, "Ray Face Culling": a zero ray-space area is culled. Two coincident vertices give zero
    // area in every implementation (identical inputs, identical arithmetic).
    if item.degenerate {
        return miss(MissReason::Degenerate);
    }
    let inst = &scene.instances[w.instance as usize];
    // A ray in a triangle's plane, the plane normal to an axis the ray does not move along (so
    // never an oblique ray).
    if !rf.oblique && inst.identity && triangles().transform.as_ref().is_none_or_identity() {
        let pos = pos();
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
    // The world vertices with their error bounds, in place (copied only for the full
    // classification below), and their values.
    let world_at = map3(ids, |i| scene.world_vertex(w, i));
    let values = || world_at.map(|v| v.map(|x| x.value));
    if !rf.in_f32_range && !within_f32_range(&inst.band, &values(), rf.origin, rf.direction) {
        return beyond_f32_range(&values(), rf.origin, rf.direction);
    }
    let radius = map3(ids, |i| scene.static_radius(w, i));
    // The commonest miss, robustly outside two edges, certified before the band and the
    // error-tracked edge functions (see `outside.rs`); the full classification finds it too.
    let pre = if precision == Precision::F64WithExactFallback {
        pre_test(
            &inst.band,
            world_at,
            &radius,
            rf.origin,
            rf.origin_norm,
            rf.direction,
            rf.direction_norm,
        )
    } else {
        PreTest::Undecided
    };
    let outside = TriangleOutcome {
        evaluation: Evaluation::Filter,
        ..miss(MissReason::Outside)
    };
    if pre == PreTest::Outside {
        return outside;
    }
    let world = world_at.map(|v| *v);
    let world_f64 = values();
    let band = triangle_band(
        &inst.band,
        &world_f64,
        &radius,
        rf.origin,
        rf.direction,
        rf.direction_norm,
    );
    // Near an edge line: tried against the pair's own bands before the error-tracked signs.
    if let PreTest::Mixed(edges) = pre {
        if edges.outside_of(&band) {
            return outside;
        }
    }
    // The rest in plain f64 with a-priori bounds where they decide (see `plain.rs`): the filter's
    // signs, without its running bounds.
    let plain = match &pre {
        PreTest::Mixed(edges) | PreTest::SameSide(edges) => edges.signs(ray.tmin, ray.tmax, &band),
        _ => None,
    };
    let evaluate_exact = || {
        let world = pos().map(|p| world_in::<Dyadic>(scene, w, p));
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
        Precision::F64WithExactFallback => match plain {
            Some(x) => (x, Evaluation::Filter),
            None => match triangle_signs::<BoundedF64>(
                &world,
                &v3(ray.origin),
                &v3(ray.direction),
                ray.tmin,
                ray.tmax,
                &band,
            ) {
                Some(x) => (x, Evaluation::Filter),
                None => (evaluate_exact(), Evaluation::Exact),
            },
        },
        Precision::F32FilterOnly => {
            let world = pos().map(|p| world_in::<PlainF32>(scene, w, p));
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

/// A pair whose f32 test may overflow: every sign unknown, every quantity unbounded.
/// Its values are the plain f64 edge functions, sum and plane distance (the t and barycentrics a
/// report's error is measured from), with an infinite error bound: nothing is decided from them.
fn beyond_f32_range(
    world: &[[f64; 3]; 3],
    origin: [f64; 3],
    direction: [f64; 3],
) -> TriangleOutcome {
    let a = map3([0, 1, 2], |k| map3([0, 1, 2], |c| world[k][c] - origin[c]));
    let dot = |x: [f64; 3], y: [f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let edge = map3([0, 1, 2], |i| {
        dot(direction, cross_f64(a[(i + 1) % 3], a[(i + 2) % 3]))
    });
    let unbounded = |x: f64| (x, f64::INFINITY);
    TriangleOutcome {
        class: PairClass::Vary(VaryReason::Range),
        signs: Some(TriangleSigns {
            edges: [EdgeSide::Band; 3],
            orientation: None,
            window: WindowSide::Band,
        }),
        values: Some(TriangleValues {
            edge: edge.map(unbounded),
            sum: unbounded(edge[0] + edge[1] + edge[2]),
            plane: unbounded(dot(a[0], cross_f64(a[1], a[2]))),
        }),
        intervals: Some((Interval::ALL, [Interval::ALL; 2])),
        evaluation: Evaluation::None,
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

pub(super) fn confirmation(opaque: bool, shaders: &HitShaders, primitive: u32) -> Confirmation {
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

/// Whether [`triangle_unculled`] holds for every triangle of the scene and the ray, known from the
/// ray alone where it does: a full cull mask, every instance's mask set, and no flag that culls
/// by primitive or opacity (false decides nothing).
fn none_culled(scene: &PreparedScene, ray: &Ray) -> bool {
    const CULLING: u32 =
        RayFlags::SKIP_TRIANGLES.0 | RayFlags::CULL_OPAQUE.0 | RayFlags::CULL_NO_OPAQUE.0;
    scene.every_mask_set && ray.cull_mask & 0xFF == 0xFF && ray.flags.0 & CULLING == 0
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
/// one (an unculled triangle). Small: a ray near many boxes keeps many.
pub(super) struct NearItem {
    pub(super) item: Item,
    /// Its index in the prepared scene's items.
    pub(super) index: u32,
    /// What its classification while walking found.
    pub(super) outcome: NearOutcome,
    /// The cut it was kept at (its padded box met by the ray cut there): the final cut, if the
    /// same, would keep it again.
    pub(super) kept_at: f64,
    /// Where the far test found the ray's segment meeting its padded box: whether a lower cut
    /// leaves it out, mostly without the test run again.
    pub(super) entry: FarEntry,
}

/// A near item's classification made while walking.
#[derive(Clone, Copy)]
pub(super) enum NearOutcome {
    /// None made (not a triangle, or culled before any test).
    None,
    /// A REQ-miss of an unculled triangle, decided by this arithmetic: all the outcomes need of it
    /// (the counters).
    Missed(Evaluation),
    /// The classification's index in the scratch outcomes.
    At(u32),
}

/// A procedural primitive the intersection shader must run for.
pub(super) struct MustRun {
    pub primitive: PrimitiveRef,
    pub t_hi: f64,
    /// Its index among the ray's candidates, None where it is none (its sphere is missed).
    pub candidate: Option<usize>,
}

/// Whether item `i` is far from the ray (its far box's test).
#[inline(always)]
pub(super) fn far_item(scene: &PreparedScene, i: usize, ray: &RayF64) -> bool {
    scene.item_far[i].is_far(ray, &scene.far_constants)
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
    let mut answer = None;
    trace_rays(scene, &[(ray, shaders)], config, stats, |_, a| {
        answer = Some(a)
    });
    answer.expect("an answer for the ray")
}

/// Rays whose walks through the BVH [`trace_rays`] takes in turn: while one ray's node is tested,
/// the others' next nodes arrive from memory, and their independent work fills the core. Twelve:
/// against eight, on a quiet machine (`cargo bench -p rtconf-model --bench expected_launch`, fifteen
/// passes), in four alternations on one core (`taskset -c 1`) every triangle workload traced more
/// rays per second (soup +2.5 to +3.5 %, icosphere +2.2 to +2.9 %, grid +6.9 to +7.7 %, instanced
/// +1.4 to +3.4 %), in two on both cores +1.4 to +5.7 %; with the caches another program filled
/// (`RTCONF_BENCH_EVICT=64`, three alternations on one core) instanced gained 1.2–5.9 % and grid
/// 0.7–12 %, soup and icosphere −1.7 to +6.8 %. Ten and fourteen trace about as fast as twelve;
/// six and sixteen slower, four slower still. The answers and counters are the same at any width.
const INTERLEAVED: usize = 12;

/// [`trace_ray`] of each ray with its shader table, the answers handed to `answer` with the ray's
/// index as each ray finishes (not in order). Up to `INTERLEAVED` rays walk the BVH together, one
/// node of each in turn: while one ray's nodes and items are tested, the next node of each other ray,
/// asked of the cache when it was pushed, arrives from memory (one walk alone waits for each of its
/// nodes). A slot whose ray finishes takes the next ray at once, so as many walks stay under way until
/// the rays run out (a group of rays started together would leave slots idle while its longest walk
/// ends). Each round steps every walk once, the walks whose next step tests a node in one batch and
/// those whose leaf's items' vertices are to be asked for in another, so the step's code does not
/// branch on its kind: against stepping the slots in a fixed order, the instanced workload's launch
/// rate +2.2 to +3.0 % (`RTCONF_BENCH_PASSES=31 bash scripts/bench-ab.sh expected_launch A B N`, 16
/// and 24 rounds), the other workloads within ±1.2 %. Each ray's walk and answer are its own, as if
/// traced alone.
pub fn trace_rays(
    scene: &PreparedScene,
    rays: &[(&Ray, &ShaderTable<'_>)],
    config: &TracerConfig,
    stats: &mut TracerStats,
    mut answer: impl FnMut(usize, Result<AllowedOutcomes, Vec<Problem>>),
) {
    // The thread's slots, kept between calls: a ray's trace starts in place, on the buffers and
    // stack the slot's last ray left.
    let mut slots = SLOTS.with(|s| std::mem::take(&mut *s.borrow_mut()));
    let width = INTERLEAVED.min(rays.len());
    if slots.len() < width {
        slots.resize_with(width, Default::default);
    }
    // The ray each slot walks (None: the rays ran out), and the next ray to start.
    let mut held: [Option<(usize, &Ray, &ShaderTable)>; INTERLEAVED] = [None; INTERLEAVED];
    let mut next = 0;
    let mut walking = 0;
    for (slot, held) in slots[..width].iter_mut().zip(&mut held) {
        *held = fill(scene, rays, config, slot, &mut next, stats, &mut answer).map(|i| {
            walking += 1;
            (i, rays[i].0, rays[i].1)
        });
    }
    // The slots by the kind of their next step, each kind taken in a batch every round (so the
    // step's code does not branch on which kind it is): those whose next step tests a node (after
    // visiting a leaf's fetched items), and those whose leaf's items' vertices are to be asked
    // for. A slot steps once a round either way, as in turn.
    let mut node_steps = Queue::default();
    let mut fetch_steps = Queue::default();
    for (k, h) in held[..width].iter().enumerate() {
        if h.is_some() {
            node_steps.push(k);
        }
    }
    while walking > 0 {
        let (nodes_now, fetches_now) = (node_steps.take(), fetch_steps.take());
        for &k in nodes_now.slots() {
            let k = k as usize;
            // Only a slot with a ray is queued (a slot left out would keep `walking` above zero
            // for ever).
            let (i, ray, shaders) = held[k].expect("a queued slot walks a ray");
            let slot = &mut slots[k];
            let Slot {
                rf,
                cut,
                kept,
                nodes,
                far,
                walk,
                ..
            } = slot;
            let mut visit = |item: usize| kept.visit(scene, ray, shaders, rf, config, cut, item);
            match scene.walk_advance(walk, rf, nodes, far, cut, &mut visit) {
                super::bvh::Stepped::Walking => node_steps.push(k),
                super::bvh::Stepped::Pending => fetch_steps.push(k),
                super::bvh::Stepped::Done => {
                    answer(i, Ok(slot.finish(scene, ray, shaders, config, stats)));
                    held[k] = fill(scene, rays, config, slot, &mut next, stats, &mut answer)
                        .map(|i| (i, rays[i].0, rays[i].1));
                    if held[k].is_some() {
                        node_steps.push(k);
                    } else {
                        walking -= 1;
                    }
                }
            }
        }
        for &k in fetches_now.slots() {
            let k = k as usize;
            // Where none of the items is a triangle they are visited at the next node step all
            // the same (nothing to wait for, one step later).
            scene.walk_fetch_pending(&slots[k].walk);
            node_steps.push(k);
        }
    }
    SLOTS.with(|s| *s.borrow_mut() = slots);
}

/// Slot numbers, at most [`INTERLEAVED`].
#[derive(Default, Clone, Copy)]
struct Queue {
    slots: [u8; INTERLEAVED],
    len: usize,
}

impl Queue {
    fn push(&mut self, k: usize) {
        self.slots[self.len] = k as u8;
        self.len += 1;
    }

    /// The queue as it is, leaving it empty.
    fn take(&mut self) -> Queue {
        std::mem::take(self)
    }

    fn slots(&self) -> &[u8] {
        &self.slots[..self.len]
    }
}

/// Starts the next rays of `rays` in `slot` until one has a walk to take, and returns its index;
/// the others (undefined, missing the root's bound, or traced without the BVH) are answered at once.
/// None when the rays ran out.
fn fill(
    scene: &PreparedScene,
    rays: &[(&Ray, &ShaderTable<'_>)],
    config: &TracerConfig,
    slot: &mut Slot,
    next: &mut usize,
    stats: &mut TracerStats,
    answer: &mut impl FnMut(usize, Result<AllowedOutcomes, Vec<Problem>>),
) -> Option<usize> {
    let quick = config.walks_bvh();
    while let Some(&(ray, shaders)) = rays.get(*next) {
        let i = *next;
        *next += 1;
        if let Err(problems) = slot.start(scene, ray, stats) {
            answer(i, Err(problems));
            continue;
        }
        if quick && scene.walk_start(&mut slot.walk, &slot.rf, &mut slot.nodes, &slot.cut) {
            return Some(i);
        }
        if !quick {
            for item in 0..scene.items.len() {
                slot.kept
                    .visit(scene, ray, shaders, &slot.rf, config, &slot.cut, item);
            }
        }
        answer(i, Ok(slot.finish(scene, ray, shaders, config, stats)));
    }
    None
}

/// One ray's trace under way, in a slot the thread keeps for the next ray: the ray in f64, its cut,
/// what its walk has kept, and the walk.
///
/// The cut: the least upper t bound of a triangle that must be a candidate and must be confirmed
/// (so the committed hit is at most there). Behind it an opaque triangle, or one without any-hit,
/// is unobservable: where no primitive of the scene runs any-hit for this ray and the trace may
/// not end at its first hit, a triangle whose padded box the ray cut at the cut misses is left
/// out — in every mode alike (the BVH skips whole nodes of such triangles as the cut falls).
#[derive(Default)]
struct Slot {
    rf: RayF64,
    cut: std::cell::Cell<f64>,
    kept: Kept,
    /// The walk's counters.
    nodes: u64,
    far: u64,
    walk: super::bvh::Walk,
}

/// What a ray's visits keep: the near items, whether a cut is allowed (asked once), the count of
/// items found far.
#[derive(Default)]
struct Kept {
    may_cut: Option<bool>,
    /// No triangle of the scene is culled for the ray (`triangle_unculled` holds for all): every
    /// instance's mask meets its cull mask, and no flag culls by primitive or opacity.
    none_culled: bool,
    /// The least upper t bound of a required hit confirmed without any-hit: the cut the ray gets
    /// where no primitive runs any-hit for it and it may not end at its first hit.
    least_required: f64,
    scratch: Scratch,
    far_count: u64,
}

impl Slot {
    /// Starts the trace of a defined ray; fails with an undefined ray's undefined things.
    fn start(
        &mut self,
        scene: &PreparedScene,
        ray: &Ray,
        stats: &mut TracerStats,
    ) -> Result<(), Vec<Problem>> {
        if !plainly_defined(ray) {
            let problems = ray_problems(ray, "ray");
            if !problems.is_empty() {
                return Err(problems);
            }
        }
        stats.rays += 1;
        self.rf = RayF64::of(ray);
        self.rf.in_f32_range = scene.in_f32_range(&self.rf);
        self.cut.set(f64::INFINITY);
        self.kept.may_cut = None;
        self.kept.none_culled = none_culled(scene, ray);
        self.kept.least_required = f64::INFINITY;
        self.kept.far_count = 0;
        self.nodes = 0;
        self.far = 0;
        Ok(())
    }

    /// The allowed outcomes from the near items the walk kept, the ray cut at its cut; the slot's
    /// buffers are left empty for the next ray.
    fn finish(
        &mut self,
        scene: &PreparedScene,
        ray: &Ray,
        shaders: &ShaderTable<'_>,
        config: &TracerConfig,
        stats: &mut TracerStats,
    ) -> AllowedOutcomes {
        stats.nodes_visited += self.nodes;
        stats.far_rejections += self.far + self.kept.far_count;
        let shaderless_cut = if ray.flags.contains(RayFlags::TERMINATE_ON_FIRST_HIT) {
            f64::INFINITY
        } else {
            self.kept.least_required
        };
        outcomes_of_near(
            scene,
            ray,
            shaders,
            config,
            &self.rf,
            [self.cut.get(), shaderless_cut],
            &mut self.kept.scratch,
            stats,
        )
    }
}

impl Kept {
    /// Visits item `i` of the walk of `ray`: left out when far, or behind the cut; else kept, a
    /// triangle not culled classified at once (a required hit lowers the cut).
    #[allow(clippy::too_many_arguments)] // one ray's parts, borrowed apart from its walk
    #[inline(always)]
    fn visit(
        &mut self,
        scene: &PreparedScene,
        ray: &Ray,
        shaders: &ShaderTable<'_>,
        rf: &RayF64,
        config: &TracerConfig,
        cut: &std::cell::Cell<f64>,
        i: usize,
    ) {
        let far = |i: usize, ray: &RayF64| far_item(scene, i, ray);
        let Scratch { near, outcomes, .. } = &mut self.scratch;
        let item = scene.items[i];
        let entry = if config.far_test {
            let Some(entry) = scene.item_far[i].entry(rf, &scene.far_constants) else {
                self.far_count += 1;
                return;
            };
            entry
        } else {
            FarEntry::UNKNOWN
        };
        let w = &scene.geometries[item.geometry as usize];
        if w.kind != PrimitiveKind::Triangle {
            near.push(NearItem {
                item,
                index: i as u32,
                outcome: NearOutcome::None,
                kept_at: f64::INFINITY,
                entry,
            });
            return;
        }
        // Behind the cut already: the final cut, never above it, leaves it out too.
        let c = cut.get();
        if c < rf.tmax
            && entry.far_at(c, || {
                let mut cut_ray = *rf;
                cut_ray.tmax = c;
                far(i, &cut_ray)
            })
        {
            return;
        }
        let outcome = (self.none_culled || triangle_unculled(scene, w, ray))
            .then(|| classify_triangle(scene, w, &item, ray, rf, config.precision));
        if let Some(t_hi) = outcome
            .as_ref()
            .and_then(|out| required_hit_t(scene, w, ray, out))
        {
            self.least_required = self.least_required.min(t_hi);
            if t_hi < cut.get()
                && *self
                    .may_cut
                    .get_or_insert_with(|| cut_allowed_for(scene, ray, shaders))
            {
                cut.set(t_hi);
            }
        }
        near.push(NearItem {
            item,
            index: i as u32,
            outcome: match outcome {
                None => NearOutcome::None,
                Some(o) if matches!(o.class, PairClass::ReqMiss(_)) => {
                    NearOutcome::Missed(o.evaluation)
                }
                Some(o) => {
                    outcomes.push(o);
                    NearOutcome::At(outcomes.len() as u32 - 1)
                }
            },
            kept_at: c,
            entry,
        });
    }
}
/// Buffers one ray's trace needs and none keeps, reused by the next ray of the thread.
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) near: Vec<NearItem>,
    pub(super) hits: Vec<TriangleHit>,
    /// The near items' classifications.
    pub(super) outcomes: Vec<TriangleOutcome>,
    /// The ray in the space of each instance whose spheres it met, by instance.
    pub(super) scaled: Vec<(u32, super::sphere::ScaledRay<BoundedF64>)>,
    /// The ray as the box test takes it in each instance whose boxes it met, by instance.
    pub(super) box_rays: Vec<(u32, super::box_crossing::BoxRay)>,
}

thread_local! {
    /// The thread's slots for rays under way ([`trace_rays`]).
    static SLOTS: std::cell::RefCell<Vec<Slot>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Traces every ray of a launch (one shader table for all, e.g. uniform SBT parameters), several at
/// a time ([`trace_rays`]); fails with the first undefined ray's problems.
pub fn trace_launch(
    scene: &PreparedScene,
    rays: &[Ray],
    shaders: &ShaderTable<'_>,
    config: &TracerConfig,
    stats: &mut TracerStats,
) -> Result<Vec<AllowedOutcomes>, Vec<Problem>> {
    let pairs: Vec<(&Ray, &ShaderTable)> = rays.iter().map(|r| (r, shaders)).collect();
    let mut all: Vec<Option<AllowedOutcomes>> = Vec::new();
    all.resize_with(rays.len(), || None);
    // The problems of the first undefined ray (answers come as rays finish, not in order).
    let mut undefined: Option<(usize, Vec<Problem>)> = None;
    trace_rays(scene, &pairs, config, stats, |i, a| match a {
        Ok(a) => all[i] = Some(a),
        Err(problems) => {
            if undefined.as_ref().is_none_or(|(first, _)| i < *first) {
                undefined = Some((i, problems));
            }
        }
    });
    match undefined {
        Some((_, problems)) => Err(problems),
        None => Ok(all
            .into_iter()
            .map(|a| a.expect("every ray answered"))
            .collect()),
    }
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

    /// Where the ray alone says no triangle is culled, none is: on the instanced workload with
    /// its instances' masks, FORCE_* flags and geometries' OPAQUE bits varied (a mask of zero
    /// among them), for rays of every cull mask and culling flag tried.
    #[test]
    fn a_ray_that_culls_nothing_culls_no_triangle() {
        let w = super::super::workload::standard_workload(4, "instanced");
        let (mut culling_nothing, mut culling_some) = (0, 0);
        for zero_mask in [false, true] {
            let mut scene = w.scene.clone();
            for (k, inst) in scene.instances.iter_mut().enumerate() {
                inst.mask = [0xFF, 0x01, 0x80, 0x3C][k % 4];
                inst.flags.force_opaque = k % 3 == 1;
                inst.flags.force_no_opaque = k % 3 == 2;
            }
            if zero_mask {
                scene.instances[5].mask = 0;
            }
            scene.bottom_levels[0].geometries[0].flags.opaque = false;
            let scene = PreparedScene::new(&scene).expect("a defined scene");
            let flags = [0, 0x1, 0x2, 0x40, 0x80, 0x100, 0x200, 0x10];
            for (&f, cull_mask) in flags
                .iter()
                .flat_map(|f| [0xFF, 0x1FF, 0x7F, 0x01, 0x00].map(move |m| (f, m)))
            {
                let mut ray = w.rays[0];
                ray.flags = RayFlags(f);
                ray.cull_mask = cull_mask;
                let every = scene
                    .geometries
                    .iter()
                    .filter(|g| g.kind == PrimitiveKind::Triangle)
                    .all(|g| triangle_unculled(&scene, g, &ray));
                if none_culled(&scene, &ray) {
                    culling_nothing += 1;
                    assert!(every, "flags {f:#x} cull mask {cull_mask:#x}");
                } else if !every {
                    culling_some += 1;
                }
            }
        }
        assert!(
            culling_nothing > 0 && culling_some > 0,
            "{culling_nothing} rays cull nothing, {culling_some} some"
        );
    }

    /// The far test's entry answers the test at a lower `tmax` as running it again does: on the
    /// standard workloads' camera rays, every item, and cuts at, just below and just above each
    /// entry t, between, and at the segment's ends; both kinds of entry occur, and most answers
    /// need no second test.
    #[test]
    fn a_far_entry_answers_a_lower_cut_as_the_test_does() {
        let (mut exact, mut inexact, mut answered, mut rerun) = (0, 0, 0, 0);
        for w in super::super::workload::standard_workloads(12, false) {
            let scene = PreparedScene::new(&w.scene).expect("a defined workload");
            for ray in &w.rays {
                let rf = RayF64::of(ray);
                for i in 0..scene.items.len() {
                    let Some(entry) = scene.item_far[i].entry(&rf, &scene.far_constants) else {
                        assert!(far_item(&scene, i, &rf));
                        continue;
                    };
                    assert!(!far_item(&scene, i, &rf));
                    *(if entry.exact {
                        &mut exact
                    } else {
                        &mut inexact
                    }) += 1;
                    let t = entry.t.clamp(rf.tmin, rf.tmax);
                    let cuts = [
                        rf.tmin,
                        t,
                        t.next_down().max(rf.tmin),
                        t.next_up().min(rf.tmax),
                        0.5 * (rf.tmin + t),
                        0.5 * (t + rf.tmax.min(1e30)),
                        rf.tmax,
                    ];
                    for c in cuts {
                        let mut cut_ray = rf;
                        cut_ray.tmax = c;
                        let mut ran = false;
                        let by_entry = entry.far_at(c, || {
                            ran = true;
                            far_item(&scene, i, &cut_ray)
                        });
                        assert_eq!(
                            by_entry,
                            far_item(&scene, i, &cut_ray),
                            "{} item {i} cut {c} {entry:?} {ray:?}",
                            w.name
                        );
                        *(if ran { &mut rerun } else { &mut answered }) += 1;
                    }
                }
            }
        }
        assert!(exact > 0 && inexact > 0, "{exact} exact, {inexact} not");
        assert!(
            answered > rerun,
            "{answered} answered, {rerun} tested again"
        );
    }
}
