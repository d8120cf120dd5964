//! rtconf harness: realises model cases on a real Vulkan driver under the validation layer, records and
//! runs the trace call, and reports what the layer said and what the shaders wrote.

pub mod build; // issue 5
pub mod compare;
pub mod error;
pub mod execute;
pub mod layout;
pub mod observe;
pub mod realise;
pub mod resources; // issue 4
pub mod probe;
pub mod shaders;
pub mod structs;
pub mod vk_tables;
pub mod vulkan;
pub mod worker;

pub use error::HarnessError;
pub use execute::{execute, Executor};
pub use observe::{CaseResult, Observation, Status};
pub use probe::probe;
pub use vulkan::Driver;
pub use worker::{run_in_workers, run_in_workers_with, worker_main, WorkerCommand};
