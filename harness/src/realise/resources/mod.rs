//! Realises a case's resource state on a device: descriptor set layouts, pipeline layouts,
//! descriptor sets with their written descriptors, samplers, images and views, buffers and buffer views,
//! the binds and pushes recorded before the trace, and stage shaders that perform exactly the declared
//! accesses — so the validation layer's draw-time checks see the state the model judged.
//!
//! **Set numbering.** The harness's own set (scene, output, rays, callables) stays at set 0, where every
//! stage shader of the harness reads it; the case's set `n` is realised as set `n + 1`. Every realised
//! pipeline layout is `[harness set layout] ++ the case layout's sets` (with the case layout's push
//! constant ranges), so two realised layouts are compatible for set `n + 1` exactly when the case's are
//! compatible for set `n`, and the harness set, bound first with the pipeline's layout, is never disturbed
//! by the case's binds (its definition is the same in every layout).
//!
//! **Shaders.** Each stage that declares accesses (and the raygen always) is the harness's own shader of
//! that stage (`shaders/raygen.rgen`, `closest_hit.rchit`, `miss.rmiss`, `any_hit.rahit`,
//! `intersection.rint`, `callable.rcall`) with the stage's accesses injected at the start of `main`: one
//! GLSL declaration per access (aliases of one binding are allowed), the access itself in straight-line
//! code, and its result folded into a value that is consumed only under a condition that never holds at
//! run time (so every access is static use and none changes the output words; the stage's own code runs
//! after it). The templated module replaces the harness's in every stage of that kind in the pipeline
//! (`DeviceCache::create_pipeline_with`). Accesses in a stage the pipeline has no shader of are
//! unsupported (nothing bound would use them statically); a stage the pipeline has but the launch does
//! not reach still uses them statically, which is what these rules ask. Texel operands narrower than
//! four components, which GLSL's `imageStore` cannot express, are patched into the compiled module
//! (`OpImageWrite` with a narrow constant texel, see [`patch_narrow_writes`]). Sources are compiled in process
//! (`crate::shaders::compile_glsl`, the linked shaderc library) at first use, memoised by content, with `NV` defined for VK_NV_ray_tracing
//! pipelines (the same GLSL in GL_NV_ray_tracing names, as build.rs compiles the harness's shaders).
//!
//! **Descriptor buffers.** A pipeline the state says was created with DESCRIPTOR_BUFFER_BIT_EXT is
//! created with it; descriptors that come from descriptor buffers are written into descriptor memory
//! (`descriptor_buffer.rs`): every set layout, the harness's own included, is a descriptor buffer set
//! layout, the harness's set lives in the same buffer at offset 0, and the binds are one
//! `vkCmdBindDescriptorBuffersEXT` and `vkCmdSetDescriptorBufferOffsetsEXT` calls (set `n + 1` for
//! the case's set `n`, as above). Memory that is not resident is a sparse descriptor buffer with no
//! page bound. The case's device must enable `descriptorBuffer` (and, for memory that is not resident,
//! `sparseBinding` and `sparseResidencyBuffer`); the generator enables them.
//!
//! **Immutable samplers and Y′CbCr conversions.** A binding's immutable samplers are its set layout's
//! `pImmutableSamplers` (a write's sampler is then ignored). A sampler and a view that enable a Y′CbCr
//! conversion share one `VkSamplerYcbcrConversion` (`ycbcr.rs`), given to both in their `pNext`; the
//! sampler is an immutable sampler, the image has one level and one layer, its transitions name the
//! colour aspect (all planes of an image that is not disjoint), and its memory is bound whole.
//!
//! What is not realised is reported not realised by [`unsupported`] with the reason (vendor objects,
//! sparse images and tile memory, cubic filters, implicit-LOD sampling, which ray
//! tracing stages cannot do, 64-bit float images, 64-bit samplers and textures, 64-bit integer images on
//! a device that does not enable shaderImageInt64Atomics, accesses in a stage the pipeline lacks,
//! descriptors of the wrong kind); [`unbound_set`] refuses sets statically used but never bound under a
//! layer older than the first seen to validate them.

mod descriptor_buffer;
mod glsl;
mod images;
mod objects;
mod ycbcr;

pub use glsl::{compile_stage, stage_glsl, stage_source};

use glsl::pipeline_has;
use objects::renew_command_buffers;

