//! The rule table: one row per VUID the loaded registry defines for the modelled commands and the
//! structures they take. A row is executable (compiled from its text by the template compiler, or a
//! hand-written predicate tagged with the VUID), not executable with a written reason, or pending.
//! Coverage is this table joined with the registry's VUID set, never a hand count.

pub mod predicate;
pub mod reasons;
pub mod template;

use crate::call::{Call, Param, Table};
use crate::case::{Body, Case};
use crate::command::CommandId;
use crate::profile::DeviceProfile;
use crate::verdict::{Verdict, Violation};
use crate::world::{DeviceState, World};
use predicate::{Failure, NullHitKind, Predicate};
use vk_registry::vuid::{Condition, VuidRecord, VuidSet};

/// The structures whose VUIDs apply to the KHR trace calls' parameters.
pub const TRACE_STRUCTURES: &[&str] = &[
    "VkStridedDeviceAddressRegionKHR",
    "VkTraceRaysIndirectCommandKHR",
];

/// Whether a VUID scope is one the table has rows for: a modelled command or a trace structure.
pub fn modelled_scope(scope: &str) -> bool {
    CommandId::from_vk_name(scope).is_some() || TRACE_STRUCTURES.contains(&scope)
}

/// The status of a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    Executable,
    NotExecutable,
    Pending,
}

/// Where an executable row's predicate came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Source {
    Template,
    Hand,
}

/// One row of the rule table.
#[derive(Debug, Clone)]
pub struct Row {
    pub vuid: String,
    pub scope: String,
    pub status: Status,
    pub source: Option<Source>,
    pub reason: Option<String>,
    pub condition: Condition,
    pub predicate: Option<Predicate>,
}

/// A coverage line as `rtconf coverage --json` prints it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct CoverageRow {
    pub vuid: String,
    pub scope: String,
    pub status: Status,
    pub source: Option<Source>,
    pub reason: Option<String>,
}

/// The hand-written predicate for a VUID tag, shared by every trace command that carries the tag.
fn hand_rule(scope: &str, tag: &str) -> Option<Predicate> {
    if !CommandId::from_vk_name(scope).is_some_and(CommandId::is_trace) {
        return None;
    }
    use crate::flags::PipelineCreate as F;
    Some(match tag {
        // VUID-…-None-03429: handles reached by the launch come from the bound pipeline.
        "03429" => Predicate::HandlesFromBoundPipeline,
        // VUID-…-maxPipelineRayRecursionDepth-03679 (KHR), -maxRecursionDepth-03625 (NV).
        "03679" | "03625" => Predicate::RecursionWithinPipelineLimit,
        // VUID-…-flags-03511: the handle at the miss region's address is not zero under NO_NULL_MISS.
        "03511" => Predicate::NoNullMissAtRegionAddress,
        // VUID-…-flags-03512/03513/03514: hit records reached are not zero under NO_NULL_*.
        "03512" => Predicate::NoNullHitReached(NullHitKind::AnyHit),
        "03513" => Predicate::NoNullHitReached(NullHitKind::ClosestHit),
        "03514" => Predicate::NoNullHitReached(NullHitKind::Intersection),
        // VUID-…-pHitShaderBindingTable-04735/04736: hit group type matches the geometry reached.
        "04735" => Predicate::HitGroupTypeMatchesGeometry(crate::world::GeometryKind::Triangles),
        "04736" => Predicate::HitGroupTypeMatchesGeometry(crate::world::GeometryKind::Aabbs),
        // VUID-…-commandBuffer-02701 and -None-09458: dynamic stack size set when dynamic.
        "02701" | "09458" => Predicate::DynamicStackSizeSet,
        // VUID-…-allowClusterAccelerationStructure-10577/10578 (and the indirect command's): a scene
        // with cluster acceleration structures needs a pipeline created to allow them.
        "10577" | "10578" | "10579" => Predicate::ClusterStructuresAllowed,
        // VUID-…-None-02859 and -None-08608: no dynamic state set that the pipeline has static.
        "02859" | "08608" => Predicate::NoStaticStateSet,
        // VUID-…-commandBuffer-02707: no protected resource from an unprotected command buffer.
        "02707" => Predicate::NoProtectedResourceFromUnprotected,
        // VUID-…-rayTracingMotionBlurPipelineTraceRaysIndirect-04951.
        "04951" => Predicate::FeatureEnabledIfPipelineFlag(
            F::RAY_TRACING_ALLOW_MOTION_BIT_NV,
            "rayTracingMotionBlurPipelineTraceRaysIndirect".into(),
        ),
        // VUID-…-None-02700: a pipeline is bound.
        "02700" => Predicate::PipelineBound,
        // VUID-…-None-08606: "If the shaderObject feature is not enabled, a valid pipeline must be bound".
        "08606" => Predicate::PipelineBoundWhenShaderObject(false),
        // VUID-…-None-08607: "If the shaderObject feature is enabled, either a valid pipeline … or … shader
        // objects": ray tracing stages have no shader objects, so a pipeline must be bound — but only where
        // the feature is enabled.
        "08607" => Predicate::PipelineBoundWhenShaderObject(true),
        _ => return None,
    })
}

