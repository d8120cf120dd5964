//! Descriptor memory (VK_EXT_descriptor_buffer) for a resource state whose descriptors come from
//! descriptor buffers: one host-visible buffer holding the harness's set and every case set at aligned
//! offsets, each descriptor written with `vkGetDescriptorEXT` from what the state's writes say, bound
//! with `vkCmdBindDescriptorBuffersEXT` and placed with `vkCmdSetDescriptorBufferOffsetsEXT`.
//!
//! Every set layout of such a state (the harness's included: a pipeline layout mixes no descriptor
//! buffer set layouts with others, VUID-VkPipelineLayoutCreateInfo-pSetLayouts-08008) is created with
//! `VK_DESCRIPTOR_SET_LAYOUT_CREATE_DESCRIPTOR_BUFFER_BIT_EXT`, so no descriptor set is allocated and the
//! harness's own set lives in the descriptor buffer too ([`DescriptorMemory::write_harness_set`]).

use super::*;
use crate::error::vkfail;
use crate::realise::Tlas;
use crate::vk::descriptors::DescriptorBufferDevice;
use crate::vk::VkDevice;

/// The harness's own set (binding 0 the scene when `trace`, 1 the records, 2 the rays, 3 the callable
/// indices, 4 the spheres) as a descriptor buffer set layout: the same bindings, types and stages as
/// `DeviceCache::layouts` gives them, so the harness's shaders read it unchanged.
pub(super) fn harness_set_layout(
    dev: &VkDevice,
    trace: bool,
    api: model::world::PipelineApi,
) -> Result<vk::DescriptorSetLayout, HarnessError> {
    let bindings = crate::realise::pipeline::harness_set_bindings(trace, api);
    // SAFETY: a valid create info on a device with the descriptorBuffer feature.
    unsafe {
        dev.device.create_descriptor_set_layout(
            &vk::DescriptorSetLayoutCreateInfo::default()
                .flags(vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT)
                .bindings(&bindings),
            None,
        )
    }
    .map_err(vkfail("vkCreateDescriptorSetLayout"))
}

fn structure_type(api: model::world::PipelineApi) -> vk::DescriptorType {
    match api {
        model::world::PipelineApi::Khr => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        model::world::PipelineApi::Nv => vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
    }
}

/// What one descriptor is made of, for `vkGetDescriptorEXT`.
pub(super) enum Source {
    Sampler(vk::Sampler),
    Image(vk::DescriptorImageInfo),
    /// A buffer range (uniform or storage buffer) or a texel buffer's range and format.
    Address {
        address: u64,
        range: u64,
        format: vk::Format,
    },
    Structure(u64),
}

/// The descriptor buffer of a state: where each set lives in it, and the binds recorded with it.
pub(super) struct DescriptorMemory {
    memory: Allocation,
    harness_layout: vk::DescriptorSetLayout,
    harness_offset: u64,
    sets: HashMap<String, (vk::DescriptorSetLayout, u64)>,
    /// `vkCmdSetDescriptorBufferOffsetsEXT` calls: layout, first set, one offset per set.
    binds: Vec<(vk::PipelineLayout, u32, Vec<u64>)>,
    api: model::world::PipelineApi,
}

