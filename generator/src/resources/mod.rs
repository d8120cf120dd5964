//! Resource worlds for the shared resource-access rules: a valid [`ResourceState`] built
//! from a device profile's formats (strategy [`state_strategy`]), and one mutation per executable
//! resource rule that makes exactly that rule fire, with the co-violations the captured devices make
//! unavoidable declared.
//!
//! Mutations are named by the VUID tag they break ([`ResourceMutation`]); [`mutate`] edits a world
//! in place and is what [`apply`] (the `generator::mutation` hook) and the tests call.

use crate::mutation_io::{Mutated, MutationInput};
use crate::plan::{realize, Plan};
use crate::GenError;
use model::resources::formats::{self, Usage};
use model::resources::*;
use model::world::{CommandBufferState, DeviceState};
use model::DeviceProfile;
use proptest::prelude::*;
use vk_registry::vuid::Condition;

/// The rule tags with a mutation, and whether the rule needs an extension no captured driver has.
pub const TAGS: &[(&str, Option<&str>)] = &[
    ("02697", None),
    ("08600", None),
    ("02698", None),
    ("06425", None),
    ("08602", None),
    ("08601", None),
    ("02699", None),
    ("08114", None),
    ("08116", None),
    ("08115", None),
    ("08117", None),
    ("08119", None),
    ("02702", None),
    ("08609", None),
    ("09636", None),
    ("02703", None),
    ("08610", None),
    ("02704", None),
    ("08611", None),
    ("09635", None),
    ("02705", None),
    ("02706", None),
    ("06935", None),
    ("06936", None),
    ("02691", None),
    ("07888", None),
    ("02692", Some("cubic")),
    ("02693", Some("cubic")),
    ("02694", Some("cubic")),
    ("02695", Some("cubic")),
    ("09212", Some("cubic")),
    ("09213", Some("cubic")),
    ("09214", Some("cubic")),
    ("02696", None),
    ("04115", None),
    ("08795", None),
    ("04469", None),
    ("08796", None),
    ("04470", None),
    ("04471", None),
    ("04472", None),
    ("04473", None),
    ("04474", None),
    ("04475", None),
    ("04553", None),
    ("04770", None),
    ("09598", None),
    ("09599", None),
    ("06478", None),
    ("06479", None),
    ("06550", None),
    ("06551", None),
    ("06971", Some("qcom")),
    ("06972", Some("qcom")),
    ("06973", Some("qcom")),
    ("06974", Some("qcom")),
    ("06975", Some("qcom")),
    ("09215", Some("qcom")),
    ("09216", Some("qcom")),
    ("06976", Some("qcom")),
    ("09217", Some("qcom")),
    ("06977", Some("qcom")),
    ("06978", Some("qcom")),
    ("07027", None),
    ("07028", None),
    ("07029", None),
    ("07030", None),
    ("07752", None),
    ("07753", None),
    ("09600", None),
    ("10068", None),
    ("09900", Some("tensor")),
    ("09905", Some("tensor")),
    ("09906", Some("tensor")),
    ("10678", Some("tile")),
    ("10679", Some("tile")),
    ("10746", Some("tile")),
];

/// A mutation that breaks the resource rule with this VUID tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResourceMutation {
    pub tag: &'static str,
}

/// The resource mutation for a trace command's VUID, if it is a resource rule.
pub fn mutation_for(vuid: &str) -> Option<ResourceMutation> {
    let rest = vuid.strip_prefix("VUID-")?;
    let (scope, rest) = rest.split_once('-')?;
    if !model::CommandId::from_vk_name(scope).is_some_and(model::CommandId::is_trace) {
        return None;
    }
    let tag = rest.rsplit('-').next()?;
    TAGS.iter()
        .find(|(t, _)| *t == tag)
        .map(|(t, _)| ResourceMutation { tag: t })
}

/// Vendor families: no captured driver has the extension, so cases are model-only.
pub fn vendor(m: ResourceMutation) -> Option<&'static str> {
    TAGS.iter().find(|(t, _)| *t == m.tag).and_then(|(_, v)| *v)
}

/// Whether the mutation can be generated for a profile.
pub fn supported(m: ResourceMutation, profile: &DeviceProfile) -> Result<(), GenError> {
    if let Some(family) = vendor(m) {
        return Err(GenError::Unsupported(format!(
            "resource rule {} ({family}) needs an extension `{}` lacks; the model judges such cases, no captured driver can run them",
            m.tag, profile.name
        )));
    }
    let mut st = valid_state(profile, 0, u32::MAX);
    let mut dev = DeviceState::default();
    let mut cb = CommandBufferState::default();
    mutate(m, &mut st, &mut dev, &mut cb, profile, 0)
        .map(|_| ())
        .map_err(GenError::Unsupported)
}

// ---------------------------------------------------------------------------------------------
// Valid states

fn feats(profile: &DeviceProfile, f: &str, u: Usage) -> std::collections::BTreeSet<String> {
    formats::features(profile, f, u).unwrap_or_default()
}

/// The profile's formats with every bit of `need` and none of `not` for a usage, 32-bit or narrower.
fn formats_with(profile: &DeviceProfile, u: Usage, need: &[&str], not: &[&str]) -> Vec<String> {
    formats::reported(profile)
        .into_iter()
        .filter(|f| formats::info(f).is_some_and(|i| i.width <= 32))
        .filter(|f| {
            let s = feats(profile, f, u);
            need.iter().all(|b| s.contains(*b)) && not.iter().all(|b| !s.contains(*b))
        })
        .map(String::from)
        .collect()
}

fn pick(v: &[String], choice: u32) -> Option<String> {
    (!v.is_empty()).then(|| v[choice as usize % v.len()].clone())
}

fn numeric(f: &str) -> Numeric {
    formats::info(f).map_or(Numeric::Float, |i| i.numeric)
}

fn components(f: &str) -> u32 {
    formats::info(f).map_or(4, |i| i.components)
}

fn image_type(f: &str, dim: Dim) -> ImageType {
    ImageType {
        dim,
        arrayed: false,
        sampled_type: numeric(f),
        width: 32,
        format_unknown: false,
    }
}

