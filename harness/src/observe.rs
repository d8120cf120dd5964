//! What the harness saw when it ran a case: the run status, the VUIDs the validation layer reported while
//! the trace call was recorded, and the words the shaders wrote.

use crate::vulkan::LayerMessage;

/// How a case's run ended.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Status {
    /// Recorded (and, for valid cases, submitted and read back).
    Ran,
    /// The device or the harness cannot realise the case; the reason names what is missing.
    Unsupported { reason: String },
    /// The driver, the layer or the worker process failed.
    Crash { message: String },
    /// The case ran past its time limit.
    Timeout { seconds: f64 },
}

/// The harness's observation of one case.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Observation {
    pub status: Status,
    /// Sorted, unique `pMessageIdName`s of the layer's errors while the trace call was recorded.
    pub layer_vuids: Vec<String>,
    /// Those messages in full (errors and warnings), for reports.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub layer_messages: Vec<LayerMessage>,
    /// The output words of a valid case (one per launch ID, x fastest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<Vec<u32>>,
}

impl Observation {
    pub fn with_status(status: Status) -> Observation {
        Observation {
            status,
            layer_vuids: Vec::new(),
            layer_messages: Vec::new(),
            output: None,
        }
    }

    pub fn unsupported(reason: impl Into<String>) -> Observation {
        Observation::with_status(Status::Unsupported {
            reason: reason.into(),
        })
    }

    pub fn crash(message: impl Into<String>) -> Observation {
        Observation::with_status(Status::Crash {
            message: message.into(),
        })
    }

    /// Keeps the messages and derives the sorted unique VUIDs of the errors among them.
    pub fn set_messages(&mut self, messages: Vec<LayerMessage>) {
        let mut ids: Vec<String> = messages
            .iter()
            .filter(|m| m.severity == "error" && !m.id.is_empty())
            .map(|m| m.id.clone())
            .collect();
        ids.sort();
        ids.dedup();
        self.layer_vuids = ids;
        self.layer_messages = messages;
    }
}

/// One case's result as the worker pool reports it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CaseResult {
    /// Position of the case in the batch given to the pool.
    pub index: usize,
    pub name: String,
    pub observation: Observation,
    /// Wall time of the case in the worker, in milliseconds.
    pub millis: f64,
}
