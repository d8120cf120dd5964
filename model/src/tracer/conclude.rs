//! From one ray's candidates to the set of outcomes the spec allows: the committed hits the
//! traversal may produce ("Ray Closest Hit Determination"), the miss rule, and the bounds on the
//! any-hit and intersection invocation counts ("Ray Result Determination"; semantics.md §2, §10).
//!
//! Traversal order is unspecified, so the allowed committed hits are: every confirmable candidate
//! whose t may be at most the t of every required confirmable candidate (the closest, with
//! overlapping intervals VARY), and — when the trace may end early — every confirmable candidate
//! that could be confirmed first (TerminateOnFirstHit: any of them; an any-hit `Terminate` rule:
//! those candidates).

use super::traverse::{opacity, opacity_culled, MustRun};
use super::*;
use crate::scene::{Ray, RayFlags};

/// From the candidates to the allowed committed hits, the miss rule and the invocation counts.
pub(super) fn conclude(
    scene: &PreparedScene,
    ray: &Ray,
    shaders: &ShaderTable<'_>,
    candidates: Vec<Candidate>,
    must_run: Vec<MustRun>,
    watertight: Vec<WatertightGroup>,
) -> AllowedOutcomes {
    if candidates.is_empty() && must_run.is_empty() {
        return without_candidates(scene, ray, shaders, candidates, watertight);
    }
    conclude_candidates(scene, ray, shaders, candidates, must_run, watertight)
}

/// [`conclude`] for a ray without candidates and without an intersection that must run (most rays
/// that miss): no candidate to order, commit or run any-hit for, so the miss is required and both
/// counts are 0 at least, any-hit's at most, as the general rules give for an empty set (a test
/// compares the two).
fn without_candidates(
    scene: &PreparedScene,
    ray: &Ray,
    shaders: &ShaderTable<'_>,
    candidates: Vec<Candidate>,
    watertight: Vec<WatertightGroup>,
) -> AllowedOutcomes {
    AllowedOutcomes {
        miss: MissRule {
            allowed: true,
            required: true,
            discouraged: watertight.iter().any(|g| g.expect_hit),
        },
        committable: few::Few::new(),
        candidates,
        miss_shader: shaders.miss,
        skip_closest_hit: ray.flags.contains(RayFlags::SKIP_CLOSEST_HIT_SHADER),
        terminate_on_first_hit: ray.flags.contains(RayFlags::TERMINATE_ON_FIRST_HIT),
        any_hit: CountBounds {
            min: 0,
            max: Some(0),
        },
        intersection: CountBounds {
            min: 0,
            max: if reachable_procedural(scene, ray, shaders) {
                None
            } else {
                Some(0)
            },
        },
        watertight,
        vary: false,
        must_run: Vec::new(),
    }
}

/// Whether an intersection shader may run for the ray: a procedural geometry its flags and mask do
/// not cull has one (boxes may be enlarged without bound, so any of them is reachable).
fn reachable_procedural(scene: &PreparedScene, ray: &Ray, shaders: &ShaderTable<'_>) -> bool {
    if ray.flags.contains(RayFlags::SKIP_AABBS) {
        return false;
    }
    scene.procedural.iter().any(|&(i, g)| {
        let inst = &scene.scene.instances[i as usize];
        if inst.mask as u32 & ray.cull_mask & 0xFF == 0 {
            return false;
        }
        let b = inst
            .bottom_level
            .expect("a procedural geometry's instance has a level");
        let geometry = &scene.scene.bottom_levels[b as usize].geometries[g as usize];
        let opaque = opacity(ray, inst, geometry.flags.opaque);
        !opacity_culled(ray, opaque) && (shaders.hit)(i, g).has_intersection()
    })
}