pub const LAYOUT: &str = "pl";
pub const SET_LAYOUT: &str = "sl0";
pub const SET: &str = "ds0";

/// A valid resource state for the profile: `choice` picks formats, `bits` which accesses the raygen
/// shader makes (bit i: access i of sample, storage read, storage write, uniform load, storage store,
/// texel fetch, texel read or atomic; bit 7 push constants; bit 8 the read goes through an Unknown format).
pub fn valid_state(profile: &DeviceProfile, choice: u32, bits: u32) -> ResourceState {
    let sampled = pick(
        &formats_with(profile, Usage::Optimal, &["SAMPLED_IMAGE_BIT"], &[]),
        choice,
    )
    .unwrap_or("VK_FORMAT_R8G8B8A8_UNORM".into());
    let storage = pick(
        &formats_with(profile, Usage::Optimal, &["STORAGE_IMAGE_BIT"], &[]),
        choice / 3,
    )
    .unwrap_or("VK_FORMAT_R32_UINT".into());
    let utb = pick(
        &formats_with(profile, Usage::Buffer, &["UNIFORM_TEXEL_BUFFER_BIT"], &[]),
        choice / 7,
    )
    .unwrap_or("VK_FORMAT_R32_UINT".into());
    let stb = pick(
        &formats_with(profile, Usage::Buffer, &["STORAGE_TEXEL_BUFFER_BIT"], &[]),
        choice / 11,
    )
    .unwrap_or("VK_FORMAT_R32_UINT".into());
    let linear = feats(profile, &sampled, Usage::Optimal)
        .contains("SAMPLED_IMAGE_FILTER_LINEAR_BIT")
        && choice % 2 == 0;
    let filter = if linear {
        Filter::Linear
    } else {
        Filter::Nearest
    };
    let b = |ty, binding| LayoutBinding {
        binding,
        ty,
        count: if binding == 0 { 2 } else { 1 },
    };
    let layout = SetLayout {
        name: SET_LAYOUT.into(),
        bindings: vec![
            b(DescriptorType::CombinedImageSampler, 0),
            b(DescriptorType::StorageImage, 1),
            b(DescriptorType::UniformBuffer, 2),
            b(DescriptorType::StorageBuffer, 3),
            b(DescriptorType::UniformTexelBuffer, 4),
            b(DescriptorType::StorageTexelBuffer, 5),
        ],
    };
    let img = |name: &str, format: &str, layout| Image {
        name: name.into(),
        format: format.into(),
        extent: [16, 16, 1],
        layout,
        ..Default::default()
    };
    let view = |name: &str, image: &str, format: &str| ImageView {
        name: name.into(),
        image: image.into(),
        view_type: ViewType::TwoD,
        format: format.into(),
        aspect: Aspect::Color,
        level_count: 1,
        layer_count: 1,
        ycbcr_conversion: false,
    };
    let w = |binding, element, descriptor| Write {
        binding,
        element,
        descriptor,
    };
    let image_d = |v: &str, s: Option<&str>, layout| Descriptor::Image {
        view: v.into(),
        sampler: s.map(String::from),
        layout,
    };
    let buf_d = |name: &str| Descriptor::Buffer {
        buffer: name.into(),
        offset: 0,
        range: Some(64),
    };
    let mut accesses = vec![];
    let on = |i: u32| bits & (1 << i) != 0;
    if on(0) {
        accesses.push(Access {
            binding: 0,
            element: choice % 2,
            op: Op::Sample,
            image: Some(image_type(&sampled, Dim::TwoD)),
            ..Default::default()
        });
    }
    let stf = feats(profile, &storage, Usage::Optimal);
    if on(1) {
        let mut t = image_type(&storage, Dim::TwoD);
        t.format_unknown = on(8) && stf.contains("STORAGE_READ_WITHOUT_FORMAT_BIT");
        accesses.push(Access {
            binding: 1,
            op: Op::Read,
            image: Some(t),
            ..Default::default()
        });
    }
    if on(2) {
        let mut t = image_type(&storage, Dim::TwoD);
        t.format_unknown = on(8) && stf.contains("STORAGE_WRITE_WITHOUT_FORMAT_BIT");
        accesses.push(Access {
            binding: 1,
            op: Op::Write,
            image: Some(t),
            texel_components: Some(4.max(components(&storage))),
            ..Default::default()
        });
    }
    if on(3) {
        accesses.push(Access {
            binding: 2,
            op: Op::Load,
            bytes: Some([0, 16 + 16 * (choice % 3) as u64]),
            ..Default::default()
        });
    }
    if on(4) {
        accesses.push(Access {
            binding: 3,
            op: Op::Store,
            bytes: Some([48, 16]),
            ..Default::default()
        });
    }
    if on(5) {
        accesses.push(Access {
            binding: 4,
            op: Op::Fetch,
            image: Some(image_type(&utb, Dim::Buffer)),
            ..Default::default()
        });
    }
    if on(6) {
        let atomic = feats(profile, &stb, Usage::Buffer)
            .contains("STORAGE_TEXEL_BUFFER_ATOMIC_BIT")
            && choice % 2 == 1;
        let op = if atomic { Op::Atomic } else { Op::Read };
        accesses.push(Access {
            binding: 5,
            op,
            image: Some(image_type(&stb, Dim::Buffer)),
            ..Default::default()
        });
    }
    let push = on(7);
    ResourceState {
        set_layouts: vec![layout],
        pipeline_layouts: vec![PipelineLayout {
            name: LAYOUT.into(),
            sets: vec![SET_LAYOUT.into()],
            push_ranges: vec![PushRange {
                offset: 0,
                size: 16,
            }],
        }],
        pipeline_layout: Some(LAYOUT.into()),
        descriptor_sets: vec![DescriptorSet {
            name: SET.into(),
            layout: SET_LAYOUT.into(),
            writes: vec![
                w(
                    0,
                    0,
                    image_d("view", Some("smp"), ImageLayout::ShaderReadOnlyOptimal),
                ),
                w(
                    0,
                    1,
                    image_d("view", Some("smp"), ImageLayout::ShaderReadOnlyOptimal),
                ),
                w(1, 0, image_d("sview", None, ImageLayout::General)),
                w(2, 0, buf_d("ubo")),
                w(3, 0, buf_d("ssbo")),
                w(4, 0, Descriptor::TexelBuffer { view: "utb".into() }),
                w(5, 0, Descriptor::TexelBuffer { view: "stb".into() }),
            ],
        }],
        bound_sets: vec![BoundSet {
            set: 0,
            descriptor_set: SET.into(),
            layout: LAYOUT.into(),
        }],
        pushes: if push {
            vec![Push {
                layout: LAYOUT.into(),
                offset: 0,
                size: 16,
            }]
        } else {
            vec![]
        },
        samplers: vec![Sampler {
            name: "smp".into(),
            mag_filter: filter,
            min_filter: filter,
            ..Default::default()
        }],
        images: vec![
            img("img", &sampled, ImageLayout::ShaderReadOnlyOptimal),
            img("simg", &storage, ImageLayout::General),
        ],
        image_views: vec![
            view("view", "img", &sampled),
            view("sview", "simg", &storage),
        ],
        buffers: ["ubo", "ssbo", "tbuf"]
            .iter()
            .map(|n| Buffer {
                name: n.to_string(),
                size: 256,
                ..Default::default()
            })
            .collect(),
        buffer_views: vec![
            BufferView {
                name: "utb".into(),
                buffer: "tbuf".into(),
                format: utb,
            },
            BufferView {
                name: "stb".into(),
                buffer: "tbuf".into(),
                format: stb,
            },
        ],
        stages: vec![StageUse {
            stage: Stage::Raygen,
            accesses,
            push_constants: push.then_some([0, 16]),
            robustness: Default::default(),
        }],
        ..Default::default()
    }
}