impl DescriptorMemory {
    /// Lays out the harness's set (with `harness_layout`) and each of `sets` (name and descriptor
    /// buffer set layout) in one buffer: host-visible, or — when `resident` is false — a sparse
    /// buffer with no page bound (`fence` is the one sparse binding waits on), whose descriptors are
    /// never written.
    pub(super) fn new(
        dev: &VkDevice,
        harness_layout: vk::DescriptorSetLayout,
        sets: &[(String, vk::DescriptorSetLayout)],
        api: model::world::PipelineApi,
        resident: bool,
        fence: vk::Fence,
    ) -> Result<DescriptorMemory, HarnessError> {
        let db = db(dev)?;
        let align = db.offset_alignment;
        // SAFETY: the layouts were created with DESCRIPTOR_BUFFER_BIT_EXT on this device.
        let size_of = |l| unsafe { db.ext.get_descriptor_set_layout_size(l) };
        let mut at = size_of(harness_layout).div_ceil(align) * align;
        let mut placed = HashMap::new();
        for (name, l) in sets {
            placed.insert(name.clone(), (*l, at));
            at += size_of(*l).div_ceil(align) * align;
        }
        let usage = vk::BufferUsageFlags::RESOURCE_DESCRIPTOR_BUFFER_EXT
            | vk::BufferUsageFlags::SAMPLER_DESCRIPTOR_BUFFER_EXT
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let memory = if resident {
            let m = Allocation::new(
                dev,
                at.max(align),
                usage,
                vk::BufferCreateFlags::empty(),
                align,
            )?;
            m.write(0, &vec![0u8; at.max(align) as usize]);
            m
        } else {
            if !(dev.has_feature("sparseBinding") && dev.has_feature("sparseResidencyBuffer")) {
                return unsup("descriptor memory that is not resident is a sparse descriptor buffer with no page bound, which needs the sparseBinding and sparseResidencyBuffer features the case does not enable");
            }
            // No memory is bound, so no write lands: every descriptor, the harness's too, is in
            // memory that is not resident.
            Allocation::sparse(
                dev,
                fence,
                at.max(align),
                usage,
                vk::BufferCreateFlags::SPARSE_BINDING | vk::BufferCreateFlags::SPARSE_RESIDENCY,
                crate::vk::memory::SparsePlan::Unbound,
            )?
        };
        if memory.address % align != 0 {
            let at = memory.address;
            memory.destroy(dev);
            return unsup(format!(
                "the descriptor buffer was placed at {at:#x}, not a multiple of descriptorBufferOffsetAlignment ({align})"
            ));
        }
        Ok(DescriptorMemory {
            memory,
            harness_layout,
            harness_offset: 0,
            sets: placed,
            binds: Vec::new(),
            api,
        })
    }

    /// Writes the descriptor of `source` as type `ty` at `element` of `binding` (of type `slot`) in
    /// case set `set`.
    pub(super) fn write(
        &self,
        dev: &VkDevice,
        set: &str,
        binding: u32,
        element: u32,
        (ty, slot, count): (vk::DescriptorType, vk::DescriptorType, u32),
        source: &Source,
    ) -> Result<(), HarnessError> {
        let &(layout, base) = self.sets.get(set).ok_or_else(|| {
            HarnessError::NotRealised(format!("descriptor set `{set}` has no descriptor memory"))
        })?;
        write_at(
            dev,
            &self.memory,
            layout,
            base,
            binding,
            element,
            (ty, slot, count),
            source,
        )
    }

    /// Writes the harness's own set: the records, rays, callables and spheres buffers (binding 1–4, as
    /// device address and range) and the scene's top level, when traced.
    pub(crate) fn write_harness_set(
        &self,
        dev: &VkDevice,
        buffers: [(u64, u64); 4],
        tlas: Option<Tlas>,
    ) -> Result<(), HarnessError> {
        for (i, &(address, range)) in buffers.iter().enumerate() {
            let source = Source::Address {
                address,
                range,
                format: vk::Format::UNDEFINED,
            };
            write_at(
                dev,
                &self.memory,
                self.harness_layout,
                self.harness_offset,
                i as u32 + 1,
                0,
                (
                    vk::DescriptorType::STORAGE_BUFFER,
                    vk::DescriptorType::STORAGE_BUFFER,
                    1,
                ),
                &source,
            )?;
        }
        let structure = match tlas {
            None => return Ok(()),
            // SAFETY: a live structure of this device.
            Some(Tlas::Khr(t)) => unsafe {
                dev.accel
                    .as_ref()
                    .ok_or_else(|| {
                        HarnessError::NotRealised(
                            "a KHR scene without VK_KHR_acceleration_structure".into(),
                        )
                    })?
                    .get_acceleration_structure_device_address(
                        &vk::AccelerationStructureDeviceAddressInfoKHR::default()
                            .acceleration_structure(t),
                    )
            },
            // SAFETY: as above.
            Some(Tlas::Nv(t)) => unsafe {
                dev.nv
                    .as_ref()
                    .ok_or_else(|| {
                        HarnessError::NotRealised("an NV scene without VK_NV_ray_tracing".into())
                    })?
                    .get_acceleration_structure_handle(t)
                    .map_err(vkfail("vkGetAccelerationStructureHandleNV"))?
            },
        };
        write_at(
            dev,
            &self.memory,
            self.harness_layout,
            self.harness_offset,
            0,
            0,
            (structure_type(self.api), structure_type(self.api), 1),
            &Source::Structure(structure),
        )
    }

