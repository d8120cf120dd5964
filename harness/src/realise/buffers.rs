//! A trace world's buffers on the device, from their plan ([`BufferPlan`]): placed at 4096-aligned
//! addresses, bound as the world says (whole, sparse in pieces, or not at all), with their writes
//! made (shader group handles of the bound or a foreign pipeline, indirect commands). A finished
//! case's whole-bound buffers are kept ([`SpareBuffers`]) for later cases that ask for the same kind.

use super::DeviceCache;
use crate::error::HarnessError;
use crate::plan::trace::{BufferPlan, BufferWrite};
use crate::shaders::ShaderBody;
use crate::vk::memory::{Allocation, SparsePlan};
use ash::vk;
use model::call::BUFFER_PLACEMENT_ALIGNMENT;
use model::world::{HandleRef, Pipeline, PipelineApi};

/// Case buffers a finished case gave back, kept (mapped, bound to their own memory, placed at
/// [`BUFFER_PLACEMENT_ALIGNMENT`] as every case buffer is) for a later case of the same device that
/// asks for a buffer of the same size, usage and create flags: taken
/// instead of a fresh buffer, memory and binding, and zeroed first, so the case sees what a fresh
/// allocation holds. Only whole-bound buffers of at most [`SpareBuffers::LARGEST`] bytes are kept,
/// at most [`SpareBuffers::COUNT`] of them; the others are destroyed when given back.
#[derive(Default)]
pub(crate) struct SpareBuffers {
    kept: Vec<Allocation>,
}

impl SpareBuffers {
    /// The largest buffer kept (zeroing it on reuse stays far cheaper than a fresh one).
    const LARGEST: u64 = 1 << 20;
    /// The most buffers kept.
    const COUNT: usize = 32;

    /// A kept buffer made as asked, zeroed, or None.
    fn take(
        &mut self,
        size: u64,
        usage: vk::BufferUsageFlags,
        flags: vk::BufferCreateFlags,
    ) -> Option<Allocation> {
        let at = self
            .kept
            .iter()
            .position(|a| a.made_as(size, usage, flags))?;
        let a = self.kept.swap_remove(at);
        a.zero();
        Some(a)
    }

    /// Keeps `a` for a later case, or destroys it. The GPU no longer uses it.
    pub(crate) fn give_back(&mut self, a: Allocation, dev: &crate::vk::VkDevice) {
        let keep = self.kept.len() < Self::COUNT && a.size <= Self::LARGEST && a.whole_bound();
        if keep {
            self.kept.push(a);
        } else {
            a.destroy(dev);
        }
    }

    /// Destroys every kept buffer.
    pub(crate) fn destroy(&mut self, dev: &crate::vk::VkDevice) {
        for a in self.kept.drain(..) {
            a.destroy(dev);
        }
    }
}

impl DeviceCache {
    /// Why a sparse buffer cannot be made validly here, if it cannot: the features its flags need must be
    /// enabled (VUID-VkBufferCreateInfo-flags-00915/00916/00917) and the harness's queue must bind sparse.
    fn check_sparse(&self, b: &BufferPlan) -> Result<(), HarnessError> {
        use model::flags::BufferCreate;
        let flags = BufferCreate(b.flags as u64);
        let needs = [
            (
                BufferCreate::SPARSE_BINDING_BIT,
                "sparseBinding",
                "VUID-VkBufferCreateInfo-flags-00915",
            ),
            (
                BufferCreate::SPARSE_RESIDENCY_BIT,
                "sparseResidencyBuffer",
                "VUID-VkBufferCreateInfo-flags-00916",
            ),
            (
                BufferCreate::SPARSE_ALIASED_BIT,
                "sparseResidencyAliased",
                "VUID-VkBufferCreateInfo-flags-00917",
            ),
        ];
        for (flag, feature, vuid) in needs {
            if flags.contains(flag) && !self.dev.has_feature(feature) {
                return Err(HarnessError::NotRealised(format!(
                    "buffer `{}` is sparse but the case does not enable {feature}, so creating it is invalid ({vuid})",
                    b.name
                )));
            }
        }
        if !flags.contains(BufferCreate::SPARSE_BINDING_BIT) {
            return Err(HarnessError::NotRealised(format!(
                "buffer `{}` has sparse residency/aliasing flags without SPARSE_BINDING (VUID-VkBufferCreateInfo-flags-00918)",
                b.name
            )));
        }
        if !self.dev.sparse_binding {
            return Err(HarnessError::NotRealised(format!(
                "buffer `{}` is sparse but the device lacks sparseBinding or its compute queue family has no \
                 VK_QUEUE_SPARSE_BINDING_BIT, so vkQueueBindSparse cannot bind it",
                b.name
            )));
        }
        Ok(())
    }
}