/// Valid resource states for a profile (the empty state among them).
pub fn state_strategy(profile: &DeviceProfile) -> BoxedStrategy<ResourceState> {
    let p = profile.clone();
    prop_oneof![
        1 => Just(ResourceState::default()),
        6 => (0..64u32, 0..512u32).prop_map(move |(c, b)| valid_state(&p, c, b)),
    ]
    .boxed()
}

// ---------------------------------------------------------------------------------------------
// Mutations

fn access_mut(st: &mut ResourceState) -> &mut Vec<Access> {
    if st.stages.is_empty() {
        st.stages.push(StageUse {
            stage: Stage::Raygen,
            accesses: vec![],
            push_constants: None,
            robustness: Default::default(),
        });
    }
    &mut st.stages[0].accesses
}

fn set_binding(st: &mut ResourceState, binding: u32, ty: DescriptorType, count: u32) {
    let l = st
        .set_layouts
        .iter_mut()
        .find(|l| l.name == SET_LAYOUT)
        .expect("the base layout");
    l.bindings.retain(|b| b.binding != binding);
    l.bindings.push(LayoutBinding { binding, ty, count });
}

fn write(st: &mut ResourceState, binding: u32, d: Descriptor) {
    let s = st
        .descriptor_sets
        .iter_mut()
        .find(|s| s.name == SET)
        .expect("the base set");
    s.writes.retain(|w| w.binding != binding);
    s.writes.push(Write {
        binding,
        element: 0,
        descriptor: d,
    });
}

fn add_image(
    st: &mut ResourceState,
    name: &str,
    format: &str,
    view_type: ViewType,
    layout: ImageLayout,
) {
    st.images.retain(|i| i.name != name);
    st.image_views.retain(|v| v.name != name);
    st.images.push(Image {
        name: name.into(),
        format: format.into(),
        extent: [16, 16, 1],
        layout,
        ..Default::default()
    });
    st.image_views.push(ImageView {
        name: name.into(),
        image: name.into(),
        view_type,
        format: format.into(),
        aspect: Aspect::Color,
        level_count: 1,
        layer_count: 1,
        ycbcr_conversion: false,
    });
}

fn add_sampler(st: &mut ResourceState, s: Sampler) {
    st.samplers.retain(|x| x.name != s.name);
    st.samplers.push(s);
}

/// Binding 6: a combined image sampler over image `x` (format `format`, view type `vt`) with sampler
/// `xs`; returns the access that samples it (op and type to adjust).
fn sampled_x(
    st: &mut ResourceState,
    format: &str,
    vt: ViewType,
    sampler: Sampler,
    op: Op,
) -> Access {
    add_image(st, "x", format, vt, ImageLayout::ShaderReadOnlyOptimal);
    add_sampler(
        st,
        Sampler {
            name: "xs".into(),
            ..sampler
        },
    );
    set_binding(st, 6, DescriptorType::CombinedImageSampler, 1);
    write(
        st,
        6,
        Descriptor::Image {
            view: "x".into(),
            sampler: Some("xs".into()),
            layout: ImageLayout::ShaderReadOnlyOptimal,
        },
    );
    let (dim, arrayed) = match vt {
        ViewType::OneD => (Dim::OneD, false),
        ViewType::OneDArray => (Dim::OneD, true),
        ViewType::TwoD => (Dim::TwoD, false),
        ViewType::TwoDArray => (Dim::TwoD, true),
        ViewType::ThreeD => (Dim::ThreeD, false),
        ViewType::Cube => (Dim::Cube, false),
        ViewType::CubeArray => (Dim::Cube, true),
    };
    Access {
        binding: 6,
        op,
        image: Some(ImageType {
            dim,
            arrayed,
            ..image_type(format, dim)
        }),
        ..Default::default()
    }
}

/// Binding 7: an image descriptor of type `ty` over image `y` (no sampler); returns its access.
fn plain_y(
    st: &mut ResourceState,
    ty: DescriptorType,
    format: &str,
    layout: ImageLayout,
    op: Op,
) -> Access {
    add_image(st, "y", format, ViewType::TwoD, layout);
    set_binding(st, 7, ty, 1);
    write(
        st,
        7,
        Descriptor::Image {
            view: "y".into(),
            sampler: None,
            layout,
        },
    );
    Access {
        binding: 7,
        op,
        image: Some(image_type(format, Dim::TwoD)),
        ..Default::default()
    }
}

