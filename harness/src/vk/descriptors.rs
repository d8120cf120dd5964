//! Descriptor writes the harness's own sets share: whole storage buffers and one acceleration
//! structure (KHR or NV) per binding.

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
