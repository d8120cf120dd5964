//! `vkCmdBuildAccelerationStructuresIndirectKHR` end to end in the model: the build world and call,
//! the rule table of the command, and the meaning of a valid build (semantics.md §4, §8).
//!
//! A [`BuildCase`] is the build counterpart of [`crate::Case`]: one serde type, written as YAML under
//! `cases/build/`, generated, judged, executed and replayed as the same value.

pub mod call;
pub mod rules;
pub mod semantics;
pub mod world;

pub use call::{
    BuildGeometryInfo, BuildIndirect, BuildMode, Geometry, GeometryData, IndexType, VertexFormat,
};
pub use rules::{BuildRuleSet, Compiled};
pub use semantics::{
    build_primitives, direct_build, indirect_build, indirect_ranges, BuiltPrimitive, Shape,
};
pub use world::{
    AccelerationStructure, AsType, BuildBuffer, BuildContents, BuildSizes, BuildWorld, RangeInfo,
};

use crate::case::{CaseError, Intent};

/// A build case: a world, one indirect build call, and what it is meant to be.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildCase {
    pub name: String,
    pub profile: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<String>,
    pub intent: Intent,
    pub world: BuildWorld,
    pub call: BuildIndirect,
}

impl BuildCase {
    pub fn from_yaml(path: &str, text: &str) -> Result<BuildCase, CaseError> {
        crate::case::parse_yaml(path, text)
    }

    pub fn to_yaml(&self) -> String {
        serde_yaml::to_string(self).expect("a build case always serialises")
    }

    /// The VUIDs the case expects its verdict to hold, sorted.
    pub fn expected_vuids(&self) -> Vec<String> {
        self.intent.expected_vuids()
    }
}
