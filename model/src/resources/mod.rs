//! The world of resources a launch's shaders touch: descriptor set layouts and sets with
//! their written descriptors, samplers, images and image views, buffers and buffer views, tensors,
//! pipeline layouts and what was bound and pushed with them, and a per-stage summary of each shader's
//! static resource use. The rules every dispatching command shares with draw/dispatch are judged
//! against it by [`rules`].
//!
//! Everything is symbolic, like the rest of the world: objects are named, a descriptor names the view
//! or buffer it was written with, an access names the set and binding it goes through. A name that
//! no object carries is a destroyed (or never created) object. Format features come from the device
//! profile (see [`formats`]).
//!
//! The model reads a stage's accesses as performed by every invocation of a launch that launches
//! anything; the harness places them in straight-line code, so static and dynamic use coincide.

pub mod formats;
pub mod rules;

pub use rules::{rule_for, Entry, ResourceRule};

/// A shader stage of a ray tracing pipeline.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    Raygen,
    AnyHit,
    ClosestHit,
    Miss,
    Intersection,
    Callable,
}

/// `VkDescriptorType`, the ones these rules speak of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DescriptorType {
    Sampler,
    CombinedImageSampler,
    SampledImage,
    StorageImage,
    UniformTexelBuffer,
    StorageTexelBuffer,
    UniformBuffer,
    StorageBuffer,
    InputAttachment,
    SampleWeightImageQcom,
    BlockMatchImageQcom,
    TensorArm,
}

impl DescriptorType {
    /// The type a `VK_DESCRIPTOR_TYPE_*` name stands for, if it is one these rules speak of.
    pub fn from_vk_name(name: &str) -> Option<DescriptorType> {
        use DescriptorType as D;
        Some(match name.strip_prefix("VK_DESCRIPTOR_TYPE_")? {
            "SAMPLER" => D::Sampler,
            "COMBINED_IMAGE_SAMPLER" => D::CombinedImageSampler,
            "SAMPLED_IMAGE" => D::SampledImage,
            "STORAGE_IMAGE" => D::StorageImage,
            "UNIFORM_TEXEL_BUFFER" => D::UniformTexelBuffer,
            "STORAGE_TEXEL_BUFFER" => D::StorageTexelBuffer,
            "UNIFORM_BUFFER" => D::UniformBuffer,
            "STORAGE_BUFFER" => D::StorageBuffer,
            "INPUT_ATTACHMENT" => D::InputAttachment,
            "SAMPLE_WEIGHT_IMAGE_QCOM" => D::SampleWeightImageQcom,
            "BLOCK_MATCH_IMAGE_QCOM" => D::BlockMatchImageQcom,
            "TENSOR_ARM" => D::TensorArm,
            _ => return None,
        })
    }

    /// The descriptor types a VUID text names (`VK_DESCRIPTOR_TYPE_*`), in the order written.
    pub fn named_in(text: &str) -> Vec<DescriptorType> {
        let mut out = Vec::new();
        for (at, _) in text.match_indices("VK_DESCRIPTOR_TYPE_") {
            let name: String = text[at..]
                .chars()
                .take_while(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            if let Some(t) = DescriptorType::from_vk_name(&name) {
                if !out.contains(&t) {
                    out.push(t);
                }
            }
        }
        out
    }
}

/// `VkImageLayout`, the ones a descriptor is written with or an image is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImageLayout {
    Undefined,
    #[default]
    General,
    ShaderReadOnlyOptimal,
    ReadOnlyOptimal,
    DepthStencilReadOnlyOptimal,
    TransferDstOptimal,
    AttachmentFeedbackLoopOptimal,
}

/// `VkImageViewType`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ViewType {
    #[serde(rename = "1d")]
    OneD,
    #[default]
    #[serde(rename = "2d")]
    TwoD,
    #[serde(rename = "3d")]
    ThreeD,
    Cube,
    #[serde(rename = "1d-array")]
    OneDArray,
    #[serde(rename = "2d-array")]
    TwoDArray,
    CubeArray,
}

/// The `Dim` operand of `OpTypeImage`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Dim {
    #[serde(rename = "1d")]
    OneD,
    #[default]
    #[serde(rename = "2d")]
    TwoD,
    #[serde(rename = "3d")]
    ThreeD,
    Cube,
    Buffer,
}