use crate::error::HarnessError;
use crate::realise::DeviceCache;
use crate::shaders::{ShaderBody, ShaderKind};
use crate::vk::memory::Allocation;
use ash::vk;
use model::resources::*;
use model::world::World;
use std::collections::HashMap;

fn unsup<T>(s: impl Into<String>) -> Result<T, HarnessError> {
    Err(HarnessError::NotRealised(s.into()))
}

/// The ray tracing stages every realised binding and push constant range is visible to.
pub(crate) fn rt_stages() -> vk::ShaderStageFlags {
    vk::ShaderStageFlags::RAYGEN_KHR
        | vk::ShaderStageFlags::ANY_HIT_KHR
        | vk::ShaderStageFlags::CLOSEST_HIT_KHR
        | vk::ShaderStageFlags::MISS_KHR
        | vk::ShaderStageFlags::INTERSECTION_KHR
        | vk::ShaderStageFlags::CALLABLE_KHR
}

/// Why the harness cannot realise this world's resource state, if it cannot (checked before any device
/// work; [`Realised::new`] may still find a reason in what the device or GLSL cannot express).
pub(crate) fn unsupported(world: &World) -> Option<String> {
    let st = &world.resources;
    if st.is_empty() {
        return None;
    }
    if (st.descriptor_source == DescriptorSource::Buffers || st.pipeline_descriptor_buffer)
        && !world.device.extension("VK_EXT_descriptor_buffer")
    {
        return Some("descriptor buffers and DESCRIPTOR_BUFFER_BIT_EXT pipelines need VK_EXT_descriptor_buffer, which the case does not enable".into());
    }
    if st.descriptor_source == DescriptorSource::Buffers
        && !world.device.feature("descriptorBuffer")
    {
        return Some("descriptor buffers are bound (vkCmdBindDescriptorBuffersEXT) only with the descriptorBuffer feature, which the case does not enable".into());
    }
    if !st.tensors.is_empty() || !st.tensor_views.is_empty() {
        return Some(
            "tensors (VK_ARM_tensors) are not realised: no reachable driver has the extension"
                .into(),
        );
    }
    if st.tile != TileState::default()
        || st.images.iter().any(|i| i.tile_memory.is_some())
        || st.buffers.iter().any(|b| b.tile_memory.is_some())
    {
        return Some("tile shading and tile memory (VK_QCOM_tile_shading / _tile_memory_heap) are not realised: no reachable driver has them".into());
    }
    if st.images.iter().any(|i| i.sparse_residency) || st.buffers.iter().any(|b| b.sparse_residency)
    {
        return Some(
            "sparse-resident images and buffers of a resource state are not realised yet".into(),
        );
    }
    if st.images.iter().any(|i| i.corner_sampled)
        && !world.device.extension("VK_NV_corner_sampled_image")
    {
        return Some("a corner-sampled image needs VK_NV_corner_sampled_image, which the case does not enable".into());
    }
    if st.descriptor_source == DescriptorSource::Buffers
        && st
            .set_layouts
            .iter()
            .any(|l| l.bindings.iter().any(|b| !b.immutable_samplers.is_empty()))
    {
        return Some("immutable samplers in descriptor buffer set layouts are not realised".into());
    }
    if let Some(why) = ycbcr::unsupported(world) {
        return Some(why);
    }
    if st.samplers.iter().any(|s| {
        s.filters(Filter::CubicExt)
            || s.image_processing
            || s.reduction == Reduction::WeightedAverageRangeclampQcom
            || s.cubic_weights != CubicWeights::CatmullRom
    }) {
        return Some("cubic filtering and QCOM image processing samplers are not realised by the harness (it creates no such sampler, whether the device has the extensions or not)".into());
    }
    if let Some(p) = world.pipeline.as_ref() {
        for s in st
            .stages
            .iter()
            .filter(|s| !s.accesses.is_empty() || s.push_constants.is_some())
        {
            if !pipeline_has(p, s.stage) {
                return Some(format!(
                    "the state declares accesses in the {:?} stage but the pipeline has no such shader, so nothing \
                     bound uses them statically (the model reads them as performed; the harness cannot place them)",
                    s.stage
                ));
            }
        }
    }
    if st
        .stages
        .iter()
        .any(|s| s.robustness != StageRobustness::default())
    {
        return Some(
            "per-stage pipeline robustness (VK_EXT_pipeline_robustness) is not realised yet".into(),
        );
    }
    for a in st.stages.iter().flat_map(|s| &s.accesses) {
        if a.op.is_qcom_processing() || matches!(a.op, Op::SampleWeightQcom | Op::Tensor) {
            return Some(format!(
                "{:?} accesses are vendor instructions no reachable driver has",
                a.op
            ));
        }
        if a.implicit_lod || a.lod_bias {
            return Some(
                "implicit-LOD sampling (and a LOD bias, which needs it) is not valid SPIR-V in a ray tracing stage: \
                 no shader the harness can build performs it"
                    .into(),
            );
        }
        if let Some(why) = a.image.and_then(|t| sixty_four_bit(world, st, a, &t)) {
            return Some(why);
        }
    }
    None
}

