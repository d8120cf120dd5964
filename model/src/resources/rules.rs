//! The resource-access rules the trace commands share with draw/dispatch: which VUID tag is which
//! [`ResourceRule`] (the text decides between versions' wordings), and what each rule checks in a
//! world's [`ResourceState`](super::ResourceState).
//!
//! Rules whose resources no captured driver exposes (QCOM image processing and tile shading, cubic
//! filtering, ARM tensors) are executable here all the same; their row carries a note saying they
//! cannot be exercised on a driver the project can reach ([`Entry::Executable::note`]).

use super::formats::{self, Usage};
use super::*;
use crate::rules::predicate::Failure;
use crate::rules::Context;
use vk_registry::vuid::VuidRecord;

/// What the rule table makes of a resource VUID.
#[derive(Debug, Clone, PartialEq)]
pub enum Entry {
    Executable {
        rule: ResourceRule,
        /// Set for vendor rules no captured driver can exercise.
        note: Option<String>,
    },
    NotExecutable(String),
}

/// Which view a width rule speaks of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewKind {
    Image,
    Buffer,
}

/// A resource-access rule, parameterised where versions word it differently.
#[derive(Debug, Clone, PartialEq)]
pub enum ResourceRule {
    /// 02697, 08600: every statically used set is bound with a layout compatible for that set.
    SetsBound,
    /// 02698, 06425, 08602: statically used push constant bytes were set with a layout compatible for
    /// push constants (`unless_maintenance4`: not required when `maintenance4` is enabled).
    PushConstantsSet { unless_maintenance4: bool },
    /// 08601: push constant bytes the shaders use that were set, were set with a compatible layout
    /// (with `maintenance4` a value need not be set; 08602 covers unset values without it).
    PushConstantsCompatible,
    /// 02699, 08114: statically used descriptors of bound sets are valid (08114: unless the pipeline
    /// uses descriptor buffers).
    DescriptorsValid { unless_descriptor_buffer: bool },
    /// 08116: with descriptor buffers and a descriptor-buffer pipeline, used descriptors are valid.
    DescriptorBufferDescriptorsValid,
    /// 08115: descriptors from `vkCmdBindDescriptorSets` need a pipeline without DESCRIPTOR_BUFFER.
    SetsNeedPlainPipeline,
    /// 08117: descriptors from descriptor buffers need a DESCRIPTOR_BUFFER pipeline.
    BuffersNeedDescriptorBufferPipeline,
    /// 08119: descriptor buffer memory is resident.
    DescriptorMemoryResident,
    /// 02702, 08609, 09636: an unnormalized sampler samples only 1D or 2D views.
    UnnormalizedViewType,
    /// 02703, 08610: no ImplicitLod, Dref or Proj sampling with an unnormalized sampler.
    UnnormalizedInstruction,
    /// 02704, 08611: no LOD bias or offset with an unnormalized sampler.
    UnnormalizedBiasOffset,
    /// 09635: an unnormalized sampler samples views of one level and one layer.
    UnnormalizedLevelsLayers,
    /// 02705, 02706, 06935, 06936: uniform / storage buffer accesses stay in range without robustness.
    InRange {
        uniform: bool,
        pipeline_robustness: bool,
    },
    /// 02691: atomics on an image view need STORAGE_IMAGE_ATOMIC.
    ImageAtomicFeature,
    /// 07888: atomics on a storage texel buffer need STORAGE_TEXEL_BUFFER_ATOMIC.
    TexelBufferAtomicFeature,
    /// 02692: cubic sampling needs SAMPLED_IMAGE_FILTER_CUBIC.
    CubicFeature,
    /// 02693: no cubic sampling of 3D, cube or cube array views (`unless_filter_cubic`: the older
    /// wording that exempts devices with `VK_EXT_filter_cubic` enabled).
    CubicViewType { unless_filter_cubic: bool },
    /// 02694, 02695: the view type and format support cubic filtering (with min/max reduction).
    CubicSupport { minmax: bool },
    /// 09212: range-clamp reduction with cubic sampling needs `cubicRangeClamp`.
    CubicRangeClamp,
    /// 09213: range-clamp reduction only with cubic sampling.
    RangeClampNeedsCubic,
    /// 09214: non-Catmull-Rom cubic weights need `selectableCubicWeights`.
    CubicWeights,
    /// 02696: corner-sampled images are sampled with CLAMP_TO_EDGE only.
    CornerSampledClamp,
    /// 04115, 08795 (`a8_exempt`), 04469 (buffer views): the written texel has enough components.
    WriteComponents { view: ViewKind, a8_exempt: bool },
    /// 08796: writes to A8_UNORM views have four components.
    WriteComponentsA8,
    /// 04470–04473: the `Sampled Type` width is 64 exactly for 64-bit formats.
    SampledTypeWidth { view: ViewKind, sixty_four: bool },
    /// 04474, 04475: 64-bit atomics on sparse-residency resources need `sparseImageInt64Atomics`.
    SparseInt64Atomics { view: ViewKind },
    /// 04553, 04770: linear (mip)filtering needs FILTER_LINEAR (`weighted_only`: the newer wording
    /// that limits it to the weighted-average reduction).
    LinearFilterFeature { mipmap: bool, weighted_only: bool },
    /// 09598, 09599: min/max reduction with linear (mip)filtering needs FILTER_MINMAX.
    MinmaxFilterFeature { mipmap: bool },
    /// 06478: depth comparison on a view with the depth aspect.
    DepthCompareAspect,
    /// 06479: depth comparison needs SAMPLED_IMAGE_DEPTH_COMPARISON.
    DepthCompareFeature,
    /// 06550: Y′CbCr samplers and views only with `OpImageSample*`.
    YcbcrSampleOnly,
    /// 06551: no offsets with Y′CbCr samplers and views.
    YcbcrNoOffset,
    /// 06971–06975, 09215: a QCOM image processing op needs its format feature.
    QcomFeature { op: Op, feature: &'static str },
    /// 09216: block matching windows read single-component formats.
    QcomSingleComponent,
    /// 06976 (`window: false`), 09217: block match reference coordinates pass integer texel validation.
    QcomReferenceCoords { window: bool },
    /// 06977: QCOM processing ops use IMAGE_PROCESSING samplers (`window`: the window/gather ops count).
    QcomProcessingSampler { window: bool },
    /// 06978: other instructions use no IMAGE_PROCESSING sampler.
    QcomNoProcessingSampler { window: bool },
    /// 07027–07030: storage reads/writes through an `Unknown` format need the WITHOUT_FORMAT feature.
    WithoutFormat { write: bool, view: ViewKind },
    /// 07752: the view type matches `Dim` and `Arrayed`.
    ViewTypeMatchesDim,
    /// 07753: the format's numeric class matches the `Sampled Type` (`buffer_views`: the wording that
    /// includes buffer views).
    NumericTypeMatches { buffer_views: bool },
    /// 09600: accessed image descriptors' subresources are in the layout they were written with.
    LayoutMatches,
    /// 10068: array indices are below the binding's descriptor count.
    ArrayIndexInRange,
    /// 09900: tensors accessed were created with SHADER usage.
    TensorShaderUsage,
    /// 09905: `Rank` equals the tensor's dimension count.
    TensorRank,
    /// 09906: the element type is compatible with the tensor view's format.
    TensorElementType,
    /// 10678: no ray tracing stage runs inside a tile shading render pass.
    TileShadingStages,
    /// 10679: with per-tile execution, no image is accessed in the feedback loop layout.
    NoFeedbackLoopPerTile,
    /// 10746: tile memory a resource is bound to is the command buffer's bound tile memory.
    ActiveTileMemory,
}

const SHADER_OBJECT: &str = "speaks only of VkShaderEXT objects: VK_EXT_shader_object has no ray tracing stages, so no \
     shader object is ever bound at the ray tracing bind point and a trace command cannot violate it";

const NOT_ON_DRIVERS: &str =
    "executable in the model; not exercisable on a captured driver (lavapipe, nvidia-h100): needs ";

/// The entry for a record of a trace command, if it is one of the shared resource-access rules.
pub fn rule_for(r: &VuidRecord) -> Option<Entry> {
    if !crate::CommandId::from_vk_name(&r.scope).is_some_and(crate::CommandId::is_trace) {
        return None;
    }
    let t = r.text.as_str();
    use ResourceRule as R;
    let (rule, vendor): (ResourceRule, Option<&str>) = match r.tag.as_str() {
        "02697" | "08600" => (R::SetsBound, None),
        "02698" => (
            R::PushConstantsSet {
                unless_maintenance4: false,
            },
            None,
        ),
        "06425" | "08602" => (
            R::PushConstantsSet {
                unless_maintenance4: true,
            },
            None,
        ),
        "08601" => (R::PushConstantsCompatible, None),
        "02699" => (
            R::DescriptorsValid {
                unless_descriptor_buffer: false,
            },
            None,
        ),
        "08114" => (
            R::DescriptorsValid {
                unless_descriptor_buffer: true,
            },
            None,
        ),
        "08116" => (R::DescriptorBufferDescriptorsValid, None),
        "08115" => (R::SetsNeedPlainPipeline, None),
        "08117" => (R::BuffersNeedDescriptorBufferPipeline, None),
        "08119" => (R::DescriptorMemoryResident, None),
        "08604" | "08605" | "08612" | "08613" => {
            return Some(Entry::NotExecutable(SHADER_OBJECT.into()))
        }
        "02702" | "08609" | "09636" => (R::UnnormalizedViewType, None),
        "02703" | "08610" => (R::UnnormalizedInstruction, None),
        "02704" | "08611" => (R::UnnormalizedBiasOffset, None),
        "09635" => (R::UnnormalizedLevelsLayers, None),
        "02705" => (
            R::InRange {
                uniform: true,
                pipeline_robustness: false,
            },
            None,
        ),
        "02706" => (
            R::InRange {
                uniform: false,
                pipeline_robustness: false,
            },
            None,
        ),
        "06935" => (
            R::InRange {
                uniform: true,
                pipeline_robustness: true,
            },
            None,
        ),
        "06936" => (
            R::InRange {
                uniform: false,
                pipeline_robustness: true,
            },
            None,
        ),
        "02691" => (R::ImageAtomicFeature, None),
        "07888" => (R::TexelBufferAtomicFeature, None),
        "02692" => (
            R::CubicFeature,
            Some("VK_EXT_filter_cubic or VK_IMG_filter_cubic"),
        ),
        "02693" => (
            R::CubicViewType {
                unless_filter_cubic: t.contains("not enabled"),
            },
            Some("VK_EXT_filter_cubic or VK_IMG_filter_cubic"),
        ),
        "02694" => (
            R::CubicSupport { minmax: false },
            Some("VK_EXT_filter_cubic"),
        ),
        "02695" => (
            R::CubicSupport { minmax: true },
            Some("VK_EXT_filter_cubic"),
        ),
        "09212" => (R::CubicRangeClamp, Some("VK_QCOM_filter_cubic_clamp")),
        "09213" => (R::RangeClampNeedsCubic, Some("VK_QCOM_filter_cubic_clamp")),
        "09214" => (R::CubicWeights, Some("VK_QCOM_filter_cubic_weights")),
        "02696" => (R::CornerSampledClamp, None),
        "04115" => (
            R::WriteComponents {
                view: ViewKind::Image,
                a8_exempt: false,
            },
            None,
        ),
        "08795" => (
            R::WriteComponents {
                view: ViewKind::Image,
                a8_exempt: true,
            },
            None,
        ),
        "04469" => (
            R::WriteComponents {
                view: ViewKind::Buffer,
                a8_exempt: false,
            },
            None,
        ),
        "08796" => (R::WriteComponentsA8, None),
        "04470" => (
            R::SampledTypeWidth {
                view: ViewKind::Image,
                sixty_four: true,
            },
            None,
        ),
        "04471" => (
            R::SampledTypeWidth {
                view: ViewKind::Image,
                sixty_four: false,
            },
            None,
        ),
        "04472" => (
            R::SampledTypeWidth {
                view: ViewKind::Buffer,
                sixty_four: true,
            },
            None,
        ),
        "04473" => (
            R::SampledTypeWidth {
                view: ViewKind::Buffer,
                sixty_four: false,
            },
            None,
        ),
        "04474" => (
            R::SparseInt64Atomics {
                view: ViewKind::Image,
            },
            None,
        ),
        "04475" => (
            R::SparseInt64Atomics {
                view: ViewKind::Buffer,
            },
            None,
        ),
        "04553" => (
            R::LinearFilterFeature {
                mipmap: false,
                weighted_only: t.contains("WEIGHTED_AVERAGE"),
            },
            None,
        ),
        "04770" => (
            R::LinearFilterFeature {
                mipmap: true,
                weighted_only: t.contains("WEIGHTED_AVERAGE"),
            },
            None,
        ),
        "09598" => (R::MinmaxFilterFeature { mipmap: false }, None),
        "09599" => (R::MinmaxFilterFeature { mipmap: true }, None),
        "06478" => (R::DepthCompareAspect, None),
        "06479" => (R::DepthCompareFeature, None),
        "06550" => (R::YcbcrSampleOnly, None),
        "06551" => (R::YcbcrNoOffset, None),
        "06971" => (
            R::QcomFeature {
                op: Op::WeightedSampleQcom,
                feature: "WEIGHT_SAMPLED_IMAGE_BIT_QCOM",
            },
            Some("VK_QCOM_image_processing"),
        ),
        "06972" => (
            R::QcomFeature {
                op: Op::SampleWeightQcom,
                feature: "WEIGHT_IMAGE_BIT_QCOM",
            },
            Some("VK_QCOM_image_processing"),
        ),
        "06973" => (
            R::QcomFeature {
                op: Op::BoxFilterQcom,
                feature: "BOX_FILTER_SAMPLED_BIT_QCOM",
            },
            Some("VK_QCOM_image_processing"),
        ),
        "06974" => (
            R::QcomFeature {
                op: Op::BlockMatchSsdQcom,
                feature: "BLOCK_MATCHING_BIT_QCOM",
            },
            Some("VK_QCOM_image_processing"),
        ),
        "06975" => (
            R::QcomFeature {
                op: Op::BlockMatchSadQcom,
                feature: "BLOCK_MATCHING_BIT_QCOM",
            },
            Some("VK_QCOM_image_processing"),
        ),
        "09215" => (
            R::QcomFeature {
                op: Op::BlockMatchWindowQcom,
                feature: "BLOCK_MATCHING_BIT_QCOM",
            },
            Some("VK_QCOM_image_processing2"),
        ),
        "09216" => (R::QcomSingleComponent, Some("VK_QCOM_image_processing2")),
        "06976" => (
            R::QcomReferenceCoords { window: false },
            Some("VK_QCOM_image_processing"),
        ),
        "09217" => (
            R::QcomReferenceCoords { window: true },
            Some("VK_QCOM_image_processing2"),
        ),
        "06977" => (
            R::QcomProcessingSampler {
                window: t.contains("Window"),
            },
            Some("VK_QCOM_image_processing"),
        ),
        "06978" => (
            R::QcomNoProcessingSampler {
                window: t.contains("Window"),
            },
            Some("VK_QCOM_image_processing"),
        ),
        "07027" => (
            R::WithoutFormat {
                write: true,
                view: ViewKind::Image,
            },
            None,
        ),
        "07028" => (
            R::WithoutFormat {
                write: false,
                view: ViewKind::Image,
            },
            None,
        ),
        "07029" => (
            R::WithoutFormat {
                write: true,
                view: ViewKind::Buffer,
            },
            None,
        ),
        "07030" => (
            R::WithoutFormat {
                write: false,
                view: ViewKind::Buffer,
            },
            None,
        ),
        "07752" => (R::ViewTypeMatchesDim, None),
        "07753" => (
            R::NumericTypeMatches {
                buffer_views: t.contains("VkBufferView"),
            },
            None,
        ),
        "09600" => (R::LayoutMatches, None),
        "10068" => (R::ArrayIndexInRange, None),
        "09900" => (R::TensorShaderUsage, Some("VK_ARM_tensors")),
        "09905" => (R::TensorRank, Some("VK_ARM_tensors")),
        "09906" => (R::TensorElementType, Some("VK_ARM_tensors")),
        "10678" => (R::TileShadingStages, Some("VK_QCOM_tile_shading")),
        "10679" => (R::NoFeedbackLoopPerTile, Some("VK_QCOM_tile_shading")),
        "10746" => (R::ActiveTileMemory, Some("VK_QCOM_tile_memory_heap")),
        _ => return None,
    };
    Some(Entry::Executable {
        rule,
        note: vendor.map(|e| format!("{NOT_ON_DRIVERS}{e}")),
    })
}

/// The vendor extensions each vendor family needs (for tests that keep the notes honest).
pub fn vendor_extensions(note: &str) -> Vec<&str> {
    note.strip_prefix(NOT_ON_DRIVERS)
        .map(|e| e.split(" or ").collect())
        .unwrap_or_default()
}

/// One access resolved through the bound set to its descriptor and objects.
pub struct Resolved<'a> {
    pub stage: Stage,
    pub index: usize,
    pub access: &'a Access,
    pub bound: Option<&'a BoundSet>,
    pub set: Option<&'a DescriptorSet>,
    pub binding: Option<&'a LayoutBinding>,
    pub descriptor: Option<&'a Descriptor>,
    pub view: Option<&'a ImageView>,
    pub image: Option<&'a Image>,
    pub sampler: Option<&'a Sampler>,
    pub buffer_view: Option<&'a BufferView>,
    pub buffer: Option<&'a Buffer>,
    pub tensor_view: Option<&'a TensorView>,
    pub tensor: Option<&'a Tensor>,
}

