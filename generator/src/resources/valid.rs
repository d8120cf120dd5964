//! Valid resource states: descriptor set layouts, sets, images, views, samplers, texel buffers and push
//! constants built from a profile's formats, with accesses every stage can make, and their strategy.

use super::*;
use proptest::prelude::*;

pub(super) fn feats(
    profile: &DeviceProfile,
    f: &str,
    u: Usage,
) -> std::collections::BTreeSet<String> {
    formats::features(profile, f, u).unwrap_or_default()
}

/// The profile's formats with every bit of `need` and none of `not` for a usage, 32-bit or narrower.
pub(super) fn formats_with(
    profile: &DeviceProfile,
    u: Usage,
    need: &[&str],
    not: &[&str],
) -> Vec<String> {
    formats::reported(profile)
        .into_iter()
        .filter(|f| formats::info(f).is_some_and(|i| i.width <= 32))
        .filter(|f| {
            let has = |b: &&str| formats::has_bit(profile, f, u, b) == Some(true);
            need.iter().all(has) && !not.iter().any(has)
        })
        .map(String::from)
        .collect()
}

pub(super) fn pick(v: &[String], choice: u32) -> Option<String> {
    (!v.is_empty()).then(|| v[choice as usize % v.len()].clone())
}

pub(super) fn numeric(f: &str) -> Numeric {
    formats::info(f).map_or(Numeric::Float, |i| i.numeric)
}

pub(super) fn components(f: &str) -> u32 {
    formats::info(f).map_or(4, |i| i.components)
}

pub(super) fn image_type(f: &str, dim: Dim) -> ImageType {
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
        immutable_samplers: vec![],
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
