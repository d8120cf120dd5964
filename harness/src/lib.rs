//! rtconf harness: realises model cases on a real Vulkan driver under the validation layer, records and
//! runs the trace call, and reports what the layer said and what the shaders wrote.

pub mod error;
pub mod layout;
pub mod probe;
pub mod shaders;
pub mod structs;
pub mod vk_tables;
pub mod vulkan;

pub use error::HarnessError;
pub use probe::probe;
pub use vulkan::Driver;
