//! Verdicts: the VUIDs a call violates, each with the parameter path it concerns and a one-line problem.

use std::collections::BTreeSet;

/// One violated rule.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub struct Violation {
    pub vuid: String,
    /// Where in the call or world (`pMissShaderBindingTable.stride`, `world.command_buffer`).
    pub context: String,
    pub problem: String,
}

/// The model's judgement of one call: violations sorted by VUID, then context.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct Verdict {
    pub violations: Vec<Violation>,
}

impl Verdict {
    pub fn is_valid(&self) -> bool {
        self.violations.is_empty()
    }

    /// The distinct VUIDs violated, sorted.
    pub fn vuids(&self) -> BTreeSet<&str> {
        self.violations.iter().map(|v| v.vuid.as_str()).collect()
    }

    pub fn violates(&self, vuid: &str) -> bool {
        self.violations.iter().any(|v| v.vuid == vuid)
    }
}