/// [`conclude`] for any candidates.
fn conclude_candidates(
    scene: &PreparedScene,
    ray: &Ray,
    shaders: &ShaderTable<'_>,
    candidates: Vec<Candidate>,
    must_run: Vec<MustRun>,
    watertight: Vec<WatertightGroup>,
) -> AllowedOutcomes {
    let tofh = ray.flags.contains(RayFlags::TERMINATE_ON_FIRST_HIT);
    let fact = |c: &Candidate| {
        let ok = c.confirmation.confirms();
        Facts {
            confirmable: ok,
            early: c.confirmation.ends_trace(tofh),
            hull: c.t_hull(),
        }
    };
    // On the stack for the usual few candidates.
    const FEW: usize = 8;
    let mut few = [const {
        Facts {
            confirmable: false,
            early: false,
            hull: Interval::ALL,
        }
    }; FEW];
    let many: Vec<Facts>;
    let facts: &[Facts] = if candidates.len() <= FEW {
        for (f, c) in few.iter_mut().zip(&candidates) {
            *f = fact(c);
        }
        &few[..candidates.len()]
    } else {
        many = candidates.iter().map(fact).collect();
        &many
    };
    let confirmable = |i: usize| facts[i].confirmable;
    let hulls = |i: usize| facts[i].hull;
    let required = |i: usize| confirmable(i) && candidates[i].presence == Presence::Required;
    let order = Order::of(facts, required);
    let no_required = order.required_hi.count == 0;
    let committable: few::Few<usize, 4> = (0..candidates.len())
        .filter(|&i| order.committable(facts, i, required(i)))
        .collect();
    // A candidate must be processed when nothing can end the trace or shrink tmax below it first.
    let must_process = |i: Option<usize>, t_hi: f64| order.must_process(facts, i, t_hi);
    // Any-hit: at most once per candidate with NO_DUPLICATE_ANY_HIT, unbounded otherwise; with
    // TerminateOnFirstHit every accepting invocation ends the trace.
    let mut any_hit_max: Option<u32> = Some(0);
    let mut accepting_any_hit = false;
    let mut any_hit_min = 0u32;
    for (i, c) in candidates.iter().enumerate() {
        if !c.confirmation.runs_any_hit() {
            continue;
        }
        let accepts = c.confirmation.confirms();
        accepting_any_hit |= accepts;
        if !(tofh && accepts) {
            any_hit_max = match (any_hit_max, c.no_duplicate_any_hit) {
                (Some(m), true) => Some(m + 1),
                _ => None,
            };
        }
        if c.presence == Presence::Required && must_process(Some(i), hulls(i).hi) {
            any_hit_min += 1;
        }
    }
    if tofh && accepting_any_hit {
        any_hit_max = any_hit_max.map(|m| m + 1);
    }
    // Intersection shaders may run for any reachable box (boxes may be enlarged without bound).
    let reachable_procedural = reachable_procedural(scene, ray, shaders);
    let mut must_run: Vec<PrimitiveRef> = must_run
        .iter()
        .filter(|m| must_process(m.candidate, m.t_hi))
        .map(|m| m.primitive)
        .collect();
    // In primitive order, as the candidates: the walk's order is the BVH's.
    must_run.sort_unstable();
    let intersection_min = must_run.len() as u32;
    let discouraged = no_required && watertight.iter().any(|g| g.expect_hit);
    let vary = candidates.iter().any(|c| c.presence == Presence::Possible)
        || committable.len() > 1
        || candidates.iter().any(|c| c.reports.len() > 1);
    AllowedOutcomes {
        miss: MissRule {
            allowed: no_required,
            required: committable.is_empty(),
            discouraged,
        },
        committable,
        candidates,
        miss_shader: shaders.miss,
        skip_closest_hit: ray.flags.contains(RayFlags::SKIP_CLOSEST_HIT_SHADER),
        terminate_on_first_hit: tofh,
        any_hit: CountBounds {
            min: any_hit_min,
            max: any_hit_max,
        },
        intersection: CountBounds {
            min: intersection_min,
            max: if reachable_procedural { None } else { Some(0) },
        },
        watertight,
        vary,
        must_run,
    }
}

/// Per candidate: confirmable, may end the trace early, and the hull of its t intervals.
#[derive(Debug, Clone, Copy)]
struct Facts {
    confirmable: bool,
    early: bool,
    hull: Interval,
}

/// The least two keys over a set of candidates, the least with its candidate, and the members whose
/// key is NaN counted apart: the least over the set without any one member, in O(1). (A ray may have
/// thousands of candidates — an ill-conditioned instance's band is wide — and each asks about all
/// the others.)
#[derive(Debug, Default, Clone, Copy)]
struct Least {
    count: usize,
    nan: usize,
    least: Option<(usize, f64)>,
    second: Option<f64>,
}

