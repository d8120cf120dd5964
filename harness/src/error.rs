//! The harness's error type: every failure names what is missing and how to get it.

/// The command that installs lavapipe, the loader, the validation layer and glslang.
pub const SETUP_COMMAND: &str = "bash scripts/setup.sh";

/// What went wrong before or while talking to a driver.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    #[error("the Vulkan loader (libvulkan.so.1) could not be loaded: {0}; install it with `{SETUP_COMMAND}`")]
    LoaderMissing(String),
    #[error("the driver manifest (ICD json) `{0}` does not exist; install lavapipe with `{SETUP_COMMAND}`, or give the path of an existing ICD json")]
    IcdMissing(String),
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
}

impl HarnessError {
    pub fn vk(what: impl Into<String>) -> impl FnOnce(ash::vk::Result) -> HarnessError {
        let what = what.into();
        move |result| HarnessError::Vulkan { what, result }
    }
}
