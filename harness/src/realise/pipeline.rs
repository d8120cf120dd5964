//! Ray tracing pipelines of a world's description: the harness's descriptor layouts, one stage per
//! group — a module of the kind's code, or of a case's templated code of that kind, with the group's
//! constants written into it —, KHR or NV, cached per device, with the spec's default stack size.

use super::DeviceCache;

/// The group create infos of one API (KHR or NV: the same members under two types) from
/// `(type, [general, closest-hit, any-hit, intersection])` per group.
macro_rules! group_infos {
    ($groups:expr, $info:ty) => {
        $groups
            .iter()
            .map(|(ty, [gen, ch, ah, is])| {
                <$info>::default()
                    .ty(*ty)
                    .general_shader(*gen)
                    .closest_hit_shader(*ch)
                    .any_hit_shader(*ah)
                    .intersection_shader(*is)
            })
            .collect()
    };
}
use crate::error::{vkfail, HarnessError};
use crate::shaders::{self, ShaderBody, ShaderKind};
use ash::vk;
use model::world::{Pipeline, PipelineApi};

/// The descriptor set layout and pipeline layout of one raygen variant.
#[derive(Clone, Copy)]
pub(crate) struct Layouts {
    pub(crate) set: vk::DescriptorSetLayout,
    pub(crate) pipeline: vk::PipelineLayout,
}

/// A created ray tracing pipeline and its group handles.
#[derive(Clone)]
pub(crate) struct RealPipeline {
    pub(crate) pipeline: vk::Pipeline,
    pub(crate) handles: Vec<u8>,
    /// The stack size the spec's default formula gives for the pipeline's recursion depth (section "Ray
    /// Tracing Pipeline Stack"), used for `vkCmdSetRayTracingPipelineStackSizeKHR`; 0 for NV pipelines.
    pub(crate) default_stack_size: u32,
}