impl Least {
    fn add(&mut self, i: usize, key: f64) {
        self.count += 1;
        if key.is_nan() {
            self.nan += 1;
            return;
        }
        match self.least {
            Some((_, l)) if key >= l => {
                if self.second.is_none_or(|s| key < s) {
                    self.second = Some(key);
                }
            }
            _ => {
                self.second = self.least.map(|(_, l)| l);
                self.least = Some((i, key));
            }
        }
    }

    /// The set without `member` (one of it, with its key; None: the whole set): how many members
    /// are left, how many of those have a NaN key, and the least key that is not NaN.
    fn without(&self, member: Option<(usize, f64)>) -> (usize, usize, Option<f64>) {
        let Some((i, key)) = member else {
            return (self.count, self.nan, self.least.map(|(_, l)| l));
        };
        if key.is_nan() {
            return (self.count - 1, self.nan - 1, self.least.map(|(_, l)| l));
        }
        let least = match self.least {
            Some((j, _)) if j == i => self.second,
            other => other.map(|(_, l)| l),
        };
        (self.count - 1, self.nan, least)
    }
}

/// What the committed-hit and must-process rules ask of the other candidates, gathered once: the t
/// hulls' upper ends of the required confirmable candidates, the number of confirmable candidates
/// that may end the trace early, and the lower ends of the other confirmable ones.
struct Order {
    required_hi: Least,
    early: usize,
    late_lo: Least,
}

impl Order {
    fn of(facts: &[Facts], required: impl Fn(usize) -> bool) -> Order {
        let mut o = Order {
            required_hi: Least::default(),
            early: 0,
            late_lo: Least::default(),
        };
        for (i, f) in facts.iter().enumerate() {
            if !f.confirmable {
                continue;
            }
            if required(i) {
                o.required_hi.add(i, f.hull.hi);
            }
            if f.early {
                o.early += 1;
            } else {
                o.late_lo.add(i, f.hull.lo);
            }
        }
        o
    }

    /// Whether candidate `i` may be the committed hit: confirmable, and it may end the trace early or
    /// its t may be at most that of every other required confirmable candidate (`hull.lo ≤ hull.hi`
    /// of each).
    fn committable(&self, facts: &[Facts], i: usize, required: bool) -> bool {
        let f = &facts[i];
        if !f.confirmable {
            return false;
        }
        if f.early {
            return true;
        }
        let (left, nan, least) = self.required_hi.without(required.then_some((i, f.hull.hi)));
        left == 0 || (!f.hull.lo.is_nan() && nan == 0 && least.is_none_or(|m| f.hull.lo <= m))
    }

