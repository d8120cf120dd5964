//! What every one-VUID mutation reads besides the plan, and what it gives back: the interface the trace
//! mutations (`crate::mutation`) and the resource mutations (`crate::resources`) share, kept apart from
//! both so neither imports the other for it.

use crate::plan::Limits;
use model::rules::RuleSet;
use model::{Call, CommandId, DeviceProfile, World};

/// Everything a mutation reads besides the plan.
pub struct MutationInput<'a> {
    pub profile: &'a DeviceProfile,
    pub rules: &'a RuleSet,
    pub lim: &'a Limits,
    pub command: CommandId,
    /// The VUID the case targets.
    pub vuid: &'a str,
    /// 0: the boundary value; larger: other violating values.
    pub knob: u32,
    /// A second free choice (which table, which record).
    pub pick: u32,
}

/// What every mutation of one spec reads: the device, the rules, the layout numbers, the command and
/// the targeted VUID, owned so a strategy can keep it.
pub struct Target {
    pub profile: DeviceProfile,
    pub rules: std::sync::Arc<RuleSet>,
    pub lim: Limits,
    pub command: CommandId,
    pub vuid: String,
}

impl Target {
    /// The input of the mutation drawn with `knob` (0: the boundary value) and `pick`.
    pub fn input(&self, knob: u32, pick: u32) -> MutationInput<'_> {
        MutationInput {
            profile: &self.profile,
            rules: &self.rules,
            lim: &self.lim,
            command: self.command,
            vuid: &self.vuid,
            knob,
            pick,
        }
    }
}

/// A mutated case: the world, the call and the declared co-violations.
pub struct Mutated {
    pub world: World,
    pub call: Call,
    pub also: Vec<String>,
}
