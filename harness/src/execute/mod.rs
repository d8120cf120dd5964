//! Executes a case on one driver: a trace case on the device for its enabled state (cached), with the
//! world realised and the call recorded with the layer's messages collected — dropped by the layer
//! unless the case is run as valid, in which case it is submitted and the output words read back — and
//! a build case through the build path (`execute::accel`). Every command gives one [`Observation`].

mod accel;
mod trace;

use crate::error::HarnessError;
use crate::observe::{Observation, Status, TraceCheck};
use crate::realise::DeviceCache;
use crate::vk::{Driver, VkDevice, VkInstance};
use model::case::Case;
use model::world::World;
use model::DeviceProfile;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

/// The most output words the harness reads back for one launch.
pub const MAX_OUTPUT_WORDS: usize = 1 << 24;

/// How the harness is asked to run a case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct Execution {
    /// Run the case for real: submit it and read the output back (trace), build it directly and trace
    /// what was built (build). Otherwise the call is only recorded under the layer, which drops it.
    pub run_valid: bool,
    /// How a build's traced check traces its rays.
    #[serde(default)]
    pub check: TraceCheck,
}

impl Execution {
    /// The execution a case gets on a device of `profile`: for real when it is valid, or violates only
    /// what the device makes unavoidable ([`Case::runs_as_valid`]).
    pub fn for_case(case: &Case, profile: &DeviceProfile) -> Execution {
        Execution {
            run_valid: case.runs_as_valid(profile),
            check: TraceCheck::Auto,
        }
    }
}

/// Runs cases on one driver, caching a device per distinct enabled (extensions, features) set.
pub struct Executor {
    inst: Arc<VkInstance>,
    devices: HashMap<String, Result<DeviceCache, HarnessError>>,
    /// How long a valid case's submission may run.
    pub gpu_timeout: Duration,
}

impl Executor {
    /// Loads `driver` with the validation layer.
    pub fn new(driver: Driver) -> Result<Executor, HarnessError> {
        Ok(Executor {
            inst: Arc::new(VkInstance::new(driver, true)?),
            devices: HashMap::new(),
            gpu_timeout: Duration::from_secs(20),
        })
    }

    pub fn driver(&self) -> &Driver {
        &self.inst.driver
    }

    fn device_key(world: &World) -> String {
        serde_json::to_string(&world.device).unwrap_or_default()
    }

    /// Runs one case and reports what the layer said and what the device produced (see
    /// [`Executor::execute_trace`] and the build path).
    pub fn execute(&mut self, case: &Case, exec: &Execution) -> Observation {
        if case.as_trace().is_some() {
            self.execute_trace(case, exec.run_valid)
        } else {
            accel::execute(&self.inst, case, exec.run_valid, exec.check)
        }
    }

    /// What the device builds for a build case, seen through arbitrary rays: the case's first info
    /// built directly with the ranges the model reads from memory, then one ray (+z, t in [0, 100]) from
    /// each origin. For writing down what a driver built where no named deviation explains it.
    pub fn probe_rays(
        &self,
        case: &Case,
        origins: &[[f32; 3]],
        check: TraceCheck,
    ) -> Result<crate::observe::Hits, HarnessError> {
        crate::accel_check::probe_rays(&self.inst, case, origins, check)
    }

    fn device(&mut self, world: &World) -> Result<&mut DeviceCache, HarnessError> {
        let key = Self::device_key(world);
        if !self.devices.contains_key(&key) {
            let made = VkDevice::new(
                self.inst.clone(),
                &world.device.extensions,
                &world.device.features,
            )
            .and_then(DeviceCache::new);
            self.inst.collector.clear();
            self.devices.insert(key.clone(), made);
        }
        match self.devices.get_mut(&key).expect("inserted above") {
            Ok(c) => Ok(c),
            Err(e) => Err(e.clone()),
        }
    }
}

/// An error of the trace path as an observation: unsupported with its reason, a timeout, or a crash
/// with the error's message.
fn failure(e: HarnessError) -> Observation {
    match e {
        HarnessError::Unsupported(s) => Observation::unsupported(s),
        HarnessError::Timeout(_) => Observation::with_status(Status::Timeout { seconds: 0.0 }),
        HarnessError::Failed(s) => Observation::crash(s),
        HarnessError::OutOfMemory(s) => Observation::out_of_memory(s),
        e => Observation::crash(e.to_string()),
    }
}

impl Executor {
    /// Runs one trace case and reports what the layer said and, when run as valid, what the shaders
    /// wrote.
    ///
    /// A submission that ends in ERROR_DEVICE_LOST is a crash of this case; one that does not finish in
    /// [`Executor::gpu_timeout`] is its timeout. Either way the device is dropped from the executor
    /// without touching it again (its objects are leaked, see `DeviceCache::lost`), so no later case
    /// reuses it.
    fn execute_trace(&mut self, case: &Case, run_valid: bool) -> Observation {
        let Some(body) = case.as_trace() else {
            return Observation::crash(format!("{} is not a trace case", case.name));
        };
        trace::trace(self, body, run_valid)
    }
}
