//! From the near items one ray's walk kept to its allowed outcomes: the cut applied, mask,
//! primitive, opacity and facing culling (spec, "Ray Culling"), each remaining pair's reports and
//! confirmation, the watertight groups, and `conclude.rs`'s committed hits.

use super::arith::{Dyadic, Num, PlainF32};
use super::box_crossing::BoxRay;
use super::conclude::conclude;
use super::prepare::{PreparedScene, RayF64};
use super::sphere::{
    sphere_band, sphere_reports, sphere_signs, sphere_signs_scaled, ScaledRay, SphereBand,
    SphereSigns,
};
use super::traverse::{
    classify_triangle, confirmation, far_item, opacity, opacity_culled, MustRun, NearItem,
    NearOutcome, Scratch,
};
use super::triangle::{PairClass, VaryReason};
use super::watertight::{watertight_groups, TriangleHit};
use super::*;
use crate::scene::{GeometryData, Ray, RayFlags, Sphere};
use std::cmp::Ordering;

/// The allowed outcomes of `ray` (`rf` in f64, cut at `cut_at`) from the near items in `scratch`,
/// which is left empty for the next ray.
#[allow(clippy::too_many_arguments)] // one ray's trace, its buffers and the counters
pub(super) fn outcomes_of_near(
    scene: &PreparedScene,
    ray: &Ray,
    shaders: &ShaderTable<'_>,
    config: &TracerConfig,
    rf: &RayF64,
    [cut_at, shaderless_cut]: [f64; 2],
    scratch: &mut Scratch,
    stats: &mut TracerStats,
) -> AllowedOutcomes {
    let Scratch {
        near,
        hits,
        outcomes,
        scaled,
        box_rays,
    } = scratch;
    if near.is_empty() {
        // Nothing near the ray (every near item has its outcome, so there is none to forget).
        debug_assert!(hits.is_empty() && outcomes.is_empty());
        return conclude(scene, ray, shaders, Vec::new(), Vec::new(), Vec::new());
    }
    // What the cut leaves out of what was kept before it fell.
    if cut_at < rf.tmax {
        let mut cut_ray = *rf;
        cut_ray.tmax = cut_at;
        near.retain(|n| {
            scene.geometries[n.item.geometry as usize].kind != PrimitiveKind::Triangle
                || n.kept_at == cut_at
                || !n
                    .entry
                    .far_at(cut_at, || far_item(scene, n.index as usize, &cut_ray))
        });
    }
    // The near items in the walk's order: the candidates they give are put in a deterministic
    // order below (a ray near hundreds of boxes has few candidates among them).

    // Allocated by the first candidate (most near pairs are misses), for one only: most rays that
    // have any have one, and a launch keeps every ray's candidates (a Vec's first push would make
    // room for four).
    let mut candidates: Vec<Candidate> = Vec::new();
    let push_candidate = |candidates: &mut Vec<Candidate>, c: Candidate| {
        if candidates.capacity() == 0 {
            // Allocated at its size outright (growing an empty list goes the longer way).
            *candidates = vec![c];
            return;
        }
        candidates.push(c);
    };
    let mut must_run: Vec<MustRun> = Vec::new();
    // Where the ray's own table allowed no cut but a table without any-hit would have: the ray
    // cut there, to mark what that cut leaves out (`Candidate::behind_shaderless_cut`) as the
    // retain above leaves out what the ray's own cut does.
    let shaderless = (shaderless_cut < rf.tmax && shaderless_cut != cut_at).then(|| {
        let mut r = *rf;
        r.tmax = shaderless_cut;
        r
    });
    // The ray in the space of each instance whose spheres it met ([`ScaledRay`]), made once per
    // instance: the walk meets the boxes of instances that overlap in turn.
    scaled.clear();
    // Likewise the ray as the box test takes it ([`BoxRay`]).
    box_rays.clear();
    for NearItem {
        item,
        outcome: near_outcome,
        index,
        entry,
        ..
    } in near.drain(..)
    {
        if let NearOutcome::Missed(evaluation) = near_outcome {
            // Classified while walking, so unculled (mask, primitive and opacity culling, see
            // `traverse::triangle_unculled`): a pair tested, a REQ-miss.
            stats.pair_tests += 1;
            evaluation.count(stats);
            stats.req_miss += 1;
            continue;
        }
        let outcome = match near_outcome {
            NearOutcome::At(k) => outcomes.get(k as usize),
            _ => None,
        };
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
        match w.kind {
            PrimitiveKind::Triangle => {
                stats.pair_tests += 1;
                // Spec, "Ray Opacity Culling": a culled triangle is a REQ-miss whatever its
                // intersection, counted as a culled box is, and not tested (the traversal
                // classified only unculled ones).
                if opacity_culled(ray, opaque) {
                    stats.req_miss += 1;
                    continue;
                }
                // Classified while traversing, or now (read in place, not copied).
                let computed;
                let out = match outcome {
                    Some(o) => o,
                    None => {
                        computed = classify_triangle(scene, w, &item, ray, rf, config.precision);
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
                let t_scale = reach_in_t(
                    item.vertices
                        .map(|i| scene.world_vertex(w, i as usize).map(|x| x.value)),
                    ray,
                );
                let single = kinds.len() == 1;
                let reports = kinds
                    .iter()
                    .map(|&k| AllowedReport {
                        hit_kind: k,
                        t,
                        barycentrics: Some(bary),
                        t_exact,
                        barycentrics_exact: Some(bary_exact),
                        t_scale,
                        required: presence == Presence::Required && single,
                    })
                    .collect();
                hits.push(TriangleHit {
                    candidate: candidates.len(),
                    bottom_level: w.bottom_level,
                    class: w.transform_class,
                    geometry: item.geometry,
                    primitive: item.primitive,
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
                        behind_shaderless_cut: shaderless.as_ref().is_some_and(|r| {
                            entry.far_at(r.tmax, || far_item(scene, index as usize, r))
                        }),
                    },
                );
            }
            PrimitiveKind::Aabb => {
                let hit_shaders = hit_shaders();
                if opacity_culled(ray, opaque) || !hit_shaders.has_intersection() {
                    stats.pair_tests += 1;
                    stats.req_miss += 1;
                    continue;
                }
                let GeometryData::Aabbs(a) = &geometry.data else {
                    unreachable!()
                };
                // A box the ray robustly crosses is a candidate: its shader must run (up to
                // where a confirmed hit may end the trace or shrink tmax first).
                let box_ray = of_instance(box_rays, w.instance, || {
                    BoxRay::new(
                        &scene.instances[w.instance as usize].band,
                        rf.origin,
                        rf.direction,
                        rf.tmin,
                        rf.tmax,
                    )
                });
                let box_entry = box_ray.entry(&a.boxes[item.primitive as usize]);
                // The sphere's far box missed: the shader reports nothing, whatever it is run for.
                if config.far_test && scene.sphere_far[index as usize].entry(rf).is_none() {
                    if let Some(t_hi) = box_entry {
                        must_run.push(MustRun {
                            primitive: prim,
                            t_hi,
                            candidate: None,
                        });
                    }
                    stats.far_rejections += 1;
                    continue;
                }
                stats.pair_tests += 1;
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
                    sphere_signs_in::<Dyadic>(m, &sphere, ray, &band)
                        .expect("exact arithmetic decides every sign")
                };
                let signs = match config.precision {
                    Precision::ExactOnly => exact(stats),
                    Precision::F64WithExactFallback => {
                        let in_instance = of_instance(scaled, w.instance, || {
                            ScaledRay::of(m, ray.origin, ray.direction)
                        });
                        match sphere_signs_scaled(in_instance, &sphere, ray.tmin, ray.tmax, &band) {
                            Some(s) => {
                                stats.filter_decided += 1;
                                s
                            }
                            None => exact(stats),
                        }
                    }
                    Precision::F32FilterOnly => {
                        stats.f32_evaluations += 1;
                        sphere_signs_in::<PlainF32>(m, &sphere, ray, &band)
                            .expect("f32 signs are taken at face value")
                    }
                };
                // Run for the sphere it crosses or the box it crosses, whichever is met first.
                let must = match (
                    signs.must_run.then(|| band.t0.hi.max(band.t1.lo)),
                    box_entry,
                ) {
                    (Some(s), Some(b)) => Some(s.min(b)),
                    (s, b) => s.or(b),
                };
                if let Some(t_hi) = must {
                    must_run.push(MustRun {
                        primitive: prim,
                        t_hi,
                        candidate: None,
                    });
                }
                let reports: few::Few<AllowedReport, 1> = sphere_reports(&signs, &band)
                    .into_iter()
                    .map(|r| AllowedReport {
                        hit_kind: r.hit_kind,
                        t: r.t,
                        barycentrics: None,
                        t_exact: r.t.mid(),
                        barycentrics_exact: None,
                        t_scale: 0.0,
                        required: r.required && signs.must_run,
                    })
                    .collect();
                if reports.is_empty() {
                    stats.req_miss += 1;
                    continue;
                }
                if must.is_some() {
                    if let Some(m) = must_run.last_mut() {
                        // Pushed next: its index among the candidates.
                        m.candidate = Some(candidates.len());
                    }
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
                        behind_shaderless_cut: false,
                    },
                );
            }
        }
    }
    in_key_order(&mut candidates, hits, &mut must_run);
    let watertight = watertight_groups(scene, ray, &candidates, hits);
    hits.clear();
    outcomes.clear();
    conclude(scene, ray, shaders, candidates, must_run, watertight)
}