    /// Adds the binds of the state: the harness's set at set 0 with `harness_layout`, then each bound
    /// case set `n` at `n + 1` with its realised layout. A bind that starts at set 1 carries the
    /// harness's set with it (as set 0 of one call), so no call leaves a lower set unplaced.
    pub(super) fn add_binds(
        &mut self,
        harness_layout: vk::PipelineLayout,
        binds: &[(vk::PipelineLayout, u32, String)],
    ) -> Result<(), HarnessError> {
        let offset = |name: &str| {
            self.sets.get(name).map(|s| s.1).ok_or_else(|| {
                HarnessError::NotRealised(format!(
                    "descriptor set `{name}` has no descriptor memory"
                ))
            })
        };
        let mut calls = Vec::new();
        match binds.first() {
            Some((layout, 1, name)) => {
                calls.push((*layout, 0, vec![self.harness_offset, offset(name)?]))
            }
            _ => calls.push((harness_layout, 0, vec![self.harness_offset])),
        }
        for (i, (layout, set, name)) in binds.iter().enumerate() {
            if i == 0 && *set == 1 {
                continue;
            }
            calls.push((*layout, *set, vec![offset(name)?]));
        }
        self.binds = calls;
        Ok(())
    }

    /// Records the buffer's binding and the offsets of every bind.
    ///
    /// # Safety
    /// `cb` is recording on the device of this memory.
    pub(super) unsafe fn record(&self, dev: &VkDevice, cb: vk::CommandBuffer) {
        let Some(db) = dev.descriptor_buffer.as_ref() else {
            return;
        };
        let info = [vk::DescriptorBufferBindingInfoEXT::default()
            .address(self.memory.address)
            .usage(
                vk::BufferUsageFlags::RESOURCE_DESCRIPTOR_BUFFER_EXT
                    | vk::BufferUsageFlags::SAMPLER_DESCRIPTOR_BUFFER_EXT
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            )];
        db.ext.cmd_bind_descriptor_buffers(cb, &info);
        for (layout, first, offsets) in &self.binds {
            let indices = vec![0u32; offsets.len()];
            db.ext.cmd_set_descriptor_buffer_offsets(
                cb,
                vk::PipelineBindPoint::RAY_TRACING_KHR,
                *layout,
                *first,
                &indices,
                offsets,
            );
        }
    }

    /// Destroys the buffer (the harness's set layout is the owner's).
    pub(super) fn destroy(self, dev: &VkDevice) {
        self.memory.destroy(dev);
    }
}

fn db(dev: &VkDevice) -> Result<&DescriptorBufferDevice, HarnessError> {
    dev.descriptor_buffer.as_ref().ok_or_else(|| {
        HarnessError::NotRealised(
            "descriptor buffers are bound only on a device created with VK_EXT_descriptor_buffer and the \
             descriptorBuffer feature, which the case does not enable"
                .into(),
        )
    })
}