/// The image view types a `Dim` with `Arrayed` accepts (spirvenv's image dimension table).
pub fn view_type_matches(view: ViewType, dim: Dim, arrayed: bool) -> bool {
    matches!(
        (view, dim, arrayed),
        (ViewType::OneD, Dim::OneD, false)
            | (ViewType::OneDArray, Dim::OneD, true)
            | (ViewType::TwoD, Dim::TwoD, false)
            | (ViewType::TwoDArray, Dim::TwoD, true)
            | (ViewType::ThreeD, Dim::ThreeD, false)
            | (ViewType::Cube, Dim::Cube, false)
            | (ViewType::CubeArray, Dim::Cube, true)
    )
}

/// A numeric type class: of a format, of an `OpTypeImage`'s `Sampled Type`, of a tensor element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Numeric {
    #[default]
    Float,
    Int,
    Uint,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Filter {
    #[default]
    Nearest,
    Linear,
    CubicExt,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MipmapMode {
    #[default]
    Nearest,
    Linear,
}

/// `VkSamplerReductionMode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reduction {
    #[default]
    WeightedAverage,
    Min,
    Max,
    WeightedAverageRangeclampQcom,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AddressMode {
    Repeat,
    MirroredRepeat,
    #[default]
    ClampToEdge,
    ClampToBorder,
    MirrorClampToEdge,
}

/// `VkCubicFilterWeightsQCOM` (Catmull-Rom when the sampler names none).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CubicWeights {
    #[default]
    CatmullRom,
    ZeroTangentCardinal,
    BSpline,
    MitchellNetravali,
}

/// A `VkSampler`.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sampler {
    pub name: String,
    pub mag_filter: Filter,
    pub min_filter: Filter,
    pub mipmap_mode: MipmapMode,
    pub reduction: Reduction,
    pub compare_enable: bool,
    pub unnormalized_coordinates: bool,
    /// U, V, W.
    pub address_modes: [AddressMode; 3],
    pub cubic_weights: CubicWeights,
    /// Created with a `VkSamplerYcbcrConversionInfo`.
    pub ycbcr_conversion: bool,
    /// Created with `VK_SAMPLER_CREATE_IMAGE_PROCESSING_BIT_QCOM`.
    pub image_processing: bool,
}

impl Sampler {
    pub fn filters(&self, f: Filter) -> bool {
        self.mag_filter == f || self.min_filter == f
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Tiling {
    #[default]
    Optimal,
    Linear,
}

/// A `VkImage`: what the rules need of its creation and its current state.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Image {
    pub name: String,
    /// `VK_FORMAT_…` name.
    pub format: String,
    pub extent: [u32; 3],
    pub tiling: Tiling,
    /// `VK_IMAGE_CREATE_CORNER_SAMPLED_BIT_NV`.
    pub corner_sampled: bool,
    /// `VK_IMAGE_CREATE_SPARSE_RESIDENCY_BIT`.
    pub sparse_residency: bool,
    /// The layout every subresource is in when the launch executes.
    pub layout: ImageLayout,
    /// The `VkDeviceMemory` from a `VK_MEMORY_HEAP_TILE_MEMORY_BIT_QCOM` heap it is bound to, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tile_memory: Option<String>,
}

/// `VkImageAspectFlags` of a view, as one value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Aspect {
    #[default]
    Color,
    Depth,
    Stencil,
    DepthStencil,
}

/// A `VkImageView`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageView {
    pub name: String,
    pub image: String,
    #[serde(default)]
    pub view_type: ViewType,
    pub format: String,
    #[serde(default)]
    pub aspect: Aspect,
    #[serde(default = "one")]
    pub level_count: u32,
    #[serde(default = "one")]
    pub layer_count: u32,
    /// Created with a `VkSamplerYcbcrConversionInfo`.
    #[serde(default, skip_serializing_if = "is_false")]
    pub ycbcr_conversion: bool,
}

/// A `VkBuffer` that descriptors use (the SBT and indirect buffers live in `World::buffers`).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Buffer {
    pub name: String,
    pub size: u64,
    /// `VK_BUFFER_CREATE_SPARSE_RESIDENCY_BIT`.
    pub sparse_residency: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tile_memory: Option<String>,
}

/// A `VkBufferView`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BufferView {
    pub name: String,
    pub buffer: String,
    pub format: String,
}

/// A `VkTensorARM`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tensor {
    pub name: String,
    /// `pDescription->usage` contains `VK_TENSOR_USAGE_SHADER_BIT_ARM`.
    #[serde(default = "yes")]
    pub shader_usage: bool,
    pub dimension_count: u32,
    pub format: String,
}

/// A `VkTensorViewARM`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TensorView {
    pub name: String,
    pub tensor: String,
    pub format: String,
}

