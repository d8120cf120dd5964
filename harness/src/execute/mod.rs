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
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct Execution {
    /// Run the case for real: submit it and read the output back (trace), build it directly and trace
    /// what was built (build). Otherwise the call is only recorded under the layer, which drops it.
    pub run_valid: bool,
    /// How a build's traced check traces its rays.
    #[serde(default)]
    pub check: TraceCheck,
    /// VUIDs the layer's validation of the recorded call continues past (the messenger does not abort
    /// the call for them): the ones the device makes unavoidable, so the layer's later checks still
    /// run. A call the layer then finds nothing else wrong with reaches the driver's recording of it —
    /// recorded, never submitted, as every invalid call the layer does not catch.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub continue_past: Vec<String>,
}

impl Execution {
    /// The execution a case gets on a device of `profile`: for real when it is valid, or violates only
    /// what the device makes unavoidable ([`Case::runs_as_valid`]).
    pub fn for_case(case: &Case, profile: &DeviceProfile) -> Execution {
        Execution {
            run_valid: case.runs_as_valid(profile),
            check: TraceCheck::Auto,
            continue_past: match case.body {
                model::Body::Accel(_) => model::accel::unavoidable(profile),
                model::Body::Trace(_) => vec![],
            },
        }
    }
}

/// The capabilities of a case's command pool's queue family when it lacks compute: the device then
/// also gets a queue of a family without compute, and the case's command buffer comes from its pool.
pub(crate) fn pool_without_compute(
    cbs: &model::world::CommandBufferState,
) -> Option<model::flags::QueueFlags> {
    (!cbs
        .pool_queue
        .contains(model::flags::QueueFlags::COMPUTE_BIT))
    .then_some(cbs.pool_queue)
}

/// Runs cases on one driver, caching a device per distinct enabled (extensions, features) set and
/// pool family without compute — and, on a driver that numbers shader group handles in creation
/// order, a device per valid pipeline (see `Executor::handles_by_creation_order`).
pub struct Executor {
    inst: Arc<VkInstance>,
    devices: HashMap<String, Result<DeviceCache, HarnessError>>,
    /// The keys of the devices made for one valid pipeline each, least recently used first (at most
    /// [`PIPELINE_DEVICES`] are kept).
    pipeline_devices: Vec<String>,
    /// Whether two pipelines made alike on one device get different group handles: measured on this
    /// driver at the first valid case with a pipeline.
    handles_by_creation: Option<bool>,
    /// How long a valid case's submission may run.
    pub gpu_timeout: Duration,
}

/// The keys of what a worker keeps between cases ([`Executor::affinity`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Affinity {
    /// The case's device.
    pub device: u64,
    /// The case's pipeline on that device.
    pub pipeline: u64,
}

/// The most devices of one valid pipeline each an executor keeps.
const PIPELINE_DEVICES: usize = 8;

impl Executor {
    /// Loads `driver` with the validation layer.
    pub fn new(driver: Driver) -> Result<Executor, HarnessError> {
        Ok(Executor {
            inst: Arc::new(VkInstance::new(driver, true)?),
            devices: HashMap::new(),
            pipeline_devices: Vec::new(),
            handles_by_creation: None,
            gpu_timeout: Duration::from_secs(20),
        })
    }

    pub fn driver(&self) -> &Driver {
        &self.inst.driver
    }

    /// The device, driver and layer that run this executor's cases.
    pub fn running_on(&self) -> crate::observe::RunningOn {
        let _turn = crate::vk::turn::take();
        self.inst.running_on()
    }

    /// The cache key of a world's device: its extensions and features, and the capabilities of its pool's
    /// family where that lacks compute (such a device has a second queue).
    fn device_key(world: &World) -> String {
        let device = serde_json::to_string(&world.device).unwrap_or_default();
        match pool_without_compute(&world.command_buffer) {
            Some(q) => format!("{device} pool {:#x}", q.0),
            None => device,
        }
    }

    /// What a worker keeps from `case` for later cases: the key of its device (`Executor::device_key`)
    /// and of its pipeline on that device, hashed; None for a case that keeps nothing (a build case
    /// makes its own device). Cases of one key are best run by one worker (see
    /// [`crate::worker::run_stream_on`]): a second worker would make the device, its first views of
    /// each format and the pipeline again.
    pub fn affinity(case: &Case) -> Option<Affinity> {
        use std::hash::{Hash, Hasher};
        let trace = case.as_trace()?;
        let world = &trace.world;
        // Only this process compares the keys: equal strings, equal keys.
        let hash = |parts: &[&str]| {
            let mut h = std::collections::hash_map::DefaultHasher::new();
            parts.hash(&mut h);
            h.finish()
        };
        let device = Self::device_key(world);
        let pipeline = serde_json::to_string(&world.pipeline).unwrap_or_default();
        Some(Affinity {
            device: hash(&[&device]),
            pipeline: hash(&[&device, &pipeline]),
        })
    }