/// The first validation layer seen to validate a trace call whose shaders statically use a set that
/// was never bound (1.4.309 reports VUID-...-None-08600 for it).
const UNBOUND_SET_VALIDATED_SINCE: u32 = vk::make_api_version(0, 1, 4, 309);

/// Why a call whose shaders statically use a set nothing bound is not recorded under the loaded
/// layer (`layer_spec`: its spec version, None without a layer): VK_LAYER_KHRONOS_validation 1.3.239
/// crashes validating it, so a layer older than the first seen to validate it (or none, which would
/// hand the call to the driver) is not shown it.
pub(crate) fn unbound_set(world: &World, layer_spec: Option<u32>) -> Option<String> {
    let st = &world.resources;
    let n = st
        .used_sets()
        .into_iter()
        .find(|&n| st.bound(n).is_none())?;
    let layer = match layer_spec {
        Some(v) if v >= UNBOUND_SET_VALIDATED_SINCE => return None,
        Some(v) => format!(
            "VK_LAYER_KHRONOS_validation {}.{}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v),
            vk::api_version_patch(v)
        ),
        None => "no validation layer (the call would reach the driver)".into(),
    };
    Some(format!(
        "set {n} is statically used but never bound: not recorded under {layer}, older than 1.4.309, the first \
         layer seen to validate such a trace call (1.3.239 crashes with SIGSEGV or an uncaught C++ exception)"
    ))
}

/// Why an access whose image type or view format is 64-bit is not realised: a 64-bit float
/// `Sampled Type` is no valid SPIR-V; a storage access's known `Image Format` whose width is not the
/// `Sampled Type`'s breaks VUID-StandaloneSpirv-Image-04965 (only an Unknown-format access can hold
/// such a pair; a sampled image's format is always Unknown); GLSL has 64-bit integer storage images
/// (GL_EXT_shader_image_int64) but no 64-bit samplers or textures; and a 64-bit integer `Sampled Type`
/// is realised only on a device that enables what its capabilities need (`Int64ImageEXT`:
/// shaderImageInt64Atomics of VK_EXT_shader_image_atomic_int64; `Int64`: shaderInt64). A 32-bit `Sampled Type` over a 64-bit view (an Unknown-format storage access or a
/// fetch) is realised as it is.
fn sixty_four_bit(world: &World, st: &ResourceState, a: &Access, t: &ImageType) -> Option<String> {
    let view = glsl::view_format(st, a);
    let view_bits = view
        .as_deref()
        .and_then(model::resources::formats::info)
        .map(|f| f.width);
    if t.width != 64 && view_bits != Some(64) {
        return None;
    }
    if t.width == 64 && t.sampled_type == Numeric::Float {
        return Some(
            "a 64-bit float Sampled Type is not valid SPIR-V (Int64ImageEXT allows 64-bit integer images only), so no shader \
             performs this access"
                .into(),
        );
    }
    // Only storage accesses declare an Image Format: a sampled image's is always Unknown.
    let storage = matches!(a.op, Op::Read | Op::Write | Op::Atomic);
    if storage && !t.format_unknown && view_bits.is_some_and(|b| b != t.width) {
        return Some(format!(
            "a {}-bit Sampled Type with the known Image Format of a {} view breaks VUID-StandaloneSpirv-Image-04965 (the \
             Image Format's width is the Sampled Type's); only an Unknown-format access can pair them",
            t.width,
            view.as_deref().unwrap_or("64-bit")
        ));
    }
    if t.width != 64 {
        return None;
    }
    if a.op.samples() || a.op == Op::Fetch {
        return Some(
            "a 64-bit integer Sampled Type through a sampler or texture: GLSL has no such types (GL_EXT_shader_image_int64 \
             adds storage images only), so the harness writes no shader that performs this access"
                .into(),
        );
    }
    let lacking: Vec<&str> = ["shaderImageInt64Atomics", "shaderInt64"]
        .into_iter()
        .filter(|f| !world.device.feature(f))
        .collect();
    if !world.device.extension("VK_EXT_shader_image_atomic_int64") || !lacking.is_empty() {
        return Some(format!(
            "a 64-bit integer Sampled Type needs the Int64ImageEXT and Int64 capabilities, whose features \
             (VK_EXT_shader_image_atomic_int64's shaderImageInt64Atomics, shaderInt64) the case does not enable{}",
            if lacking.is_empty() {
                " (the extension is missing)".to_string()
            } else {
                format!(" (missing: {})", lacking.join(", "))
            }
        ));
    }
    None
}