/// Binding 8: a texel buffer of type `ty` with view `z` of `format` on buffer `zb`.
fn texel_z(
    st: &mut ResourceState,
    ty: DescriptorType,
    format: &str,
    sparse: bool,
    op: Op,
) -> Access {
    st.buffers.retain(|b| b.name != "zb");
    st.buffers.push(Buffer {
        name: "zb".into(),
        size: 256,
        sparse_residency: sparse,
        tile_memory: None,
    });
    st.buffer_views.retain(|b| b.name != "z");
    st.buffer_views.push(BufferView {
        name: "z".into(),
        buffer: "zb".into(),
        format: format.into(),
    });
    set_binding(st, 8, ty, 1);
    write(st, 8, Descriptor::TexelBuffer { view: "z".into() });
    Access {
        binding: 8,
        op,
        image: Some(image_type(format, Dim::Buffer)),
        ..Default::default()
    }
}

fn first(v: Vec<String>, what: &str) -> Result<String, String> {
    v.into_iter()
        .next()
        .ok_or_else(|| format!("the profile reports no format {what}"))
}

const F64: &str = "VK_FORMAT_R64_UINT";

/// Breaks the rule `m` in a world made of `st` (a valid state from [`valid_state`]), the device
/// state and the command buffer; returns the tags (or implicit names such as `renderpass`) of the
/// declared co-violations. `Err` when the profile cannot express the violation.
pub fn mutate(
    m: ResourceMutation,
    st: &mut ResourceState,
    dev: &mut DeviceState,
    cb: &mut CommandBufferState,
    profile: &DeviceProfile,
    knob: u32,
) -> Result<Vec<&'static str>, String> {
    let mut also: Vec<&'static str> = vec![];
    let nearest = Sampler {
        mag_filter: Filter::Nearest,
        min_filter: Filter::Nearest,
        ..Default::default()
    };
    let linear_ok = first(
        formats_with(
            profile,
            Usage::Optimal,
            &["SAMPLED_IMAGE_BIT", "SAMPLED_IMAGE_FILTER_LINEAR_BIT"],
            &[],
        ),
        "that can be linearly filtered",
    );
    let sampled = first(
        formats_with(profile, Usage::Optimal, &["SAMPLED_IMAGE_BIT"], &[]),
        "that can be sampled",
    )?;
    let cubic = Sampler {
        mag_filter: Filter::CubicExt,
        min_filter: Filter::CubicExt,
        ..Default::default()
    };
    let qcom = Sampler {
        image_processing: true,
        ..nearest.clone()
    };
    match m.tag {
        "02697" | "08600" => {
            access_mut(st).push(Access {
                binding: 2,
                op: Op::Load,
                bytes: Some([0, 4]),
                ..Default::default()
            });
            if knob % 2 == 0 {
                st.bound_sets.clear();
            } else {
                // Bound with a layout whose set 0 is defined differently.
                st.set_layouts.push(SetLayout {
                    name: "sl-other".into(),
                    bindings: vec![LayoutBinding {
                        binding: 9,
                        ty: DescriptorType::Sampler,
                        count: 1,
                    }],
                });
                st.pipeline_layouts.push(PipelineLayout {
                    name: "pl-other".into(),
                    sets: vec!["sl-other".into()],
                    push_ranges: vec![PushRange {
                        offset: 0,
                        size: 16,
                    }],
                });
                // A set of that layout, so the bind itself is valid (binding `ds0` with `pl-other` would
                // also break VUID-vkCmdBindDescriptorSets-pDescriptorSets-00358).
                st.descriptor_sets.push(DescriptorSet {
                    name: "ds-other".into(),
                    layout: "sl-other".into(),
                    writes: vec![],
                });
                st.bound_sets[0] = BoundSet {
                    set: 0,
                    descriptor_set: "ds-other".into(),
                    layout: "pl-other".into(),
                };
            }
        }
        "02698" | "06425" | "08602" => {
            dev.features.remove("maintenance4");
            st.stages[0].push_constants = Some([0, 4 + 4 * (knob % 4)]);
            st.pushes.clear();
        }
        "08601" => {
            if !profile.has_feature("maintenance4") {
                return Err("maintenance4 is not supported, so an incompatible push also leaves values unset".into());
            }
            dev.features.insert("maintenance4".into());
            st.stages[0].push_constants = Some([0, 16]);
            st.pipeline_layouts.push(PipelineLayout {
                name: "pl-push".into(),
                sets: vec![SET_LAYOUT.into()],
                push_ranges: vec![PushRange {
                    offset: 0,
                    size: 32,
                }],
            });
            st.pushes = vec![Push {
                layout: "pl-push".into(),
                offset: 0,
                size: 16,
            }];
        }
        "02699" | "08114" | "08116" => {
            if m.tag == "08116" {
                st.descriptor_source = DescriptorSource::Buffers;
                st.pipeline_descriptor_buffer = true;
            }
            access_mut(st).push(Access {
                binding: 3,
                op: Op::Store,
                bytes: Some([0, 4]),
                ..Default::default()
            });
            match knob % 3 {
                0 => st
                    .descriptor_sets
                    .iter_mut()
                    .find(|s| s.name == SET)
                    .unwrap()
                    .writes
                    .retain(|w| w.binding != 3),
                1 => write(
                    st,
                    3,
                    Descriptor::Buffer {
                        buffer: "destroyed-buffer".into(),
                        offset: 0,
                        range: None,
                    },
                ),
                _ => write(st, 3, Descriptor::TexelBuffer { view: "stb".into() }),
            }
        }
        "08115" => st.pipeline_descriptor_buffer = true,
        "08117" => st.descriptor_source = DescriptorSource::Buffers,
        "08119" => {
            st.descriptor_source = DescriptorSource::Buffers;
            st.pipeline_descriptor_buffer = true;
            st.descriptor_memory_not_resident = true;
            access_mut(st).push(Access {
                binding: 2,
                op: Op::Load,
                bytes: Some([0, 4]),
                ..Default::default()
            });
        }
        "02702" | "08609" | "09636" | "02703" | "08610" | "02704" | "08611" | "09635" => {
            let vt = if matches!(m.tag, "02702" | "08609" | "09636") {
                [
                    ViewType::TwoDArray,
                    ViewType::ThreeD,
                    ViewType::Cube,
                    ViewType::OneDArray,
                ][knob as usize % 4]
            } else {
                [ViewType::TwoD, ViewType::OneD][knob as usize % 2]
            };
            let mut a = sampled_x(
                st,
                &sampled,
                vt,
                Sampler {
                    unnormalized_coordinates: true,
                    ..nearest.clone()
                },
                Op::Sample,
            );
            // Ray tracing stages have no implicit derivatives: implicit-LOD sampling (and a LOD bias, an
            // operand only implicit-LOD instructions take) is not valid SPIR-V there, so the variants are
            // the explicit-LOD forms that still break the rule: `OpImageSampleProjExplicitLod` (Proj in
            // the name) and an explicit-LOD sample with a constant offset (the view type varies by knob).
            match m.tag {
                "02703" | "08610" => a.proj = true,
                "02704" | "08611" => a.offset = true,
                "09635" => {
                    st.image_views
                        .iter_mut()
                        .find(|v| v.name == "x")
                        .unwrap()
                        .level_count = 2
                }
                _ => {}
            }
            access_mut(st).push(a);
        }
        "02705" | "02706" | "06935" | "06936" => {
            dev.features.remove("robustBufferAccess");
            let uniform = matches!(m.tag, "02705" | "06935");
            let binding = if uniform { 2 } else { 3 };
            let over = 1 + (knob % 4) as u64 * 4;
            access_mut(st).push(Access {
                binding,
                op: if uniform { Op::Load } else { Op::Store },
                bytes: Some([64 - 4 + over, 4]),
                ..Default::default()
            });
        }
        "02691" => {
            let f = first(
                formats_with(
                    profile,
                    Usage::Optimal,
                    &["STORAGE_IMAGE_BIT"],
                    &["STORAGE_IMAGE_ATOMIC_BIT"],
                ),
                "with storage but not atomic images",
            )?;
            let a = plain_y(
                st,
                DescriptorType::StorageImage,
                &f,
                ImageLayout::General,
                Op::Atomic,
            );
            access_mut(st).push(a);
        }
        "07888" => {
            let f = first(
                formats_with(
                    profile,
                    Usage::Buffer,
                    &["STORAGE_TEXEL_BUFFER_BIT"],
                    &["STORAGE_TEXEL_BUFFER_ATOMIC_BIT"],
                ),
                "with storage but not atomic texel buffers",
            )?;
            let a = texel_z(
                st,
                DescriptorType::StorageTexelBuffer,
                &f,
                false,
                Op::Atomic,
            );
            access_mut(st).push(a);
        }
        "02692" | "02694" | "02693" | "02695" | "09212" | "09214" => {
            let vt = if m.tag == "02693" {
                [ViewType::ThreeD, ViewType::Cube, ViewType::CubeArray][knob as usize % 3]
            } else {
                ViewType::TwoD
            };
            let s = match m.tag {
                "02695" => Sampler {
                    reduction: [Reduction::Min, Reduction::Max][knob as usize % 2],
                    ..cubic.clone()
                },
                "09212" => Sampler {
                    reduction: Reduction::WeightedAverageRangeclampQcom,
                    ..cubic.clone()
                },
                "09214" => Sampler {
                    cubic_weights: CubicWeights::BSpline,
                    ..cubic.clone()
                },
                _ => cubic.clone(),
            };
            let a = sampled_x(st, &sampled, vt, s, Op::Sample);
            access_mut(st).push(a);
            // No captured format has the cubic feature: the feature and support rules fire with any.
            also.extend(["02692", "02694"]);
            if m.tag == "02693" {
                also.push("02693");
            }
        }
        "09213" => {
            let a = sampled_x(
                st,
                &sampled,
                ViewType::TwoD,
                Sampler {
                    reduction: Reduction::WeightedAverageRangeclampQcom,
                    ..nearest.clone()
                },
                Op::Sample,
            );
            access_mut(st).push(a);
        }
        "02696" => {
            let mode = [
                AddressMode::Repeat,
                AddressMode::ClampToBorder,
                AddressMode::MirroredRepeat,
            ][knob as usize % 3];
            let mut s = nearest.clone();
            s.address_modes[(knob as usize / 3) % 3] = mode;
            let a = sampled_x(st, &sampled, ViewType::TwoD, s, Op::Sample);
            st.images
                .iter_mut()
                .find(|i| i.name == "x")
                .unwrap()
                .corner_sampled = true;
            access_mut(st).push(a);
        }
        "04115" | "08795" => {
            let f = first(
                formats_with(profile, Usage::Optimal, &["STORAGE_IMAGE_BIT"], &[])
                    .into_iter()
                    .filter(|f| components(f) >= 2)
                    .collect(),
                "storage image with two or more components",
            )?;
            let mut a = plain_y(
                st,
                DescriptorType::StorageImage,
                &f,
                ImageLayout::General,
                Op::Write,
            );
            a.texel_components = Some(components(&f) - 1 - knob % (components(&f) - 1));
            access_mut(st).push(a);
        }
        "04469" => {
            let f = first(
                formats_with(profile, Usage::Buffer, &["STORAGE_TEXEL_BUFFER_BIT"], &[])
                    .into_iter()
                    .filter(|f| components(f) >= 2)
                    .collect(),
                "storage texel buffer with two or more components",
            )?;
            let mut a = texel_z(st, DescriptorType::StorageTexelBuffer, &f, false, Op::Write);
            a.texel_components = Some(components(&f) - 1 - knob % (components(&f) - 1));
            access_mut(st).push(a);
        }
        "08796" => {
            let mut a = plain_y(
                st,
                DescriptorType::StorageImage,
                "VK_FORMAT_A8_UNORM",
                ImageLayout::General,
                Op::Write,
            );
            a.texel_components = Some(1 + knob % 3);
            access_mut(st).push(a);
        }
        "04470" | "04474" => {
            let mut a = plain_y(
                st,
                DescriptorType::StorageImage,
                F64,
                ImageLayout::General,
                Op::Atomic,
            );
            if m.tag == "04470" {
                a.op = Op::Read;
            } else {
                a.image.as_mut().unwrap().width = 64;
                dev.features.remove("sparseImageInt64Atomics");
                st.images
                    .iter_mut()
                    .find(|i| i.name == "y")
                    .unwrap()
                    .sparse_residency = true;
            }
            access_mut(st).push(a);
        }
        "04472" | "04475" => {
            let mut a = texel_z(
                st,
                DescriptorType::StorageTexelBuffer,
                F64,
                m.tag == "04475",
                Op::Atomic,
            );
            if m.tag == "04472" {
                a.op = Op::Read;
            } else {
                a.image.as_mut().unwrap().width = 64;
                dev.features.remove("sparseImageInt64Atomics");
            }
            access_mut(st).push(a);
        }
        "04471" => {
            let f = first(
                formats_with(profile, Usage::Optimal, &["STORAGE_IMAGE_BIT"], &[]),
                "for storage images",
            )?;
            let mut a = plain_y(
                st,
                DescriptorType::StorageImage,
                &f,
                ImageLayout::General,
                Op::Read,
            );
            a.image.as_mut().unwrap().width = 64;
            access_mut(st).push(a);
        }
        "04473" => {
            let f = first(
                formats_with(profile, Usage::Buffer, &["STORAGE_TEXEL_BUFFER_BIT"], &[]),
                "for storage texel buffers",
            )?;
            let mut a = texel_z(st, DescriptorType::StorageTexelBuffer, &f, false, Op::Read);
            a.image.as_mut().unwrap().width = 64;
            access_mut(st).push(a);
        }
        "04553" | "04770" => {
            let f = first(
                formats_with(
                    profile,
                    Usage::Optimal,
                    &["SAMPLED_IMAGE_BIT"],
                    &["SAMPLED_IMAGE_FILTER_LINEAR_BIT"],
                ),
                "that can be sampled but not linearly filtered",
            )?;
            let s = if m.tag == "04553" {
                let mut s = nearest.clone();
                if knob % 2 == 0 {
                    s.mag_filter = Filter::Linear
                } else {
                    s.min_filter = Filter::Linear
                }
                s
            } else {
                Sampler {
                    mipmap_mode: MipmapMode::Linear,
                    ..nearest.clone()
                }
            };
            let a = sampled_x(st, &f, ViewType::TwoD, s, Op::Sample);
            access_mut(st).push(a);
        }
        "09598" | "09599" => {
            let f = first(
                formats_with(
                    profile,
                    Usage::Optimal,
                    &["SAMPLED_IMAGE_BIT", "SAMPLED_IMAGE_FILTER_LINEAR_BIT"],
                    &["SAMPLED_IMAGE_FILTER_MINMAX_BIT"],
                ),
                "that can be linearly filtered but not with min/max",
            )?;
            let red = [Reduction::Min, Reduction::Max][knob as usize % 2];
            let s = if m.tag == "09598" {
                Sampler {
                    mag_filter: Filter::Linear,
                    min_filter: Filter::Linear,
                    reduction: red,
                    ..Default::default()
                }
            } else {
                Sampler {
                    mipmap_mode: MipmapMode::Linear,
                    reduction: red,
                    ..nearest.clone()
                }
            };
            let a = sampled_x(st, &f, ViewType::TwoD, s, Op::Sample);
            access_mut(st).push(a);
        }
        "06478" | "06479" => {
            // Captured profiles report no depth format, and their colour formats lack the depth
            // comparison feature: 06479 fires with any view in them; 06478 needs a colour aspect.
            let mut a = sampled_x(
                st,
                &sampled,
                ViewType::TwoD,
                Sampler {
                    compare_enable: true,
                    ..nearest.clone()
                },
                Op::Sample,
            );
            a.dref = true;
            if m.tag == "06478" {
                also.push("06479");
            } else {
                st.image_views
                    .iter_mut()
                    .find(|v| v.name == "x")
                    .unwrap()
                    .aspect = Aspect::Depth;
            }
            access_mut(st).push(a);
        }
        "06550" | "06551" => {
            let mut a = sampled_x(
                st,
                &sampled,
                ViewType::TwoD,
                Sampler {
                    ycbcr_conversion: true,
                    ..nearest.clone()
                },
                Op::Sample,
            );
            if knob % 2 == 1 {
                st.samplers
                    .iter_mut()
                    .find(|s| s.name == "xs")
                    .unwrap()
                    .ycbcr_conversion = false;
                st.image_views
                    .iter_mut()
                    .find(|v| v.name == "x")
                    .unwrap()
                    .ycbcr_conversion = true;
            }
            if m.tag == "06550" {
                a.op = [Op::Fetch, Op::Read][knob as usize / 2 % 2];
            } else {
                a.offset = true;
            }
            access_mut(st).push(a);
        }
        "06971" | "06973" | "06974" | "06975" | "09215" | "06976" | "09217" | "09216" | "06977" => {
            let op = match m.tag {
                "06971" => Op::WeightedSampleQcom,
                "06973" | "06977" => Op::BoxFilterQcom,
                "06974" | "06976" => Op::BlockMatchSsdQcom,
                "06975" => Op::BlockMatchSadQcom,
                _ => Op::BlockMatchWindowQcom,
            };
            let single = first(
                formats_with(profile, Usage::Optimal, &["SAMPLED_IMAGE_BIT"], &[])
                    .into_iter()
                    .filter(|f| components(f) == 1)
                    .collect(),
                "single-component",
            )?;
            let multi = first(
                formats_with(profile, Usage::Optimal, &["SAMPLED_IMAGE_BIT"], &[])
                    .into_iter()
                    .filter(|f| components(f) > 1)
                    .collect(),
                "multi-component",
            )?;
            let f = if m.tag == "09216" { multi } else { single };
            let s = if m.tag == "06977" {
                nearest.clone()
            } else {
                qcom.clone()
            };
            let mut a = sampled_x(st, &f, ViewType::TwoD, s, op);
            if matches!(m.tag, "06976" | "09217") {
                a.reference = Some([[16, 0], [-1, 0], [0, 16]][knob as usize % 3]);
            }
            access_mut(st).push(a);
            // No captured format has the QCOM format features.
            also.push(match op {
                Op::WeightedSampleQcom => "06971",
                Op::BoxFilterQcom => "06973",
                Op::BlockMatchSsdQcom => "06974",
                Op::BlockMatchSadQcom => "06975",
                _ => "09215",
            });
        }
        "06972" => {
            let a = plain_y(
                st,
                DescriptorType::SampleWeightImageQcom,
                &sampled,
                ImageLayout::ShaderReadOnlyOptimal,
                Op::SampleWeightQcom,
            );
            access_mut(st).push(a);
        }
        "06978" => {
            let a = sampled_x(
                st,
                &sampled,
                ViewType::TwoD,
                qcom.clone(),
                [Op::Sample, Op::Fetch][knob as usize % 2],
            );
            access_mut(st).push(a);
        }
        "07027" | "07028" => {
            let f = first(
                formats_with(profile, Usage::Optimal, &[], &["STORAGE_IMAGE_BIT"]),
                "without storage image support",
            )?;
            let op = if m.tag == "07027" {
                Op::Write
            } else {
                Op::Read
            };
            let mut a = plain_y(
                st,
                DescriptorType::StorageImage,
                &f,
                ImageLayout::General,
                op,
            );
            a.image.as_mut().unwrap().format_unknown = true;
            a.texel_components = Some(4);
            access_mut(st).push(a);
        }
        "07029" | "07030" => {
            let f = first(
                formats_with(profile, Usage::Buffer, &[], &["STORAGE_TEXEL_BUFFER_BIT"]),
                "without storage texel buffer support",
            )?;
            let op = if m.tag == "07029" {
                Op::Write
            } else {
                Op::Read
            };
            let mut a = texel_z(st, DescriptorType::StorageTexelBuffer, &f, false, op);
            a.image.as_mut().unwrap().format_unknown = true;
            a.texel_components = Some(4);
            access_mut(st).push(a);
        }
        "07752" => {
            let mut a = sampled_x(st, &sampled, ViewType::TwoD, nearest.clone(), Op::Sample);
            let t = a.image.as_mut().unwrap();
            match knob % 3 {
                0 => t.arrayed = true,
                1 => t.dim = Dim::ThreeD,
                _ => t.dim = Dim::Cube,
            }
            access_mut(st).push(a);
        }
        "07753" => {
            let mut a = sampled_x(st, &sampled, ViewType::TwoD, nearest.clone(), Op::Sample);
            let t = a.image.as_mut().unwrap();
            t.sampled_type = match t.sampled_type {
                Numeric::Float => [Numeric::Uint, Numeric::Int][knob as usize % 2],
                _ => Numeric::Float,
            };
            access_mut(st).push(a);
        }
        "09600" => {
            let mut a = sampled_x(st, &sampled, ViewType::TwoD, nearest.clone(), Op::Sample);
            a.op = Op::Fetch;
            st.images.iter_mut().find(|i| i.name == "x").unwrap().layout = [
                ImageLayout::General,
                ImageLayout::TransferDstOptimal,
                ImageLayout::Undefined,
            ][knob as usize % 3];
            access_mut(st).push(a);
        }
        "10068" => {
            let a = Access {
                binding: 0,
                element: 2 + knob % 3,
                op: Op::Sample,
                image: Some(image_type(&st.image_views[0].format, Dim::TwoD)),
                ..Default::default()
            };
            access_mut(st).push(a);
        }
        "09900" | "09905" | "09906" => {
            st.tensors.push(Tensor {
                name: "t".into(),
                shader_usage: m.tag != "09900",
                dimension_count: 2,
                format: "VK_FORMAT_R32_SFLOAT".into(),
            });
            st.tensor_views.push(TensorView {
                name: "tv".into(),
                tensor: "t".into(),
                format: "VK_FORMAT_R32_SFLOAT".into(),
            });
            set_binding(st, 9, DescriptorType::TensorArm, 1);
            write(st, 9, Descriptor::Tensor { view: "tv".into() });
            let mut a = Access {
                binding: 9,
                op: Op::Tensor,
                tensor_rank: Some(2),
                image: Some(image_type("VK_FORMAT_R32_SFLOAT", Dim::Buffer)),
                ..Default::default()
            };
            if m.tag == "09905" {
                a.tensor_rank = Some([3, 1, 4][knob as usize % 3]);
            }
            if m.tag == "09906" {
                a.image.as_mut().unwrap().sampled_type = Numeric::Uint;
            }
            access_mut(st).push(a);
        }
        "10678" => {
            st.tile.in_tile_shading_render_pass = true;
            cb.in_render_pass = true;
            also.push("renderpass");
        }
        "10679" => {
            st.tile.in_tile_shading_render_pass = true;
            st.tile.per_tile_execution = true;
            cb.in_render_pass = true;
            let a = plain_y(
                st,
                DescriptorType::StorageImage,
                &sampled,
                ImageLayout::AttachmentFeedbackLoopOptimal,
                Op::Read,
            );
            access_mut(st).push(a);
            also.extend(["renderpass", "10678"]);
        }
        "10746" => {
            let a = plain_y(
                st,
                DescriptorType::StorageImage,
                &sampled,
                ImageLayout::General,
                Op::Read,
            );
            st.images
                .iter_mut()
                .find(|i| i.name == "y")
                .unwrap()
                .tile_memory = Some("tile-mem".into());
            if knob % 2 == 1 {
                st.tile.bound_memory = Some("other-tile-mem".into());
            }
            access_mut(st).push(a);
        }
        other => return Err(format!("no resource mutation for tag {other}")),
    }
    let _ = linear_ok;
    Ok(also)
}

