//! The rule-table hook for `vkCmdBuildAccelerationStructuresIndirectKHR`: turns the build module's
//! compiled rule (or its reason) into the shared coverage [`Row`]. The predicate itself lives in
//! [`crate::accel::rules`] and is judged by [`crate::accel::BuildRuleSet`].

use super::{Row, Status};
use crate::accel::rules::{compile, Compiled};
use vk_registry::vuid::VuidRecord;

/// The coverage row of one build VUID.
pub fn row(r: &VuidRecord) -> Row {
    let mut row = Row {
        vuid: r.id.clone(),
        scope: r.scope.clone(),
        status: Status::Pending,
        source: None,
        reason: None,
        condition: r.condition.clone(),
        predicate: None,
    };
    match compile(r) {
        Compiled::Rule(_, source) => {
            row.status = Status::Executable;
            row.source = Some(source);
        }
        Compiled::NotExecutable(why) => {
            row.status = Status::NotExecutable;
            row.reason = Some(why);
        }
        Compiled::Pending(why) => row.reason = Some(why),
    }
    row
}