/// The command a VUID's predicate reads parameters of (structure VUIDs: the KHR indirect call).
fn command_for_scope(scope: &str) -> &str {
    if TRACE_STRUCTURES.contains(&scope) {
        "vkCmdTraceRaysIndirectKHR"
    } else {
        scope
    }
}

impl Row {
    /// Builds the row for one registry record: template first, then the hand table, then a reason.
    pub fn for_record(r: &VuidRecord) -> Row {
        let mut row = Row {
            vuid: r.id.clone(),
            scope: r.scope.clone(),
            status: Status::Pending,
            source: None,
            reason: None,
            condition: r.condition.clone(),
            predicate: None,
        };
        if CommandId::from_vk_name(&r.scope) == Some(CommandId::BuildAccelerationStructuresIndirect)
        {
            // The build command: template shapes, then its tag table (`crate::accel::rules`).
            match crate::accel::rules::compile(r) {
                crate::accel::rules::Compiled::Rule(p, source) => {
                    row.status = Status::Executable;
                    row.source = Some(source);
                    row.predicate = Some(p);
                }
                crate::accel::rules::Compiled::NotExecutable(why) => {
                    row.status = Status::NotExecutable;
                    row.reason = Some(why);
                }
                crate::accel::rules::Compiled::Pending(why) => row.reason = Some(why),
            }
            return row;
        }
        if let Some(p) = template::compile(&r.scope, command_for_scope(&r.scope), &r.text) {
            row.status = Status::Executable;
            row.source = Some(Source::Template);
            row.predicate = Some(p);
        } else if let Some(p) = hand_rule(&r.scope, &r.tag) {
            row.status = Status::Executable;
            row.source = Some(Source::Hand);
            row.predicate = Some(p);
        } else if let Some(e) = crate::resources::rule_for(r) {
            // The resource-access rules shared with draw/dispatch.
            match e {
                crate::resources::Entry::Executable { rule, note } => {
                    row.status = Status::Executable;
                    row.source = Some(Source::Hand);
                    row.predicate = Some(Predicate::Resource(rule));
                    row.reason = note;
                }
                crate::resources::Entry::NotExecutable(why) => {
                    row.status = Status::NotExecutable;
                    row.reason = Some(why);
                }
            }
        } else {
            let (status, reason) = reasons::classify(r);
            row.status = status;
            row.reason = Some(reason);
        }
        row
    }

    pub fn coverage(&self) -> CoverageRow {
        CoverageRow {
            vuid: self.vuid.clone(),
            scope: self.scope.clone(),
            status: self.status,
            source: self.source,
            reason: self.reason.clone(),
        }
    }
}

/// The rule table for one loaded registry version. Cloned for every generated spec's strategy, so
/// the rows are shared, not copied.
#[derive(Debug, Clone)]
pub struct RuleSet {
    pub version: Option<String>,
    pub rows: std::sync::Arc<[Row]>,
}

impl RuleSet {
    /// One row per VUID of the modelled scopes in the set, in VUID order.
    pub fn from_vuids(set: &VuidSet) -> RuleSet {
        let rows = set
            .records
            .iter()
            .filter(|r| modelled_scope(&r.scope))
            .map(Row::for_record)
            .collect();
        RuleSet {
            version: set.version.clone(),
            rows,
        }
    }

    pub fn row(&self, vuid: &str) -> Option<&Row> {
        self.rows.iter().find(|r| r.vuid == vuid)
    }

    /// The coverage table, optionally for one command (its structures' rows included for the KHR calls).
    pub fn coverage(&self, command: Option<CommandId>) -> Vec<CoverageRow> {
        self.rows
            .iter()
            .filter(|r| command.is_none_or(|c| applies_to(&r.scope, c)))
            .map(Row::coverage)
            .collect()
    }