    /// Whether candidate `i` (None: a primitive that is no candidate) must be processed up to
    /// `t_hi`: no other confirmable candidate may end the trace early, and every other confirmable
    /// one lies beyond `t_hi`.
    fn must_process(&self, facts: &[Facts], i: Option<usize>, t_hi: f64) -> bool {
        let own = i.map(|i| (i, facts[i]));
        let own_early = own.is_some_and(|(_, f)| f.confirmable && f.early);
        if self.early > usize::from(own_early) {
            return false;
        }
        let skip = own
            .filter(|(_, f)| f.confirmable && !f.early)
            .map(|(i, f)| (i, f.hull.lo));
        let (left, nan, least) = self.late_lo.without(skip);
        if t_hi.is_nan() {
            return left == 0;
        }
        nan == 0 && least.is_none_or(|m| m > t_hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray without candidates is concluded by `without_candidates` exactly as the general rules
    /// conclude an empty set, whatever its flags, cull mask, shader table, the scene's procedural
    /// geometries and the watertight groups passed in.
    #[test]
    fn a_ray_without_candidates_concludes_as_the_general_rules_do() {
        use crate::scene::{build, Scene, SceneInstance};
        let mut boxes = SceneInstance::of(1);
        boxes.mask = 0x0F;
        let scenes = [
            Scene {
                bottom_levels: vec![build::icosphere(1, 1.0)],
                instances: vec![SceneInstance::of(0)],
            },
            Scene {
                bottom_levels: vec![
                    build::icosphere(1, 1.0),
                    build::spheres_in_boxes(3, 4, 5.0, 1.0),
                ],
                instances: vec![SceneInstance::of(0), boxes],
            },
        ];
        let groups = |expect_hit: bool| {
            vec![WatertightGroup {
                shape: WatertightShape::SharedEdge,
                members: Vec::new(),
                expect_hit,
                t: Interval { lo: 1.0, hi: 2.0 },
            }]
        };
        let mut compared = 0;
        for scene in &scenes {
            let prepared = PreparedScene::new(scene).expect("a defined scene");
            for intersection in [false, true] {
                let hit = move |_: u32, _: u32| HitShaders {
                    zero_group: false,
                    closest_hit: true,
                    any_hit: None,
                    intersection,
                    group: 1,
                };
                for zero_group in [false, true] {
                    let shaders = ShaderTable {
                        hit: &hit,
                        miss: MissShader {
                            zero_group,
                            group: 2,
                        },
                    };
                    for flags in [0, 1, 2, 4, 8, 4 | 8, 64, 128, 256, 512, 1 | 512] {
                        for cull_mask in [0xFF, 0xF0, 0x01] {
                            let mut ray = Ray::new([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], 0.0, 10.0);
                            ray.flags = RayFlags(flags);
                            ray.cull_mask = cull_mask;
                            for watertight in [Vec::new(), groups(false), groups(true)] {
                                let general = conclude_candidates(
                                    &prepared,
                                    &ray,
                                    &shaders,
                                    Vec::new(),
                                    Vec::new(),
                                    watertight.clone(),
                                );
                                let fast = conclude(
                                    &prepared,
                                    &ray,
                                    &shaders,
                                    Vec::new(),
                                    Vec::new(),
                                    watertight,
                                );
                                assert_eq!(fast, general, "flags {flags} mask {cull_mask}");
                                compared += usize::from(fast.intersection.max.is_none());
                            }
                        }
                    }
                }
            }
        }
        // Some rays could reach an intersection shader, so that rule was compared too.
        assert!(compared > 0);
    }

    /// The rules as first written, each asking every other candidate in turn: the reference
    /// [`Order`] must agree with.
    fn committable_by_pairs(facts: &[Facts], required: &[bool], i: usize) -> bool {
        facts[i].confirmable
            && (facts[i].early
                || (0..facts.len()).all(|r| {
                    !(facts[r].confirmable && required[r])
                        || r == i
                        || facts[i].hull.lo <= facts[r].hull.hi
                }))
    }

    fn must_process_by_pairs(facts: &[Facts], i: Option<usize>, t_hi: f64) -> bool {
        (0..facts.len()).all(|c| {
            Some(c) == i || !facts[c].confirmable || (!facts[c].early && facts[c].hull.lo > t_hi)
        })
    }

    #[test]
    fn the_gathered_order_answers_as_asking_every_other_candidate() {
        // Keys from a small set with ties, infinities and NaN, so every branch of Least is met.
        let keys = [
            f64::NEG_INFINITY,
            -1.0,
            0.0,
            0.5,
            0.5,
            1.0,
            2.0,
            f64::INFINITY,
            f64::NAN,
        ];
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        let mut checked = (0, 0);
        for round in 0..4000 {
            let n = 1 + next(if round % 10 == 0 { 40 } else { 7 });
            let facts: Vec<Facts> = (0..n)
                .map(|_| Facts {
                    confirmable: next(5) != 0,
                    early: next(6) == 0,
                    hull: Interval {
                        lo: keys[next(keys.len())],
                        hi: keys[next(keys.len())],
                    },
                })
                .collect();
            let required: Vec<bool> = (0..n).map(|_| next(3) != 0).collect();
            let order = Order::of(&facts, |i| facts[i].confirmable && required[i]);
            for i in 0..n {
                let req = facts[i].confirmable && required[i];
                assert_eq!(
                    order.committable(&facts, i, req),
                    committable_by_pairs(&facts, &required, i),
                    "committable {i} of {facts:?} required {required:?}"
                );
                for t in keys {
                    for own in [Some(i), None] {
                        assert_eq!(
                            order.must_process(&facts, own, t),
                            must_process_by_pairs(&facts, own, t),
                            "must_process {own:?} at {t} of {facts:?}"
                        );
                        checked.1 += usize::from(must_process_by_pairs(&facts, own, t));
                    }
                }
                checked.0 += usize::from(committable_by_pairs(&facts, &required, i));
            }
        }
        // Both answers were met often.
        assert!(checked.0 > 1000 && checked.1 > 1000, "{checked:?}");
    }
}
