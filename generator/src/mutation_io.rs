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

/// A mutated case: the world, the call and the declared co-violations.
pub struct Mutated {
    pub world: World,
    pub call: Call,
    pub also: Vec<String>,
}