    /// Runs one case and reports what the layer said and what the device produced (see
    /// `Executor::execute_trace` and the build path).
    pub fn execute(&mut self, case: &Case, exec: &Execution) -> Observation {
        let _turn = crate::vk::turn::take();
        if case.as_trace().is_some() {
            self.execute_trace(case, exec.run_valid)
        } else {
            accel::execute(&self.inst, case, exec)
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
        let _turn = crate::vk::turn::take();
        crate::accel_check::probe_rays(&self.inst, case, origins, check)
    }

    /// The cache key of the device a case runs on: its world's ([`Executor::device_key`]), and for a
    /// valid case on a driver that numbers handles in creation order, its pipeline too.
    fn case_device_key(&mut self, world: &World, valid: bool) -> String {
        let key = Self::device_key(world);
        match world.pipeline.as_ref() {
            Some(p) if valid && self.handles_by_creation_order(world) => {
                format!(
                    "{key} pipeline {}",
                    serde_json::to_string(p).unwrap_or_default()
                )
            }
            _ => key,
        }
    }

    /// Whether this driver gives two pipelines made alike on one device different shader group
    /// handles, measured once on a device of `world`'s own with a raygen-only pipeline of its kind
    /// made twice.
    ///
    /// A driver that numbers handles in the order pipelines are made may build those numbers into each
    /// pipeline's code (lavapipe lowers a whole ray tracing pipeline into one compute shader that
    /// compares the raygen record's handle with each group's number). The same pipeline made at
    /// another place in a device's life is then other code, which the driver compiles anew (seconds
    /// on lavapipe, at the first dispatch) and its shader cache never recognises, so which cases a
    /// worker happened to run before decided what it compiled. On such a driver each valid pipeline
    /// gets a device of its own, made first there: the same pipeline is the same code in every worker
    /// and every run, and the driver's cache serves it.
    fn handles_by_creation_order(&mut self, world: &World) -> bool {
        if let Some(known) = self.handles_by_creation {
            return known;
        }
        let Some(p) = world.pipeline.as_ref() else {
            return false;
        };
        // The smallest pipeline of the world's kind answers as well as its own: its raygen group
        // alone, tracing nothing, so the driver compiles little (lavapipe numbers every group).
        let raygen_only = model::world::Pipeline {
            api: p.api,
            flags: Default::default(),
            groups: vec![model::world::ShaderGroup::General {
                stage: model::world::GeneralStage::Raygen,
            }],
            max_recursion_depth: p.max_recursion_depth.min(1),
            dynamic_stack_size: false,
            allow_cluster_acceleration_structures: false,
        };
        let measured = {
            let _phase = crate::timing::span(crate::timing::Phase::Device);
            VkDevice::new(
                self.inst.clone(),
                &world.device.extensions,
                &world.device.features,
                None,
            )
            .and_then(DeviceCache::new)
        }
        .and_then(|mut cache| {
            // Handles name groups, not code: the interface-only body is the cheapest to make.
            let body = crate::shaders::ShaderBody::InterfaceOnly;
            let first = cache
                .pipeline(&raygen_only, false, body, false)?
                .handles
                .clone();
            let second = cache
                .pipeline(&raygen_only, false, body, true)?
                .handles
                .clone();
            Ok(first != second)
        });
        self.inst.collector.clear();
        // A device or pipeline this world cannot make says nothing; ask again at the next case.
        match measured {
            Ok(known) => {
                self.handles_by_creation = Some(known);
                known
            }
            Err(_) => false,
        }
    }

    /// Writes the layer's records of the modules it passed on each device (see `vk::validated`), as
    /// destroying the devices would: for a process that ends without destroying them.
    pub fn save_validated(&mut self) {
        let _turn = crate::vk::turn::take();
        for cache in self.devices.values_mut().flatten() {
            if let Some(v) = &mut cache.dev.validated {
                v.save();
            }
        }
    }

    /// Forgets a case's device (lost: its objects are leaked, see `DeviceCache::lost`).
    fn forget_device(&mut self, world: &World, valid: bool) {
        let key = self.case_device_key(world, valid);
        self.pipeline_devices.retain(|k| *k != key);
        self.devices.remove(&key);
    }

    fn device(&mut self, world: &World, valid: bool) -> Result<&mut DeviceCache, HarnessError> {
        let key = self.case_device_key(world, valid);
        if key != Self::device_key(world) {
            // Least recently used last out: a device in use moves to the back.
            match self.pipeline_devices.iter().position(|k| *k == key) {
                Some(i) => {
                    let used = self.pipeline_devices.remove(i);
                    self.pipeline_devices.push(used);
                }
                None => {
                    self.pipeline_devices.push(key.clone());
                    if self.pipeline_devices.len() > PIPELINE_DEVICES {
                        let oldest = self.pipeline_devices.remove(0);
                        // Destroying a device (and what its cache holds) is the driver's work, as
                        // making one is.
                        let _phase = crate::timing::span(crate::timing::Phase::Device);
                        drop(self.devices.remove(&oldest));
                    }
                }
            }
        }
        if !self.devices.contains_key(&key) {
            let _phase = crate::timing::span(crate::timing::Phase::Device);
            let made = VkDevice::new(
                self.inst.clone(),
                &world.device.extensions,
                &world.device.features,
                pool_without_compute(&world.command_buffer),
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

use crate::observe::DeviceLack;
use ash::vk;

/// Why a command buffer state cannot be realised on this device for any command, if it cannot: a
/// protected command buffer, a video coding scope, a pool of a queue family without compute on a device
/// whose every family has compute. What the device lacks is said as a [`DeviceLack`] (the session checks
/// it against the profile); what the harness does not do, as not realised. What a command's plan cannot
/// record in a pool without compute is the plan's to refuse.
pub(crate) fn unrealisable_command_buffer(
    inst: &VkInstance,
    cbs: &model::world::CommandBufferState,
) -> Option<HarnessError> {
    // SAFETY: plain query.
    let families = unsafe {
        inst.instance
            .get_physical_device_queue_family_properties(inst.physical)
    };
    let any = |f: vk::QueueFlags| families.iter().any(|p| p.queue_flags.intersects(f));
    if cbs.protected {
        // Asked only here: reading every feature structure costs more than most cases' recording.
        let protected_memory = inst
            .device_features()
            .iter()
            .any(|(k, on)| *on && k.ends_with("::protectedMemory"));
        let why = "a protected command buffer comes from a pool created with VK_COMMAND_POOL_CREATE_PROTECTED_BIT, \
             which needs the protectedMemory feature (VUID-VkCommandPoolCreateInfo-flags-02860) and a queue \
             created with VK_DEVICE_QUEUE_CREATE_PROTECTED_BIT";
        return Some(if protected_memory {
            HarnessError::NotRealised(format!(
                "{why}; the harness's device creates no protected queue"
            ))
        } else {
            HarnessError::lacks(
                DeviceLack::Feature("protectedMemory".into()),
                format!("{why}; the device lacks protectedMemory"),
            )
        });
    }
    if cbs.in_video_coding {
        let video = vk::QueueFlags::VIDEO_DECODE_KHR | vk::QueueFlags::VIDEO_ENCODE_KHR;
        return Some(if any(video) {
            HarnessError::NotRealised(
                "a video coding scope needs a video session (VK_KHR_video_queue) on a video queue; the harness \
                 creates neither"
                    .into(),
            )
        } else {
            HarnessError::lacks(
                DeviceLack::QueueFamilyWithAny(vec![
                    "VK_QUEUE_VIDEO_DECODE_BIT_KHR".into(),
                    "VK_QUEUE_VIDEO_ENCODE_BIT_KHR".into(),
                ]),
                "a video coding scope (vkCmdBeginVideoCodingKHR) needs a queue family with video decode or \
                 encode; the device has none",
            )
        });
    }
    // A pool of a family without compute comes from a queue of such a family the device is created with
    // (`VkDevice::new`); a device whose every family has compute lacks one.
    if pool_without_compute(cbs).is_some()
        && families
            .iter()
            .all(|p| p.queue_flags.contains(vk::QueueFlags::COMPUTE))
    {
        return Some(crate::vk::device::lacks_family_without_compute(
            families.len(),
        ));
    }
    None
}

/// An error of the trace path as an observation: unsupported with its reason, a timeout, or a crash
/// with the error's message.
fn failure(e: HarnessError) -> Observation {
    match e {
        HarnessError::NotRealised(s) => Observation::not_realised(s),
        HarnessError::DeviceLacks { lack, reason } => Observation::unsupported(lack, reason),
        HarnessError::Timeout { seconds, .. } => {
            Observation::with_status(Status::Timeout { seconds })
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gpu_timeout_reports_how_long_the_harness_waited() {
        let o = failure(HarnessError::Timeout {
            seconds: 20.0,
            message: "the GPU did not finish within 20s".into(),
        });
        assert_eq!(o.status, Status::Timeout { seconds: 20.0 });
    }
}