impl Resolved<'_> {
    fn at(&self) -> String {
        format!(
            "world.resources.stages[{:?}].accesses[{}] (set {}, binding {}[{}])",
            self.stage, self.index, self.access.set, self.access.binding, self.access.element
        )
    }
    fn image_format(&self) -> Option<&str> {
        self.view.map(|v| v.format.as_str())
    }
    fn view_features(
        &self,
        profile: &crate::DeviceProfile,
    ) -> Option<std::collections::BTreeSet<String>> {
        let v = self.view?;
        let usage = if self.image.is_some_and(|i| i.tiling == Tiling::Linear) {
            Usage::Linear
        } else {
            Usage::Optimal
        };
        formats::features(profile, &v.format, usage)
    }
    fn buffer_view_features(
        &self,
        profile: &crate::DeviceProfile,
    ) -> Option<std::collections::BTreeSet<String>> {
        formats::features(profile, &self.buffer_view?.format, Usage::Buffer)
    }
    fn ty(&self) -> ImageType {
        self.access.image.unwrap_or_default()
    }
    fn is_texel_buffer(&self) -> bool {
        self.buffer_view.is_some()
    }
}

/// Every access of every stage, resolved.
pub fn resolve(rs: &ResourceState) -> Vec<Resolved<'_>> {
    let mut out = vec![];
    for st in &rs.stages {
        for (index, a) in st.accesses.iter().enumerate() {
            let bound = rs.bound(a.set);
            let set = bound.and_then(|b| rs.descriptor_set(&b.descriptor_set));
            let binding = set
                .and_then(|s| rs.set_layout(&s.layout))
                .and_then(|l| l.binding(a.binding));
            let descriptor = set.and_then(|s| s.written(a.binding, a.element));
            let mut r = Resolved {
                stage: st.stage,
                index,
                access: a,
                bound,
                set,
                binding,
                descriptor,
                view: None,
                image: None,
                sampler: None,
                buffer_view: None,
                buffer: None,
                tensor_view: None,
                tensor: None,
            };
            match descriptor {
                Some(Descriptor::Image { view, sampler, .. }) => {
                    r.view = rs.image_view(view);
                    r.image = r.view.and_then(|v| rs.image(&v.image));
                    r.sampler = sampler.as_deref().and_then(|s| rs.sampler(s));
                }
                Some(Descriptor::TexelBuffer { view }) => {
                    r.buffer_view = rs.buffer_view(view);
                    r.buffer = r.buffer_view.and_then(|v| rs.buffer(&v.buffer));
                }
                Some(Descriptor::Buffer { buffer, .. }) => r.buffer = rs.buffer(buffer),
                Some(Descriptor::Tensor { view }) => {
                    r.tensor_view = rs.tensor_view(view);
                    r.tensor = r.tensor_view.and_then(|v| rs.tensor(&v.tensor));
                }
                Some(Descriptor::Sampler { sampler }) => r.sampler = rs.sampler(sampler),
                None => {}
            }
            if let Some([s, b]) = a.sampler_at {
                let d = rs
                    .bound(s)
                    .and_then(|x| rs.descriptor_set(&x.descriptor_set))
                    .and_then(|x| x.written(b, 0));
                if let Some(
                    Descriptor::Sampler { sampler }
                    | Descriptor::Image {
                        sampler: Some(sampler),
                        ..
                    },
                ) = d
                {
                    r.sampler = rs.sampler(sampler);
                }
            }
            out.push(r);
        }
    }
    out
}