/// One binding of a descriptor set layout.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayoutBinding {
    pub binding: u32,
    #[serde(rename = "type")]
    pub ty: DescriptorType,
    #[serde(default = "one")]
    pub count: u32,
    /// `pImmutableSamplers`: the sampler of each element (empty: none), which a write's sampler cannot
    /// replace. A sampler with a Y′CbCr conversion is only ever one of these.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub immutable_samplers: Vec<String>,
}

/// A `VkDescriptorSetLayout`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetLayout {
    pub name: String,
    #[serde(default)]
    pub bindings: Vec<LayoutBinding>,
}

impl SetLayout {
    pub fn binding(&self, b: u32) -> Option<&LayoutBinding> {
        self.bindings.iter().find(|x| x.binding == b)
    }
}

/// A push constant range of a pipeline layout (all ray tracing stages).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PushRange {
    pub offset: u32,
    pub size: u32,
}

/// A `VkPipelineLayout`: set layouts by set number, push constant ranges.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineLayout {
    pub name: String,
    #[serde(default)]
    pub sets: Vec<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub push_ranges: Vec<PushRange>,
}

/// What a descriptor was written with.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Descriptor {
    /// An image descriptor (sampled, storage, combined, input attachment, QCOM weight / block match).
    Image {
        view: String,
        /// The immutable or written sampler of a combined image sampler.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sampler: Option<String>,
        /// `imageLayout` of the write.
        #[serde(default)]
        layout: ImageLayout,
    },
    Sampler {
        sampler: String,
    },
    TexelBuffer {
        view: String,
    },
    /// `range: None` is `VK_WHOLE_SIZE`.
    Buffer {
        buffer: String,
        #[serde(default)]
        offset: u64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        range: Option<u64>,
    },
    Tensor {
        view: String,
    },
}

/// One written array element of a descriptor set.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Write {
    pub binding: u32,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub element: u32,
    pub descriptor: Descriptor,
}

/// A `VkDescriptorSet` (or, with descriptor buffers, the descriptors at one set's buffer offset).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DescriptorSet {
    pub name: String,
    pub layout: String,
    #[serde(default)]
    pub writes: Vec<Write>,
}

impl DescriptorSet {
    pub fn written(&self, binding: u32, element: u32) -> Option<&Descriptor> {
        self.writes
            .iter()
            .rev()
            .find(|w| w.binding == binding && w.element == element)
            .map(|w| &w.descriptor)
    }
}

/// A set bound at the ray tracing bind point with `vkCmdBindDescriptorSets` (or a descriptor buffer
/// offset set with `vkCmdSetDescriptorBufferOffsetsEXT`), and the pipeline layout it was bound with.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundSet {
    pub set: u32,
    pub descriptor_set: String,
    pub layout: String,
}

/// One `vkCmdPushConstants` at the ray tracing stages.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Push {
    pub layout: String,
    pub offset: u32,
    pub size: u32,
}

/// The instruction an access is made with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Op {
    /// `OpImageSample*` / `OpImageSparseSample*` (see the access's `implicit-lod`, `dref`, `proj`, …).
    #[default]
    Sample,
    /// `OpImageFetch`.
    Fetch,
    /// `OpImageRead` of a storage image or storage texel buffer.
    Read,
    /// `OpImageWrite`.
    Write,
    /// An atomic instruction on an image or texel buffer (`OpImageTexelPointer`).
    Atomic,
    /// `OpLoad` from a uniform or storage buffer.
    Load,
    /// `OpStore` to a storage buffer.
    Store,
    /// `OpImageWeightedSampleQCOM` sampling the view.
    WeightedSampleQcom,
    /// The weight image of an `OpImageWeightedSampleQCOM`.
    SampleWeightQcom,
    BoxFilterQcom,
    BlockMatchSsdQcom,
    BlockMatchSadQcom,
    /// `OpImageBlockMatchWindow*QCOM` and `OpImageBlockMatchGather*QCOM`.
    BlockMatchWindowQcom,
    /// A read or write of an `OpTypeTensorARM` resource.
    Tensor,
}

impl Op {
    pub fn is_qcom_processing(self) -> bool {
        matches!(
            self,
            Op::WeightedSampleQcom
                | Op::BoxFilterQcom
                | Op::BlockMatchSsdQcom
                | Op::BlockMatchSadQcom
                | Op::BlockMatchWindowQcom
        )
    }
    /// Whether the access samples through a sampler (filtering rules apply).
    pub fn samples(self) -> bool {
        matches!(
            self,
            Op::Sample | Op::WeightedSampleQcom | Op::BoxFilterQcom
        )
    }
}

