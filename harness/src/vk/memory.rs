//! Buffer memory: host-visible allocations mapped for the harness's writes and reads, placed at a
//! requested address alignment, and sparse buffers bound whole, in two pieces, or not at all.

use crate::error::{vkfail, HarnessError};
use crate::vk::VkDevice;
use ash::vk;
use model::call::BUFFER_PLACEMENT_ALIGNMENT;

/// One memory object behind (part of) a buffer: where it sits in the buffer and its host mapping.
struct Piece {
    memory: vk::DeviceMemory,
    /// Byte offset in the buffer where this memory's range starts.
    at: u64,
    /// Bytes of the buffer backed by this memory.
    len: u64,
    /// Host pointer to the buffer byte `at`.
    ptr: *mut u8,
}

/// A buffer with host-visible memory, mapped, and its device address (0 without bufferDeviceAddress). Most
/// buffers have one memory object; a sparse buffer of a `Scattered` case has two, and an `Unbound` sparse
/// buffer none. Memory that is not HOST_COHERENT is flushed after host writes and invalidated before reads.
pub(crate) struct Allocation {
    pub(crate) buffer: vk::Buffer,
    pub(crate) address: u64,
    pub(crate) size: u64,
    /// The usage it was made with (its device address is asked for only with SHADER_DEVICE_ADDRESS).
    usage: vk::BufferUsageFlags,
    /// The create flags it was made with.
    flags: vk::BufferCreateFlags,
    pieces: Vec<Piece>,
    /// The device, kept only when the memory is not HOST_COHERENT (to flush and invalidate).
    non_coherent: Option<ash::Device>,
}

/// How a buffer's pages are bound, for [`Allocation::sparse`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SparsePlan {
    /// No memory bound at all.
    Unbound,
    /// The whole buffer bound to one memory object.
    One,
    /// The first half of the sparse blocks bound to one memory object, the rest to a second.
    Two,
}

/// A host-visible memory type for `bits`: coherent if there is one, else any host-visible type (flushed).
fn host_memory_type(dev: &VkDevice, bits: u32) -> Option<(u32, bool)> {
    let visible = vk::MemoryPropertyFlags::HOST_VISIBLE;
    dev.memory_type(bits, visible | vk::MemoryPropertyFlags::HOST_COHERENT)
        .map(|t| (t, true))
        .or_else(|| dev.memory_type(bits, visible).map(|t| (t, false)))
}

fn allocate(dev: &VkDevice, size: u64, memory_type: u32) -> Result<vk::DeviceMemory, HarnessError> {
    let mut flags_info =
        vk::MemoryAllocateFlagsInfo::default().flags(vk::MemoryAllocateFlags::DEVICE_ADDRESS);
    let mut ai = vk::MemoryAllocateInfo::default()
        .allocation_size(size)
        .memory_type_index(memory_type);
    if dev.has_feature("bufferDeviceAddress") {
        ai = ai.push_next(&mut flags_info);
    }
    // SAFETY: valid allocate info.
    unsafe { dev.device.allocate_memory(&ai, None) }.map_err(|r| {
        match crate::error::oom_or(format!("vkAllocateMemory({size})"), r) {
            e @ HarnessError::OutOfMemory(_) => e,
            _ => HarnessError::Failed(format!("vkAllocateMemory({size}) failed: {r:?}")),
        }
    })
}

/// The buffer's device address, or 0 where it has none: the device lacks bufferDeviceAddress, or the
/// buffer was made without SHADER_DEVICE_ADDRESS usage (asking would itself be invalid,
/// VUID-VkBufferDeviceAddressInfo-buffer-02601).
fn address_of(dev: &VkDevice, b: vk::Buffer, usage: vk::BufferUsageFlags) -> u64 {
    if dev.has_feature("bufferDeviceAddress")
        && usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS)
    {
        // SAFETY: b is bound completely to memory allocated with DEVICE_ADDRESS, or sparse
        // (VUID-VkBufferDeviceAddressInfo-buffer-02600 exempts sparse buffers).
        unsafe {
            dev.device
                .get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(b))
        }
    } else {
        0
    }
}

