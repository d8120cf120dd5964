//! The commands rtconf models, as one typed id: every place that names a command (cases, rule scopes,
//! run plans, results) goes through [`CommandId`] and its Vulkan name.

/// A command the model judges.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub enum CommandId {
    /// `vkCmdTraceRaysIndirectKHR`.
    #[serde(rename = "vkCmdTraceRaysIndirectKHR")]
    TraceRaysIndirect,
    /// `vkCmdTraceRaysKHR`, the direct peer of the indirect call.
    #[serde(rename = "vkCmdTraceRaysKHR")]
    TraceRays,
    /// `vkCmdTraceRaysNV`.
    #[serde(rename = "vkCmdTraceRaysNV")]
    TraceRaysNv,
    /// `vkCmdBuildAccelerationStructuresIndirectKHR`.
    #[serde(rename = "vkCmdBuildAccelerationStructuresIndirectKHR")]
    BuildAccelerationStructuresIndirect,
}

impl CommandId {
    /// Every modelled command.
    pub const ALL: [CommandId; 4] = [
        CommandId::TraceRaysIndirect,
        CommandId::TraceRays,
        CommandId::TraceRaysNv,
        CommandId::BuildAccelerationStructuresIndirect,
    ];

    /// The trace commands, in the order a run plans them.
    pub const TRACE: [CommandId; 3] = [
        CommandId::TraceRaysIndirect,
        CommandId::TraceRaysNv,
        CommandId::TraceRays,
    ];

    /// The Vulkan command name.
    pub fn vk_name(self) -> &'static str {
        match self {
            CommandId::TraceRaysIndirect => "vkCmdTraceRaysIndirectKHR",
            CommandId::TraceRays => "vkCmdTraceRaysKHR",
            CommandId::TraceRaysNv => "vkCmdTraceRaysNV",
            CommandId::BuildAccelerationStructuresIndirect => {
                "vkCmdBuildAccelerationStructuresIndirectKHR"
            }
        }
    }

    /// The command of a Vulkan name, if it is one the model judges.
    pub fn from_vk_name(name: &str) -> Option<CommandId> {
        CommandId::ALL.into_iter().find(|c| c.vk_name() == name)
    }

    /// The command a VUID names in its scope (`VUID-vkCmdTraceRaysKHR-stride-03686`), if it names one.
    pub fn from_vuid(vuid: &str) -> Option<CommandId> {
        CommandId::from_vk_name(vuid.strip_prefix("VUID-")?.split('-').next()?)
    }

    /// Whether the command traces rays (as opposed to building acceleration structures).
    pub fn is_trace(self) -> bool {
        self != CommandId::BuildAccelerationStructuresIndirect
    }

    pub fn is_nv(self) -> bool {
        self == CommandId::TraceRaysNv
    }

    /// The stem of generated valid case names (`trace-indirect-valid-1-0`).
    pub fn case_stem(self) -> &'static str {
        match self {
            CommandId::TraceRaysIndirect => "trace-indirect",
            CommandId::TraceRays => "trace",
            CommandId::TraceRaysNv => "trace-nv",
            CommandId::BuildAccelerationStructuresIndirect => "build",
        }
    }
}

impl std::fmt::Display for CommandId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.vk_name())
    }
}

#[cfg(test)]
mod tests {
    use super::CommandId;

    #[test]
    fn names_round_trip_and_vuids_name_their_command() {
        for c in CommandId::ALL {
            assert_eq!(CommandId::from_vk_name(c.vk_name()), Some(c));
        }
        assert_eq!(
            CommandId::from_vuid("VUID-vkCmdTraceRaysNV-maxRecursionDepth-03625"),
            Some(CommandId::TraceRaysNv)
        );
        assert_eq!(
            CommandId::from_vuid("VUID-VkStridedDeviceAddressRegionKHR-size-04631"),
            None
        );
        assert_eq!(CommandId::from_vk_name("vkCmdDraw"), None);
    }
}