/// The `OpTypeImage` an image access goes through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImageType {
    pub dim: Dim,
    pub arrayed: bool,
    /// `Sampled Type` class and its `Width`.
    pub sampled_type: Numeric,
    pub width: u32,
    /// `Image Format` is `Unknown`.
    pub format_unknown: bool,
}

impl Default for ImageType {
    fn default() -> Self {
        ImageType {
            dim: Dim::TwoD,
            arrayed: false,
            sampled_type: Numeric::Float,
            width: 32,
            format_unknown: false,
        }
    }
}

/// One access a stage's shader makes through a descriptor.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Access {
    pub set: u32,
    pub binding: u32,
    /// The array index used.
    #[serde(skip_serializing_if = "is_zero")]
    pub element: u32,
    pub op: Op,
    /// The `OpTypeImage` (None for buffers and tensors).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image: Option<ImageType>,
    /// A separate sampler combined with the image (`[set, binding]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampler_at: Option<[u32; 2]>,
    #[serde(skip_serializing_if = "is_false")]
    pub implicit_lod: bool,
    #[serde(skip_serializing_if = "is_false")]
    pub dref: bool,
    #[serde(skip_serializing_if = "is_false")]
    pub proj: bool,
    #[serde(skip_serializing_if = "is_false")]
    pub lod_bias: bool,
    /// `ConstOffset` or `Offset` operand.
    #[serde(skip_serializing_if = "is_false")]
    pub offset: bool,
    /// Components of the `Texel` operand of an `OpImageWrite`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texel_components: Option<u32>,
    /// Bytes `[offset, offset + size)` accessed, relative to the descriptor's range.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bytes: Option<[u64; 2]>,
    /// Reference coordinates of a block match.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<[i64; 2]>,
    /// `Rank` of the `OpTypeTensorARM` (element type: `image.sampled_type` and `width`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tensor_rank: Option<u32>,
}

/// Pipeline robustness a stage was created with, per resource class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StageRobustness {
    /// `ROBUST_BUFFER_ACCESS` or `_2` for `uniformBuffers`.
    pub uniform_buffers: bool,
    pub storage_buffers: bool,
}

/// The static resource use of one stage's shader.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageUse {
    pub stage: Stage,
    #[serde(default)]
    pub accesses: Vec<Access>,
    /// Push constant bytes `[offset, offset + size)` the shader reads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub push_constants: Option<[u32; 2]>,
    #[serde(default, skip_serializing_if = "is_default")]
    pub robustness: StageRobustness,
}

/// Where the launch's descriptors come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DescriptorSource {
    /// `vkCmdBindDescriptorSets`.
    #[default]
    Sets,
    /// `vkCmdSetDescriptorBufferOffsetsEXT`.
    Buffers,
}

/// Tile shading and tile memory state of the command buffer (`VK_QCOM_tile_shading`, `_tile_memory_heap`).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TileState {
    pub in_tile_shading_render_pass: bool,
    pub per_tile_execution: bool,
    /// The tile memory bound with `vkCmdBindTileMemoryQCOM`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bound_memory: Option<String>,
}

/// Everything of the world that the shared resource-access rules speak of. Empty by default: a case
/// whose shaders touch no resource.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ResourceState {
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub set_layouts: Vec<SetLayout>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pipeline_layouts: Vec<PipelineLayout>,
    /// The layout the bound pipeline was created with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pipeline_layout: Option<String>,
    /// The bound pipeline was created with `VK_PIPELINE_CREATE_DESCRIPTOR_BUFFER_BIT_EXT`.
    #[serde(skip_serializing_if = "is_false")]
    pub pipeline_descriptor_buffer: bool,
    #[serde(skip_serializing_if = "is_default")]
    pub descriptor_source: DescriptorSource,
    /// With descriptor buffers: the descriptor buffers' memory is not resident.
    #[serde(skip_serializing_if = "is_false")]
    pub descriptor_memory_not_resident: bool,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub descriptor_sets: Vec<DescriptorSet>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub bound_sets: Vec<BoundSet>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pushes: Vec<Push>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub samplers: Vec<Sampler>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub images: Vec<Image>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub image_views: Vec<ImageView>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub buffers: Vec<Buffer>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub buffer_views: Vec<BufferView>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tensors: Vec<Tensor>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tensor_views: Vec<TensorView>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stages: Vec<StageUse>,
    #[serde(skip_serializing_if = "is_default")]
    pub tile: TileState,
}

