//! The Vulkan objects of a resource state: set and pipeline layouts after the harness's own set,
//! descriptor pools and sets with their writes, samplers, images and views, buffers and buffer views,
//! the templated stage modules and the case's pipeline.

use super::glsl::{patch_narrow_writes, shader_kind};
use super::*;
use crate::error::vkfail;
use model::world::PipelineApi;

pub(super) fn descriptor_type(t: DescriptorType) -> Result<vk::DescriptorType, HarnessError> {
    Ok(match t {
        DescriptorType::Sampler => vk::DescriptorType::SAMPLER,
        DescriptorType::CombinedImageSampler => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        DescriptorType::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
        DescriptorType::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
        DescriptorType::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
        DescriptorType::StorageTexelBuffer => vk::DescriptorType::STORAGE_TEXEL_BUFFER,
        DescriptorType::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
        DescriptorType::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
        other => {
            return unsup(format!(
                "{other:?} descriptors are not realised (vendor or input attachment)"
            ))
        }
    })
}

/// `VK_FORMAT_…` name to `vk::Format`, through ash's names of the core and extension ranges.
pub(super) fn vk_format(name: &str) -> Result<vk::Format, HarnessError> {
    let n = name.strip_prefix("VK_FORMAT_").unwrap_or(name);
    let ranges = [
        (0, 185),
        (1_000_054_000, 1_000_054_008),
        (1_000_066_000, 1_000_066_014),
        (1_000_156_000, 1_000_156_034),
        (1_000_330_000, 1_000_330_004),
        (1_000_340_000, 1_000_340_002),
        (1_000_470_000, 1_000_470_002),
    ];
    ranges
        .iter()
        .flat_map(|&(a, b)| a..b)
        .map(vk::Format::from_raw)
        .find(|f| format!("{f:?}") == n)
        .ok_or_else(|| {
            HarnessError::NotRealised(format!("format {name} is unknown to the harness"))
        })
}

pub(super) fn vk_layout(l: ImageLayout) -> Result<vk::ImageLayout, HarnessError> {
    Ok(match l {
        ImageLayout::Undefined => vk::ImageLayout::UNDEFINED,
        ImageLayout::General => vk::ImageLayout::GENERAL,
        ImageLayout::ShaderReadOnlyOptimal => vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        ImageLayout::ReadOnlyOptimal => vk::ImageLayout::READ_ONLY_OPTIMAL,
        ImageLayout::DepthStencilReadOnlyOptimal => {
            vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL
        }
        ImageLayout::TransferDstOptimal => vk::ImageLayout::TRANSFER_DST_OPTIMAL,
        ImageLayout::AttachmentFeedbackLoopOptimal => {
            return unsup("the attachment feedback loop layout is not realised")
        }
    })
}

fn filter(f: Filter) -> vk::Filter {
    match f {
        Filter::Nearest => vk::Filter::NEAREST,
        Filter::Linear => vk::Filter::LINEAR,
        Filter::CubicExt => vk::Filter::CUBIC_EXT,
    }
}

fn address(m: AddressMode) -> vk::SamplerAddressMode {
    match m {
        AddressMode::Repeat => vk::SamplerAddressMode::REPEAT,
        AddressMode::MirroredRepeat => vk::SamplerAddressMode::MIRRORED_REPEAT,
        AddressMode::ClampToEdge => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        AddressMode::ClampToBorder => vk::SamplerAddressMode::CLAMP_TO_BORDER,
        AddressMode::MirrorClampToEdge => vk::SamplerAddressMode::MIRROR_CLAMP_TO_EDGE,
    }
}

pub(super) fn aspect_of(format: &str) -> vk::ImageAspectFlags {
    let n = format.strip_prefix("VK_FORMAT_").unwrap_or(format);
    match (
        n.starts_with('D') || n.contains("_D"),
        n.contains('S') && (n.starts_with('S') || n.contains("S8")),
    ) {
        (true, true) => vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL,
        (true, false) => vk::ImageAspectFlags::DEPTH,
        (false, true) if n.starts_with("S8") => vk::ImageAspectFlags::STENCIL,
        _ => vk::ImageAspectFlags::COLOR,
    }
}

