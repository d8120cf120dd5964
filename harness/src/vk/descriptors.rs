//! Descriptor writes the harness's own sets share: whole storage buffers and one acceleration
//! structure (KHR or NV) per binding; and VK_EXT_descriptor_buffer's entry points and descriptor sizes.

use ash::vk;

/// The whole of `buffer`, as a descriptor's buffer info.
pub(crate) fn whole(buffer: vk::Buffer) -> [vk::DescriptorBufferInfo; 1] {
    [vk::DescriptorBufferInfo {
        buffer,
        offset: 0,
        range: vk::WHOLE_SIZE,
    }]
}

/// A write of the storage buffer `info` at `binding` of `set`.
pub(crate) fn storage_write(
    set: vk::DescriptorSet,
    binding: u32,
    info: &[vk::DescriptorBufferInfo; 1],
) -> vk::WriteDescriptorSet<'_> {
    vk::WriteDescriptorSet::default()
        .dst_set(set)
        .dst_binding(binding)
        .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
        .buffer_info(info)
}

/// A write of one acceleration structure of descriptor type `ty` at `binding` of `set`; `structure` is
/// the KHR or NV extension structure naming it.
pub(crate) fn structure_write<'a, T: vk::ExtendsWriteDescriptorSet + ?Sized>(
    set: vk::DescriptorSet,
    binding: u32,
    ty: vk::DescriptorType,
    structure: &'a mut T,
) -> vk::WriteDescriptorSet<'a> {
    let mut w = vk::WriteDescriptorSet::default()
        .dst_set(set)
        .dst_binding(binding)
        .descriptor_type(ty)
        .push_next(structure);
    w.descriptor_count = 1;
    w
}

/// VK_EXT_descriptor_buffer on a device created with the `descriptorBuffer` feature: its commands and
/// the properties descriptor memory is laid out with.
pub(crate) struct DescriptorBufferDevice {
    pub(crate) ext: ash::ext::descriptor_buffer::Device,
    /// `descriptorBufferOffsetAlignment`: every set's offset in a descriptor buffer is a multiple of it.
    pub(crate) offset_alignment: u64,
    /// The size of one descriptor of each type, as `vkGetDescriptorEXT` writes it.
    sizes: Vec<(vk::DescriptorType, usize)>,
    /// `combinedImageSamplerDescriptorSingleArray`: when false, an array of combined image samplers
    /// is laid out as its image descriptors followed by its sampler descriptors.
    pub(crate) combined_single_array: bool,
}

impl DescriptorBufferDevice {
    /// The extension's entry points and properties on `device` of `physical`.
    pub(crate) fn new(
        instance: &ash::Instance,
        physical: vk::PhysicalDevice,
        device: &ash::Device,
    ) -> DescriptorBufferDevice {
        let mut props = vk::PhysicalDeviceDescriptorBufferPropertiesEXT::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut props);
        // SAFETY: the device exposes the extension (the caller enabled it), so the structure is known.
        unsafe { instance.get_physical_device_properties2(physical, &mut p2) };
        let sizes = vec![
            (vk::DescriptorType::SAMPLER, props.sampler_descriptor_size),
            (
                vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                props.combined_image_sampler_descriptor_size,
            ),
            (
                vk::DescriptorType::SAMPLED_IMAGE,
                props.sampled_image_descriptor_size,
            ),
            (
                vk::DescriptorType::STORAGE_IMAGE,
                props.storage_image_descriptor_size,
            ),
            (
                vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
                props.uniform_texel_buffer_descriptor_size,
            ),
            (
                vk::DescriptorType::STORAGE_TEXEL_BUFFER,
                props.storage_texel_buffer_descriptor_size,
            ),
            (
                vk::DescriptorType::UNIFORM_BUFFER,
                props.uniform_buffer_descriptor_size,
            ),
            (
                vk::DescriptorType::STORAGE_BUFFER,
                props.storage_buffer_descriptor_size,
            ),
            (
                vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                props.acceleration_structure_descriptor_size,
            ),
            (
                vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
                props.acceleration_structure_descriptor_size,
            ),
        ];
        DescriptorBufferDevice {
            ext: ash::ext::descriptor_buffer::Device::new(instance, device),
            offset_alignment: props.descriptor_buffer_offset_alignment.max(1),
            sizes,
            combined_single_array: props.combined_image_sampler_descriptor_single_array != 0,
        }
    }

    /// The size of one descriptor of type `ty` (0 for a type the extension gives no size).
    pub(crate) fn size(&self, ty: vk::DescriptorType) -> usize {
        self.sizes
            .iter()
            .find(|(t, _)| *t == ty)
            .map_or(0, |(_, s)| *s)
    }
}