#[allow(clippy::too_many_arguments)]
fn write_at(
    dev: &VkDevice,
    memory: &Allocation,
    layout: vk::DescriptorSetLayout,
    base: u64,
    binding: u32,
    element: u32,
    (ty, slot, count): (vk::DescriptorType, vk::DescriptorType, u32),
    source: &Source,
) -> Result<(), HarnessError> {
    let db = db(dev)?;
    let (size, stride) = (db.size(ty), db.size(slot));
    if size == 0 || stride == 0 {
        return unsup(format!(
            "{ty:?} or {slot:?} descriptors have no size in descriptor memory"
        ));
    }
    if size > stride {
        return unsup(format!(
            "a {ty:?} descriptor ({size} bytes) written where a {slot:?} binding holds {stride} bytes would run into the next descriptor"
        ));
    }
    let address_info;
    let mut data = vk::DescriptorDataEXT::default();
    let image_info;
    let sampler;
    match (source, ty) {
        (Source::Sampler(s), vk::DescriptorType::SAMPLER) => {
            sampler = *s;
            data.p_sampler = &sampler;
        }
        (Source::Image(i), vk::DescriptorType::COMBINED_IMAGE_SAMPLER) => {
            image_info = *i;
            data.p_combined_image_sampler = &image_info;
        }
        (Source::Image(i), vk::DescriptorType::SAMPLED_IMAGE) => {
            image_info = *i;
            data.p_sampled_image = &image_info;
        }
        (Source::Image(i), vk::DescriptorType::STORAGE_IMAGE) => {
            image_info = *i;
            data.p_storage_image = &image_info;
        }
        (
            &Source::Address {
                address,
                range,
                format,
            },
            vk::DescriptorType::UNIFORM_BUFFER
            | vk::DescriptorType::STORAGE_BUFFER
            | vk::DescriptorType::UNIFORM_TEXEL_BUFFER
            | vk::DescriptorType::STORAGE_TEXEL_BUFFER,
        ) => {
            address_info = vk::DescriptorAddressInfoEXT::default()
                .address(address)
                .range(range)
                .format(format);
            let p: *const vk::DescriptorAddressInfoEXT = &address_info;
            match ty {
                vk::DescriptorType::UNIFORM_BUFFER => data.p_uniform_buffer = p,
                vk::DescriptorType::STORAGE_BUFFER => data.p_storage_buffer = p,
                vk::DescriptorType::UNIFORM_TEXEL_BUFFER => data.p_uniform_texel_buffer = p,
                _ => data.p_storage_texel_buffer = p,
            }
        }
        (&Source::Structure(a), _) => data.acceleration_structure = a,
        _ => {
            return unsup(format!(
                "a {ty:?} descriptor cannot be made of what the state writes there"
            ))
        }
    }
    let info = vk::DescriptorGetInfoEXT::default().ty(ty).data(data);
    let mut bytes = vec![0u8; size];
    // SAFETY: `info` points at locals that outlive the calls; the layout is a descriptor buffer layout.
    let offset = unsafe {
        db.ext.get_descriptor(&info, &mut bytes);
        db.ext
            .get_descriptor_set_layout_binding_offset(layout, binding)
    };
    let at = base + offset;
    if ty == vk::DescriptorType::COMBINED_IMAGE_SAMPLER && !db.combined_single_array {
        // The image parts of the whole array first, then its sampler parts.
        let image = db.size(vk::DescriptorType::SAMPLED_IMAGE).min(bytes.len());
        let sampler = bytes.len() - image;
        memory.write(at + element as u64 * image as u64, &bytes[..image]);
        memory.write(
            at + count as u64 * image as u64 + element as u64 * sampler as u64,
            &bytes[image..],
        );
    } else {
        memory.write(at + element as u64 * stride as u64, &bytes);
    }
    Ok(())
}