/// Puts a ray's candidates in (instance, geometry, primitive) order, an order independent of the BVH
/// (unique per candidate), renumbering the triangle hits and must-run intersections that point at
/// them; the hits go in their candidates' order, as if made in it.
/// The entry of `instance` in a ray's per-instance cache, made by `make` where there is none yet (a
/// ray meets the primitives of a few instances, in turn where they overlap).
fn of_instance<T>(cache: &mut Vec<(u32, T)>, instance: u32, make: impl FnOnce() -> T) -> &T {
    let at = match cache.iter().position(|(i, _)| *i == instance) {
        Some(at) => at,
        None => {
            cache.push((instance, make()));
            cache.len() - 1
        }
    };
    &cache[at].1
}

fn in_key_order(
    candidates: &mut Vec<Candidate>,
    hits: &mut [TriangleHit],
    must_run: &mut [MustRun],
) {
    let key = |c: &Candidate| {
        (
            c.primitive.instance,
            c.primitive.geometry,
            c.primitive.primitive,
        )
    };
    if candidates.is_sorted_by_key(key) {
        return;
    }
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_unstable_by_key(|&i| key(&candidates[i]));
    let mut place = vec![0usize; order.len()];
    for (new, &old) in order.iter().enumerate() {
        place[old] = new;
    }
    let mut taken: Vec<Option<Candidate>> = candidates.drain(..).map(Some).collect();
    candidates.extend(
        order
            .iter()
            .map(|&i| taken[i].take().expect("each candidate taken once")),
    );
    for h in hits.iter_mut() {
        h.candidate = place[h.candidate];
    }
    hits.sort_unstable_by_key(|h| h.candidate);
    for m in must_run.iter_mut() {
        if let Some(c) = m.candidate.as_mut() {
            *c = place[*c];
        }
    }
}

/// The signs of `ray` against `sphere` of the instance transform `m` in the arithmetic `N`, None where
/// it cannot decide them.
fn sphere_signs_in<N: Num>(
    m: &[[f32; 4]; 3],
    sphere: &Sphere,
    ray: &Ray,
    band: &SphereBand,
) -> Option<SphereSigns> {
    sphere_signs::<N>(
        m,
        sphere,
        ray.origin,
        ray.direction,
        ray.tmin,
        ray.tmax,
        band,
    )
}

/// max over the vertices of |v − o|∞, over |d|∞: the t at which the ray has come as far as the
/// triangle's farthest vertex is from its origin (see [`AllowedReport::t_scale`]); 0 for a zero
/// direction.
fn reach_in_t(world: [[f64; 3]; 3], ray: &Ray) -> f64 {
    let d = ray
        .direction
        .iter()
        .fold(0f64, |m, &x| m.max((x as f64).abs()));
    let reach = world
        .iter()
        .flat_map(|v| (0..3).map(move |k| (v[k] - ray.origin[k] as f64).abs()))
        .fold(0f64, f64::max);
    if d > 0.0 {
        reach / d
    } else {
        0.0
    }
}