/// Replaces the cache's command buffers with fresh ones. The 1.3.239 layer keeps a command buffer's
/// push-constant state across vkResetCommandBuffer/vkBeginCommandBuffer, so an earlier case's push would
/// hide a later case's "push constants never set" (VUID-…-maintenance4-06425) on a reused one.
pub(super) fn renew_command_buffers(cache: &mut DeviceCache) -> Result<(), HarnessError> {
    let d = &cache.dev.device;
    // SAFETY: the old command buffers are not pending (earlier cases waited or never submitted).
    unsafe {
        let alloc = |level| {
            d.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(cache.cmds.pool)
                    .level(level)
                    .command_buffer_count(1),
            )
            .map(|v| v[0])
            .map_err(vkfail("vkAllocateCommandBuffers"))
        };
        let primary = alloc(vk::CommandBufferLevel::PRIMARY)?;
        let secondary = match alloc(vk::CommandBufferLevel::SECONDARY) {
            Ok(s) => s,
            Err(e) => {
                d.free_command_buffers(cache.cmds.pool, &[primary]);
                return Err(e);
            }
        };
        d.free_command_buffers(cache.cmds.pool, &[cache.cmds.cb, cache.cmds.secondary]);
        cache.cmds.cb = primary;
        cache.cmds.secondary = secondary;
    }
    Ok(())
}

impl Realised {
    /// The realised immutable samplers of a binding (`pImmutableSamplers`), one per element.
    fn immutable_samplers(
        &self,
        l: &SetLayout,
        b: &LayoutBinding,
    ) -> Result<Vec<vk::Sampler>, HarnessError> {
        if b.immutable_samplers.is_empty() {
            return Ok(vec![]);
        }
        if !matches!(
            b.ty,
            DescriptorType::Sampler | DescriptorType::CombinedImageSampler
        ) || b.immutable_samplers.len() != b.count as usize
        {
            return unsup(format!(
                "set layout `{}` binding {} ({:?}, count {}) names {} immutable samplers: only sampler and combined image \
                 sampler bindings have them, one per element",
                l.name,
                b.binding,
                b.ty,
                b.count,
                b.immutable_samplers.len()
            ));
        }
        b.immutable_samplers
            .iter()
            .map(|n| {
                self.samplers.get(n).copied().ok_or_else(|| {
                    HarnessError::NotRealised(format!(
                        "set layout `{}` binding {} names immutable sampler `{n}`, which the state lacks",
                        l.name, b.binding
                    ))
                })
            })
            .collect()
    }

