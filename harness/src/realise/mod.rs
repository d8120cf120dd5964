//! Realises a trace case's world on a device: buffers placed at 4096-aligned addresses with their
//! contents (shader group handles, indirect commands), the ray tracing pipeline with one stage per
//! group (its constants written into the module), the scene (one BLAS per bottom
//! level, a TLAS; KHR or NV structures), the case's resource state, and a build case's buffers and
//! structures ([`accel`]). Pipelines and scenes are cached per
//! device across cases ([`DeviceCache`]).

pub(crate) mod accel;
mod buffers;
mod pipeline;
pub(crate) mod resources;
pub(crate) mod scene;

pub(crate) use pipeline::{Layouts, RealPipeline};
pub(crate) use scene::{Scene, Tlas};

use crate::error::{vkfail, HarnessError};
use crate::shaders::{ShaderBody, ShaderKind};
use crate::vk::commands::Commands;
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use std::collections::HashMap;

/// Per-device objects the harness reuses across cases.
pub(crate) struct DeviceCache {
    /// By kind, NV or not, body and the two constants written into the module.
    modules: HashMap<(ShaderKind, bool, ShaderBody, [u32; 2]), vk::ShaderModule>,
    layouts: HashMap<(bool, bool), Layouts>,
    pipelines: HashMap<String, Result<RealPipeline, HarnessError>>,
    scenes: HashMap<String, Result<Scene, HarnessError>>,
    /// The keys of `scenes`, oldest first.
    scene_order: Vec<String>,
    /// The command pool, the primary and secondary buffers cases are recorded into, the fence, and
    /// the empty render pass.
    pub(crate) cmds: Commands,
    /// The pool of the harness's descriptor sets: one per set layout (`harness_sets`).
    descriptor_pool: vk::DescriptorPool,
    /// The harness's descriptor set of each set layout cases used, kept across cases and written anew
    /// by each (no case's command buffer outlives its case).
    harness_sets: Vec<(vk::DescriptorSetLayout, vk::DescriptorSet)>,
    /// Output records and rays, reused and grown as needed.
    pub(crate) output: Option<Allocation>,
    pub(crate) rays: Option<Allocation>,
    /// The callable record indices the raygen executes: a 16-byte header (count) and one u32 each.
    pub(crate) callables: Option<Allocation>,
    /// The spheres buffer bound when the case builds no scene (the binding is always written).
    pub(crate) no_spheres: Option<Allocation>,
    /// Finished cases' buffers kept for later cases.
    spare: buffers::SpareBuffers,
    /// Set when a submission ended in DEVICE_LOST or a timeout: nothing may be recorded on this device
    /// again, and dropping it neither waits for it nor resets what is pending on it.
    pub(crate) lost: bool,
    /// The pipeline of a case with a resource state (its own raygen module and pipeline
    /// layout, made by `crate::realise::resources`), returned by [`DeviceCache::pipeline`] for the case's own
    /// (non-foreign) pipeline while that case runs. Owned and destroyed by `crate::realise::resources::Realised`,
    /// unless it is a copy of one [`resources::Shared`] keeps.
    pub(crate) resource_pipeline: Option<RealPipeline>,
    /// Resource-state layouts and pipelines shared by content across cases.
    pub(crate) shared_resources: resources::Shared,
    pub(crate) dev: VkDevice,
}

/// The harness's set layouts a device may have ([`DeviceCache::layouts`]: KHR or NV, read-back or not),
/// each with its one set in the pool.
const HARNESS_SETS: u32 = 4;

/// The ray data the raygen shader reads: std430 `Ray` (64 bytes) after a 16-byte header.
pub(crate) use crate::plan::trace::RAY_RECORD_SIZE;