/// Whether the descriptor kind fits the layout binding's type.
fn kind_fits(d: &Descriptor, ty: DescriptorType) -> bool {
    use DescriptorType as T;
    match d {
        Descriptor::Image { sampler, .. } => match ty {
            T::CombinedImageSampler => sampler.is_some(),
            T::SampledImage
            | T::StorageImage
            | T::InputAttachment
            | T::SampleWeightImageQcom
            | T::BlockMatchImageQcom => true,
            _ => false,
        },
        Descriptor::Sampler { .. } => ty == T::Sampler,
        Descriptor::TexelBuffer { .. } => {
            matches!(ty, T::UniformTexelBuffer | T::StorageTexelBuffer)
        }
        Descriptor::Buffer { .. } => matches!(ty, T::UniformBuffer | T::StorageBuffer),
        Descriptor::Tensor { .. } => ty == T::TensorArm,
    }
}

/// Why a used descriptor is not valid, if it is not.
fn descriptor_problem(rs: &ResourceState, r: &Resolved) -> Option<String> {
    let Some(set) = r.set else { return None }; // unbound sets are SetsBound's concern
    let Some(binding) = r.binding else {
        return Some(format!(
            "set `{}` has no binding {}",
            set.name, r.access.binding
        ));
    };
    if r.access.element >= binding.count {
        return None; // ArrayIndexInRange's concern
    }
    let Some(d) = r.descriptor else {
        return Some(format!(
            "element {} of binding {} of set `{}` was never written",
            r.access.element, r.access.binding, set.name
        ));
    };
    if !kind_fits(d, binding.ty) {
        return Some(format!(
            "holds a descriptor that is not a valid {:?}",
            binding.ty
        ));
    }
    let missing =
        |what: &str, n: &str| Some(format!("its {what} `{n}` does not exist (destroyed)"));
    match d {
        Descriptor::Image { view, sampler, .. } => {
            match rs.image_view(view) {
                None => return missing("image view", view),
                Some(v) if rs.image(&v.image).is_none() => return missing("image", &v.image),
                _ => {}
            }
            if let Some(s) = sampler {
                if rs.sampler(s).is_none() {
                    return missing("sampler", s);
                }
            }
        }
        Descriptor::Sampler { sampler } if rs.sampler(sampler).is_none() => {
            return missing("sampler", sampler)
        }
        Descriptor::TexelBuffer { view } => match rs.buffer_view(view) {
            None => return missing("buffer view", view),
            Some(v) if rs.buffer(&v.buffer).is_none() => return missing("buffer", &v.buffer),
            _ => {}
        },
        Descriptor::Buffer { buffer, .. } if rs.buffer(buffer).is_none() => {
            return missing("buffer", buffer)
        }
        Descriptor::Tensor { view } => match rs.tensor_view(view) {
            None => return missing("tensor view", view),
            Some(v) if rs.tensor(&v.tensor).is_none() => return missing("tensor", &v.tensor),
            _ => {}
        },
        _ => {}
    }
    None
}