/// Makes a registry condition hold on the case's device by enabling extensions the profile has
/// (and leaving out the ones it negates). False when it cannot.
pub fn satisfy(
    c: &Condition,
    profile: &DeviceProfile,
    exts: &mut std::collections::BTreeSet<String>,
) -> bool {
    let (major, minor) = profile.api_major_minor();
    let version = |n: &str| {
        n.strip_prefix("VK_VERSION_").map(|v| {
            let mut it = v.split('_').map(|p| p.parse::<u32>().unwrap_or(0));
            (major, minor) >= (it.next().unwrap_or(1), it.next().unwrap_or(0))
        })
    };
    match c {
        Condition::Always => true,
        Condition::Ext(n) => match version(n) {
            Some(v) => v,
            None if exts.contains(n) => true,
            None if profile.has_extension(n) => {
                exts.insert(n.clone());
                true
            }
            None => false,
        },
        Condition::Not(inner) => {
            let names: Vec<String> = inner.names().into_iter().map(String::from).collect();
            for n in &names {
                if version(n).is_none() {
                    exts.remove(n);
                }
            }
            !inner.eval(&|n: &str| version(n).unwrap_or_else(|| exts.contains(n)))
        }
        Condition::All(v) => v.iter().all(|x| satisfy(x, profile, exts)),
        Condition::Any(v) => {
            if c.eval(&|n: &str| version(n).unwrap_or_else(|| exts.contains(n))) {
                return true;
            }
            v.iter().any(|x| satisfy(x, profile, exts))
        }
    }
}

