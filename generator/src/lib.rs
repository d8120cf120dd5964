//! proptest strategies for valid and one-VUID-invalid rtconf cases, generation with fixed seeds, and
//! shrinking of failing cases into `cases/regressions/`.
//!
//! A [`CaseSpec`] names the command and the intent (valid, or violating one VUID); [`generate_range`]
//! turns it into cases deterministically from a seed for every command (trace calls through
//! [`case_strategy`], builds through [`accel`]), judged with the rules it is given;
//! [`shrink_failure`] minimises a failing trace case and writes it as YAML.

pub mod accel;
pub mod aim;
pub mod mutation;
pub mod mutation_io;
pub mod plan;
pub mod profiles;
pub mod registry;
pub mod resources;
pub mod scenes;
pub mod valid;

pub use mutation::{mutations_for, unmutated, Mutation, NullHit};
pub use plan::Limits;
pub use valid::DimensionRange;

use model::rules::{applies_to, RuleSet, Status};
use model::{Case, CommandId, DeviceProfile, Intent};
use proptest::strategy::{BoxedStrategy, Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::path::{Path, PathBuf};

/// Why cases could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum GenError {
    #[error("unsupported by profile: {0}")]
    Unsupported(String),
    #[error("profile `{profile}` does not report `{limit}`")]
    MissingLimit { profile: String, limit: String },
    #[error("{vuid} is not a rule of {command}")]
    NotForCommand { vuid: String, command: String },
    #[error("{vuid} is not an executable rule ({status})")]
    NotExecutable { vuid: String, status: String },
    #[error("no mutation is written for {0}")]
    NoMutation(String),
    #[error("profile: {0}")]
    Profile(String),
    #[error("registry: {0}")]
    Registry(String),
    #[error("i/o: {0}")]
    Io(String),
}

/// What a generated case is meant to be.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SpecIntent {
    Valid,
    /// Violates this VUID (plus the co-violations the device makes unavoidable).
    Violate(String),
}

/// The knobs of a generation request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaseSpec {
    /// The command; for a violating spec, the command the VUID names (see [`CaseSpec::for_vuid`]).
    pub command: CommandId,
    pub intent: SpecIntent,
    /// How large the launch dimensions of the underlying valid case are.
    pub dimensions: DimensionRange,
    /// Valid cases only: trace a rendered scene (`scenes`) instead of aimed geometry.
    pub rendered: bool,
}

impl CaseSpec {
    pub fn valid(command: CommandId) -> CaseSpec {
        CaseSpec {
            command,
            intent: SpecIntent::Valid,
            dimensions: DimensionRange::Small,
            rendered: false,
        }
    }

    /// A valid spec whose cases trace rendered scenes (camera, random and edge-aimed rays).
    pub fn rendered(command: CommandId) -> CaseSpec {
        CaseSpec {
            rendered: true,
            ..CaseSpec::valid(command)
        }
    }

    pub fn violate(command: CommandId, vuid: &str) -> CaseSpec {
        CaseSpec {
            command,
            intent: SpecIntent::Violate(vuid.to_string()),
            dimensions: DimensionRange::Small,
            rendered: false,
        }
    }

    /// The spec violating `vuid`, for the command its scope names, or `command` for a structure's VUID
    /// (`VUID-VkStridedDeviceAddressRegionKHR-…` applies to the KHR trace calls).
    pub fn for_vuid(vuid: &str, command: CommandId) -> CaseSpec {
        CaseSpec::violate(CommandId::from_vuid(vuid).unwrap_or(command), vuid)
    }

    /// The same request with dimensions up to the profile's limits.
    pub fn at_limits(mut self) -> CaseSpec {
        self.dimensions = DimensionRange::Limits;
        self
    }
}

/// The short form of a VUID used in case names (`vkCmdTraceRaysKHR-stride-03686`).
pub fn short_vuid(vuid: &str) -> &str {
    vuid.strip_prefix("VUID-").unwrap_or(vuid)
}

/// The executable VUIDs that apply to a command (its own rows and its structures'), sorted.
pub fn executable_vuids(rules: &RuleSet, command: CommandId) -> Vec<String> {
    let mut v: Vec<String> = rules
        .rows
        .iter()
        .filter(|r| r.status == Status::Executable && applies_to(&r.scope, command))
        .map(|r| r.vuid.clone())
        .collect();
    v.sort();
    v
}