impl Realised {
    /// Writes every case set's descriptors into descriptor memory laid out for the state's sets (the
    /// descriptor buffer counterpart of the descriptor set writes): images and samplers by handle,
    /// buffers and texel buffers by device address, a buffer the state does not hold made, written and
    /// destroyed.
    pub(super) fn write_descriptor_memory(
        &mut self,
        dev: &VkDevice,
        st: &ResourceState,
        harness_layout: vk::DescriptorSetLayout,
        api: model::world::PipelineApi,
        usage: vk::BufferUsageFlags,
        fence: vk::Fence,
    ) -> Result<(), HarnessError> {
        let mut sets = Vec::new();
        for s in &st.descriptor_sets {
            let l = *self.set_layouts.get(&s.layout).ok_or_else(|| {
                HarnessError::NotRealised(format!(
                    "descriptor set `{}` has layout `{}`, which the state lacks",
                    s.name, s.layout
                ))
            })?;
            sets.push((s.name.clone(), l));
        }
        let resident = !st.descriptor_memory_not_resident;
        let memory = DescriptorMemory::new(dev, harness_layout, &sets, api, resident, fence)?;
        // The memory is owned from here on, so an error below still destroys it.
        self.descriptor_memory = Some(memory);
        let memory = self.descriptor_memory.as_ref().expect("set above");
        let mut doomed: Vec<Allocation> = Vec::new();
        let result = (|| {
            for s in &st.descriptor_sets {
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
                    let slot = objects::descriptor_type(b.ty)?;
                    // The type the descriptor is made as: the binding's, except a texel buffer view
                    // written at a buffer binding, whose memory then holds a texel buffer descriptor.
                    let mut ty = slot;
                    let source = match (&w.descriptor, b.ty) {
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
                            let v = *self.views.get(view).ok_or_else(|| {
                                HarnessError::NotRealised(format!(
                                    "descriptor names view `{view}`, which the state lacks (destroyed views are not realised)"
                                ))
                            })?;
                            let smp = match (b.ty, sampler) {
                                (DescriptorType::CombinedImageSampler, Some(n)) => {
                                    *self.samplers.get(n).ok_or_else(|| {
                                        HarnessError::NotRealised(format!(
                                            "descriptor names sampler `{n}`, which the state lacks"
                                        ))
                                    })?
                                }
                                (DescriptorType::CombinedImageSampler, None) => {
                                    return unsup("a combined image sampler written without a sampler (immutable samplers are not modelled)")
                                }
                                _ => vk::Sampler::null(),
                            };
                            Source::Image(vk::DescriptorImageInfo {
                                sampler: smp,
                                image_view: v,
                                image_layout: objects::vk_layout(*layout)?,
                            })
                        }
                        (Descriptor::Sampler { sampler }, DescriptorType::Sampler) => {
                            Source::Sampler(*self.samplers.get(sampler).ok_or_else(|| {
                                HarnessError::NotRealised(format!(
                                    "descriptor names sampler `{sampler}`, which the state lacks"
                                ))
                            })?)
                        }
                        (
                            Descriptor::TexelBuffer { view },
                            DescriptorType::UniformTexelBuffer
                            | DescriptorType::StorageTexelBuffer
                            | DescriptorType::UniformBuffer
                            | DescriptorType::StorageBuffer,
                        ) => {
                            ty = match b.ty {
                                DescriptorType::UniformBuffer => {
                                    vk::DescriptorType::UNIFORM_TEXEL_BUFFER
                                }
                                DescriptorType::StorageBuffer => {
                                    vk::DescriptorType::STORAGE_TEXEL_BUFFER
                                }
                                _ => slot,
                            };
                            let bv = st.buffer_view(view).ok_or_else(|| {
                                HarnessError::NotRealised(format!(
                                    "descriptor names buffer view `{view}`, which the state lacks"
                                ))
                            })?;
                            let a = self.buffers.get(&bv.buffer).ok_or_else(|| {
                                HarnessError::NotRealised(format!(
                                    "buffer view `{view}` of buffer `{}`, which the state lacks",
                                    bv.buffer
                                ))
                            })?;
                            Source::Address {
                                address: a.address,
                                range: a.size,
                                format: objects::vk_format(&bv.format)?,
                            }
                        }
                        (
                            Descriptor::Buffer {
                                buffer,
                                offset,
                                range,
                            },
                            DescriptorType::UniformBuffer | DescriptorType::StorageBuffer,
                        ) => {
                            let (address, size) = match self.buffers.get(buffer) {
                                Some(a) => (a.address, a.size),
                                None => {
                                    // A buffer the state does not hold: destroyed after the write.
                                    let a = Allocation::new(
                                        dev,
                                        256,
                                        usage,
                                        vk::BufferCreateFlags::empty(),
                                        1,
                                    )?;
                                    let r = (a.address, a.size);
                                    doomed.push(a);
                                    r
                                }
                            };
                            Source::Address {
                                address: address + offset,
                                range: range.unwrap_or(size.saturating_sub(*offset)),
                                format: vk::Format::UNDEFINED,
                            }
                        }
                        _ => {
                            return unsup(format!(
                                "set `{}` binding {} ({:?}) is written with {:?}, which a descriptor of that type cannot carry",
                                s.name, w.binding, b.ty, w.descriptor
                            ))
                        }
                    };
                    memory.write(
                        dev,
                        &s.name,
                        w.binding,
                        w.element,
                        (ty, slot, b.count),
                        &source,
                    )?;
                }
            }
            Ok(())
        })();
        for a in doomed {
            a.destroy(dev);
        }
        result
    }
}