/// The stack size of the spec's default pipeline stack computation ("Ray Tracing Pipeline Stack"):
/// `raygen + min(1, depth) × max(closestHit, miss, intersection + anyHit) + max(0, depth - 1) ×
/// max(closestHit, miss) + 2 × callable`, each term the largest stack size of that shader kind. A pipeline
/// with dynamic stack size must be given at least this (an arbitrary constant is too small on real GPUs
/// once closest-hit shaders trace again).
fn default_stack_size(
    rt: &ash::khr::ray_tracing_pipeline::Device,
    pipeline: vk::Pipeline,
    groups: &[(vk::RayTracingShaderGroupTypeKHR, [u32; 4])],
    depth: u32,
) -> u32 {
    let unused = vk::SHADER_UNUSED_KHR;
    let (mut raygen, mut miss, mut callable, mut closest, mut any, mut isect) =
        (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
    for (g, (ty, [gen, ch, ah, is])) in groups.iter().enumerate() {
        // SAFETY: valid pipeline and group; only shaders the group has are queried.
        let size = |which| unsafe {
            rt.get_ray_tracing_shader_group_stack_size(pipeline, g as u32, which)
        };
        if *ty == vk::RayTracingShaderGroupTypeKHR::GENERAL && *gen != unused {
            // Which general stage this is does not matter for the maximum of its own kind; count it in all
            // three general kinds conservatively.
            let s = size(vk::ShaderGroupShaderKHR::GENERAL);
            raygen = raygen.max(s);
            miss = miss.max(s);
            callable = callable.max(s);
        }
        if *ch != unused {
            closest = closest.max(size(vk::ShaderGroupShaderKHR::CLOSEST_HIT));
        }
        if *ah != unused {
            any = any.max(size(vk::ShaderGroupShaderKHR::ANY_HIT));
        }
        if *is != unused {
            isect = isect.max(size(vk::ShaderGroupShaderKHR::INTERSECTION));
        }
    }
    let d = depth as u64;
    let total = raygen
        + d.min(1) * closest.max(miss).max(isect + any)
        + d.saturating_sub(1) * closest.max(miss)
        + 2 * callable;
    total.min(u32::MAX as u64) as u32
}

impl DeviceCache {
    /// The module of a stage with its two constants (group index, any-hit rule) written into
    /// its SPIR-V as ordinary constants ([`shaders::with_spec_values`]): a module without
    /// specialisation constants, which a validation layer validates once, when it is made, instead
    /// of specialising and validating it anew for every stage of every pipeline.
    fn module(
        &mut self,
        kind: ShaderKind,
        api: PipelineApi,
        body: ShaderBody,
        values: [u32; 2],
    ) -> Result<vk::ShaderModule, HarnessError> {
        let key = (kind, api == PipelineApi::Nv, body, values);
        if let Some(m) = self.modules.get(&key) {
            return Ok(*m);
        }
        let code = shaders::with_spec_values(&shaders::spirv(kind, api, body)?, &values);
        let m = shaders::module(&self.dev, &code)?;
        self.modules.insert(key, m);
        Ok(m)
    }

    /// Layouts for the raygen variant: with the scene at binding 0 (`trace`, a KHR or NV acceleration
    /// structure by `api`) or without; the bindings are the plan's
    /// ([`crate::plan::trace::harness_bindings`]).
    pub(crate) fn layouts(
        &mut self,
        trace: bool,
        api: PipelineApi,
    ) -> Result<Layouts, HarnessError> {
        if let Some(l) = self.layouts.get(&(trace, api == PipelineApi::Nv)) {
            return Ok(*l);
        }
        let bindings = harness_set_bindings(trace, api);
        let d = &self.dev.device;
        // SAFETY: valid create infos.
        let set = unsafe {
            d.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
        }
        .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
        let sets = [set];
        // SAFETY: as above.
        let pipeline = unsafe {
            d.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
                None,
            )
        }
        .map_err(vkfail("vkCreatePipelineLayout"))?;
        let l = Layouts { set, pipeline };
        self.layouts.insert((trace, api == PipelineApi::Nv), l);
        Ok(l)
    }

    /// The pipeline for a description with modules of `body` (cached); `foreign` makes a second,
    /// distinct pipeline of it.
    pub(crate) fn pipeline(
        &mut self,
        p: &Pipeline,
        trace: bool,
        body: ShaderBody,
        foreign: bool,
    ) -> Result<&RealPipeline, HarnessError> {
        // A case with a resource state runs its own pipeline (see `resource_pipeline`).
        // (Checked, then borrowed: returning the borrow from an `if let` would keep `self` borrowed
        // for the cache insertion below.)
        #[allow(clippy::unnecessary_unwrap)]
        if !foreign && self.resource_pipeline.is_some() {
            return Ok(self.resource_pipeline.as_ref().expect("checked"));
        }
        let key = format!(
            "{}|{trace}|{body:?}|{foreign}",
            serde_json::to_string(p).unwrap_or_default()
        );
        if !self.pipelines.contains_key(&key) {
            let made = self.create_pipeline(p, trace, body);
            self.pipelines.insert(key.clone(), made);
        }
        match &self.pipelines[&key] {
            Ok(p) => Ok(p),
            Err(e) => Err(e.clone()),
        }
    }

    fn create_pipeline(
        &mut self,
        p: &Pipeline,
        trace: bool,
        body: ShaderBody,
    ) -> Result<RealPipeline, HarnessError> {
        let layout = self.layouts(trace, p.api)?.pipeline;
        self.create_pipeline_with(p, trace, body, layout, &[], &mut Vec::new())
    }

    /// The pipeline for a description with `layout` and, for each shader kind `templated` names,
    /// that SPIR-V in every stage of that kind with the stage's constants written into it (used by
    /// `crate::realise::resources` for cases with a resource state: its templated raygen,
    /// closest-hit, miss, ... code). The modules made of it go into `made`, the caller's to destroy
    /// with its case. Not cached here (`crate::realise::resources::Shared` keeps them by content).
    pub(crate) fn create_pipeline_with(
        &mut self,
        p: &Pipeline,
        trace: bool,
        body: ShaderBody,
        layout: vk::PipelineLayout,
        templated: &[(ShaderKind, Vec<u32>)],
        made: &mut Vec<(ShaderKind, vk::ShaderModule)>,
    ) -> Result<RealPipeline, HarnessError> {
        let _phase = crate::timing::span(crate::timing::Phase::Pipeline);
        let api = p.api;
        match api {
            PipelineApi::Khr if self.dev.rt.is_none() => {
                return Err(HarnessError::NotRealised(
                    "the case does not enable VK_KHR_ray_tracing_pipeline, so no ray tracing pipeline can be made".into(),
                ))
            }
            PipelineApi::Nv if self.dev.nv.is_none() => {
                return Err(HarnessError::NotRealised(
                    "the case does not enable VK_NV_ray_tracing, so no NV ray tracing pipeline can be made".into(),
                ))
            }
            _ => {}
        }
        // The plan's stages, each a module with its two constants (group index, any-hit rule)
        // written in: of its kind's harness code (kept per device), or of the templated code where
        // `templated` has its kind (made once per kind and constants here); and per group (type,
        // [general, closest, any, intersection]). No stage is given specialisation info (see
        // [`shaders::with_spec_values`]).
        let plan = crate::plan::PipelinePlan::of(p, trace, body)?;
        let mut own: Vec<((ShaderKind, [u32; 2]), vk::ShaderModule)> = Vec::new();
        let mut stage_list: Vec<(vk::ShaderStageFlags, vk::ShaderModule)> =
            Vec::with_capacity(plan.stages.len());
        for st in &plan.stages {
            let values = [st.group, st.any_hit_rule];
            let m = match templated.iter().find(|(k, _)| *k == st.shader) {
                Some((kind, code)) => match own.iter().find(|(key, _)| *key == (*kind, values)) {
                    Some(&(_, m)) => m,
                    None => {
                        let m =
                            shaders::module(&self.dev, &shaders::with_spec_values(code, &values))?;
                        made.push((*kind, m));
                        own.push(((*kind, values), m));
                        m
                    }
                },
                None => self.module(st.shader, api, body, values)?,
            };
            stage_list.push((vk::ShaderStageFlags::from_raw(st.stage), m));
        }
        let groups: Vec<(vk::RayTracingShaderGroupTypeKHR, [u32; 4])> = plan
            .groups
            .iter()
            .map(|g| {
                (
                    vk::RayTracingShaderGroupTypeKHR::from_raw(g.ty.raw()),
                    [g.general, g.closest_hit, g.any_hit, g.intersection],
                )
            })
            .collect();
        let main = c"main";
        let stages: Vec<vk::PipelineShaderStageCreateInfo> = stage_list
            .iter()
            .map(|(flag, m)| {
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(*flag)
                    .module(*m)
                    .name(main)
            })
            .collect();
        let flags = vk::PipelineCreateFlags::from_raw(p.flags.0 as u32);
        let hs = self.dev.limits.handle_size as usize;
        let n = p.groups.len();
        if api == PipelineApi::Nv {
            let hs = self.dev.limits.nv_handle_size as usize;
            let nv_groups: Vec<vk::RayTracingShaderGroupCreateInfoNV> =
                group_infos!(groups, vk::RayTracingShaderGroupCreateInfoNV);
            let info = vk::RayTracingPipelineCreateInfoNV::default()
                .flags(flags & crate::plan::pipeline::NV_PIPELINE_FLAGS)
                .stages(&stages)
                .groups(&nv_groups)
                .max_recursion_depth(p.max_recursion_depth)
                .layout(layout);
            let nv = self.dev.nv.as_ref().expect("checked above");
            // SAFETY: every pointer in `info` outlives the call.
            let pipeline = unsafe {
                nv.create_ray_tracing_pipelines(vk::PipelineCache::null(), &[info], None)
            }
            .map_err(|(_, r)| {
                HarnessError::Failed(format!("vkCreateRayTracingPipelinesNV failed: {r:?}"))
            })?[0];
            let mut handles = vec![0u8; hs * n];
            if n > 0 {
                // SAFETY: valid pipeline, group range inside it, data sized for the groups.
                if let Err(r) = unsafe {
                    nv.get_ray_tracing_shader_group_handles(pipeline, 0, n as u32, &mut handles)
                } {
                    // SAFETY: destroying what we created.
                    unsafe { self.dev.device.destroy_pipeline(pipeline, None) };
                    return Err(HarnessError::Failed(format!(
                        "vkGetRayTracingShaderGroupHandlesNV failed: {r:?}"
                    )));
                }
            }
            return Ok(RealPipeline {
                pipeline,
                handles,
                default_stack_size: 0,
            });
        }
        let khr_groups: Vec<vk::RayTracingShaderGroupCreateInfoKHR> =
            group_infos!(groups, vk::RayTracingShaderGroupCreateInfoKHR);
        let dynamic = [vk::DynamicState::RAY_TRACING_PIPELINE_STACK_SIZE_KHR];
        let dyn_info = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic);
        let iface = vk::RayTracingPipelineInterfaceCreateInfoKHR::default()
            .max_pipeline_ray_payload_size(crate::plan::pipeline::MAX_PAYLOAD_SIZE)
            .max_pipeline_ray_hit_attribute_size(crate::plan::pipeline::MAX_HIT_ATTRIBUTE_SIZE);
        let mut info = vk::RayTracingPipelineCreateInfoKHR::default()
            .flags(flags)
            .stages(&stages)
            .groups(&khr_groups)
            .max_pipeline_ray_recursion_depth(p.max_recursion_depth)
            .layout(layout);
        if p.dynamic_stack_size {
            info = info.dynamic_state(&dyn_info);
        }
        if flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR) {
            info = info.library_interface(&iface);
        }
        let rt = self.dev.rt.as_ref().expect("checked above");
        // SAFETY: every pointer in `info` outlives the call.
        let pipeline = unsafe {
            rt.create_ray_tracing_pipelines(
                vk::DeferredOperationKHR::null(),
                vk::PipelineCache::null(),
                &[info],
                None,
            )
        }
        .map_err(|(_, r)| {
            HarnessError::Failed(format!("vkCreateRayTracingPipelinesKHR failed: {r:?}"))
        })?[0];
        let library = flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR);
        let handles = if library || n == 0 {
            vec![0u8; hs * n]
        } else {
            // SAFETY: valid pipeline, group range inside it.
            unsafe { rt.get_ray_tracing_shader_group_handles(pipeline, 0, n as u32, hs * n) }
                .map_err(vkfail("vkGetRayTracingShaderGroupHandlesKHR"))?
        };
        let default_stack_size = if library {
            0
        } else {
            default_stack_size(rt, pipeline, &groups, p.max_recursion_depth)
        };
        Ok(RealPipeline {
            pipeline,
            handles,
            default_stack_size,
        })
    }
}

/// The harness's descriptor set as Vulkan bindings: the plan's
/// ([`crate::plan::trace::harness_bindings`]), one descriptor each.
pub(crate) fn harness_set_bindings(
    trace: bool,
    api: PipelineApi,
) -> Vec<vk::DescriptorSetLayoutBinding<'static>> {
    crate::plan::trace::harness_bindings(trace, api)
        .iter()
        .map(|b| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b.binding)
                .descriptor_type(vk::DescriptorType::from_raw(b.ty))
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::from_raw(b.stages))
        })
        .collect()
}