// ---------------------------------------------------------------------------------------------
// GLSL

/// Resource-state objects a device's cases share by content: set layouts, pipeline layouts and the
/// ray tracing pipelines made with templated stages. Two cases whose layouts are defined identically
/// get the same layout handles, which the layer and the spec judge alike (layouts are compared by
/// compatibility, that is by content); and two whose pipeline description, templated modules' SPIR-V
/// and realised layout are the same run one pipeline, so the driver compiles it once. States whose
/// set layouts hold immutable samplers or whose descriptors come from descriptor buffers keep their
/// own objects (their layouts reference the case's samplers and its descriptor buffer set layout).
#[derive(Default)]
pub(crate) struct Shared {
    /// By [`set_layout_key`].
    set_layouts: HashMap<String, vk::DescriptorSetLayout>,
    /// By the set layouts' keys and the push constant ranges.
    pipeline_layouts: HashMap<String, vk::PipelineLayout>,
    /// Hashed over the whole key (the SPIR-V included) and found by comparing it.
    pipelines: HashMap<PipelineKey, crate::realise::RealPipeline>,
}

/// What makes two resource-state pipelines the same.
#[derive(PartialEq, Eq, Hash)]
struct PipelineKey {
    /// The pipeline description as JSON (its flags with DESCRIPTOR_BUFFER_BIT_EXT where the state asks).
    description: String,
    trace: bool,
    /// The body of the stages that are not templated (the templated ones are in `modules`).
    body: ShaderBody,
    /// The realised pipeline layout's key.
    layout: String,
    /// The templated module of each stage kind, as SPIR-V.
    modules: Vec<(ShaderKind, Vec<u32>)>,
}

/// The content of a set layout as created: its flags and, per binding, number, type and count (every
/// binding is visible to every ray tracing stage; none has immutable samplers here).
fn set_layout_key(flags: vk::DescriptorSetLayoutCreateFlags, l: &SetLayout) -> String {
    let bindings: Vec<(u32, DescriptorType, u32)> = l
        .bindings
        .iter()
        .map(|b| (b.binding, b.ty, b.count))
        .collect();
    format!("{:#x}|{bindings:?}", flags.as_raw())
}

/// The content of a pipeline layout as created: the harness's set layout (set 0), the case's set
/// layouts' keys in set order, and the push constant ranges.
fn pipeline_layout_key(
    harness_set: vk::DescriptorSetLayout,
    sets: &[&str],
    ranges: &[PushRange],
) -> String {
    let ranges: Vec<(u32, u32)> = ranges.iter().map(|r| (r.offset, r.size)).collect();
    format!("{:?}|{}|{ranges:?}", harness_set, sets.join(";"))
}

impl Shared {
    /// Destroys every shared object (nothing recorded with them is pending).
    pub(crate) fn destroy(&mut self, d: &ash::Device) {
        // SAFETY: the caller's contract; pipelines go before the layouts they were made with.
        unsafe {
            for (_, p) in self.pipelines.drain() {
                d.destroy_pipeline(p.pipeline, None);
            }
            for (_, h) in self.pipeline_layouts.drain() {
                d.destroy_pipeline_layout(h, None);
            }
            for (_, h) in self.set_layouts.drain() {
                d.destroy_descriptor_set_layout(h, None);
            }
        }
    }
}