    /// The executable rows a device cannot have judged because its profile lacks a limit they compare
    /// against, with the missing limits: such a row is reported, not silently dropped.
    pub fn unjudged_on(&self, profile: &DeviceProfile) -> Vec<(String, Vec<String>)> {
        self.rows
            .iter()
            .filter(|r| r.status == Status::Executable)
            .filter_map(|r| {
                let missing = r.predicate.as_ref()?.missing_limits(profile);
                (!missing.is_empty()).then(|| (r.vuid.clone(), missing))
            })
            .collect()
    }

    /// Prepares the rows that apply to `command` on a device: the profile's API version and the
    /// device's enabled extensions decide each row's registry condition once, not per call.
    pub fn prepare<'a>(
        &'a self,
        profile: &'a DeviceProfile,
        device: &DeviceState,
        command: CommandId,
    ) -> Judge<'a> {
        let (major, minor) = profile.api_major_minor();
        let enabled = |name: &str| -> bool {
            if let Some(v) = name.strip_prefix("VK_VERSION_") {
                let mut it = v.split('_').map(|p| p.parse::<u32>().unwrap_or(0));
                let want = (it.next().unwrap_or(1), it.next().unwrap_or(0));
                return (major, minor) >= want;
            }
            device.extension(name)
        };
        let active = self
            .rows
            .iter()
            .filter(|r| {
                r.status == Status::Executable
                    && applies_to(&r.scope, command)
                    && r.condition.eval(&enabled)
            })
            .filter_map(|r| Some((r, r.predicate.as_ref()?.for_device(profile)?)))
            .collect();
        Judge { profile, active }
    }

    /// The verdict on one case's call in its world (any command).
    pub fn judge(&self, profile: &DeviceProfile, body: &Body) -> Verdict {
        self.prepare(profile, body.device(), body.command())
            .judge(body)
    }
}

/// Whether rows of `scope` are judged for a call of `command`.
pub fn applies_to(scope: &str, command: CommandId) -> bool {
    scope == command.vk_name()
        || (scope == "VkStridedDeviceAddressRegionKHR"
            && matches!(command, CommandId::TraceRaysIndirect | CommandId::TraceRays))
        || (scope == "VkTraceRaysIndirectCommandKHR" && command == CommandId::TraceRaysIndirect)
}

/// The rows that apply to one command on one device, ready to judge calls.
pub struct Judge<'a> {
    profile: &'a DeviceProfile,
    /// Each applicable row with its predicate resolved for the device.
    active: Vec<(&'a Row, Predicate)>,
}

/// What a trace predicate sees.
pub struct Context<'a> {
    pub profile: &'a DeviceProfile,
    pub world: &'a World,
    pub call: &'a Call,
}

impl Context<'_> {
    /// The address/table parameters of the call that name a buffer the launch reads.
    pub fn used_buffer_params(&self) -> Vec<Param> {
        let mut v: Vec<Param> = Table::ALL.iter().map(|&t| Param::TableAddress(t)).collect();
        if matches!(self.call, Call::TraceRaysIndirect(_)) {
            v.push(Param::IndirectAddress);
        }
        v
    }
}

impl Judge<'_> {
    /// The verdict on one call: every violated row with its context, sorted.
    pub fn judge(&self, body: &Body) -> Verdict {
        let mut violations = Vec::new();
        let mut failures = Vec::new();
        let mut record = |row: &Row, failures: &mut Vec<Failure>| {
            for f in failures.drain(..) {
                violations.push(Violation {
                    vuid: row.vuid.clone(),
                    context: f.context,
                    problem: f.problem,
                });
            }
        };
        match body {
            Body::Trace(t) => {
                let cx = Context {
                    profile: self.profile,
                    world: &t.world,
                    call: &t.call,
                };
                for (row, p) in &self.active {
                    p.check(&cx, &mut failures);
                    record(row, &mut failures);
                }
            }
            Body::Accel(a) => {
                let cx = crate::accel::rules::AccelContext::new(self.profile, &a.world, &a.call);
                for (row, p) in &self.active {
                    match p {
                        Predicate::Accel(ap) => cx.check(ap, &mut failures),
                        Predicate::State(sp) => {
                            failures.extend(sp.check(&a.world.device, &a.world.command_buffer))
                        }
                        // Trace predicates never apply to the build command's rows.
                        _ => {}
                    }
                    record(row, &mut failures);
                }
            }
        }
        violations.sort();
        violations.dedup();
        Verdict { violations }
    }

    /// How many rows are active.
    pub fn len(&self) -> usize {
        self.active.len()
    }

    pub fn is_empty(&self) -> bool {
        self.active.is_empty()
    }
}

/// Judges one case on one device: the verdict of the rule table on its call in its world.
pub fn validate(rules: &RuleSet, profile: &DeviceProfile, case: &Case) -> Verdict {
    rules.judge(profile, &case.body)
}