/// A buffer of `size` bytes (at least 1) with no memory bound yet.
pub(crate) fn create_buffer(
    dev: &VkDevice,
    size: u64,
    usage: vk::BufferUsageFlags,
    flags: vk::BufferCreateFlags,
) -> Result<vk::Buffer, HarnessError> {
    let info = vk::BufferCreateInfo::default()
        .size(size.max(1))
        .usage(usage)
        .flags(flags);
    // SAFETY: valid create info.
    unsafe { dev.device.create_buffer(&info, None) }
        .map_err(|r| crate::error::oom_or(format!("vkCreateBuffer({size} bytes)"), r))
}

impl Allocation {
    /// A buffer holding `bytes` (at least `min` bytes long) at an address that is a multiple of `align`.
    pub(crate) fn filled(
        dev: &VkDevice,
        bytes: &[u8],
        min: u64,
        usage: vk::BufferUsageFlags,
        align: u64,
    ) -> Result<Allocation, HarnessError> {
        let a = Allocation::new(
            dev,
            (bytes.len() as u64).max(min),
            usage,
            vk::BufferCreateFlags::empty(),
            align,
        )?;
        a.write(0, bytes);
        Ok(a)
    }

    /// Creates a buffer of `size` bytes, binds it to its own host-visible memory at an address that is a
    /// multiple of `align` (when `align` > 1), and maps it.
    pub(crate) fn new(
        dev: &VkDevice,
        size: u64,
        usage: vk::BufferUsageFlags,
        flags: vk::BufferCreateFlags,
        align: u64,
    ) -> Result<Allocation, HarnessError> {
        let d = &dev.device;
        let mut buffer = create_buffer(dev, size, usage, flags)?;
        // SAFETY: buffer is valid.
        let req = unsafe { d.get_buffer_memory_requirements(buffer) };
        let Some((mt, coherent)) = host_memory_type(dev, req.memory_type_bits) else {
            // SAFETY: destroying what we created.
            unsafe { d.destroy_buffer(buffer, None) };
            return Err(HarnessError::NotRealised(
                "no host-visible memory type for a buffer".into(),
            ));
        };
        let bda = dev.has_feature("bufferDeviceAddress");
        let alloc_size = req.size + if align > 1 { align } else { 0 };
        let memory = match allocate(dev, alloc_size, mt) {
            Ok(m) => m,
            Err(e) => {
                // SAFETY: destroying what we created.
                unsafe { d.destroy_buffer(buffer, None) };
                return Err(e);
            }
        };
        let cleanup = |buffer: vk::Buffer| {
            // SAFETY: destroying what we created.
            unsafe {
                d.destroy_buffer(buffer, None);
                d.free_memory(memory, None);
            }
        };
        // SAFETY: fresh buffer, fresh memory large enough.
        if let Err(r) = unsafe { d.bind_buffer_memory(buffer, memory, 0) } {
            cleanup(buffer);
            return Err(HarnessError::Failed(format!(
                "vkBindBufferMemory failed: {r:?}"
            )));
        }
        let mut address = address_of(dev, buffer, usage);
        let mut offset = 0;
        if bda && align > 1 && address % align != 0 {
            let delta = align - address % align;
            if delta % req.alignment.max(1) != 0 {
                cleanup(buffer);
                return Err(HarnessError::NotRealised(format!(
                    "cannot place a buffer at a {align}-aligned device address (memory at {address:#x}, alignment {})",
                    req.alignment
                )));
            }
            // SAFETY: replacing the buffer by an identical one bound at the aligning offset.
            unsafe { d.destroy_buffer(buffer, None) };
            buffer = match create_buffer(dev, size, usage, flags) {
                Ok(b) => b,
                Err(e) => {
                    // SAFETY: freeing what we allocated.
                    unsafe { d.free_memory(memory, None) };
                    return Err(e);
                }
            };
            // SAFETY: offset + size fits the allocation.
            if let Err(r) = unsafe { d.bind_buffer_memory(buffer, memory, delta) } {
                cleanup(buffer);
                return Err(HarnessError::Failed(format!(
                    "vkBindBufferMemory failed: {r:?}"
                )));
            }
            offset = delta;
            address = address_of(dev, buffer, usage);
            if address % align != 0 {
                cleanup(buffer);
                return Err(HarnessError::NotRealised(format!(
                    "the driver placed a buffer at {address:#x}, not a multiple of {align}"
                )));
            }
        }
        // SAFETY: host-visible memory, whole range.
        let ptr =
            match unsafe { d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()) } {
                Ok(p) => p as *mut u8,
                Err(r) => {
                    cleanup(buffer);
                    return Err(HarnessError::Failed(format!("vkMapMemory failed: {r:?}")));
                }
            };
        // SAFETY: mapped range covers offset..offset+size.
        let ptr = unsafe { ptr.add(offset as usize) };
        let a = Allocation {
            buffer,
            address,
            size,
            usage,
            flags,
            pieces: vec![Piece {
                memory,
                at: 0,
                len: size,
                ptr,
            }],
            non_coherent: (!coherent).then(|| d.clone()),
        };
        a.zero();
        Ok(a)
    }

    /// Creates a sparse buffer (`flags` has SPARSE_BINDING) and binds its pages with `vkQueueBindSparse` as
    /// `plan` says, waiting on `fence` (unsignalled, left unsignalled) for the binding to finish.
    pub(crate) fn sparse(
        dev: &VkDevice,
        fence: vk::Fence,
        size: u64,
        usage: vk::BufferUsageFlags,
        flags: vk::BufferCreateFlags,
        plan: SparsePlan,
    ) -> Result<Allocation, HarnessError> {
        // The caller checked that sparseBinding is enabled.
        let buffer = create_buffer(dev, size, usage, flags)?;
        let mut a = Allocation {
            buffer,
            address: 0,
            size,
            usage,
            flags,
            pieces: Vec::new(),
            non_coherent: None,
        };
        match a.bind_sparse(dev, fence, plan) {
            Ok(()) => Ok(a),
            Err(e) => {
                a.destroy(dev);
                Err(e)
            }
        }
    }

    fn bind_sparse(
        &mut self,
        dev: &VkDevice,
        fence: vk::Fence,
        plan: SparsePlan,
    ) -> Result<(), HarnessError> {
        let d = &dev.device;
        // SAFETY: valid buffer.
        let req = unsafe { d.get_buffer_memory_requirements(self.buffer) };
        let block = req.alignment.max(1);
        let blocks = req.size.div_ceil(block);
        let ranges: Vec<(u64, u64)> = match plan {
            SparsePlan::Unbound => vec![],
            SparsePlan::One => vec![(0, blocks * block)],
            SparsePlan::Two if blocks < 2 => {
                return Err(HarnessError::NotRealised(format!(
                    "a sparse buffer of {} bytes is one sparse block ({block} bytes) here, so its pages cannot be \
                     scattered over two memory objects",
                    self.size
                )))
            }
            SparsePlan::Two => vec![(0, blocks / 2 * block), (blocks / 2 * block, (blocks - blocks / 2) * block)],
        };
        if !ranges.is_empty() {
            let Some((mt, coherent)) = host_memory_type(dev, req.memory_type_bits) else {
                return Err(HarnessError::NotRealised(
                    "no host-visible memory type for a sparse buffer (the harness writes its contents from the host)".into(),
                ));
            };
            if !coherent {
                self.non_coherent = Some(d.clone());
            }
            for &(at, len) in &ranges {
                let memory = allocate(dev, len, mt)?;
                // SAFETY: host-visible memory, whole range.
                let ptr = match unsafe {
                    d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
                } {
                    Ok(p) => p as *mut u8,
                    Err(r) => {
                        // SAFETY: freeing what we allocated.
                        unsafe { d.free_memory(memory, None) };
                        return Err(HarnessError::Failed(format!("vkMapMemory failed: {r:?}")));
                    }
                };
                self.pieces.push(Piece {
                    memory,
                    at,
                    len,
                    ptr,
                });
            }
            let binds: Vec<vk::SparseMemoryBind> = self
                .pieces
                .iter()
                .map(|p| vk::SparseMemoryBind {
                    resource_offset: p.at,
                    size: p.len,
                    memory: p.memory,
                    memory_offset: 0,
                    flags: Default::default(),
                })
                .collect();
            let buffer_binds = [vk::SparseBufferMemoryBindInfo::default()
                .buffer(self.buffer)
                .binds(&binds)];
            let bind = [vk::BindSparseInfo::default().buffer_binds(&buffer_binds)];
            // SAFETY: the queue's family has SPARSE_BINDING (checked by the caller); the fence is unsignalled.
            unsafe {
                d.queue_bind_sparse(dev.queue, &bind, fence)
                    .map_err(vkfail("vkQueueBindSparse"))?;
                d.wait_for_fences(&[fence], true, 10_000_000_000)
                    .map_err(vkfail("vkWaitForFences (sparse binding)"))?;
                d.reset_fences(&[fence]).map_err(vkfail("vkResetFences"))?;
            }
            self.zero();
        }
        self.address = address_of(dev, self.buffer, self.usage);
        if dev.has_feature("bufferDeviceAddress") && self.address % BUFFER_PLACEMENT_ALIGNMENT != 0
        {
            return Err(HarnessError::NotRealised(format!(
                "the driver placed a sparse buffer at {:#x}, not a multiple of {BUFFER_PLACEMENT_ALIGNMENT}",
                self.address
            )));
        }
        Ok(())
    }

    /// The memory objects behind the buffer (one, two for a scattered sparse buffer, none when unbound).
    pub(crate) fn memory_count(&self) -> usize {
        self.pieces.len()
    }

    /// Whether this is a buffer of `size` bytes made with `usage` and `flags`, bound whole to one memory
    /// object of its own (what [`Allocation::new`] makes): one that may stand in for a fresh one of those.
    pub(crate) fn made_as(
        &self,
        size: u64,
        usage: vk::BufferUsageFlags,
        flags: vk::BufferCreateFlags,
    ) -> bool {
        self.size == size && self.usage == usage && self.flags == flags && self.whole_bound()
    }

    /// Whether the buffer is bound whole to one memory object of its own (not sparse).
    pub(crate) fn whole_bound(&self) -> bool {
        self.pieces.len() == 1 && !self.flags.contains(vk::BufferCreateFlags::SPARSE_BINDING)
    }

    /// Sets every bound byte of the buffer to zero (what a fresh allocation holds).
    pub(crate) fn zero(&self) {
        for p in &self.pieces {
            let n = p.len.min(self.size.saturating_sub(p.at));
            // SAFETY: the piece's mapped range is `len` bytes from `ptr`, and n <= len.
            unsafe { std::ptr::write_bytes(p.ptr, 0, n as usize) };
        }
        self.sync(true);
    }

    /// Copies `bytes` to `offset`, cutting what would fall past the end of the buffer or onto unbound pages.
    pub(crate) fn write(&self, offset: u64, bytes: &[u8]) {
        self.copy_in(offset, bytes);
        self.sync(true);
    }

    /// Writes `pattern` `count` times from `offset` on (clipped to the allocation like
    /// [`Allocation::write`]), through a buffer of at most 64 KiB instead of the whole repetition.
    pub(crate) fn write_repeated(&self, offset: u64, pattern: &[u8], count: usize) {
        if pattern.is_empty() || count == 0 {
            return;
        }
        let per_chunk = ((64 << 10) / pattern.len()).clamp(1, count);
        let chunk = pattern.repeat(per_chunk);
        let mut at = offset;
        let mut left = count;
        while left > 0 && at < self.size {
            let n = left.min(per_chunk);
            self.copy_in(at, &chunk[..n * pattern.len()]);
            at = at.saturating_add((n * pattern.len()) as u64);
            left -= n;
        }
        self.sync(true);
    }

    /// Copies `bytes` to `offset` (clipped to the allocation) without flushing.
    fn copy_in(&self, offset: u64, bytes: &[u8]) {
        let end = offset.saturating_add(bytes.len() as u64).min(self.size);
        for p in &self.pieces {
            let (lo, hi) = (offset.max(p.at), end.min(p.at + p.len));
            if lo >= hi {
                continue;
            }
            // SAFETY: lo..hi lies inside this piece's mapped range.
            unsafe {
                std::ptr::copy_nonoverlapping(
                    bytes.as_ptr().add((lo - offset) as usize),
                    p.ptr.add((lo - p.at) as usize),
                    (hi - lo) as usize,
                )
            };
        }
    }

    pub(crate) fn read_u32s(&self, count: usize) -> Vec<u32> {
        self.sync(false);
        let n = count.min((self.size / 4) as usize);
        // The words are copied as bytes straight into their vector (host byte order, as the device
        // wrote them).
        let mut words = vec![0u32; n];
        let len = (n * 4) as u64;
        for p in &self.pieces {
            let (lo, hi) = (p.at.min(len), (p.at + p.len).min(len));
            if lo < hi {
                // SAFETY: lo..hi lies inside this piece's mapped range and inside `words`' n * 4 bytes.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        p.ptr,
                        words.as_mut_ptr().cast::<u8>().add(lo as usize),
                        (hi - lo) as usize,
                    )
                };
            }
        }
        words
    }

    /// Flushes host writes (`to_device`) or invalidates host caches before reading, on non-coherent memory.
    fn sync(&self, to_device: bool) {
        let Some(d) = &self.non_coherent else { return };
        let ranges: Vec<vk::MappedMemoryRange> = self
            .pieces
            .iter()
            .map(|p| {
                vk::MappedMemoryRange::default()
                    .memory(p.memory)
                    .offset(0)
                    .size(vk::WHOLE_SIZE)
            })
            .collect();
        // SAFETY: every memory object is mapped whole; WHOLE_SIZE from offset 0 needs no atom alignment.
        unsafe {
            let _ = if to_device {
                d.flush_mapped_memory_ranges(&ranges)
            } else {
                d.invalidate_mapped_memory_ranges(&ranges)
            };
        }
    }

    pub(crate) fn destroy(self, dev: &VkDevice) {
        // SAFETY: the GPU no longer uses the buffer (callers wait first, or the device is lost).
        unsafe {
            dev.device.destroy_buffer(self.buffer, None);
            for p in &self.pieces {
                dev.device.unmap_memory(p.memory);
                dev.device.free_memory(p.memory, None);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vk::plain_lavapipe_device;

    /// A pattern written repeatedly reads back as the whole repetition, across the 64 KiB pieces it is
    /// written in, and a repetition longer than the allocation is cut at its end (lavapipe).
    #[test]
    fn a_pattern_written_repeatedly_reads_back_whole_and_cut_at_the_end() {
        // Vulkan called directly, as the executor does, in the process's turn.
        let _turn = crate::vk::turn::take();
        let dev = plain_lavapipe_device();
        let pattern: Vec<u8> = (0u8..112)
            .map(|b| b.wrapping_mul(7).wrapping_add(3))
            .collect();
        // 1,500 copies: 168,000 bytes, three pieces of at most 64 KiB.
        let count = 1500;
        let size = (pattern.len() * count) as u64;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let whole = Allocation::new(&dev, size, usage, vk::BufferCreateFlags::empty(), 1).unwrap();
        whole.write(0, &vec![0u8; size as usize]);
        whole.write_repeated(0, &pattern, count);
        let words = whole.read_u32s((size / 4) as usize);
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        assert_eq!(bytes, pattern.repeat(count));
        whole.destroy(&dev);
        // Half the size: the writes stop at the end, and what is there is the repetition's start.
        let half =
            Allocation::new(&dev, size / 2, usage, vk::BufferCreateFlags::empty(), 1).unwrap();
        half.write_repeated(0, &pattern, count);
        let words = half.read_u32s((size / 8) as usize);
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        assert_eq!(bytes[..], pattern.repeat(count)[..bytes.len()]);
        half.destroy(&dev);
    }
}