/// Checks that a spec can be generated on a profile: the command's extension, the VUID's row and mutation.
pub fn check_spec(
    profile: &DeviceProfile,
    rules: &RuleSet,
    spec: &CaseSpec,
) -> Result<Option<Mutation>, GenError> {
    let ext = if spec.command.is_nv() {
        "VK_NV_ray_tracing"
    } else {
        "VK_KHR_ray_tracing_pipeline"
    };
    if !profile.has_extension(ext) {
        return Err(GenError::Unsupported(format!(
            "{} needs {ext}, which `{}` lacks",
            spec.command.vk_name(),
            profile.name
        )));
    }
    let SpecIntent::Violate(vuid) = &spec.intent else {
        return Ok(None);
    };
    let row = rules
        .row(vuid)
        .filter(|r| applies_to(&r.scope, spec.command))
        .ok_or_else(|| GenError::NotForCommand {
            vuid: vuid.clone(),
            command: spec.command.vk_name().into(),
        })?;
    if row.status != Status::Executable {
        return Err(GenError::NotExecutable {
            vuid: vuid.clone(),
            status: format!("{:?}", row.status),
        });
    }
    let m = mutations_for(vuid).ok_or_else(|| GenError::NoMutation(vuid.clone()))?;
    mutation::supported(m, profile, spec.command)?;
    // The row's registry condition must hold on the device the case enables (04951 needs the motion
    // blur extension, 02707 Vulkan 1.1), or the rule cannot fire.
    let (major, minor) = profile.api_major_minor();
    let ok = row.condition.eval(&|name: &str| {
        if let Some(v) = name.strip_prefix("VK_VERSION_") {
            let mut it = v.split('_').map(|p| p.parse::<u32>().unwrap_or(0));
            return (major, minor) >= (it.next().unwrap_or(1), it.next().unwrap_or(0));
        }
        profile.has_extension(name)
    });
    if !ok {
        return Err(GenError::Unsupported(format!(
            "{vuid}: its registry condition does not hold on `{}`",
            profile.name
        )));
    }
    Ok(Some(m))
}

/// The proptest strategy for one spec's cases (names and seeds are filled by [`generate`]).
pub fn case_strategy(
    profile: &DeviceProfile,
    profile_name: &str,
    rules: &RuleSet,
    spec: &CaseSpec,
) -> Result<BoxedStrategy<Case>, GenError> {
    let m = check_spec(profile, rules, spec)?;
    let lim = Limits::for_command(profile, spec.command)?;
    let profile = profile.clone();
    let profile_name = profile_name.to_string();
    let command = spec.command;
    let dims = spec.dimensions;
    match (m, &spec.intent) {
        (None, _) if spec.rendered => Ok((scenes::draw_strategy(), valid::raw_strategy())
            .prop_map(move |(draw, raw)| {
                let plan = valid::resolve(&raw, &profile, &lim, command, dims, Some(&draw));
                let (world, call) = plan::realize(&plan, &lim);
                Case::trace("", &profile_name, Intent::Valid, world, call)
            })
            .boxed()),
        (None, _) => Ok(valid::raw_strategy()
            .prop_map(move |raw| {
                let plan = valid::resolve(&raw, &profile, &lim, command, dims, None);
                let (world, call) = plan::realize(&plan, &lim);
                Case::trace("", &profile_name, Intent::Valid, world, call)
            })
            .boxed()),
        (Some(m), SpecIntent::Violate(vuid)) => {
            // Probe once so an inexpressible mutation is an error, not a panic inside the strategy.
            let rules = std::sync::Arc::new(rules.clone());
            let vuid = vuid.clone();
            let probe_raw = valid::raw_strategy()
                .new_tree(&mut runner_for(0))
                .map_err(|e| GenError::Io(e.to_string()))?
                .current();
            let canonical = !mutation::edits_pipeline(m);
            let base =
                move |raw: &valid::Raw, shape: u32, profile: &DeviceProfile, lim: &Limits| {
                    if canonical {
                        valid::canonical_base(raw, shape, profile, lim, command, dims)
                    } else {
                        valid::resolve(raw, profile, lim, command, dims, None)
                    }
                };
            let probe = base(&probe_raw, 0, &profile, &lim);
            let target = mutation_io::Target {
                profile,
                rules,
                lim,
                command,
                vuid,
            };
            mutation::apply(m, probe, &target.input(0, 0))?;
            // Knob 0 (the boundary value) is drawn most often and is where shrinking goes.
            let knob = proptest::prop_oneof![3 => proptest::strategy::Just(0u32), 2 => 0..4u32];
            // The base world's pipeline: one of the canonical shapes, picked by the seed (shape 0
            // is where shrinking goes), unless the mutation edits the pipeline.
            let shape = 0..valid::CANONICAL_PIPELINES;
            Ok((valid::raw_strategy(), knob, 0..4u32, shape)
                .prop_map(move |(raw, knob, pick, shape)| {
                    let plan = base(&raw, shape, &target.profile, &target.lim);
                    let mutated = mutation::apply(m, plan, &target.input(knob, pick))
                        .expect("a mutation that applied once applies to every plan");
                    let intent = Intent::Violates {
                        vuid: target.vuid.clone(),
                        also: mutated.also,
                    };
                    Case::trace("", &profile_name, intent, mutated.world, mutated.call)
                })
                .boxed())
        }
        (Some(_), SpecIntent::Valid) => unreachable!("a valid spec has no mutation"),
    }
}

/// The 32-byte ChaCha seed of case `index` of a run seeded with `seed`.
fn seed_bytes(seed: u64, index: u64) -> [u8; 32] {
    let mut b = [0u8; 32];
    b[..8].copy_from_slice(&seed.to_le_bytes());
    b[8..16].copy_from_slice(&index.to_le_bytes());
    b[16..24].copy_from_slice(b"rtconfgn");
    b
}

