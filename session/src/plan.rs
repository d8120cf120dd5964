//! The plan of a run: which specs (command × valid or one VUID) are generated, each with its seed.

use crate::error::SessionError;
use generator::{CaseSpec, SpecIntent};
use model::rules::{applies_to, RuleSet, Status};
use model::{CommandId, DeviceProfile};

/// What a run is asked to cover.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Scope {
    /// Commands to run (empty: every trace command the profile supports; the build command runs only
    /// when named).
    pub commands: Vec<CommandId>,
    /// Only these VUIDs' invalid cases (empty: every executable VUID with a mutation).
    pub vuids: Vec<String>,
    /// Only valid cases.
    pub valid_only: bool,
    /// The run's seed: spec `i` of a command family is generated from `seed + i`.
    pub seed: u64,
    /// Rendered-scene cases per trace command (at least; a larger `count` wins); 0: none.
    pub rendered: usize,
}

/// Rendered-scene cases per trace command a run makes by default.
pub const DEFAULT_RENDERED: usize = 100;

/// One spec of a run and the seed its cases are drawn from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlannedSpec {
    pub spec: CaseSpec,
    pub seed: u64,
    /// Cases of this spec, when not the run's count (rendered specs).
    pub count: Option<usize>,
}

impl PlannedSpec {
    /// The spec as a person reads it: the command and the VUID it violates, or `valid`.
    pub fn label(&self) -> String {
        match &self.spec.intent {
            SpecIntent::Valid if self.spec.rendered => {
                format!("{} rendered", self.spec.command.vk_name())
            }
            SpecIntent::Valid => format!("{} valid", self.spec.command.vk_name()),
            SpecIntent::Violate(v) => v.clone(),
        }
    }
}

/// Parses command names as the command line gives them.
pub fn commands(names: &[String]) -> Result<Vec<CommandId>, SessionError> {
    names
        .iter()
        .map(|n| {
            CommandId::from_vk_name(n).ok_or_else(|| {
                SessionError::Usage(format!(
                    "unknown command `{}` (one of {})",
                    vk_registry::error::excerpt(n),
                    CommandId::ALL.map(CommandId::vk_name).join(", ")
                ))
            })
        })
        .collect()
}

/// The specs of a run: per command, one valid spec and one per executable VUID with a mutation; the
/// trace commands first, then one rendered-scene spec per trace command (`scope.rendered` cases each,
/// or the run's count when larger), then the build. Seeds count within each family (trace specs from
/// `seed`, build specs from `seed` again), so a spec keeps the seed and the case names earlier runs
/// gave it.
pub fn plan(scope: &Scope, rules: &RuleSet, profile: &DeviceProfile) -> Vec<PlannedSpec> {
    let commands: Vec<CommandId> = if scope.commands.is_empty() {
        CommandId::TRACE
            .into_iter()
            .filter(|c| !c.is_nv() || profile.has_extension("VK_NV_ray_tracing"))
            .collect()
    } else {
        scope.commands.clone()
    };
    let mut trace = Vec::new();
    let mut build = Vec::new();
    let rendered: Vec<CaseSpec> = commands
        .iter()
        .filter(|c| c.is_trace() && scope.vuids.is_empty() && scope.rendered > 0)
        .map(|&c| CaseSpec::rendered(c))
        .collect();
    for command in commands {
        let specs = if command.is_trace() {
            &mut trace
        } else {
            &mut build
        };
        if scope.vuids.is_empty() {
            specs.push(CaseSpec::valid(command));
        }
        if scope.valid_only {
            continue;
        }
        for row in rules
            .rows
            .iter()
            .filter(|r| r.status == Status::Executable && applies_to(&r.scope, command))
        {
            if !scope.vuids.is_empty() && !scope.vuids.contains(&row.vuid) {
                continue;
            }
            if has_mutation(command, &row.vuid) {
                specs.push(CaseSpec::violate(command, &row.vuid));
            }
        }
    }
    trace.extend(rendered);
    let seeded = |specs: Vec<CaseSpec>| {
        specs.into_iter().enumerate().map(|(i, spec)| PlannedSpec {
            count: spec.rendered.then_some(scope.rendered),
            spec,
            seed: scope.seed.wrapping_add(i as u64),
        })
    };
    seeded(trace).chain(seeded(build)).collect()
}

/// Whether the generator has a mutation that violates `vuid` in a call of `command`.
pub fn has_mutation(command: CommandId, vuid: &str) -> bool {
    if command.is_trace() {
        generator::mutations_for(vuid).is_some()
    } else {
        generator::accel::mutation_for(vuid).is_some()
    }
}

/// The executable rows no run can test: for a command, the rows that apply to it whose VUID no
/// mutation violates (a run plans no invalid case for them), as (command, VUID, why no mutation is
/// written, where the generator says).
pub fn untested(
    rules: &RuleSet,
    command: Option<CommandId>,
) -> Vec<(CommandId, String, Option<&'static str>)> {
    let mut out = Vec::new();
    for c in CommandId::ALL
        .into_iter()
        .filter(|c| command.is_none_or(|x| x == *c))
    {
        for row in rules
            .rows
            .iter()
            .filter(|r| r.status == Status::Executable && applies_to(&r.scope, c))
        {
            if !has_mutation(c, &row.vuid) {
                let why = if c.is_trace() {
                    generator::unmutated(&row.vuid)
                } else {
                    generator::accel::unmutated(&row.vuid)
                };
                out.push((c, row.vuid.clone(), why));
            }
        }
    }
    out
}