/// The ray tracing stages a launch executes, by the model's semantics: the raygen, the miss, closest-hit
/// and intersection shaders of the records its rays reach ([`model::semantics::records_read`]) and the
/// callables it executes. Any-hit shaders are left out: whether one runs depends on opacity, which the
/// world does not describe. Sorted, without repeats.
pub fn launch_stages(world: &model::world::World, call: &model::call::Call) -> Vec<Stage> {
    use model::call::Table;
    use model::semantics::{record_handle, records_read};
    use model::world::{GeneralStage, HandleRef, ShaderGroup};
    let mut out = vec![];
    let records = records_read(world, call);
    if !records.is_empty() {
        out.push(Stage::Raygen);
    }
    for (table, index) in records {
        let group = match record_handle(world, call, table, index) {
            Some(HandleRef::Group(g)) => world
                .pipeline
                .as_ref()
                .and_then(|p| p.groups.get(g as usize)),
            _ => None,
        };
        match (table, group) {
            (
                Table::Miss,
                Some(ShaderGroup::General {
                    stage: GeneralStage::Miss,
                }),
            ) => out.push(Stage::Miss),
            (
                Table::Callable,
                Some(ShaderGroup::General {
                    stage: GeneralStage::Callable,
                }),
            ) => out.push(Stage::Callable),
            (
                Table::Hit,
                Some(ShaderGroup::TrianglesHit {
                    closest_hit: true, ..
                }),
            ) => out.push(Stage::ClosestHit),
            (
                Table::Hit,
                Some(ShaderGroup::ProceduralHit {
                    intersection: true,
                    closest_hit,
                    ..
                }),
            ) => {
                // An AABB ray reaches this record only when it targets an AABB geometry, which the
                // intersection shader reports (semantics.md §3).
                out.push(Stage::Intersection);
                if *closest_hit {
                    out.push(Stage::ClosestHit);
                }
            }
            _ => {}
        }
    }
    out.sort();
    out.dedup();
    out
}

