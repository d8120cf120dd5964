//! rtconf harness: the device side. It realises cases of every modelled command on a real Vulkan driver
//! under the validation layer, records (and, for cases run as valid, submits) the call, and reports one
//! [`Observation`] per case: what the layer said and what the device produced. It judges nothing.
//!
//! Layout: [`plan`] (what a case makes and records, as data: realised here, exported as C, printed by
//! replay), `vk` (Vulkan plumbing), `shaders` (the one shader path), `realise` (worlds on the
//! device), `execute` (one [`Executor`] for every command), `accel_check` (the traced check of a
//! build), [`worker`] (worker processes), [`observe`] (what came back), [`probe`](mod@probe)
//! (device profiles).

pub(crate) mod accel_check;
pub mod driver_check;
pub mod error;
pub(crate) mod execute;
pub mod observe;
pub mod plan;
pub mod probe;
pub(crate) mod realise;
pub(crate) mod shaders;
pub mod timing;
pub(crate) mod vk;
pub mod worker;

pub use driver_check::{check_driver, check_manifest, instance_failure, CheckedDriver};
pub use error::HarnessError;
pub use execute::{Affinity, Execution, Executor};
pub use observe::{Observation, Output, RunningOn, Status, TraceCheck};
pub use probe::probe;
pub use vk::{select_layer, validation_layer, Driver, LayerInfo, LayerMessage, VALIDATION_LAYER};

/// The GLSL the harness makes of a resource state's accesses, stage by stage, its compilation with
/// either body, and what a layer reads of the module: for tests that template every stage.
pub mod resource_glsl {
    pub use crate::realise::resources::{compile_stage, stage_glsl, stage_source};
    pub use crate::shaders::{module_interface, ModuleInterface, ShaderBody};
}
pub use worker::{
    run_in_workers, run_in_workers_with, run_stream, run_stream_on, worker_main, ExitingWorkers,
    Request, Response, StartedWorkers, WorkerCommand,
};