    pub(super) fn build(
        &mut self,
        cache: &mut DeviceCache,
        world: &World,
        trace: bool,
        body: ShaderBody,
        harness_set: vk::DescriptorSetLayout,
    ) -> Result<(), HarnessError> {
        if let Some(why) = unsupported(world) {
            return unsup(why);
        }
        let st = &world.resources;
        // Descriptors from descriptor buffers: every set layout (the harness's too) is a descriptor
        // buffer layout, and descriptor memory stands in for the pool, the sets and their writes.
        let by_buffer = st.descriptor_source == DescriptorSource::Buffers;
        // The stages templated: the raygen, and every other stage that declares accesses or pushes.
        let api = world.pipeline.as_ref().map_or(PipelineApi::Khr, |p| p.api);
        let mut templated = vec![Stage::Raygen];
        for s in &st.stages {
            if s.stage != Stage::Raygen
                && (!s.accesses.is_empty() || s.push_constants.is_some())
                && !templated.contains(&s.stage)
            {
                templated.push(s.stage);
            }
        }
        let mut sources = Vec::new();
        for &stage in &templated {
            let (glsl, narrow) =
                stage_glsl(st, stage, stage_source(stage).0).map_err(|e| match e {
                    HarnessError::NotRealised(why) => {
                        HarnessError::NotRealised(format!("{stage:?} stage: {why}"))
                    }
                    e => e,
                })?;
            sources.push((stage, glsl, narrow));
        }
        // The realised pipeline layout's key, where it is shared.
        let harness_layout_key: Option<String>;
        let dev = &cache.dev;
        let d = &dev.device;
        // SAFETY (whole block): create infos reference live locals and objects of this device.
        unsafe {
            let harness_set = if by_buffer {
                self.db_harness_set = descriptor_buffer::harness_set_layout(dev, trace, api)?;
                self.db_harness_set
            } else {
                harness_set
            };
            let layout_flags = if by_buffer {
                vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT
            } else {
                vk::DescriptorSetLayoutCreateFlags::empty()
            };
            // Y′CbCr conversions, then samplers (before the set layouts that hold them as immutable samplers).
            self.ycbcr = super::ycbcr::Conversions::new(dev, st)?;
            for s in &st.samplers {
                let mut red = vk::SamplerReductionModeCreateInfo::default().reduction_mode(match s
                    .reduction
                {
                    Reduction::Min => vk::SamplerReductionMode::MIN,
                    Reduction::Max => vk::SamplerReductionMode::MAX,
                    _ => vk::SamplerReductionMode::WEIGHTED_AVERAGE,
                });
                let mut info = vk::SamplerCreateInfo::default()
                    .mag_filter(filter(s.mag_filter))
                    .min_filter(filter(s.min_filter))
                    .mipmap_mode(match s.mipmap_mode {
                        MipmapMode::Nearest => vk::SamplerMipmapMode::NEAREST,
                        MipmapMode::Linear => vk::SamplerMipmapMode::LINEAR,
                    })
                    .address_mode_u(address(s.address_modes[0]))
                    .address_mode_v(address(s.address_modes[1]))
                    .address_mode_w(address(s.address_modes[2]))
                    .compare_enable(s.compare_enable)
                    .compare_op(vk::CompareOp::LESS_OR_EQUAL)
                    .unnormalized_coordinates(s.unnormalized_coordinates)
                    .min_lod(0.0)
                    .max_lod(if s.unnormalized_coordinates {
                        0.0
                    } else {
                        vk::LOD_CLAMP_NONE
                    });
                if s.reduction != Reduction::WeightedAverage {
                    info = info.push_next(&mut red);
                }
                let mut conversion = vk::SamplerYcbcrConversionInfo::default();
                if let Some(c) = self.ycbcr.of_sampler(&s.name) {
                    conversion = conversion.conversion(c);
                    info = info.push_next(&mut conversion);
                }
                let h = d
                    .create_sampler(&info, None)
                    .map_err(vkfail("vkCreateSampler"))?;
                self.samplers.insert(s.name.clone(), h);
            }
            // Set layouts and pipeline layouts: shared by content across the device's cases where no
            // binding has immutable samplers (the layout would name this case's samplers) and the
            // descriptors are sets (a descriptor buffer layout's harness set is the case's own).
            let share = !by_buffer
                && st
                    .set_layouts
                    .iter()
                    .all(|l| l.bindings.iter().all(|b| b.immutable_samplers.is_empty()));
            self.shared_layouts = share;
            let shared = &mut cache.shared_resources;
            let mut set_keys: HashMap<&str, String> = HashMap::new();
            let mut layout_keys: HashMap<&str, String> = HashMap::new();
            for l in &st.set_layouts {
                let key = super::set_layout_key(layout_flags, l);
                if share {
                    if let Some(&h) = shared.set_layouts.get(&key) {
                        self.set_layouts.insert(l.name.clone(), h);
                        set_keys.insert(&l.name, key);
                        continue;
                    }
                }
                let immutable: Vec<Vec<vk::Sampler>> = l
                    .bindings
                    .iter()
                    .map(|b| self.immutable_samplers(l, b))
                    .collect::<Result<_, _>>()?;
                let mut bs = Vec::new();
                for (b, imm) in l.bindings.iter().zip(&immutable) {
                    let mut binding = vk::DescriptorSetLayoutBinding::default()
                        .binding(b.binding)
                        .descriptor_type(descriptor_type(b.ty)?)
                        .descriptor_count(b.count)
                        .stage_flags(rt_stages());
                    if !imm.is_empty() {
                        binding = binding.immutable_samplers(imm);
                    }
                    bs.push(binding);
                }
                let h = d
                    .create_descriptor_set_layout(
                        &vk::DescriptorSetLayoutCreateInfo::default()
                            .flags(layout_flags)
                            .bindings(&bs),
                        None,
                    )
                    .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
                if share {
                    shared.set_layouts.insert(key.clone(), h);
                }
                self.set_layouts.insert(l.name.clone(), h);
                set_keys.insert(&l.name, key);
            }
            // Pipeline layouts: the harness set, then the case's.
            for p in &st.pipeline_layouts {
                let keys: Vec<&str> = p
                    .sets
                    .iter()
                    .map(|s| set_keys.get(s.as_str()).map_or("", |k| k.as_str()))
                    .collect();
                let key = super::pipeline_layout_key(harness_set, &keys, &p.push_ranges);
                if share && p.sets.iter().all(|s| set_keys.contains_key(s.as_str())) {
                    if let Some(&h) = shared.pipeline_layouts.get(&key) {
                        self.pipeline_layouts.insert(p.name.clone(), h);
                        layout_keys.insert(&p.name, key);
                        continue;
                    }
                }
                let mut sl = vec![harness_set];
                for s in &p.sets {
                    sl.push(*self.set_layouts.get(s).ok_or_else(|| {
                        HarnessError::NotRealised(format!(
                            "pipeline layout `{}` names set layout `{s}`, which the state lacks",
                            p.name
                        ))
                    })?);
                }
                let ranges: Vec<vk::PushConstantRange> = p
                    .push_ranges
                    .iter()
                    .map(|r| vk::PushConstantRange {
                        stage_flags: rt_stages(),
                        offset: r.offset,
                        size: r.size,
                    })
                    .collect();
                let h = d
                    .create_pipeline_layout(
                        &vk::PipelineLayoutCreateInfo::default()
                            .set_layouts(&sl)
                            .push_constant_ranges(&ranges),
                        None,
                    )
                    .map_err(vkfail("vkCreatePipelineLayout"))?;
                if share {
                    shared.pipeline_layouts.insert(key.clone(), h);
                }
                self.pipeline_layouts.insert(p.name.clone(), h);
                layout_keys.insert(&p.name, key);
            }
            match st.pipeline_layout.as_deref() {
                Some(n) => {
                    self.harness_layout = *self.pipeline_layouts.get(n).ok_or_else(|| {
                        HarnessError::NotRealised(format!(
                            "the pipeline's layout `{n}` is not in the state"
                        ))
                    })?;
                    harness_layout_key = layout_keys.get(n).cloned();
                }
                None => {
                    if !st.used_sets().is_empty()
                        || st.stages.iter().any(|s| s.push_constants.is_some())
                    {
                        return unsup("the state's shaders use sets or push constants but the pipeline names no layout");
                    }
                    let key = super::pipeline_layout_key(harness_set, &[], &[]);
                    match shared.pipeline_layouts.get(&key).filter(|_| share) {
                        Some(&h) => self.harness_layout = h,
                        None => {
                            let sl = [harness_set];
                            self.harness_layout = d
                                .create_pipeline_layout(
                                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&sl),
                                    None,
                                )
                                .map_err(vkfail("vkCreatePipelineLayout"))?;
                            if share {
                                shared
                                    .pipeline_layouts
                                    .insert(key.clone(), self.harness_layout);
                            } else {
                                self.own_harness_layout = true;
                            }
                        }
                    }
                    harness_layout_key = Some(key);
                }
            }
            self.make_images(dev, st)?;
            // Buffers and buffer views.
            let usage = vk::BufferUsageFlags::UNIFORM_BUFFER
                | vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                | vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER
                | if dev.has_feature("bufferDeviceAddress") {
                    vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
                } else {
                    vk::BufferUsageFlags::empty()
                };
            for b in &st.buffers {
                let a =
                    Allocation::new(dev, b.size.max(4), usage, vk::BufferCreateFlags::empty(), 1)?;
                self.buffers.insert(b.name.clone(), a);
            }
            for v in &st.buffer_views {
                let Some(b) = self.buffers.get(&v.buffer) else {
                    return unsup(format!(
                        "buffer view `{}` of buffer `{}`, which the state lacks",
                        v.name, v.buffer
                    ));
                };
                let info = vk::BufferViewCreateInfo::default()
                    .buffer(b.buffer)
                    .format(vk_format(&v.format)?)
                    .offset(0)
                    .range(vk::WHOLE_SIZE);
                let h = d
                    .create_buffer_view(&info, None)
                    .map_err(vkfail("vkCreateBufferView"))?;
                self.buffer_views.insert(v.name.clone(), h);
            }
            if by_buffer {
                self.write_descriptor_memory(dev, st, harness_set, api, usage, cache.cmds.fence)?;
            }
            // Descriptor pool and sets.
            let mut counts: HashMap<vk::DescriptorType, u32> = HashMap::new();
            for s in st.descriptor_sets.iter().filter(|_| !by_buffer) {
                let Some(l) = st.set_layout(&s.layout) else {
                    return unsup(format!(
                        "descriptor set `{}` has layout `{}`, which the state lacks",
                        s.name, s.layout
                    ));
                };
                for b in &l.bindings {
                    // A Y′CbCr combined image sampler may take one descriptor per plane (at most 3).
                    let ycbcr = b
                        .immutable_samplers
                        .iter()
                        .any(|n| self.ycbcr.of_sampler(n).is_some());
                    *counts.entry(descriptor_type(b.ty)?).or_default() +=
                        b.count * if ycbcr { 3 } else { 1 };
                }
            }
            if !st.descriptor_sets.is_empty() && !by_buffer {
                let sizes: Vec<vk::DescriptorPoolSize> = counts
                    .iter()
                    .map(|(t, n)| vk::DescriptorPoolSize {
                        ty: *t,
                        descriptor_count: (*n).max(1),
                    })
                    .collect();
                let sizes = if sizes.is_empty() {
                    vec![vk::DescriptorPoolSize {
                        ty: vk::DescriptorType::SAMPLER,
                        descriptor_count: 1,
                    }]
                } else {
                    sizes
                };
                self.pool = d
                    .create_descriptor_pool(
                        &vk::DescriptorPoolCreateInfo::default()
                            .max_sets(st.descriptor_sets.len() as u32)
                            .pool_sizes(&sizes),
                        None,
                    )
                    .map_err(vkfail("vkCreateDescriptorPool"))?;
            }
            for s in st.descriptor_sets.iter().filter(|_| !by_buffer) {
                let l = [self.set_layouts[&s.layout]];
                let h = d
                    .allocate_descriptor_sets(
                        &vk::DescriptorSetAllocateInfo::default()
                            .descriptor_pool(self.pool)
                            .set_layouts(&l),
                    )
                    .map_err(vkfail("vkAllocateDescriptorSets"))?[0];
                self.sets.insert(s.name.clone(), h);
            }
            // Writes, one vkUpdateDescriptorSets each; destroyed objects are made, written and destroyed.
            let mut doomed: Vec<Allocation> = Vec::new();
            for s in st.descriptor_sets.iter().filter(|_| !by_buffer) {
                let l = st.set_layout(&s.layout).expect("checked above");
                for w in &s.writes {
                    let Some(b) = l.binding(w.binding) else {
                        return unsup(format!(
                            "set `{}` writes binding {}, which its layout lacks",
                            s.name, w.binding
                        ));
                    };
                    if w.element >= b.count {
                        return unsup(format!(
                            "set `{}` writes element {} of binding {} (count {})",
                            s.name, w.element, w.binding, b.count
                        ));
                    }
                    let ty = descriptor_type(b.ty)?;
                    let base = vk::WriteDescriptorSet::default()
                        .dst_set(self.sets[&s.name])
                        .dst_binding(w.binding)
                        .dst_array_element(w.element)
                        .descriptor_type(ty);
                    let wrong = || {
                        HarnessError::NotRealised(format!("set `{}` binding {} ({:?}) is written with {:?}, which a write of that type cannot carry", s.name, w.binding, b.ty, w.descriptor))
                    };
                    match (&w.descriptor, b.ty) {
                        (
                            Descriptor::Image {
                                view,
                                sampler,
                                layout,
                            },
                            DescriptorType::CombinedImageSampler
                            | DescriptorType::SampledImage
                            | DescriptorType::StorageImage,
                        ) => {
                            let v = *self.views.get(view).ok_or_else(|| HarnessError::NotRealised(format!("descriptor names view `{view}`, which the state lacks (destroyed views are not realised)")))?;
                            let smp = match (b.ty, sampler) {
                                // The immutable sampler is used; the write's is ignored.
                                (DescriptorType::CombinedImageSampler, _) if !b.immutable_samplers.is_empty() => vk::Sampler::null(),
                                (DescriptorType::CombinedImageSampler, Some(n)) => *self.samplers.get(n).ok_or_else(|| HarnessError::NotRealised(format!("descriptor names sampler `{n}`, which the state lacks")))?,
                                (DescriptorType::CombinedImageSampler, None) => return unsup("a combined image sampler written without a sampler, at a binding with no immutable sampler"),
                                _ => vk::Sampler::null(),
                            };
                            let info = [vk::DescriptorImageInfo {
                                sampler: smp,
                                image_view: v,
                                image_layout: vk_layout(*layout)?,
                            }];
                            d.update_descriptor_sets(&[base.image_info(&info)], &[]);
                        }
                        // A binding of immutable samplers is never written (its samplers are the layout's).
                        (Descriptor::Sampler { .. }, DescriptorType::Sampler)
                            if !b.immutable_samplers.is_empty() => {}
                        (Descriptor::Sampler { sampler }, DescriptorType::Sampler) => {
                            let smp = *self.samplers.get(sampler).ok_or_else(|| {
                                HarnessError::NotRealised(format!(
                                    "descriptor names sampler `{sampler}`, which the state lacks"
                                ))
                            })?;
                            let info = [vk::DescriptorImageInfo {
                                sampler: smp,
                                ..Default::default()
                            }];
                            d.update_descriptor_sets(&[base.image_info(&info)], &[]);
                        }
                        (
                            Descriptor::TexelBuffer { view },
                            DescriptorType::UniformTexelBuffer | DescriptorType::StorageTexelBuffer,
                        ) => {
                            let v = [*self.buffer_views.get(view).ok_or_else(|| {
                                HarnessError::NotRealised(format!(
                                    "descriptor names buffer view `{view}`, which the state lacks"
                                ))
                            })?];
                            d.update_descriptor_sets(&[base.texel_buffer_view(&v)], &[]);
                        }
                        (
                            Descriptor::Buffer {
                                buffer,
                                offset,
                                range,
                            },
                            DescriptorType::UniformBuffer | DescriptorType::StorageBuffer,
                        ) => {
                            let buf = match self.buffers.get(buffer) {
                                Some(a) => a.buffer,
                                None => {
                                    // A buffer the state does not hold: destroyed after the write.
                                    let a = Allocation::new(
                                        dev,
                                        256,
                                        usage,
                                        vk::BufferCreateFlags::empty(),
                                        1,
                                    )?;
                                    let h = a.buffer;
                                    doomed.push(a);
                                    h
                                }
                            };
                            let info = [vk::DescriptorBufferInfo {
                                buffer: buf,
                                offset: *offset,
                                range: range.unwrap_or(vk::WHOLE_SIZE),
                            }];
                            d.update_descriptor_sets(&[base.buffer_info(&info)], &[]);
                        }
                        _ => return Err(wrong()),
                    }
                }
            }
            for a in doomed {
                a.destroy(dev);
            }
            // Binds and pushes, recorded by `record_binds`.
            let mut buffer_binds = Vec::new();
            for b in &st.bound_sets {
                let layout = *self.pipeline_layouts.get(&b.layout).ok_or_else(|| {
                    HarnessError::NotRealised(format!(
                        "a set is bound with layout `{}`, which the state lacks",
                        b.layout
                    ))
                })?;
                if by_buffer {
                    buffer_binds.push((layout, b.set + 1, b.descriptor_set.clone()));
                    continue;
                }
                let set = *self.sets.get(&b.descriptor_set).ok_or_else(|| {
                    HarnessError::NotRealised(format!(
                        "descriptor set `{}` is bound but the state lacks it",
                        b.descriptor_set
                    ))
                })?;
                self.binds.push((layout, b.set + 1, set));
            }
            if let Some(m) = self.descriptor_memory.as_mut() {
                m.add_binds(self.harness_layout, &buffer_binds)?;
            }
            for p in &st.pushes {
                let layout = *self.pipeline_layouts.get(&p.layout).ok_or_else(|| {
                    HarnessError::NotRealised(format!(
                        "constants are pushed with layout `{}`, which the state lacks",
                        p.layout
                    ))
                })?;
                self.pushes.push((layout, p.offset, p.size));
            }
        }
        // The pipeline with the templated stages (KHR or NV GLSL by the pipeline's API).
        let mut codes = Vec::with_capacity(sources.len());
        for (stage, glsl, narrow) in &sources {
            let mut code = compile_stage(glsl, *stage, trace, api, body)?;
            patch_narrow_writes(&mut code, narrow).map_err(|e| {
                HarnessError::Failed(format!(
                    "patching the {stage:?} shader's narrow writes: {e}"
                ))
            })?;
            codes.push((shader_kind(*stage, trace), code));
        }
        let Some(p) = world.pipeline.as_ref() else {
            return Ok(());
        };
        // A descriptor buffer pipeline is created with DESCRIPTOR_BUFFER_BIT_EXT, whatever its
        // descriptors come from.
        let mut p = p.clone();
        if st.pipeline_descriptor_buffer {
            p.flags.0 |= vk::PipelineCreateFlags::DESCRIPTOR_BUFFER_EXT.as_raw() as u64;
        }
        // Shared by content (with shared layouts only: the key names the layout by its content).
        let key = harness_layout_key
            .filter(|_| self.shared_layouts)
            .map(|layout| super::PipelineKey {
                description: serde_json::to_string(&p).unwrap_or_default(),
                trace,
                body,
                layout,
                modules: codes.clone(),
            });
        if let Some(rp) = key
            .as_ref()
            .and_then(|k| cache.shared_resources.pipelines.get(k))
        {
            cache.resource_pipeline = Some(rp.clone());
            self.shared_pipeline = true;
            return Ok(());
        }
        let rp = cache.create_pipeline_with(
            &p,
            trace,
            body,
            self.harness_layout,
            &codes,
            &mut self.modules,
        )?;
        if let Some(k) = key {
            cache.shared_resources.pipelines.insert(k, rp.clone());
            self.shared_pipeline = true;
        }
        cache.resource_pipeline = Some(rp);
        Ok(())
    }
}