/// Moves the state's declared accesses and push constant reads (all in the first stage, as
/// [`valid_state`] and [`mutate`] place them) into `stage`.
pub fn move_to_stage(st: &mut ResourceState, stage: Stage) {
    if st.stages.is_empty() || stage == Stage::Raygen {
        return;
    }
    st.stages[0].stage = stage;
}

/// The `generator::mutation` hook: a valid plan realised, a valid resource state added, the rule broken.
pub fn apply(
    m: ResourceMutation,
    mut plan: Plan,
    input: &MutationInput,
) -> Result<Mutated, GenError> {
    supported(m, input.profile)?;
    // Accesses are judged only for launches that run: no dimension is zero.
    for d in plan.dims.iter_mut() {
        *d = (*d).max(1);
    }
    let (mut world, call) = realize(&plan, input.lim);
    let mut st = valid_state(
        input.profile,
        input.pick * 5 + input.knob,
        input.pick.wrapping_mul(97) ^ 0x1ff,
    );
    let tags = mutate(
        m,
        &mut st,
        &mut world.device,
        &mut world.command_buffer,
        input.profile,
        input.knob,
    )
    .map_err(GenError::Unsupported)?;
    // The accesses go into one of the stages the launch executes (the raygen always runs), so every
    // stage's shader is exercised across cases and a valid case's accesses really run.
    let stages = launch_stages(&world, &call);
    if !stages.is_empty() {
        move_to_stage(&mut st, stages[input.pick as usize % stages.len()]);
    }
    world.resources = st;
    let scope = input.command.vk_name();
    // The targeted row's registry condition (a resource rule's extension) holds on the case's device.
    if let Some(row) = input.rules.row(input.vuid) {
        let mut exts = world.device.extensions.clone();
        if !satisfy(&row.condition, input.profile, &mut exts) {
            return Err(GenError::Unsupported(format!(
                "{}: its condition cannot hold on `{}`",
                input.vuid, input.profile.name
            )));
        }
        world.device.extensions = exts;
    }
    let also = tags
        .into_iter()
        .filter_map(|t| {
            input
                .rules
                .rows
                .iter()
                .find(|r| r.scope == scope && r.vuid.rsplit('-').next() == Some(t))
                .map(|r| r.vuid.clone())
        })
        .filter(|v| v != input.vuid)
        .collect();
    Ok(Mutated { world, call, also })
}
