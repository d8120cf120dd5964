//! Edits of a resource state the mutations share: bindings, descriptor writes, images, samplers and
//! the accesses that read or write them.

use super::valid::*;
use super::*;

pub(super) fn access_mut(st: &mut ResourceState) -> &mut Vec<Access> {
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

pub(super) fn set_binding(st: &mut ResourceState, binding: u32, ty: DescriptorType, count: u32) {
    let l = st
        .set_layouts
        .iter_mut()
        .find(|l| l.name == SET_LAYOUT)
        .expect("the base layout");
    l.bindings.retain(|b| b.binding != binding);
    l.bindings.push(LayoutBinding {
        binding,
        ty,
        count,
        immutable_samplers: vec![],
    });
}

/// Makes `sampler` the immutable sampler of every element of the base layout's `binding`.
pub(super) fn immutable_sampler(st: &mut ResourceState, binding: u32, sampler: &str) {
    let b = st
        .set_layouts
        .iter_mut()
        .find(|l| l.name == SET_LAYOUT)
        .and_then(|l| l.bindings.iter_mut().find(|b| b.binding == binding))
        .expect("the binding");
    b.immutable_samplers = vec![sampler.to_string(); b.count as usize];
}

/// The profile's formats that need a sampler Y′CbCr conversion and can be sampled with one: a
/// chroma sample position bit (a conversion's chroma offsets need one) and SAMPLED_IMAGE_BIT.
pub(super) fn ycbcr_formats(profile: &DeviceProfile) -> Vec<String> {
    formats::reported(profile)
        .into_iter()
        .filter(|f| formats::needs_ycbcr_conversion(f))
        .filter(|f| {
            let s = feats(profile, f, Usage::Optimal);
            s.contains("SAMPLED_IMAGE_BIT")
                && (s.contains("MIDPOINT_CHROMA_SAMPLES_BIT")
                    || s.contains("COSITED_CHROMA_SAMPLES_BIT"))
        })
        .map(String::from)
        .collect()
}

pub(super) fn write(st: &mut ResourceState, binding: u32, d: Descriptor) {
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

pub(super) fn add_image(
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

pub(super) fn add_sampler(st: &mut ResourceState, s: Sampler) {
    st.samplers.retain(|x| x.name != s.name);
    st.samplers.push(s);
}

/// Binding 6: a combined image sampler over image `x` (format `format`, view type `vt`) with sampler
/// `xs`; returns the access that samples it (op and type to adjust).
pub(super) fn sampled_x(
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
pub(super) fn plain_y(
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
pub(super) fn texel_z(
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

pub(super) fn first(v: Vec<String>, what: &str) -> Result<String, String> {
    v.into_iter()
        .next()
        .ok_or_else(|| format!("the profile reports no format {what}"))
}
