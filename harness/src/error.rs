//! The harness's error type: every failure names what is missing and how to get it.

/// The command that installs lavapipe, the loader, the validation layer and glslang.
pub const SETUP_COMMAND: &str = "bash scripts/setup.sh";

/// What went wrong before or while talking to a driver. [`HarnessError::NotRealised`] is not a failure:
/// the device or the harness cannot realise the case, and the reason names what is missing.
#[derive(Debug, Clone, thiserror::Error)]
pub enum HarnessError {
    #[error("the Vulkan loader (libvulkan.so.1) could not be loaded: {0}; install it with `{SETUP_COMMAND}`")]
    LoaderMissing(String),
    #[error("the driver manifest (ICD json) `{0}` does not exist; install lavapipe with `{SETUP_COMMAND}`, or give the path of an existing ICD json")]
    IcdMissing(String),
    #[error("the driver manifest (ICD json) `{path}` {problem}")]
    Manifest { path: String, problem: String },
    #[error("the Vulkan layer `{0}` is not installed; install it with `{SETUP_COMMAND}`")]
    LayerMissing(String),
    #[error("the driver `{0}` offers no Vulkan device; check the ICD json and `{SETUP_COMMAND}`")]
    NoDevice(String),
    #[error("{what} failed: {result:?}")]
    Vulkan {
        what: String,
        result: ash::vk::Result,
    },
    #[error("shader compilation: {0}")]
    Shader(String),
    #[error("{0}")]
    Io(String),
    /// The device lacks what the case needs: `lack` names the property, as its profile records it.
    #[error("unsupported: {reason}")]
    DeviceLacks {
        lack: crate::observe::DeviceLack,
        reason: String,
    },
    /// The harness cannot realise the case on this device (the reason names what it lacks).
    #[error("not realised: {0}")]
    NotRealised(String),
    /// Realising or running the case failed (not a Vulkan call's result: a missing object, a readback
    /// that does not fit).
    #[error("{0}")]
    Failed(String),
    /// A creation or allocation the driver refused for want of memory.
    #[error("{0}")]
    OutOfMemory(String),
    /// A submission did not finish within `seconds`; the device is not used again.
    #[error("TIMEOUT: {message}")]
    Timeout { seconds: f64, message: String },
}

impl HarnessError {
    /// The error of a Vulkan call named `what`.
    pub fn vk(what: impl Into<String>) -> impl FnOnce(ash::vk::Result) -> HarnessError {
        let what = what.into();
        move |result| HarnessError::Vulkan { what, result }
    }

    pub(crate) fn not_realised<T>(why: impl Into<String>) -> Result<T, HarnessError> {
        Err(HarnessError::NotRealised(why.into()))
    }

    pub(crate) fn lacks(
        lack: crate::observe::DeviceLack,
        reason: impl Into<String>,
    ) -> HarnessError {
        HarnessError::DeviceLacks {
            lack,
            reason: reason.into(),
        }
    }

    pub(crate) fn failed(what: impl std::fmt::Display) -> HarnessError {
        HarnessError::Failed(what.to_string())
    }
}

/// The error of a creation or allocation named `what`: out of memory is its own error, which is not a
/// crash.
pub(crate) fn oom_or(what: String, result: ash::vk::Result) -> HarnessError {
    match result {
        ash::vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | ash::vk::Result::ERROR_OUT_OF_HOST_MEMORY => {
            HarnessError::OutOfMemory(format!("{what}: {result:?}"))
        }
        result => HarnessError::Vulkan { what, result },
    }
}

/// The error of a Vulkan call named `what`, for `map_err` (the call's result is copied, so the closure
/// can be used many times).
pub(crate) fn vkfail(what: &'static str) -> impl Fn(ash::vk::Result) -> HarnessError {
    move |result| HarnessError::Vulkan {
        what: what.into(),
        result,
    }
}