fn runner_for(derived: u64) -> TestRunner {
    let bytes = seed_bytes(derived, 0);
    TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &bytes),
    )
}

/// A runner whose RNG is fixed by (seed, index), so each case can be rebuilt alone.
pub fn case_runner(seed: u64, index: u64) -> TestRunner {
    let bytes = seed_bytes(seed, index);
    TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &bytes),
    )
}

/// The name of case `index` of a spec.
pub fn case_name(spec: &CaseSpec, seed: u64, index: usize) -> String {
    match &spec.intent {
        SpecIntent::Valid => {
            let limits = if spec.dimensions == DimensionRange::Limits {
                "-limits"
            } else {
                ""
            };
            let kind = if spec.rendered { "rendered" } else { "valid" };
            format!("{}-{kind}{limits}-{seed}-{index}", spec.command.case_stem())
        }
        SpecIntent::Violate(vuid) => format!("{}-{seed}-{index}", short_vuid(vuid)),
    }
}

/// Generates `count` cases of a spec, deterministically from `seed` (see [`generate_range`]).
pub fn generate(
    profile: &DeviceProfile,
    profile_name: &str,
    rules: &RuleSet,
    spec: &CaseSpec,
    count: usize,
    seed: u64,
) -> Result<Vec<Case>, GenError> {
    generate_range(profile, profile_name, rules, spec, 0..count, seed)
}

/// Cases `range` of a spec's sequence for `seed`, for any command — the same cases at those indices
/// however the range is sliced, so a long run can be generated a slice at a time. A trace case `i`
/// records `"<seed>/<i>"`; a build case is the first of the plans drawn for its index that the
/// spec's mutation fits (an index none fits gives no case), judged with `rules`.
pub fn generate_range(
    profile: &DeviceProfile,
    profile_name: &str,
    rules: &RuleSet,
    spec: &CaseSpec,
    range: std::ops::Range<usize>,
    seed: u64,
) -> Result<Vec<Case>, GenError> {
    if !spec.command.is_trace() {
        let target = match &spec.intent {
            SpecIntent::Valid => None,
            SpecIntent::Violate(v) if accel::mutation_for(v).is_some() => Some(v.as_str()),
            SpecIntent::Violate(v) => return Err(GenError::NoMutation(v.clone())),
        };
        return Ok(accel::generate_range(profile, rules, target, seed, range));
    }
    let strategy = case_strategy(profile, profile_name, rules, spec)?;
    range
        .map(|i| {
            let mut runner = case_runner(seed, i as u64);
            let mut case = strategy
                .new_tree(&mut runner)
                .map_err(|e| GenError::Io(e.to_string()))?
                .current();
            case.name = case_name(spec, seed, i);
            case.seed = Some(format!("{seed}/{i}"));
            Ok(case)
        })
        .collect()
}

/// The result of shrinking a failing case.
#[derive(Debug)]
pub struct Shrunk {
    pub case: Case,
    /// Where the YAML was written.
    pub path: PathBuf,
    /// How many simplification steps were accepted.
    pub steps: usize,
}

/// Rebuilds case `index` of (`spec`, `seed`); if `fails` holds for it, shrinks it with proptest's value
/// tree to a minimal case that still fails and writes it to `<dir>/<name>.yaml` (`dir` is usually
/// `cases/regressions`). Returns None when the case does not fail.
#[allow(clippy::too_many_arguments)] // the spec's identity (profile, rules, spec, seed, index) and where to write
pub fn shrink_failure(
    profile: &DeviceProfile,
    profile_name: &str,
    rules: &RuleSet,
    spec: &CaseSpec,
    seed: u64,
    index: usize,
    dir: &Path,
    fails: impl Fn(&Case) -> bool,
) -> Result<Option<Shrunk>, GenError> {
    let strategy = case_strategy(profile, profile_name, rules, spec)?;
    let mut runner = case_runner(seed, index as u64);
    let mut tree = strategy
        .new_tree(&mut runner)
        .map_err(|e| GenError::Io(e.to_string()))?;
    let name = case_name(spec, seed, index);
    let stamp = |mut c: Case| {
        c.name = name.clone();
        c.seed = Some(format!("{seed}/{index}"));
        c
    };
    let mut best = stamp(tree.current());
    if !fails(&best) {
        return Ok(None);
    }
    let mut steps = 0;
    // The standard proptest loop: simplify while the failure holds, complicate back when it does not.
    let mut budget = 10_000;
    while budget > 0 && tree.simplify() {
        budget -= 1;
        loop {
            let c = stamp(tree.current());
            if fails(&c) {
                best = c;
                steps += 1;
                break;
            }
            if !tree.complicate() {
                break;
            }
            budget -= 1;
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| GenError::Io(format!("{}: {e}", dir.display())))?;
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, best.to_yaml())
        .map_err(|e| GenError::Io(format!("{}: {e}", path.display())))?;
    Ok(Some(Shrunk {
        case: best,
        path,
        steps,
    }))
}