impl ResourceState {
    pub fn is_empty(&self) -> bool {
        *self == ResourceState::default()
    }
    pub fn set_layout(&self, n: &str) -> Option<&SetLayout> {
        self.set_layouts.iter().find(|x| x.name == n)
    }
    pub fn pipeline_layout_named(&self, n: &str) -> Option<&PipelineLayout> {
        self.pipeline_layouts.iter().find(|x| x.name == n)
    }
    pub fn descriptor_set(&self, n: &str) -> Option<&DescriptorSet> {
        self.descriptor_sets.iter().find(|x| x.name == n)
    }
    pub fn sampler(&self, n: &str) -> Option<&Sampler> {
        self.samplers.iter().find(|x| x.name == n)
    }
    pub fn image(&self, n: &str) -> Option<&Image> {
        self.images.iter().find(|x| x.name == n)
    }
    pub fn image_view(&self, n: &str) -> Option<&ImageView> {
        self.image_views.iter().find(|x| x.name == n)
    }
    pub fn buffer(&self, n: &str) -> Option<&Buffer> {
        self.buffers.iter().find(|x| x.name == n)
    }
    pub fn buffer_view(&self, n: &str) -> Option<&BufferView> {
        self.buffer_views.iter().find(|x| x.name == n)
    }
    pub fn tensor(&self, n: &str) -> Option<&Tensor> {
        self.tensors.iter().find(|x| x.name == n)
    }
    pub fn tensor_view(&self, n: &str) -> Option<&TensorView> {
        self.tensor_views.iter().find(|x| x.name == n)
    }
    /// The set bound at set number `n`, if any (the last bind wins).
    pub fn bound(&self, n: u32) -> Option<&BoundSet> {
        self.bound_sets.iter().rev().find(|b| b.set == n)
    }

    /// Whether two pipeline layouts are compatible for set `n`: identically defined set layouts for
    /// sets 0 through `n` (compared by definition, not by name) and identical push constant ranges
    /// (the specification's "Pipeline Layout Compatibility").
    pub fn compatible_for_set(&self, a: &str, b: &str, n: u32) -> bool {
        let (Some(a), Some(b)) = (self.pipeline_layout_named(a), self.pipeline_layout_named(b))
        else {
            return false;
        };
        a.push_ranges == b.push_ranges
            && (0..=n as usize).all(|i| match (a.sets.get(i), b.sets.get(i)) {
                (Some(x), Some(y)) => match (self.set_layout(x), self.set_layout(y)) {
                    (Some(x), Some(y)) => x.bindings == y.bindings,
                    _ => false,
                },
                _ => false,
            })
    }

    /// Whether two pipeline layouts are compatible for push constants: identical push constant ranges.
    pub fn compatible_for_push(&self, a: &str, b: &str) -> bool {
        match (self.pipeline_layout_named(a), self.pipeline_layout_named(b)) {
            (Some(a), Some(b)) => a.push_ranges == b.push_ranges,
            _ => false,
        }
    }

    /// The sets any stage statically uses, sorted.
    pub fn used_sets(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self
            .stages
            .iter()
            .flat_map(|s| {
                s.accesses
                    .iter()
                    .flat_map(|a| std::iter::once(a.set).chain(a.sampler_at.map(|x| x[0])))
            })
            .collect();
        v.sort();
        v.dedup();
        v
    }
}

fn one() -> u32 {
    1
}
fn yes() -> bool {
    true
}
fn is_false(v: &bool) -> bool {
    !*v
}
fn is_zero(v: &u32) -> bool {
    *v == 0
}
fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compatibility_for_a_set_needs_the_same_push_constant_ranges() {
        let sl = SetLayout {
            name: "s".into(),
            bindings: vec![LayoutBinding {
                binding: 0,
                ty: DescriptorType::UniformBuffer,
                count: 1,
                immutable_samplers: vec![],
            }],
        };
        let pl = |name: &str, size| PipelineLayout {
            name: name.into(),
            sets: vec!["s".into()],
            push_ranges: vec![PushRange { offset: 0, size }],
        };
        let rs = ResourceState {
            set_layouts: vec![sl],
            pipeline_layouts: vec![pl("a", 16), pl("b", 16), pl("c", 32)],
            ..Default::default()
        };
        assert!(rs.compatible_for_set("a", "b", 0));
        assert!(!rs.compatible_for_set("a", "c", 0));
        assert!(
            !rs.compatible_for_set("a", "b", 1),
            "set 1 is in neither layout"
        );
    }
}