impl DeviceCache {
    /// Creates the case's buffers with their contents; returns them by name.
    pub(crate) fn case_buffers(
        &mut self,
        buffers: &[BufferPlan],
        pipeline: Option<(&Pipeline, bool, ShaderBody)>,
    ) -> Result<Vec<(String, Allocation)>, HarnessError> {
        let mut out: Vec<(String, Allocation)> = Vec::new();
        let r = self.case_buffers_into(buffers, pipeline, &mut out);
        if let Err(e) = r {
            self.give_back_case_buffers(out);
            return Err(e);
        }
        Ok(out)
    }

    /// Gives a case's buffers back once the GPU no longer uses them: kept for later cases where they
    /// may be ([`SpareBuffers`]), else destroyed.
    pub(crate) fn give_back_case_buffers(&mut self, buffers: Vec<(String, Allocation)>) {
        for (_, a) in buffers {
            self.spare.give_back(a, &self.dev);
        }
    }

    fn case_buffers_into(
        &mut self,
        buffers: &[BufferPlan],
        pipeline: Option<(&Pipeline, bool, ShaderBody)>,
        out: &mut Vec<(String, Allocation)>,
    ) -> Result<(), HarnessError> {
        use model::world::MemoryBinding;
        let hs = match pipeline {
            Some((p, _, _)) if p.api == PipelineApi::Nv => self.dev.limits.nv_handle_size,
            _ => self.dev.limits.handle_size,
        } as usize;
        let needs_foreign = buffers.iter().any(|b| {
            b.writes.iter().any(|w| {
                matches!(
                    w,
                    BufferWrite::Handle {
                        handle: HandleRef::Foreign(_),
                        ..
                    }
                )
            })
        });
        let own: Vec<u8> = match pipeline {
            Some((p, trace, body)) => self.pipeline(p, trace, body, false)?.handles.clone(),
            None => Vec::new(),
        };
        let foreign: Vec<u8> = match (pipeline, needs_foreign) {
            (Some((p, trace, body)), true) => self.pipeline(p, trace, body, true)?.handles.clone(),
            (None, true) => {
                return Err(HarnessError::NotRealised(
                    "foreign handles need a pipeline description to copy".into(),
                ))
            }
            _ => Vec::new(),
        };
        // KHR calls name buffers by device address; vkCmdTraceRaysNV names them by handle and needs none.
        let wants_address = pipeline.is_none_or(|(p, _, _)| p.api == PipelineApi::Khr);
        if !self.dev.has_feature("bufferDeviceAddress") && wants_address && !buffers.is_empty() {
            return Err(HarnessError::NotRealised(
                "the case does not enable bufferDeviceAddress, so the harness cannot give its buffers addresses".into(),
            ));
        }
        for b in buffers {
            let usage = vk::BufferUsageFlags::from_raw(b.usage);
            let flags = vk::BufferCreateFlags::from_raw(b.flags);
            if b.size == 0 {
                return Err(HarnessError::NotRealised(format!(
                    "buffer `{}` has size 0, which cannot be created",
                    b.name
                )));
            }
            let a = if b.sparse {
                let plan = match b.memory {
                    MemoryBinding::Whole => SparsePlan::One,
                    MemoryBinding::Unbound => SparsePlan::Unbound,
                    MemoryBinding::Scattered => SparsePlan::Two,
                };
                self.check_sparse(b)?;
                Allocation::sparse(&self.dev, self.cmds.fence, b.size, usage, flags, plan)?
            } else {
                match b.memory {
                    MemoryBinding::Whole => {}
                    MemoryBinding::Unbound => {
                        return Err(HarnessError::NotRealised(format!(
                            "buffer `{}` is not sparse and has no memory bound: vkGetBufferDeviceAddress on it is \
                             itself invalid (VUID-VkBufferDeviceAddressInfo-buffer-02600: a non-sparse buffer must be \
                             bound completely and contiguously to a single VkDeviceMemory object), so the harness \
                             cannot give it the address the call uses (binding memory, taking the address and \
                             freeing the memory is no stand-in: layers 1.3.239 and 1.4.309 then find no buffer at \
                             the address and report its usage and size rules as well)",
                            b.name
                        )))
                    }
                    MemoryBinding::Scattered => {
                        return Err(HarnessError::NotRealised(format!(
                            "buffer `{}` is not sparse, so it cannot be bound to several memory objects \
                             (vkBindBufferMemory binds one; VUID-VkBufferDeviceAddressInfo-buffer-02600)",
                            b.name
                        )))
                    }
                }
                match self.spare.take(b.size, usage, flags) {
                    Some(a) => a,
                    None => Allocation::new(
                        &self.dev,
                        b.size,
                        usage,
                        flags,
                        BUFFER_PLACEMENT_ALIGNMENT,
                    )?,
                }
            };
            for w in &b.writes {
                match w {
                    BufferWrite::Handle { offset, handle } => {
                        let bytes: Vec<u8> = match handle {
                            HandleRef::Zero => vec![0; hs],
                            HandleRef::Group(n) => own
                                .get(*n as usize * hs..(*n as usize + 1) * hs)
                                .map_or(vec![0; hs], |s| s.to_vec()),
                            HandleRef::Foreign(n) => foreign
                                .get(*n as usize * hs..(*n as usize + 1) * hs)
                                .map_or(vec![0; hs], |s| s.to_vec()),
                        };
                        a.write(*offset, &bytes);
                    }
                    BufferWrite::Bytes { offset, bytes } => a.write(*offset, bytes),
                }
            }
            out.push((b.name.clone(), a));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vk::plain_lavapipe_device;

    /// A buffer given back is taken again only for its own size, usage and flags, and then holds
    /// zeros whatever the case before wrote; what is past the limits is destroyed, not kept (lavapipe).
    #[test]
    fn a_spare_buffer_is_taken_only_as_made_and_zeroed() {
        // Vulkan called directly, as the executor does, in the process's turn.
        let _turn = crate::vk::turn::take();
        let dev = plain_lavapipe_device();
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let none = vk::BufferCreateFlags::empty();
        let a = Allocation::new(&dev, 240, usage, none, BUFFER_PLACEMENT_ALIGNMENT).unwrap();
        a.write(0, &[0xAB; 240]);
        let buffer = a.buffer;
        let mut spare = SpareBuffers::default();
        spare.give_back(a, &dev);
        assert!(spare.take(160, usage, none).is_none(), "another size");
        let other_usage = usage | vk::BufferUsageFlags::TRANSFER_SRC;
        assert!(
            spare.take(240, other_usage, none).is_none(),
            "another usage"
        );
        let flags = vk::BufferCreateFlags::PROTECTED;
        assert!(spare.take(240, usage, flags).is_none(), "other flags");
        let again = spare
            .take(240, usage, none)
            .expect("the same kind is taken");
        assert_eq!(again.buffer, buffer);
        assert_eq!(again.read_u32s(60), vec![0u32; 60]);
        assert!(spare.take(240, usage, none).is_none(), "taken once");
        // Larger than kept: destroyed when given back.
        let big = SpareBuffers::LARGEST + 4;
        let b = Allocation::new(&dev, big, usage, none, 1).unwrap();
        spare.give_back(b, &dev);
        assert!(spare.kept.is_empty());
        // At most COUNT kept.
        for _ in 0..SpareBuffers::COUNT + 3 {
            let c = Allocation::new(&dev, 64, usage, none, 1).unwrap();
            spare.give_back(c, &dev);
        }
        assert_eq!(spare.kept.len(), SpareBuffers::COUNT);
        spare.give_back(again, &dev);
        assert_eq!(spare.kept.len(), SpareBuffers::COUNT);
        spare.destroy(&dev);
        assert!(spare.kept.is_empty());
    }
}
