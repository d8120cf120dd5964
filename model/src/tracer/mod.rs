//! The certified reference tracer: for one ray against a [`Scene`](crate::scene::Scene), the SET of
//! outcomes the spec allows (semantics.md §1-5, §10; spec chapter "Ray Traversal"), each pair of ray
//! and primitive classified REQ-hit / VARY / REQ-miss against a band no conformant f32
//! implementation can leave, with a proven f64 filter and an exact fallback.
//!
//! Entry points: [`PreparedScene::new`], [`trace_ray`] → [`AllowedOutcomes`];
//! [`record::RayRecord`] (what the harness's shaders write) and [`judge::judge`] → verdicts,
//! [`summary::Summary`] for histograms over a run.

pub mod arith;
pub mod band;
mod box_crossing;
mod bvh;
mod candidates;
mod conclude;
pub mod few;
pub mod judge;
mod outside;
mod pages;
mod plain;
mod prepare;
pub mod record;
pub mod sphere;
pub mod summary;
#[cfg(test)]
mod test_support;
mod traverse;
pub mod triangle;
mod watertight;
pub mod workload;

pub use prepare::{PreparedScene, PrimitiveKind};
pub use traverse::{cut_allowed_for, opacity, opacity_culled, trace_launch, trace_ray, trace_rays};
pub use triangle::{Interval, MissReason, PairClass, VaryReason};

use serde::{Deserialize, Serialize};

/// How the signs of the predicates are evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Precision {
    /// Plain f32, signs at face value: for measurement only, no guarantee.
    F32FilterOnly,
    /// f64 with a proven running error bound; exact arithmetic when it cannot decide.
    #[default]
    F64WithExactFallback,
    /// Exact dyadic arithmetic for every pair (the reference the filter is tested against).
    ExactOnly,
}

/// Tracer settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TracerConfig {
    pub precision: Precision,
    /// Use the BVH (otherwise every primitive is tested: the reference for the BVH).
    pub use_bvh: bool,
    /// Reject primitives whose padded box the ray misses before any arithmetic (otherwise every
    /// primitive is classified in full: the reference for the far test).
    pub far_test: bool,
}

impl TracerConfig {
    /// Whether rays walk the BVH (which skips a node only where every item below it is far): the
    /// BVH and the far test both on. Brute force, the reference, goes without.
    pub fn walks_bvh(&self) -> bool {
        self.use_bvh && self.far_test
    }

    /// The default settings with another precision.
    pub fn with_precision(precision: Precision) -> TracerConfig {
        TracerConfig {
            precision,
            ..TracerConfig::default()
        }
    }
}

impl Default for TracerConfig {
    /// F64WithExactFallback, the BVH and the far test. The precision is chosen from the oracle's
    /// run time against its error (`cargo bench -p rtconf-model --bench oracle_curve`: the twelve
    /// stress families, three cases each, and the five standard workloads; 245,552 classified
    /// pairs). Against ExactOnly it misclassified no pair and found the same VARY share (30.34 %
    /// of rays), at 0.17 of ExactOnly's time per ray (geometric mean over the 17 inputs; ExactOnly
    /// is about six times slower). F32FilterOnly took 0.15 but misclassified 184 pairs (0.075 %):
    /// 26 unsound — REQ where the exact decision is not, on slivers and tiny triangles and on very
    /// long or short rays, so it would judge drivers wrongly — and 158 lost, VARY where exact
    /// decides REQ, most of them at extreme scales. The f64 filter never needed its exact
    /// fallback on these inputs; certainty costs about an eighth more time than plain f32 signs.
    fn default() -> Self {
        TracerConfig {
            precision: Precision::F64WithExactFallback,
            use_bvh: true,
            far_test: true,
        }
    }
}

