//! Numerical stress families: deterministic scenes and rays, each generated from a seed and a size,
//! that push a ray tracer where f32 arithmetic is hardest — rays exactly through shared edges and
//! vertices of closed meshes, geometry far from the origin and at extreme scales, slivers and tiny
//! triangles, grazing rays, very long and very short rays, ray intervals a few ULPs from the hit,
//! ill-conditioned, stacked and mirrored transforms, and large meshes.
//!
//! Every [`StressCase`] states what it claims about itself ([`Claim`]); [`Claim::check`] proves each
//! claim in exact dyadic arithmetic, so a family that stops doing what it says is caught before its
//! rays judge anyone. [`FamilyReport`] turns the records a driver wrote for a family's rays into
//! watertightness failures and holes, t and barycentric errors in ULPs, and what the driver did on
//! the rays the model classed VARY — through [`crate::tracer::judge`] and
//! [`crate::tracer::summary::Summary`], so feeding it a driver's records is one call.

mod aim;
mod claims;
mod families;
mod mesh;
mod numeric;
mod proofs;
mod report;
mod transforms;

pub use claims::{Claim, ClaimError, TLimit};
pub use families::families;
pub use mesh::LatticeMesh;
pub use proofs::FanIndex;
pub use report::{ErrorStats, FamilyReport, VaryChoices};

use crate::scene::{Ray, Scene};
use crate::tracer::record::RayRecord;
use crate::tracer::{
    trace_launch, AllowedOutcomes, AnyHitRule, HitShaders, MissShader, PreparedScene, ShaderTable,
    TracerConfig, TracerStats,
};

/// The miss shader group every stress case uses.
pub const STRESS_MISS_GROUP: u32 = 1000;

/// The hit group of `(instance, geometry)` in every stress case: a closest-hit shader and an
/// any-hit shader that accepts, so every candidate a driver finds is recorded in the record's
/// "seen" slots (that is how a double hit on a shared edge becomes observable). The geometries of
/// stress scenes are not opaque, for the same reason.
pub fn stress_hit_shaders(instance: u32, geometry: u32) -> HitShaders {
    HitShaders::with_any_hit(10 * instance + geometry, AnyHitRule::Accept)
}

/// The miss record of every stress case.
pub fn stress_miss_shader() -> MissShader {
    MissShader {
        zero_group: false,
        group: STRESS_MISS_GROUP,
    }
}

/// One generated case of a family: a scene, its rays (one per launch ID, x fastest), and what the
/// case claims about itself.
#[derive(Debug, Clone)]
pub struct StressCase {
    /// `family/seed`.
    pub name: String,
    pub scene: Scene,
    pub rays: Vec<Ray>,
    pub claims: Vec<Claim>,
}

impl StressCase {
    /// Checks every claim in exact arithmetic; the failures, each with the claim's index. The
    /// claims share one fresh index of the triangles around each vertex.
    pub fn check_claims(&self) -> Vec<(usize, ClaimError)> {
        let mut index = FanIndex::default();
        self.claims
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.check_indexed(self, &mut index).err().map(|e| (i, e)))
            .collect()
    }

    /// What the spec allows for every ray, under the stress shader table.
    pub fn allowed(&self, config: &TracerConfig) -> (Vec<AllowedOutcomes>, TracerStats) {
        let prepared = PreparedScene::new(&self.scene).expect("stress scenes are defined");
        self.allowed_in(&prepared, config)
    }

    /// As [`StressCase::allowed`], for a scene prepared once and traced in several modes.
    pub fn allowed_in(
        &self,
        prepared: &PreparedScene,
        config: &TracerConfig,
    ) -> (Vec<AllowedOutcomes>, TracerStats) {
        let hit = stress_hit_shaders;
        let table = ShaderTable {
            hit: &hit,
            miss: stress_miss_shader(),
        };
        let mut stats = TracerStats::default();
        let outs = trace_launch(prepared, &self.rays, &table, config, &mut stats)
            .expect("stress rays are defined");
        (outs, stats)
    }
}

/// A named generator of stress cases.
#[derive(Debug, Clone, Copy)]
pub struct Family {
    pub name: &'static str,
    /// What the family stresses, in one line.
    pub about: &'static str,
    /// `generate(seed, size)`: `size` is the number of rays (large meshes also grow with it).
    pub generate: fn(u64, usize) -> StressCase,
    /// The size `cargo test` uses.
    pub test_size: usize,
    /// The size `rtconf stress` uses.
    pub full_size: usize,
}

impl Family {
    /// The case of `seed` at `size`.
    pub fn case(&self, seed: u64, size: usize) -> StressCase {
        (self.generate)(seed, size)
    }

    /// The family's report over the cases of `seeds` at `size`: each case's claims are proven,
    /// `driver` writes the records of its rays (one per ray, in launch order), and the model under
    /// `config` judges them.
    pub fn report(
        &self,
        seeds: impl IntoIterator<Item = u64>,
        size: usize,
        config: &TracerConfig,
        mut driver: impl FnMut(&StressCase) -> Vec<RayRecord>,
    ) -> Result<FamilyReport, ClaimsFailed> {
        let mut report = FamilyReport::new(self.name);
        for seed in seeds {
            let case = self.case(seed, size);
            let failures = case.check_claims();
            if !failures.is_empty() {
                return Err(ClaimsFailed {
                    case: case.name,
                    failures,
                });
            }
            let (allowed, _) = case.allowed(config);
            report.add_case(&case.name, &allowed, &driver(&case));
        }
        Ok(report)
    }
}

/// A generated case whose claims do not hold: a bug of its family, never the driver's.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{case}: {} claims do not hold, the first: {}", failures.len(), failures[0].1)]
pub struct ClaimsFailed {
    pub case: String,
    /// `(claim index, why)`.
    pub failures: Vec<(usize, ClaimError)>,
}

/// The family named `name`.
pub fn family(name: &str) -> Option<Family> {
    families().into_iter().find(|f| f.name == name)
}
