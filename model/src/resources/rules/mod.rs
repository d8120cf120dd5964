//! The resource-access rules the trace commands share with draw/dispatch: which VUID tag is which
//! [`ResourceRule`] (the text decides between versions' wordings), and what each rule checks in a
//! world's [`ResourceState`].
//!
//! Rules whose resources no captured driver exposes (QCOM image processing and tile shading, cubic
//! filtering, ARM tensors) are executable here all the same; their row carries a note saying they
//! cannot be exercised on a driver the project can reach ([`Entry::Executable::note`]).

mod check;
mod resolve;

pub use resolve::{resolve, vendor_extensions, Resolved};

use super::*;
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
    /// 09600: the subresources of an accessed descriptor of one of `types` (the types the VUID text
    /// lists: sampled, storage and QCOM images and input attachments — not combined image samplers)
    /// are in the layout the descriptor was written with.
    LayoutMatches {
        types: Vec<crate::resources::DescriptorType>,
    },
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
        "09600" => (
            R::LayoutMatches {
                types: crate::resources::DescriptorType::named_in(t),
            },
            None,
        ),
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
