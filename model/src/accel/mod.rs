//! `vkCmdBuildAccelerationStructuresIndirectKHR` end to end in the model: the build world and call,
//! the rule table of the command, and the meaning of a valid build (semantics.md §4, §8).
//!
//! A build case is a [`crate::Case`] whose body is [`crate::AccelBody`] (this world and call); the
//! committed ones live under `cases/build/`.

pub mod call;
pub mod check;
pub mod rules;
pub mod scene;
pub mod semantics;
pub mod world;

pub use call::{
    BuildGeometryInfo, BuildIndirect, BuildMode, Geometry, GeometryData, IndexType, VertexFormat,
};
pub use rules::{AccelPredicate, Compiled};
pub use semantics::{
    build_primitives, direct_build, indirect_build, indirect_ranges, largest_range_record,
    BuiltPrimitive, Shape,
};
pub use world::{
    AccelerationStructure, AsType, BuildBuffer, BuildContents, BuildSizes, BuildWorld, RangeInfo,
};

use crate::profile::DeviceProfile;

/// The VUID of the feature the indirect build needs.
pub const FEATURE_VUID: &str =
    "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650";

/// The VUIDs every build case violates on `profile`: the feature's, when the device lacks
/// `accelerationStructureIndirectBuild` (as lavapipe does). A case expecting no more than these is
/// valid apart from the device: recorded under the layer, and also built directly and checked.
pub fn unavoidable(profile: &DeviceProfile) -> Vec<String> {
    if profile.has_feature("accelerationStructureIndirectBuild") {
        vec![]
    } else {
        vec![FEATURE_VUID.into()]
    }
}