/// What the any-hit shader of a hit group does (stated by the case, so any-hit semantics are judged).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AnyHitRule {
    /// Returns: the candidate is confirmed.
    #[default]
    Accept,
    /// `ignoreIntersectionEXT`: the candidate is dropped.
    Ignore,
    /// `terminateRayEXT`: the candidate is confirmed and the trace ends.
    Terminate,
    /// Ignores candidates with an odd PrimitiveId, accepts the others.
    IgnoreOddPrimitives,
}

impl AnyHitRule {
    /// The value of the any-hit shader's specialisation constant that selects this rule.
    pub fn code(self) -> u32 {
        match self {
            AnyHitRule::Accept => 0,
            AnyHitRule::Ignore => 1,
            AnyHitRule::Terminate => 2,
            AnyHitRule::IgnoreOddPrimitives => 3,
        }
    }

    /// Whether the shader confirms a candidate of primitive `primitive`.
    pub fn accepts(self, primitive: u32) -> bool {
        match self {
            AnyHitRule::Accept | AnyHitRule::Terminate => true,
            AnyHitRule::Ignore => false,
            AnyHitRule::IgnoreOddPrimitives => primitive & 1 == 0,
        }
    }
}

/// The hit group a ray reaches on one geometry of one instance (the caller resolves the SBT).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct HitShaders {
    /// An all-zero handle: no closest-hit (still a hit), any-hit accepts, intersection never
    /// reports (semantics.md §6).
    pub zero_group: bool,
    pub closest_hit: bool,
    pub any_hit: Option<AnyHitRule>,
    pub intersection: bool,
    /// The shader group index the record's `group` word names.
    pub group: u32,
}

impl HitShaders {
    /// A group with a closest-hit shader only.
    pub fn closest(group: u32) -> HitShaders {
        HitShaders {
            zero_group: false,
            closest_hit: true,
            any_hit: None,
            intersection: false,
            group,
        }
    }
    /// A group with closest-hit and the given any-hit rule.
    pub fn with_any_hit(group: u32, rule: AnyHitRule) -> HitShaders {
        HitShaders {
            any_hit: Some(rule),
            ..HitShaders::closest(group)
        }
    }
    /// A procedural group (closest-hit and the sphere intersection shader).
    pub fn procedural(group: u32, any_hit: Option<AnyHitRule>) -> HitShaders {
        HitShaders {
            intersection: true,
            any_hit,
            ..HitShaders::closest(group)
        }
    }
    /// The zero group.
    pub fn zero() -> HitShaders {
        HitShaders {
            zero_group: true,
            closest_hit: false,
            any_hit: None,
            intersection: false,
            group: 0,
        }
    }
    fn has_any_hit(&self) -> bool {
        !self.zero_group && self.any_hit.is_some()
    }
    fn has_intersection(&self) -> bool {
        !self.zero_group && self.intersection
    }
}

/// The miss record a ray reaches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MissShader {
    /// An all-zero handle: the miss does nothing.
    pub zero_group: bool,
    pub group: u32,
}

/// How the shader binding table resolves for one ray.
pub struct ShaderTable<'a> {
    /// `(instance index, geometry index)` → the hit group of that geometry for this ray.
    pub hit: &'a dyn Fn(u32, u32) -> HitShaders,
    pub miss: MissShader,
}

/// Counters of the work done, accumulated across rays.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TracerStats {
    pub rays: u64,
    /// Pairs (ray, primitive) classified past the far test.
    pub pair_tests: u64,
    /// Pairs rejected by the far test (REQ-miss without arithmetic).
    pub far_rejections: u64,
    /// Pairs the f64 filter decided.
    pub filter_decided: u64,
    /// Pairs that needed exact arithmetic (fallback or ExactOnly).
    pub exact_evaluations: u64,
    /// Pairs evaluated in plain f32.
    pub f32_evaluations: u64,
    pub req_hit: u64,
    pub vary: u64,
    pub req_miss: u64,
    pub nodes_visited: u64,
}

