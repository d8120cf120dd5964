//! What both traced checks bind: the rays, the 28-word records they write (pre-filled with
//! `RayRecord::PREFILL`) and the built boxes' sphere table as storage buffers, and the structure under
//! test, in one descriptor set of one layout.

use crate::error::{vkfail, HarnessError};
use crate::plan::check::CheckPlan;
use crate::vk::descriptors::{storage_write, structure_write, whole};
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use model::tracer::record::RayRecord;

/// The check's buffers and descriptor set, for shaders of `stages`. Destroy with [`CheckSet::destroy`]
/// once nothing recorded with it is pending.
pub(super) struct CheckSet {
    rays: Allocation,
    records: Allocation,
    spheres: Allocation,
    pub(super) layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    pub(super) set: vk::DescriptorSet,
    count: usize,
}

impl CheckSet {
    /// Binding 0: `scene`; 1: two `vec4` per ray (origin and tmin, direction and tmax); 2: one
    /// pre-filled `RayRecord` per ray; 3: the sphere table.
    pub(super) fn new(
        dev: &VkDevice,
        scene: vk::AccelerationStructureKHR,
        plan: &CheckPlan,
        stages: vk::ShaderStageFlags,
    ) -> Result<CheckSet, HarnessError> {
        let sb = vk::BufferUsageFlags::STORAGE_BUFFER;
        let none = vk::BufferCreateFlags::empty();
        let rays = plan.ray_bytes();
        let rb = Allocation::new(dev, rays.len() as u64, sb, none, 1)?;
        rb.write(0, &rays);
        let prefill: Vec<u8> = (0..plan.rays.len())
            .flat_map(|_| RayRecord::PREFILL)
            .flat_map(u32::to_le_bytes)
            .collect();
        let hb = Allocation::new(dev, prefill.len() as u64, sb, none, 1)?;
        hb.write(0, &prefill);
        let bb = Allocation::new(dev, plan.spheres.len() as u64, sb, none, 1)?;
        bb.write(0, &plan.spheres);
        let mut cs = CheckSet {
            rays: rb,
            records: hb,
            spheres: bb,
            layout: vk::DescriptorSetLayout::null(),
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            count: plan.rays.len(),
        };
        match cs.make_set(dev, scene, stages) {
            Ok(()) => Ok(cs),
            Err(e) => {
                cs.destroy(dev);
                Err(e)
            }
        }
    }

    fn make_set(
        &mut self,
        dev: &VkDevice,
        scene: vk::AccelerationStructureKHR,
        stages: vk::ShaderStageFlags,
    ) -> Result<(), HarnessError> {
        let d = &dev.device;
        let bind = |b: u32, t: vk::DescriptorType| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b)
                .descriptor_type(t)
                .descriptor_count(1)
                .stage_flags(stages)
        };
        let bindings = [
            bind(0, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR),
            bind(1, vk::DescriptorType::STORAGE_BUFFER),
            bind(2, vk::DescriptorType::STORAGE_BUFFER),
            bind(3, vk::DescriptorType::STORAGE_BUFFER),
        ];
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                descriptor_count: 1,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: 3,
            },
        ];
        // SAFETY: valid create infos; the objects are destroyed by `destroy`.
        unsafe {
            self.layout = d
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                    None,
                )
                .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
            self.pool = d
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(1)
                        .pool_sizes(&sizes),
                    None,
                )
                .map_err(vkfail("vkCreateDescriptorPool"))?;
            let layouts = [self.layout];
            self.set = d
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(self.pool)
                        .set_layouts(&layouts),
                )
                .map_err(vkfail("vkAllocateDescriptorSets"))?[0];
            write_check_set(
                d,
                self.set,
                scene,
                [self.rays.buffer, self.records.buffer, self.spheres.buffer],
            );
        }
        Ok(())
    }

    /// A pipeline layout of the check's one set; the caller destroys it.
    pub(super) fn pipeline_layout(
        &self,
        dev: &VkDevice,
    ) -> Result<vk::PipelineLayout, HarnessError> {
        let sets = [self.layout];
        // SAFETY: valid create info; the set layout is live.
        unsafe {
            dev.device.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
                None,
            )
        }
        .map_err(vkfail("vkCreatePipelineLayout"))
    }

    /// What the rays wrote: [`RayRecord::WORDS`] words per ray.
    pub(super) fn records(&self) -> Vec<u32> {
        self.records.read_u32s(RayRecord::WORDS * self.count)
    }

    pub(super) fn destroy(self, dev: &VkDevice) {
        let d = &dev.device;
        // SAFETY: nothing recorded with the set is pending (the caller's contract).
        unsafe {
            if self.pool != vk::DescriptorPool::null() {
                d.destroy_descriptor_pool(self.pool, None);
            }
            if self.layout != vk::DescriptorSetLayout::null() {
                d.destroy_descriptor_set_layout(self.layout, None);
            }
        }
        for a in [self.rays, self.records, self.spheres] {
            a.destroy(dev);
        }
    }
}

/// Writes the traced check's descriptor set: the structure under test at binding 0 and the rays, records
/// and sphere buffers at bindings 1 to 3 (the same layout for the ray-query and the pipeline path).
///
/// # Safety
/// `set` is a set of the check's layout that no pending command uses; the handles are live.
unsafe fn write_check_set(
    d: &ash::Device,
    set: vk::DescriptorSet,
    scene: vk::AccelerationStructureKHR,
    buffers: [vk::Buffer; 3],
) {
    let scenes = [scene];
    let mut asw =
        vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&scenes);
    let infos = buffers.map(whole);
    let writes = [
        structure_write(
            set,
            0,
            vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
            &mut asw,
        ),
        storage_write(set, 1, &infos[0]),
        storage_write(set, 2, &infos[1]),
        storage_write(set, 3, &infos[2]),
    ];
    // SAFETY: guaranteed by the caller.
    unsafe { d.update_descriptor_sets(&writes, &[]) };
}