fn launches_anything(cx: &Context) -> bool {
    cx.call
        .dimensions(cx.world)
        .is_none_or(|d| d.iter().all(|&x| x > 0))
}

fn has(set: &Option<std::collections::BTreeSet<String>>, bit: &str) -> bool {
    set.as_ref().is_none_or(|s| s.contains(bit))
}

impl ResourceRule {
    /// Whether the rule speaks of what the shaders statically use (judged even for empty launches),
    /// rather than of what a launch accesses.
    pub fn is_static(&self) -> bool {
        use ResourceRule as R;
        matches!(
            self,
            R::SetsBound
                | R::PushConstantsSet { .. }
                | R::PushConstantsCompatible
                | R::DescriptorsValid { .. }
                | R::SetsNeedPlainPipeline
                | R::BuffersNeedDescriptorBufferPipeline
                | R::TileShadingStages
        )
    }

    /// Appends a failure for each way the world breaks the rule.
    pub fn check(&self, cx: &Context, out: &mut Vec<Failure>) {
        let rs = &cx.world.resources;
        if rs.is_empty() || cx.world.bound_pipeline().is_none() {
            return;
        }
        if !self.is_static() && !launches_anything(cx) {
            return;
        }
        let mut fail = |context: String, problem: String| out.push(Failure { context, problem });
        let profile = cx.profile;
        let feature = |f: &str| cx.world.device.feature(f);
        let via_sets = rs.descriptor_source == DescriptorSource::Sets;
        use ResourceRule as R;
        match self {
            R::SetsBound => {
                let Some(pl) = rs.pipeline_layout.as_deref() else {
                    return;
                };
                for n in rs.used_sets() {
                    match rs.bound(n) {
                        None => fail(format!("set {n}"), "is statically used but no descriptor set is bound to it".into()),
                        Some(b) if !rs.compatible_for_set(&b.layout, pl, n) => fail(
                            format!("set {n}"),
                            format!("was bound with layout `{}`, not compatible for set {n} with the pipeline's `{pl}`", b.layout),
                        ),
                        Some(b) => {
                            // The set itself must have the layout the binding layout has at n.
                            let want = rs.pipeline_layout_named(&b.layout).and_then(|l| l.sets.get(n as usize));
                            let have = rs.descriptor_set(&b.descriptor_set).map(|s| &s.layout);
                            let same = match (want, have) {
                                (Some(w), Some(h)) => rs.set_layout(w).zip(rs.set_layout(h)).is_some_and(|(w, h)| w.bindings == h.bindings),
                                _ => false,
                            };
                            if !same {
                                fail(format!("set {n}"), format!("descriptor set `{}` does not match the layout it was bound with", b.descriptor_set));
                            }
                        }
                    }
                }
            }
            R::PushConstantsSet {
                unless_maintenance4,
            } => {
                if *unless_maintenance4 && feature("maintenance4") {
                    return;
                }
                let Some(pl) = rs.pipeline_layout.as_deref() else {
                    return;
                };
                for st in &rs.stages {
                    let Some([off, size]) = st.push_constants else {
                        continue;
                    };
                    for byte in off..off + size {
                        let ok = rs.pushes.iter().any(|p| {
                            p.offset <= byte
                                && byte < p.offset + p.size
                                && rs.compatible_for_push(&p.layout, pl)
                        });
                        if !ok {
                            fail(format!("world.resources.stages[{:?}].push-constants", st.stage), format!("byte {byte} is used but no push constant value was set for it with a layout compatible with `{pl}`"));
                            break;
                        }
                    }
                }
            }
            R::PushConstantsCompatible => {
                let Some(pl) = rs.pipeline_layout.as_deref() else {
                    return;
                };
                for st in &rs.stages {
                    let Some([off, size]) = st.push_constants else {
                        continue;
                    };
                    for p in &rs.pushes {
                        let overlaps = p.offset < off + size && off < p.offset + p.size;
                        if overlaps && !rs.compatible_for_push(&p.layout, pl) {
                            fail(format!("world.resources.stages[{:?}].push-constants", st.stage), format!("its bytes were pushed with layout `{}`, not compatible for push constants with `{pl}`", p.layout));
                        }
                    }
                }
            }
            R::DescriptorsValid {
                unless_descriptor_buffer,
            } => {
                if !via_sets || (*unless_descriptor_buffer && rs.pipeline_descriptor_buffer) {
                    return;
                }
                // Only sets bound compatibly are the pipeline's: a set bound with an incompatible
                // layout (02697/08600) has no descriptors the pipeline uses.
                let pl = rs.pipeline_layout.as_deref().unwrap_or_default();
                let usable = |n: u32| {
                    rs.bound(n)
                        .is_some_and(|b| rs.compatible_for_set(&b.layout, pl, n))
                };
                for r in resolve(rs).into_iter().filter(|r| usable(r.access.set)) {
                    if let Some(p) = descriptor_problem(rs, &r) {
                        fail(r.at(), p);
                    }
                }
            }
            R::DescriptorBufferDescriptorsValid => {
                if via_sets || !rs.pipeline_descriptor_buffer {
                    return;
                }
                for r in resolve(rs) {
                    if let Some(p) = descriptor_problem(rs, &r) {
                        fail(r.at(), p);
                    }
                }
            }
            R::SetsNeedPlainPipeline => {
                if via_sets && rs.pipeline_descriptor_buffer && !rs.bound_sets.is_empty() {
                    fail("world.resources.bound-sets".into(), "descriptors were bound with vkCmdBindDescriptorSets but the pipeline has DESCRIPTOR_BUFFER_BIT_EXT".into());
                }
            }
            R::BuffersNeedDescriptorBufferPipeline => {
                if !via_sets && !rs.pipeline_descriptor_buffer && !rs.bound_sets.is_empty() {
                    fail("world.resources.bound-sets".into(), "descriptors come from descriptor buffers but the pipeline lacks DESCRIPTOR_BUFFER_BIT_EXT".into());
                }
            }
            R::DescriptorMemoryResident => {
                if !via_sets
                    && rs.pipeline_descriptor_buffer
                    && rs.descriptor_memory_not_resident
                    && !resolve(rs).is_empty()
                {
                    fail(
                        "world.resources.descriptor-memory-not-resident".into(),
                        "descriptors are used from descriptor buffer memory that is not resident"
                            .into(),
                    );
                }
            }
            R::UnnormalizedViewType
            | R::UnnormalizedInstruction
            | R::UnnormalizedBiasOffset
            | R::UnnormalizedLevelsLayers => {
                for r in resolve(rs) {
                    let (Some(s), Some(v)) = (r.sampler, r.view) else {
                        continue;
                    };
                    if !s.unnormalized_coordinates || !r.access.op.samples() {
                        continue;
                    }
                    let a = r.access;
                    match self {
                        R::UnnormalizedViewType if !matches!(v.view_type, ViewType::OneD | ViewType::TwoD) => {
                            fail(r.at(), format!("sampler `{}` uses unnormalized coordinates on view `{}` of type {:?}", s.name, v.name, v.view_type))
                        }
                        R::UnnormalizedInstruction if a.implicit_lod || a.dref || a.proj => {
                            fail(r.at(), format!("sampler `{}` uses unnormalized coordinates with an ImplicitLod, Dref or Proj instruction", s.name))
                        }
                        R::UnnormalizedBiasOffset if a.lod_bias || a.offset => {
                            fail(r.at(), format!("sampler `{}` uses unnormalized coordinates with a LOD bias or offset", s.name))
                        }
                        R::UnnormalizedLevelsLayers if v.level_count != 1 || v.layer_count != 1 => fail(
                            r.at(),
                            format!("sampler `{}` uses unnormalized coordinates on view `{}` with {} levels and {} layers", s.name, v.name, v.level_count, v.layer_count),
                        ),
                        _ => {}
                    }
                }
            }
            R::InRange {
                uniform,
                pipeline_robustness,
            } => {
                if feature("robustBufferAccess") {
                    return;
                }
                for st in &rs.stages {
                    let robust = if *uniform {
                        st.robustness.uniform_buffers
                    } else {
                        st.robustness.storage_buffers
                    };
                    if *pipeline_robustness && robust {
                        continue;
                    }
                    for r in resolve(rs).into_iter().filter(|r| r.stage == st.stage) {
                        let want = if *uniform {
                            DescriptorType::UniformBuffer
                        } else {
                            DescriptorType::StorageBuffer
                        };
                        if r.binding.map(|b| b.ty) != Some(want) {
                            continue;
                        }
                        let (Some(Descriptor::Buffer { offset, range, .. }), Some(b), Some([o, n])) =
                            (r.descriptor, r.buffer, r.access.bytes)
                        else {
                            continue;
                        };
                        let len = range.unwrap_or(b.size.saturating_sub(*offset));
                        if o.saturating_add(n) > len {
                            fail(
                                r.at(),
                                format!(
                                    "accesses bytes [{o}, {}) of a {len}-byte descriptor range",
                                    o + n
                                ),
                            );
                        }
                    }
                }
            }
            R::ImageAtomicFeature | R::TexelBufferAtomicFeature => {
                for r in resolve(rs) {
                    if r.access.op != Op::Atomic {
                        continue;
                    }
                    if matches!(self, R::ImageAtomicFeature)
                        && r.view.is_some()
                        && !has(&r.view_features(profile), "STORAGE_IMAGE_ATOMIC_BIT")
                    {
                        fail(
                            r.at(),
                            format!(
                                "format {} lacks STORAGE_IMAGE_ATOMIC_BIT",
                                r.image_format().unwrap_or("?")
                            ),
                        );
                    }
                    if matches!(self, R::TexelBufferAtomicFeature)
                        && r.binding
                            .is_some_and(|b| b.ty == DescriptorType::StorageTexelBuffer)
                        && r.buffer_view.is_some()
                        && !has(
                            &r.buffer_view_features(profile),
                            "STORAGE_TEXEL_BUFFER_ATOMIC_BIT",
                        )
                    {
                        fail(
                            r.at(),
                            format!(
                                "format {} lacks STORAGE_TEXEL_BUFFER_ATOMIC_BIT",
                                r.buffer_view.map_or("?", |v| v.format.as_str())
                            ),
                        );
                    }
                }
            }
            R::CubicFeature
            | R::CubicViewType { .. }
            | R::CubicSupport { .. }
            | R::CubicRangeClamp
            | R::CubicWeights
            | R::RangeClampNeedsCubic => {
                for r in resolve(rs) {
                    let (Some(s), Some(v)) = (r.sampler, r.view) else {
                        continue;
                    };
                    if !r.access.op.samples() {
                        continue;
                    }
                    let cubic = s.filters(Filter::CubicExt);
                    let f = r.view_features(profile);
                    match self {
                        R::CubicFeature if cubic && !has(&f, "SAMPLED_IMAGE_FILTER_CUBIC_BIT_EXT") => {
                            fail(r.at(), format!("view `{}` ({}) is sampled with CUBIC but lacks SAMPLED_IMAGE_FILTER_CUBIC_BIT_EXT", v.name, v.format))
                        }
                        R::CubicViewType { unless_filter_cubic }
                            if cubic
                                && matches!(v.view_type, ViewType::ThreeD | ViewType::Cube | ViewType::CubeArray)
                                && !(*unless_filter_cubic && cx.world.device.extension("VK_EXT_filter_cubic")) =>
                        {
                            fail(r.at(), format!("view `{}` of type {:?} is sampled with CUBIC", v.name, v.view_type))
                        }
                        R::CubicSupport { minmax } if cubic && (!*minmax || matches!(s.reduction, Reduction::Min | Reduction::Max)) => {
                            // The model's stand-in for VkFilterCubicImageViewImageFormatPropertiesEXT,
                            // which profiles do not capture: 2D and 2D array views of a format with the
                            // cubic feature (and the min/max feature for min/max reduction).
                            let two_d = matches!(v.view_type, ViewType::TwoD | ViewType::TwoDArray);
                            let ok = two_d && has(&f, "SAMPLED_IMAGE_FILTER_CUBIC_BIT_EXT") && (!*minmax || has(&f, "SAMPLED_IMAGE_FILTER_MINMAX_BIT"));
                            if !ok {
                                fail(r.at(), format!("view `{}` ({:?}, {}) does not support cubic{} filtering", v.name, v.view_type, v.format, if *minmax { " min/max" } else { "" }));
                            }
                        }
                        R::CubicRangeClamp if cubic && s.reduction == Reduction::WeightedAverageRangeclampQcom && !feature("cubicRangeClamp") => {
                            fail(r.at(), "range-clamp reduction with CUBIC sampling but cubicRangeClamp is not enabled".into())
                        }
                        R::RangeClampNeedsCubic if s.reduction == Reduction::WeightedAverageRangeclampQcom && !cubic => {
                            fail(r.at(), format!("sampler `{}` has range-clamp reduction but does not filter with CUBIC", s.name))
                        }
                        R::CubicWeights if cubic && s.cubic_weights != CubicWeights::CatmullRom && !feature("selectableCubicWeights") => {
                            fail(r.at(), format!("cubic weights {:?} but selectableCubicWeights is not enabled", s.cubic_weights))
                        }
                        _ => {}
                    }
                }
            }
            R::CornerSampledClamp => {
                for r in resolve(rs) {
                    let (Some(s), Some(i)) = (r.sampler, r.image) else {
                        continue;
                    };
                    if i.corner_sampled
                        && r.access.op.samples()
                        && s.address_modes
                            .iter()
                            .any(|m| *m != AddressMode::ClampToEdge)
                    {
                        fail(
                            r.at(),
                            format!(
                                "corner-sampled image `{}` is sampled with address modes {:?}",
                                i.name, s.address_modes
                            ),
                        );
                    }
                }
            }
            R::WriteComponents { view, a8_exempt } => {
                for r in resolve(rs) {
                    if r.access.op != Op::Write {
                        continue;
                    }
                    let format = match view {
                        ViewKind::Image => r.view.map(|v| v.format.as_str()),
                        ViewKind::Buffer => r.buffer_view.map(|v| v.format.as_str()),
                    };
                    let Some(format) = format else { continue };
                    if *a8_exempt && is_a8(format) {
                        continue;
                    }
                    let (Some(fi), n) = (
                        formats::info(format),
                        r.access.texel_components.unwrap_or(4),
                    ) else {
                        continue;
                    };
                    if n < fi.components {
                        fail(
                            r.at(),
                            format!(
                                "writes a {n}-component texel to a {}-component format {format}",
                                fi.components
                            ),
                        );
                    }
                }
            }
            R::WriteComponentsA8 => {
                for r in resolve(rs) {
                    if r.access.op == Op::Write
                        && r.view.is_some_and(|v| is_a8(&v.format))
                        && r.access.texel_components.unwrap_or(4) != 4
                    {
                        fail(
                            r.at(),
                            "writes a texel of fewer than four components to an A8_UNORM view"
                                .into(),
                        );
                    }
                }
            }
            R::SampledTypeWidth { view, sixty_four } => {
                for r in resolve(rs) {
                    let format = match view {
                        ViewKind::Image => r.view.map(|v| v.format.as_str()),
                        ViewKind::Buffer => r.buffer_view.map(|v| v.format.as_str()),
                    };
                    let (Some(fi), Some(t)) = (format.and_then(formats::info), r.access.image)
                    else {
                        continue;
                    };
                    if (fi.width == 64) == *sixty_four {
                        let want = if *sixty_four { 64 } else { 32 };
                        if t.width != want {
                            fail(
                                r.at(),
                                format!(
                                    "format {} is accessed through a Sampled Type of width {}",
                                    format.unwrap_or("?"),
                                    t.width
                                ),
                            );
                        }
                    }
                }
            }
            R::SparseInt64Atomics { view } => {
                if feature("sparseImageInt64Atomics") {
                    return;
                }
                for r in resolve(rs) {
                    if r.access.op != Op::Atomic || r.ty().width != 64 {
                        continue;
                    }
                    let sparse = match view {
                        ViewKind::Image => r.image.is_some_and(|i| i.sparse_residency),
                        ViewKind::Buffer => {
                            r.is_texel_buffer() && r.buffer.is_some_and(|b| b.sparse_residency)
                        }
                    };
                    if sparse {
                        fail(r.at(), "a 64-bit atomic on a sparse-residency resource without sparseImageInt64Atomics".into());
                    }
                }
            }
            R::LinearFilterFeature {
                mipmap,
                weighted_only,
            } => {
                for r in resolve(rs) {
                    let (Some(s), Some(_)) = (r.sampler, r.view) else {
                        continue;
                    };
                    if !r.access.op.samples() || s.compare_enable {
                        continue;
                    }
                    let linear = if *mipmap {
                        s.mipmap_mode == MipmapMode::Linear
                    } else {
                        s.filters(Filter::Linear)
                    };
                    if linear
                        && (!*weighted_only || s.reduction == Reduction::WeightedAverage)
                        && !has(&r.view_features(profile), "SAMPLED_IMAGE_FILTER_LINEAR_BIT")
                    {
                        fail(
                            r.at(),
                            format!(
                                "{} filtering of {} which lacks SAMPLED_IMAGE_FILTER_LINEAR_BIT",
                                if *mipmap { "linear mipmap" } else { "linear" },
                                r.image_format().unwrap_or("?")
                            ),
                        );
                    }
                }
            }
            R::MinmaxFilterFeature { mipmap } => {
                for r in resolve(rs) {
                    let (Some(s), Some(_)) = (r.sampler, r.view) else {
                        continue;
                    };
                    if !r.access.op.samples() {
                        continue;
                    }
                    let linear = if *mipmap {
                        s.mipmap_mode == MipmapMode::Linear
                    } else {
                        s.filters(Filter::Linear)
                    };
                    if linear
                        && matches!(s.reduction, Reduction::Min | Reduction::Max)
                        && !has(&r.view_features(profile), "SAMPLED_IMAGE_FILTER_MINMAX_BIT")
                    {
                        fail(r.at(), format!("min/max reduction of {} which lacks SAMPLED_IMAGE_FILTER_MINMAX_BIT", r.image_format().unwrap_or("?")));
                    }
                }
            }
            R::DepthCompareAspect | R::DepthCompareFeature => {
                for r in resolve(rs) {
                    let Some(v) = r.view else { continue };
                    if !(r.access.op == Op::Sample && r.access.dref) {
                        continue;
                    }
                    if matches!(self, R::DepthCompareAspect)
                        && !matches!(v.aspect, Aspect::Depth | Aspect::DepthStencil)
                    {
                        fail(
                            r.at(),
                            format!(
                                "view `{}` is sampled with depth comparison but its aspect is {:?}",
                                v.name, v.aspect
                            ),
                        );
                    }
                    if matches!(self, R::DepthCompareFeature)
                        && !has(
                            &r.view_features(profile),
                            "SAMPLED_IMAGE_DEPTH_COMPARISON_BIT",
                        )
                    {
                        fail(
                            r.at(),
                            format!("{} lacks SAMPLED_IMAGE_DEPTH_COMPARISON_BIT", v.format),
                        );
                    }
                }
            }
            R::YcbcrSampleOnly | R::YcbcrNoOffset => {
                for r in resolve(rs) {
                    let ycbcr = r.sampler.is_some_and(|s| s.ycbcr_conversion)
                        || r.view.is_some_and(|v| v.ycbcr_conversion);
                    if !ycbcr {
                        continue;
                    }
                    if matches!(self, R::YcbcrSampleOnly) && r.access.op != Op::Sample {
                        fail(
                            r.at(),
                            format!("a Y′CbCr object is used with {:?}", r.access.op),
                        );
                    }
                    if matches!(self, R::YcbcrNoOffset) && r.access.offset {
                        fail(
                            r.at(),
                            "a Y′CbCr object is used with an offset operand".into(),
                        );
                    }
                }
            }
            R::QcomFeature { op, feature: bit } => {
                for r in resolve(rs) {
                    if r.access.op == *op
                        && r.view.is_some()
                        && !has(&r.view_features(profile), bit)
                    {
                        fail(
                            r.at(),
                            format!(
                                "{:?} reads {} which lacks {bit}",
                                op,
                                r.image_format().unwrap_or("?")
                            ),
                        );
                    }
                }
            }
            R::QcomSingleComponent => {
                for r in resolve(rs) {
                    if r.access.op != Op::BlockMatchWindowQcom {
                        continue;
                    }
                    if let Some(fi) = r.image_format().and_then(formats::info) {
                        if fi.components != 1 {
                            fail(
                                r.at(),
                                format!(
                                    "block match window reads {}-component {}",
                                    fi.components,
                                    r.image_format().unwrap_or("?")
                                ),
                            );
                        }
                    }
                }
            }
            R::QcomReferenceCoords { window } => {
                for r in resolve(rs) {
                    let op_ok = if *window {
                        r.access.op == Op::BlockMatchWindowQcom
                    } else {
                        matches!(r.access.op, Op::BlockMatchSsdQcom | Op::BlockMatchSadQcom)
                    };
                    let (true, Some([x, y]), Some(i)) = (op_ok, r.access.reference, r.image) else {
                        continue;
                    };
                    if x < 0 || y < 0 || x >= i.extent[0] as i64 || y >= i.extent[1].max(1) as i64 {
                        fail(
                            r.at(),
                            format!(
                                "reference coordinates ({x}, {y}) lie outside image `{}` ({}×{})",
                                i.name, i.extent[0], i.extent[1]
                            ),
                        );
                    }
                }
            }
            R::QcomProcessingSampler { window } | R::QcomNoProcessingSampler { window } => {
                for r in resolve(rs) {
                    let Some(s) = r.sampler else { continue };
                    let processing = r.access.op.is_qcom_processing()
                        && (*window || r.access.op != Op::BlockMatchWindowQcom);
                    if matches!(self, R::QcomProcessingSampler { .. })
                        && processing
                        && !s.image_processing
                    {
                        fail(
                            r.at(),
                            format!(
                                "{:?} uses sampler `{}` created without IMAGE_PROCESSING_BIT_QCOM",
                                r.access.op, s.name
                            ),
                        );
                    }
                    if matches!(self, R::QcomNoProcessingSampler { .. })
                        && !processing
                        && s.image_processing
                    {
                        fail(
                            r.at(),
                            format!(
                                "{:?} uses sampler `{}` created with IMAGE_PROCESSING_BIT_QCOM",
                                r.access.op, s.name
                            ),
                        );
                    }
                }
            }
            R::WithoutFormat { write, view } => {
                let (op, bit) = if *write {
                    (Op::Write, "STORAGE_WRITE_WITHOUT_FORMAT_BIT")
                } else {
                    (Op::Read, "STORAGE_READ_WITHOUT_FORMAT_BIT")
                };
                for r in resolve(rs) {
                    if r.access.op != op || !r.ty().format_unknown {
                        continue;
                    }
                    let (present, f) = match view {
                        ViewKind::Image => (r.view.is_some(), r.view_features(profile)),
                        ViewKind::Buffer => {
                            (r.buffer_view.is_some(), r.buffer_view_features(profile))
                        }
                    };
                    if present && !has(&f, bit) {
                        fail(
                            r.at(),
                            format!(
                                "an Unknown-format storage {} of a format lacking {bit}",
                                if *write { "write" } else { "read" }
                            ),
                        );
                    }
                }
            }
            R::ViewTypeMatchesDim => {
                for r in resolve(rs) {
                    let (Some(v), Some(t)) = (r.view, r.access.image) else {
                        continue;
                    };
                    if !view_type_matches(v.view_type, t.dim, t.arrayed) {
                        fail(
                            r.at(),
                            format!(
                                "view `{}` of type {:?} is accessed as Dim {:?}{}",
                                v.name,
                                v.view_type,
                                t.dim,
                                if t.arrayed { " Arrayed" } else { "" }
                            ),
                        );
                    }
                }
            }
            R::NumericTypeMatches { buffer_views } => {
                for r in resolve(rs) {
                    let Some(t) = r.access.image else { continue };
                    let format = match (r.view, r.buffer_view) {
                        (Some(v), _) => &v.format,
                        (None, Some(b)) if *buffer_views => &b.format,
                        _ => continue,
                    };
                    if let Some(fi) = formats::info(format) {
                        if fi.numeric != t.sampled_type {
                            fail(
                                r.at(),
                                format!(
                                    "format {format} is {:?} but the Sampled Type is {:?}",
                                    fi.numeric, t.sampled_type
                                ),
                            );
                        }
                    }
                }
            }
            R::LayoutMatches => {
                for r in resolve(rs) {
                    let (Some(Descriptor::Image { layout, .. }), Some(i), Some(b)) =
                        (r.descriptor, r.image, r.binding)
                    else {
                        continue;
                    };
                    if b.ty.has_image_layout() && i.layout != *layout {
                        fail(
                            r.at(),
                            format!(
                                "image `{}` is in {:?} but the descriptor was written with {:?}",
                                i.name, i.layout, layout
                            ),
                        );
                    }
                }
            }
            R::ArrayIndexInRange => {
                for r in resolve(rs) {
                    if let Some(b) = r.binding {
                        if r.access.element >= b.count {
                            fail(
                                r.at(),
                                format!(
                                    "index {} is not less than the descriptor count {}",
                                    r.access.element, b.count
                                ),
                            );
                        }
                    }
                }
            }
            R::TensorShaderUsage | R::TensorRank | R::TensorElementType => {
                for r in resolve(rs) {
                    let (Some(tv), Some(t)) = (r.tensor_view, r.tensor) else {
                        continue;
                    };
                    if r.access.op != Op::Tensor {
                        continue;
                    }
                    match self {
                        R::TensorShaderUsage if !t.shader_usage => fail(
                            r.at(),
                            format!("tensor `{}` was created without SHADER usage", t.name),
                        ),
                        R::TensorRank
                            if r.access.tensor_rank.is_some_and(|k| k != t.dimension_count) =>
                        {
                            fail(
                                r.at(),
                                format!(
                                    "Rank {} but tensor `{}` has {} dimensions",
                                    r.access.tensor_rank.unwrap_or(0),
                                    t.name,
                                    t.dimension_count
                                ),
                            )
                        }
                        R::TensorElementType => {
                            let ty = r.ty();
                            if let Some(fi) = formats::info(&tv.format) {
                                if fi.numeric != ty.sampled_type || fi.width != ty.width {
                                    fail(
                                        r.at(),
                                        format!(
                                            "element type {:?}{} is not compatible with {}",
                                            ty.sampled_type, ty.width, tv.format
                                        ),
                                    );
                                }
                            }
                        }
                        _ => {}
                    }
                }
            }
            R::TileShadingStages => {
                if rs.tile.in_tile_shading_render_pass {
                    fail("commandBuffer".into(), "is inside a tile shading render pass and the ray tracing stages are not vertex, fragment or compute".into());
                }
            }
            R::NoFeedbackLoopPerTile => {
                if !rs.tile.per_tile_execution {
                    return;
                }
                for r in resolve(rs) {
                    if let Some(i) = r
                        .image
                        .filter(|i| i.layout == ImageLayout::AttachmentFeedbackLoopOptimal)
                    {
                        fail(r.at(), format!("image `{}` is accessed in ATTACHMENT_FEEDBACK_LOOP_OPTIMAL under per-tile execution", i.name));
                    }
                }
            }
            R::ActiveTileMemory => {
                for r in resolve(rs) {
                    let mem = r
                        .image
                        .and_then(|i| i.tile_memory.as_ref())
                        .or(r.buffer.and_then(|b| b.tile_memory.as_ref()));
                    if let Some(m) = mem {
                        if rs.tile.bound_memory.as_ref() != Some(m) {
                            fail(r.at(), format!("resource is bound to tile memory `{m}`, which is not the command buffer's bound tile memory"));
                        }
                    }
                }
            }
        }
    }
}

fn is_a8(format: &str) -> bool {
    matches!(format, "VK_FORMAT_A8_UNORM" | "VK_FORMAT_A8_UNORM_KHR")
}