impl TracerStats {
    pub fn merge(&mut self, o: &TracerStats) {
        self.rays += o.rays;
        self.pair_tests += o.pair_tests;
        self.far_rejections += o.far_rejections;
        self.filter_decided += o.filter_decided;
        self.exact_evaluations += o.exact_evaluations;
        self.f32_evaluations += o.f32_evaluations;
        self.req_hit += o.req_hit;
        self.vary += o.vary;
        self.req_miss += o.req_miss;
        self.nodes_visited += o.nodes_visited;
    }
    /// Share of classified pairs that needed the exact fallback.
    pub fn exact_share(&self) -> f64 {
        self.exact_evaluations as f64 / self.pair_tests.max(1) as f64
    }
    /// Share of classified pairs that were VARY.
    pub fn vary_share(&self) -> f64 {
        self.vary as f64 / self.pair_tests.max(1) as f64
    }
}

/// Whether a candidate must occur or may occur.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Presence {
    Required,
    Possible,
}

/// What happens to a candidate in "Ray Intersection Confirmation".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Confirmation {
    /// Opaque: confirmed without any-hit.
    Opaque,
    /// Non-opaque without an any-hit shader (or the zero group): confirmed.
    NoAnyHit,
    /// The any-hit shader runs and confirms (`terminates`: and ends the trace).
    AnyHitAccepts { terminates: bool },
    /// The any-hit shader runs and ignores the candidate.
    AnyHitIgnores,
}

impl Confirmation {
    pub fn confirms(self) -> bool {
        !matches!(self, Confirmation::AnyHitIgnores)
    }
    /// Whether confirming the candidate ends the trace (spec, "Ray Traversal": an any-hit shader's
    /// terminateRayEXT, or TerminateOnFirstHit on the ray): nothing the traversal has not reached
    /// by then is considered, however near.
    pub fn ends_trace(self, terminate_on_first_hit: bool) -> bool {
        self.confirms()
            && (terminate_on_first_hit || self == Confirmation::AnyHitAccepts { terminates: true })
    }
    pub fn runs_any_hit(self) -> bool {
        matches!(
            self,
            Confirmation::AnyHitAccepts { .. } | Confirmation::AnyHitIgnores
        )
    }
}

/// Which primitive: InstanceId, GeometryIndex, PrimitiveId.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct PrimitiveRef {
    pub instance: u32,
    pub geometry: u32,
    pub primitive: u32,
}

/// One hit a candidate may be committed as.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AllowedReport {
    /// 0xFE front / 0xFF back for triangles; 0 entry / 1 from inside for spheres.
    pub hit_kind: u32,
    pub t: Interval,
    /// Triangles: intervals of (b, c), the weights of vertex 1 and vertex 2.
    pub barycentrics: Option<[Interval; 2]>,
    /// The exact t and barycentrics (f64 nearest), the centre the errors are measured from.
    pub t_exact: f64,
    pub barycentrics_exact: Option<[f64; 2]>,
    /// The scale t's error is counted in ULPs of, beside |t_exact| (the larger of the two): for a
    /// triangle the ray's reach to its farthest vertex in units of the ray's direction,
    /// max |v − o|∞ / |d|∞ — an f32 test finds t from vertex-minus-origin differences of that size,
    /// so a t near 0 (a ray that starts on the triangle) carries their rounding, not ULPs of its
    /// own; 0 where t_exact alone is the scale (spheres).
    #[serde(default)]
    pub t_scale: f64,
    /// Required: the only report of a required candidate.
    pub required: bool,
}

