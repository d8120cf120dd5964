//! What the harness saw when it ran a case — one type for every command: the run status, the VUIDs the
//! validation layer reported while the call was recorded, and what the device produced (the words the
//! shaders wrote for a trace call: one ray record per launch ID; the sizes it asked for and the rays traced at what it built for a
//! build). Nothing here is judged: the session compares it with the model.

use crate::vk::LayerMessage;
use model::accel::BuildSizes;

/// How a case's run ended.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Status {
    /// Recorded (and, for cases run as valid, submitted and read back).
    Ran,
    /// The device lacks what the case needs: `lacks` names the property, which the session checks
    /// against the device's profile.
    Unsupported { reason: String, lacks: DeviceLack },
    /// The harness cannot realise the case on this device; the reason names what it lacks.
    NotRealised { reason: String },
    /// The driver, the layer or the worker process failed.
    Crash { message: String },
    /// The case ran past its time limit.
    Timeout { seconds: f64 },
    /// The driver ran out of memory realising the case (`ERROR_OUT_OF_DEVICE_MEMORY`,
    /// `ERROR_OUT_OF_HOST_MEMORY` from a creation or allocation): the call was never made, so this is
    /// neither a crash nor a verdict; the session decides whose fault it is.
    OutOfMemory { message: String },
}

/// A property of the device that a case needs and the device lacks, in the terms of its profile.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DeviceLack {
    /// A feature (member name, `protectedMemory`).
    Feature(String),
    /// A device extension.
    Extension(String),
    /// No queue family has any of these capabilities (`VK_QUEUE_VIDEO_DECODE_BIT_KHR`).
    QueueFamilyWithAny(Vec<String>),
    /// Every queue family has this capability, so none lacks it (`VK_QUEUE_COMPUTE_BIT`).
    QueueFamilyWithout(String),
}

impl std::fmt::Display for DeviceLack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DeviceLack::Feature(n) => write!(f, "feature {n}"),
            DeviceLack::Extension(n) => write!(f, "extension {n}"),
            DeviceLack::QueueFamilyWithAny(q) => {
                write!(f, "a queue family with {}", q.join(" or "))
            }
            DeviceLack::QueueFamilyWithout(q) => write!(f, "a queue family without {q}"),
        }
    }
}

/// What each ray of a traced check hit: `(instance, geometry, primitive)`, or None for a miss.
pub type Hits = Vec<Option<(u32, u32, u32)>>;

/// How the rays of a build's check were traced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TraceCheck {
    /// Ray query where the device has it, else a ray tracing pipeline.
    #[default]
    Auto,
    /// `rayQueryEXT` in a compute shader.
    RayQuery,
    /// A ray tracing pipeline: raygen, closest-hit, miss, and an intersection shader for AABBs.
    Pipeline,
}

/// The traced check of a build run as valid: the case built directly (with the ranges the model reads
/// from memory), the check's rays traced at it, and, where the device has
/// `accelerationStructureIndirectBuild`, the case's own indirect build traced with the same rays.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TracedBuild {
    /// How the rays were traced (never `Auto`).
    pub check: TraceCheck,
    /// What each ray reported at the directly built structure (the committed hit of its record).
    pub hits: Hits,
    /// The rays' records at the directly built structure: `model::tracer::record::RayRecord::WORDS`
    /// words per ray, in the order of `model::accel::check::check_rays`.
    #[serde(default, with = "model::bulk")]
    pub records: Vec<u32>,
    /// The layer's VUIDs for the direct build.
    pub direct_layer_vuids: Vec<String>,
    /// The real indirect build, where the device could run it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indirect: Option<IndirectBuild>,
}

/// The case's indirect build submitted for real, traced with the direct build's rays.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IndirectBuild {
    pub hits: Hits,
    #[serde(default, with = "model::bulk")]
    pub records: Vec<u32>,
    pub layer_vuids: Vec<String>,
}

/// What ran a case: the device, its driver and the validation layer, as their properties say.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct RunningOn {
    /// `deviceName`, with `vendorID` and `deviceID`.
    pub device: String,
    /// The device's Vulkan version (`1.3.289`).
    pub api_version: String,
    /// `driverName` and `driverInfo` of VkPhysicalDeviceDriverProperties, and `driverVersion`.
    pub driver: String,
    /// The layer's name, spec version and implementation version, when it is loaded.
    pub layer: Option<String>,
}

/// What the device produced for a case.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Output {
    /// The ray records of a trace call run as valid: `model::tracer::record::RayRecord::WORDS` words
    /// per launch ID, x fastest.
    #[serde(with = "model::bulk")]
    Words(Vec<u32>),
    /// The traced check of a build run as valid.
    Rays(TracedBuild),
}

/// The harness's observation of one case.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Observation {
    pub status: Status,
    /// Sorted, unique `pMessageIdName`s of the layer's errors while the call was recorded.
    pub layer_vuids: Vec<String>,
    /// Those messages in full (errors and warnings), for reports.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub layer_messages: Vec<LayerMessage>,
    /// The sizes the device reported for each build info with its maxima (builds only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub device_sizes: Vec<BuildSizes>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<Output>,
}

impl Observation {
    pub fn with_status(status: Status) -> Observation {
        Observation {
            status,
            layer_vuids: Vec::new(),
            layer_messages: Vec::new(),
            device_sizes: Vec::new(),
            output: None,
        }
    }

    /// The device lacks `lacks` (see [`Status::Unsupported`]).
    pub fn unsupported(lacks: DeviceLack, reason: impl Into<String>) -> Observation {
        Observation::with_status(Status::Unsupported {
            reason: reason.into(),
            lacks,
        })
    }

    pub fn not_realised(reason: impl Into<String>) -> Observation {
        Observation::with_status(Status::NotRealised {
            reason: reason.into(),
        })
    }

    pub fn out_of_memory(message: impl Into<String>) -> Observation {
        Observation::with_status(Status::OutOfMemory {
            message: message.into(),
        })
    }

    pub fn crash(message: impl Into<String>) -> Observation {
        Observation::with_status(Status::Crash {
            message: message.into(),
        })
    }

    /// Keeps the messages and derives the sorted unique VUIDs of the errors among them.
    pub fn set_messages(&mut self, messages: Vec<LayerMessage>) {
        self.layer_vuids = error_ids(&messages);
        self.layer_messages = messages;
    }

    /// The output words of a trace call, when it was run as valid.
    pub fn words(&self) -> Option<&[u32]> {
        match &self.output {
            Some(Output::Words(w)) => Some(w),
            _ => None,
        }
    }

    /// The traced check of a build, when it was run as valid.
    pub fn traced(&self) -> Option<&TracedBuild> {
        match &self.output {
            Some(Output::Rays(t)) => Some(t),
            _ => None,
        }
    }
}

/// The sorted unique ids of the errors among the layer's messages.
pub fn error_ids(messages: &[LayerMessage]) -> Vec<String> {
    let mut ids: Vec<String> = messages
        .iter()
        .filter(|m| m.severity == "error" && !m.id.is_empty())
        .map(|m| m.id.clone())
        .collect();
    ids.sort();
    ids.dedup();
    ids
}