impl Drop for DeviceCache {
    fn drop(&mut self) {
        let _turn = crate::vk::turn::take();
        if self.lost {
            // A lost device: destroying its objects is allowed but waiting on it may not return on every
            // driver, and a timed-out submission may still be running. Leak every object (handles have no
            // destructor of their own) and the VkDevice with the instance it holds, rather than free memory
            // the GPU may still use or block the process; the worker then starts a fresh instance.
            self.dev.leak = true;
            return;
        }
        // SAFETY: the device is idle after this wait; everything below was made from it.
        unsafe {
            let _ = self.dev.device.device_wait_idle();
        }
        for (_, s) in std::mem::take(&mut self.scenes) {
            if let Ok(s) = s {
                self.destroy_scene(s);
            }
        }
        // Before the harness's layouts: the shared pipeline layouts hold its set layout.
        self.shared_resources.destroy(&self.dev.device);
        let d = &self.dev.device;
        // SAFETY: as above.
        unsafe {
            for (_, p) in self.pipelines.drain() {
                if let Ok(p) = p {
                    d.destroy_pipeline(p.pipeline, None);
                }
            }
            for (_, l) in self.layouts.drain() {
                d.destroy_pipeline_layout(l.pipeline, None);
                d.destroy_descriptor_set_layout(l.set, None);
            }
            for (_, m) in self.modules.drain() {
                d.destroy_shader_module(m, None);
            }
            d.destroy_descriptor_pool(self.descriptor_pool, None);
        }
        self.cmds.destroy(&self.dev);
        if let Some(a) = self.output.take() {
            a.destroy(&self.dev);
        }
        if let Some(a) = self.rays.take() {
            a.destroy(&self.dev);
        }
        if let Some(a) = self.callables.take() {
            a.destroy(&self.dev);
        }
        if let Some(a) = self.no_spheres.take() {
            a.destroy(&self.dev);
        }
        self.spare.destroy(&self.dev);
    }
}