/// A primitive that may become an intersection candidate (everything else is REQ-miss).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    pub primitive: PrimitiveRef,
    pub kind: PrimitiveKind,
    pub custom_index: u32,
    pub presence: Presence,
    /// Why it is only possible (when `presence` is Possible).
    pub vary_reason: Option<VaryReason>,
    pub opaque: bool,
    pub confirmation: Confirmation,
    pub shaders: HitShaders,
    pub no_duplicate_any_hit: bool,
    /// At most two for a triangle (its facings) or a sphere (entry and exit). The first is kept
    /// inline, two go to the heap: most triangles have one report, and a candidate with room for
    /// two inline is 248 bytes, copied with the call at every move of it and of its ray's outcomes
    /// (room for one, 144 bytes: launch rates +1 to +3 % on the standard workloads, the spheres'
    /// included, `RTCONF_BENCH_PASSES=15 bash scripts/bench-ab.sh expected_launch A B 8 NAME`).
    pub reports: few::Few<AllowedReport, 1>,
    /// A triangle the trace would have left out had no primitive of the scene run any-hit for the
    /// ray: behind the cut the ray then gets (see `traverse`), which the ray's own shader table did
    /// not allow. Such a table is the one a launch's hit reach is traced with
    /// ([`crate::semantics::ray_reach`]), so the reach is found from outcomes traced with the
    /// launch's own table by leaving these out.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub behind_shaderless_cut: bool,
}

impl Candidate {
    /// The hull of the t intervals of its reports.
    pub fn t_hull(&self) -> Interval {
        self.reports
            .iter()
            .map(|r| r.t)
            .reduce(|a, b| a.hull(&b))
            .unwrap_or(Interval::ALL)
    }
}

/// Bounds on a shader invocation count; `max: None` is unbounded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct CountBounds {
    pub min: u32,
    pub max: Option<u32>,
}

impl CountBounds {
    pub fn contains(&self, n: u32) -> bool {
        n >= self.min && !matches!(self.max, Some(m) if n > m)
    }
}

/// Whether the ray may, or must, miss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MissRule {
    /// No required confirmable candidate: a miss is allowed.
    pub allowed: bool,
    /// No candidate can be committed: a miss is required.
    pub required: bool,
    /// A watertight group should be hit (a miss is a quality warning, not a failure).
    pub discouraged: bool,
}

/// A shared edge or closed fan the ray passes through (within the band), whose triangles should be
/// hit exactly once between them (spec, "Watertightness": should not double-hit or miss).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WatertightGroup {
    pub shape: WatertightShape,
    pub members: Vec<PrimitiveRef>,
    /// Every member would be confirmed: a hole is observable as a missing hit.
    pub expect_hit: bool,
    /// Hull of the members' t intervals.
    pub t: Interval,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WatertightShape {
    SharedEdge,
    ClosedFan,
}

/// The set of outcomes the spec allows for one ray.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AllowedOutcomes {
    /// Every primitive that may become a candidate, after culling.
    pub candidates: Vec<Candidate>,
    /// Indices into `candidates` of those that may be the committed hit.
    pub committable: few::Few<usize, 4>,
    pub miss: MissRule,
    pub miss_shader: MissShader,
    /// SkipClosestHitShader was given.
    pub skip_closest_hit: bool,
    /// TerminateOnFirstHit was given: every confirmed candidate ends the trace.
    #[serde(default)]
    pub terminate_on_first_hit: bool,
    pub any_hit: CountBounds,
    pub intersection: CountBounds,
    pub watertight: Vec<WatertightGroup>,
    /// Whether any part of the answer was VARY.
    pub vary: bool,
    /// The boxes whose intersection shader must run (those `intersection.min` counts): each the
    /// ray robustly crosses, or whose sphere it does, before anything may end the trace or shrink
    /// tmax below it; in primitive order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub must_run: Vec<PrimitiveRef>,
}

impl AllowedOutcomes {
    /// The candidate of a primitive, if it may be one.
    pub fn candidate(&self, p: &PrimitiveRef) -> Option<&Candidate> {
        self.candidates.iter().find(|c| c.primitive == *p)
    }
    /// Whether a primitive may be the committed hit.
    pub fn may_commit(&self, p: &PrimitiveRef) -> bool {
        self.committable
            .iter()
            .any(|&i| self.candidates[i].primitive == *p)
    }
}