/// A case's resource state realised on a device. Destroy with [`Realised::destroy`] once nothing
/// recorded with it is pending.
pub(crate) struct Realised {
    /// The set layouts, pipeline layouts (the harness layout included) are [`Shared`]'s, not the case's.
    shared_layouts: bool,
    /// `cache.resource_pipeline` is a copy of a [`Shared`] pipeline, not the case's own.
    shared_pipeline: bool,
    set_layouts: HashMap<String, vk::DescriptorSetLayout>,
    pipeline_layouts: HashMap<String, vk::PipelineLayout>,
    /// The realised layout of the case's pipeline (`[harness set] ++ its sets`), which the harness binds
    /// its own set with.
    pub(crate) harness_layout: vk::PipelineLayout,
    own_harness_layout: bool,
    pool: vk::DescriptorPool,
    sets: HashMap<String, vk::DescriptorSet>,
    samplers: HashMap<String, vk::Sampler>,
    images: Vec<(
        String,
        vk::Image,
        vk::DeviceMemory,
        vk::ImageLayout,
        vk::ImageAspectFlags,
        u32,
        u32,
    )>,
    views: HashMap<String, vk::ImageView>,
    buffers: HashMap<String, Allocation>,
    buffer_views: HashMap<String, vk::BufferView>,
    /// The modules of the pipeline's templated stages (the raygen always; other stages when the
    /// state declares accesses or push constant reads in them), one per stage kind and constants.
    modules: Vec<(ShaderKind, vk::ShaderModule)>,
    binds: Vec<(vk::PipelineLayout, u32, vk::DescriptorSet)>,
    pushes: Vec<(vk::PipelineLayout, u32, u32)>,
    /// The descriptor memory of a state whose descriptors come from descriptor buffers (then `pool`,
    /// `sets` and `binds` stay empty), with the harness's set as a descriptor buffer set layout.
    descriptor_memory: Option<descriptor_buffer::DescriptorMemory>,
    db_harness_set: vk::DescriptorSetLayout,
    /// The Y′CbCr conversions the samplers and views were created with.
    ycbcr: ycbcr::Conversions,
}

impl Realised {
    fn empty() -> Realised {
        Realised {
            shared_layouts: false,
            shared_pipeline: false,
            set_layouts: HashMap::new(),
            pipeline_layouts: HashMap::new(),
            harness_layout: vk::PipelineLayout::null(),
            own_harness_layout: false,
            pool: vk::DescriptorPool::null(),
            sets: HashMap::new(),
            samplers: HashMap::new(),
            images: Vec::new(),
            views: HashMap::new(),
            buffers: HashMap::new(),
            buffer_views: HashMap::new(),
            modules: Vec::new(),
            binds: Vec::new(),
            pushes: Vec::new(),
            descriptor_memory: None,
            db_harness_set: vk::DescriptorSetLayout::null(),
            ycbcr: ycbcr::Conversions::default(),
        }
    }

    /// Realises `world.resources`: every object, the descriptor writes, and — when the world has a
    /// pipeline — the case's pipeline with the templated raygen, installed as `cache.resource_pipeline`.
    /// `harness_set` is the harness's own set layout (set 0 of every realised pipeline layout).
    pub(crate) fn new(
        cache: &mut DeviceCache,
        world: &World,
        trace: bool,
        body: ShaderBody,
        harness_set: vk::DescriptorSetLayout,
    ) -> Result<Realised, HarnessError> {
        renew_command_buffers(cache)?;
        let mut r = Realised::empty();
        match r.build(cache, world, trace, body, harness_set) {
            Ok(()) => Ok(r),
            Err(e) => {
                // The case's own pipeline (never used by a command buffer) goes with its objects.
                r.destroy(cache);
                Err(e)
            }
        }
    }