impl DeviceCache {
    pub(crate) fn new(dev: VkDevice) -> Result<DeviceCache, HarnessError> {
        let d = &dev.device;
        // SAFETY: valid create infos on a live device.
        unsafe {
            let cmds = Commands::new(&dev)?;
            let mut sizes = vec![vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: 5 * HARNESS_SETS,
            }];
            if dev.accel.is_some() {
                sizes.push(vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                    descriptor_count: HARNESS_SETS,
                });
            }
            if dev.nv.is_some() {
                sizes.push(vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
                    descriptor_count: HARNESS_SETS,
                });
            }
            let descriptor_pool = d
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(HARNESS_SETS)
                        .pool_sizes(&sizes),
                    None,
                )
                .map_err(vkfail("vkCreateDescriptorPool"))?;
            Ok(DeviceCache {
                modules: HashMap::new(),
                layouts: HashMap::new(),
                pipelines: HashMap::new(),
                scenes: HashMap::new(),
                scene_order: Vec::new(),
                cmds,
                descriptor_pool,
                harness_sets: Vec::new(),
                output: None,
                rays: None,
                callables: None,
                no_spheres: None,
                spare: buffers::SpareBuffers::default(),
                lost: false,
                resource_pipeline: None,
                shared_resources: resources::Shared::default(),
                dev,
            })
        }
    }

    /// The harness's descriptor set of `layout`, allocated the first time a case asks for it. Where the
    /// pool holds no more sets it is reset and the sets allocated anew: no set is in use between cases.
    pub(crate) fn harness_set(
        &mut self,
        layout: vk::DescriptorSetLayout,
    ) -> Result<vk::DescriptorSet, HarnessError> {
        if let Some(&(_, set)) = self.harness_sets.iter().find(|(l, _)| *l == layout) {
            return Ok(set);
        }
        let d = &self.dev.device;
        let layouts = [layout];
        let info = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(self.descriptor_pool)
            .set_layouts(&layouts);
        // SAFETY: the pool's sets are not in use (the cases that wrote them finished, and their
        // command buffers were reset), so the pool may be reset as well as allocated from.
        let set = match unsafe { d.allocate_descriptor_sets(&info) } {
            Ok(s) => s[0],
            // SAFETY: as above.
            Err(_) => unsafe {
                d.reset_descriptor_pool(
                    self.descriptor_pool,
                    vk::DescriptorPoolResetFlags::empty(),
                )
                .map_err(vkfail("vkResetDescriptorPool"))?;
                self.harness_sets.clear();
                d.allocate_descriptor_sets(&info)
                    .map_err(vkfail("vkAllocateDescriptorSets"))?[0]
            },
        };
        self.harness_sets.push((layout, set));
        Ok(set)
    }

    /// Submits the primary command buffer and waits for it. A lost device or a submission that does not
    /// finish marks the cache [`lost`](Self::lost): nothing is recorded or submitted on it again.
    pub(crate) fn submit_and_wait(
        &mut self,
        timeout: std::time::Duration,
    ) -> Result<(), HarnessError> {
        if self.lost {
            return Err(HarnessError::Failed(
                "the device was lost by an earlier case (ERROR_DEVICE_LOST)".into(),
            ));
        }
        let d = &self.dev.device;
        let cbs = [self.cmds.cb];
        let submit = [vk::SubmitInfo::default().command_buffers(&cbs)];
        // SAFETY: the command buffer is executable; the fence is unsignalled.
        unsafe {
            if let Err(r) = d.queue_submit(self.dev.queue, &submit, self.cmds.fence) {
                self.lost |= r == vk::Result::ERROR_DEVICE_LOST;
                return Err(HarnessError::Failed(format!("vkQueueSubmit failed: {r:?}")));
            }
            let waited = d.wait_for_fences(
                &[self.cmds.fence],
                true,
                timeout.as_nanos().min(u64::MAX as u128) as u64,
            );
            match waited {
                Ok(()) => {}
                Err(vk::Result::TIMEOUT) => {
                    self.lost = true;
                    return Err(HarnessError::Timeout {
                        seconds: timeout.as_secs_f64(),
                        message: format!("the GPU did not finish within {timeout:?}"),
                    });
                }
                Err(r) => {
                    self.lost |= r == vk::Result::ERROR_DEVICE_LOST;
                    return Err(HarnessError::Failed(format!(
                        "vkWaitForFences failed: {r:?}"
                    )));
                }
            }
            d.reset_fences(&[self.cmds.fence])
                .map_err(vkfail("vkResetFences"))?;
        }
        Ok(())
    }

    /// Buffers at least `words` output words, `rays` ray records and `callables` callable indices large
    /// (grown when needed).
    pub(crate) fn io_buffers(
        &mut self,
        words: usize,
        rays: usize,
        callables: usize,
    ) -> Result<(), HarnessError> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | self.dev.address_usage();
        let want_out = (words.max(1) * 4) as u64;
        if self.output.as_ref().is_none_or(|a| a.size < want_out) {
            if let Some(a) = self.output.take() {
                a.destroy(&self.dev);
            }
            self.output = Some(Allocation::new(
                &self.dev,
                want_out.max(4096),
                usage,
                vk::BufferCreateFlags::empty(),
                1,
            )?);
        }
        let want_rays = (16 + rays.max(1) * RAY_RECORD_SIZE) as u64;
        if self.rays.as_ref().is_none_or(|a| a.size < want_rays) {
            if let Some(a) = self.rays.take() {
                a.destroy(&self.dev);
            }
            self.rays = Some(Allocation::new(
                &self.dev,
                want_rays.max(4096),
                usage,
                vk::BufferCreateFlags::empty(),
                1,
            )?);
        }
        if self.no_spheres.is_none() {
            self.no_spheres = Some(Allocation::filled(&self.dev, &[0u8; 16], 16, usage, 256)?);
        }
        let want_calls = (16 + callables.max(1) * 4) as u64;
        if self.callables.as_ref().is_none_or(|a| a.size < want_calls) {
            if let Some(a) = self.callables.take() {
                a.destroy(&self.dev);
            }
            self.callables = Some(Allocation::new(
                &self.dev,
                want_calls.max(256),
                usage,
                vk::BufferCreateFlags::empty(),
                1,
            )?);
        }
        Ok(())
    }

    /// A render pass with no attachments and a 1x1 framebuffer, for cases recorded inside a render pass.
    pub(crate) fn empty_render_pass(
        &mut self,
    ) -> Result<(vk::RenderPass, vk::Framebuffer), HarnessError> {
        self.cmds.render_pass(&self.dev)
    }
}