    /// Records the images' transitions from UNDEFINED to the layouts the state says they are in (before
    /// any render pass begins).
    ///
    /// # Safety
    /// `cb` is recording on `d`, outside a render pass.
    pub(crate) unsafe fn record_transitions(&self, d: &ash::Device, cb: vk::CommandBuffer) {
        let barriers: Vec<vk::ImageMemoryBarrier> = self
            .images
            .iter()
            .filter(|i| i.3 != vk::ImageLayout::UNDEFINED)
            .map(|&(_, image, _, layout, aspect, levels, layers)| {
                vk::ImageMemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::empty())
                    .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE)
                    .old_layout(vk::ImageLayout::UNDEFINED)
                    .new_layout(layout)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(image)
                    .subresource_range(vk::ImageSubresourceRange {
                        aspect_mask: aspect,
                        base_mip_level: 0,
                        level_count: levels,
                        base_array_layer: 0,
                        layer_count: layers,
                    })
            })
            .collect();
        if !barriers.is_empty() {
            d.cmd_pipeline_barrier(
                cb,
                vk::PipelineStageFlags::TOP_OF_PIPE,
                vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &barriers,
            );
        }
    }

    /// Whether the harness's own set lives in descriptor memory (written with
    /// [`Realised::write_harness_set`] and placed by [`Realised::record_binds`]) instead of being bound
    /// as a descriptor set.
    pub(crate) fn harness_set_in_buffer(&self) -> bool {
        self.descriptor_memory.is_some()
    }

    /// Writes the harness's own set into descriptor memory, when it lives there: bindings 1–4 as
    /// (device address, range), and the scene's top level. Nothing otherwise.
    pub(crate) fn write_harness_set(
        &self,
        dev: &crate::vk::VkDevice,
        buffers: [(u64, u64); 4],
        tlas: Option<crate::realise::Tlas>,
    ) -> Result<(), HarnessError> {
        match &self.descriptor_memory {
            Some(m) => m.write_harness_set(dev, buffers, tlas),
            None => Ok(()),
        }
    }

    /// Records the state's binds (case set `n` at set `n + 1`) and pushes (zero bytes), in order, after
    /// the harness bound its own set with [`Realised::harness_layout`] — or, with descriptor memory,
    /// the descriptor buffer's binding and the offsets of the harness's set and the case's sets.
    ///
    /// # Safety
    /// `cb` is recording on `d`, the device of `dev`.
    pub(crate) unsafe fn record_binds(&self, dev: &crate::vk::VkDevice, cb: vk::CommandBuffer) {
        let d = &dev.device;
        if let Some(m) = &self.descriptor_memory {
            m.record(dev, cb);
        }
        for &(layout, set, ds) in &self.binds {
            d.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::RAY_TRACING_KHR,
                layout,
                set,
                &[ds],
                &[],
            );
        }
        for &(layout, offset, size) in &self.pushes {
            let zeros = vec![0u8; size as usize];
            d.cmd_push_constants(cb, layout, rt_stages(), offset, &zeros);
        }
    }

    /// Destroys every object (the case's pipeline in `cache.resource_pipeline` included).
    pub(crate) fn destroy(mut self, cache: &mut DeviceCache) {
        let d = &cache.dev.device;
        // SAFETY: nothing recorded with these objects is pending (the caller's contract).
        unsafe {
            if let Some(p) = cache.resource_pipeline.take() {
                if !self.shared_pipeline {
                    d.destroy_pipeline(p.pipeline, None);
                }
            }
            for (_, m) in self.modules {
                d.destroy_shader_module(m, None);
            }
            if let Some(m) = self.descriptor_memory {
                m.destroy(&cache.dev);
            }
            if self.db_harness_set != vk::DescriptorSetLayout::null() {
                d.destroy_descriptor_set_layout(self.db_harness_set, None);
            }
            if self.pool != vk::DescriptorPool::null() {
                d.destroy_descriptor_pool(self.pool, None);
            }
            for (_, h) in self.buffer_views {
                d.destroy_buffer_view(h, None);
            }
            for (_, a) in self.buffers {
                a.destroy(&cache.dev);
            }
            for (_, h) in self.views {
                d.destroy_image_view(h, None);
            }
            for (_, image, memory, ..) in self.images {
                d.destroy_image(image, None);
                d.free_memory(memory, None);
            }
            for (_, h) in self.samplers {
                d.destroy_sampler(h, None);
            }
            self.ycbcr.destroy(&cache.dev);
            if self.shared_layouts {
                return;
            }
            for (_, h) in self.pipeline_layouts {
                d.destroy_pipeline_layout(h, None);
            }
            if self.own_harness_layout {
                d.destroy_pipeline_layout(self.harness_layout, None);
            }
            for (_, h) in self.set_layouts {
                d.destroy_descriptor_set_layout(h, None);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ash::vk::Handle;

    fn layout(bindings: &[(u32, DescriptorType, u32)]) -> SetLayout {
        SetLayout {
            name: "l".into(),
            bindings: bindings
                .iter()
                .map(|&(binding, ty, count)| LayoutBinding {
                    binding,
                    ty,
                    count,
                    immutable_samplers: vec![],
                })
                .collect(),
        }
    }

    #[test]
    fn set_layouts_share_a_key_exactly_when_defined_identically() {
        let none = vk::DescriptorSetLayoutCreateFlags::empty();
        let base = [
            (0, DescriptorType::StorageImage, 1),
            (2, DescriptorType::Sampler, 3),
        ];
        let key = set_layout_key(none, &layout(&base));
        // The name is not content.
        let mut renamed = layout(&base);
        renamed.name = "other".into();
        assert_eq!(set_layout_key(none, &renamed), key);
        // Each planted difference: binding number, type, count, flags.
        let planted = [
            [(1, DescriptorType::StorageImage, 1), base[1]],
            [(0, DescriptorType::SampledImage, 1), base[1]],
            [(0, DescriptorType::StorageImage, 2), base[1]],
        ];
        for p in planted {
            assert_ne!(set_layout_key(none, &layout(&p)), key, "{p:?}");
        }
        let db = vk::DescriptorSetLayoutCreateFlags::DESCRIPTOR_BUFFER_EXT;
        assert_ne!(set_layout_key(db, &layout(&base)), key);
    }

    #[test]
    fn pipeline_layouts_share_a_key_exactly_when_defined_identically() {
        let harness = vk::DescriptorSetLayout::from_raw(7);
        let ranges = [PushRange {
            offset: 0,
            size: 16,
        }];
        let key = pipeline_layout_key(harness, &["a", "b"], &ranges);
        assert_eq!(pipeline_layout_key(harness, &["a", "b"], &ranges), key);
        assert_ne!(pipeline_layout_key(harness, &["b", "a"], &ranges), key);
        assert_ne!(pipeline_layout_key(harness, &["a"], &ranges), key);
        assert_ne!(
            pipeline_layout_key(
                harness,
                &["a", "b"],
                &[PushRange {
                    offset: 4,
                    size: 16
                }]
            ),
            key
        );
        assert_ne!(
            pipeline_layout_key(harness, &["a", "b"], &[PushRange { offset: 0, size: 8 }]),
            key
        );
        assert_ne!(pipeline_layout_key(harness, &["a", "b"], &[]), key);
        let other = vk::DescriptorSetLayout::from_raw(8);
        assert_ne!(pipeline_layout_key(other, &["a", "b"], &ranges), key);
    }

    /// The world of the committed hand-made indirect case (no resource state).
    fn hand_world() -> World {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../cases/hand/trace-indirect-basic.yaml");
        let text = std::fs::read_to_string(&p).expect("the hand-made case");
        let case = model::Case::from_yaml(&p.display().to_string(), &text).expect("a case file");
        case.as_trace().expect("a trace case").world.clone()
    }

    /// A world whose shaders load from set 0 with nothing bound (the generator's mutation for
    /// VUID-vkCmdTraceRaysKHR-None-08600, bound sets cleared).
    fn unbound_world() -> World {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
        let text = std::fs::read_to_string(path).expect("profiles/lavapipe.json");
        let profile =
            model::DeviceProfile::from_profiles_json("lavapipe", &text).expect("a profile");
        let m = generator::resources::mutation_for("VUID-vkCmdTraceRaysKHR-None-08600")
            .expect("a resource rule");
        let mut world = hand_world();
        let mut st = generator::resources::valid_state(&profile, 0, 0x1ff);
        generator::resources::mutate(
            m,
            &mut st,
            &mut world.device,
            &mut world.command_buffer,
            &profile,
            0,
        )
        .expect("lavapipe expresses it");
        world.resources = st;
        world
    }

    #[test]
    fn an_unbound_set_is_recorded_only_under_a_layer_that_validates_it() {
        let world = unbound_world();
        assert!(unsupported(&world).is_none(), "nothing else refused");
        let old = vk::make_api_version(0, 1, 3, 239);
        let why = unbound_set(&world, Some(old)).expect("refused under 1.3.239");
        assert!(
            why.contains("set 0") && why.contains("1.3.239") && why.contains("1.4.309"),
            "{why}"
        );
        assert!(
            unbound_set(&world, None).is_some(),
            "refused without a layer"
        );
        for since in [
            vk::make_api_version(0, 1, 4, 309),
            vk::make_api_version(0, 1, 4, 330),
        ] {
            assert_eq!(unbound_set(&world, Some(since)), None);
        }
        // A world whose sets are all bound is never refused for this.
        assert_eq!(unbound_set(&hand_world(), Some(old)), None);
    }
}
