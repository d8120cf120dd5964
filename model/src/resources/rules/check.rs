//! What each resource-access rule checks in a world's resource state, against the resolved accesses.

use super::super::formats::{self};
use super::resolve::*;
use super::*;
use crate::rules::predicate::Failure;
use crate::rules::Context;

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
                let pushed: Vec<(u64, u64)> = rs
                    .pushes
                    .iter()
                    .filter(|p| rs.compatible_for_push(&p.layout, pl))
                    .map(|p| byte_span(p.offset, p.size))
                    .collect();
                for st in &rs.stages {
                    let Some([off, size]) = st.push_constants else {
                        continue;
                    };
                    if let Some(byte) = first_uncovered(byte_span(off, size), &pushed) {
                        fail(format!("world.resources.stages[{:?}].push-constants", st.stage), format!("byte {byte} is used but no push constant value was set for it with a layout compatible with `{pl}`"));
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
                    let (used_start, used_end) = byte_span(off, size);
                    for p in &rs.pushes {
                        let (start, end) = byte_span(p.offset, p.size);
                        let overlaps = start < used_end && used_start < end;
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
                                    o.saturating_add(n)
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
            R::LayoutMatches { types } => {
                for r in resolve(rs) {
                    let (Some(Descriptor::Image { layout, .. }), Some(i), Some(b)) =
                        (r.descriptor, r.image, r.binding)
                    else {
                        continue;
                    };
                    if types.contains(&b.ty) && i.layout != *layout {
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

/// The bytes `[offset, offset + size)` a case states, as u64 bounds (no sum of two u32 overflows).
fn byte_span(offset: u32, size: u32) -> (u64, u64) {
    (u64::from(offset), u64::from(offset) + u64::from(size))
}

/// The first byte of `used` that none of the `pushed` spans covers. Each step jumps to the farthest
/// end of a span covering the current byte, so it takes at most one step per span, whatever the
/// sizes the case states.
fn first_uncovered((mut at, end): (u64, u64), pushed: &[(u64, u64)]) -> Option<u64> {
    while at < end {
        let reach = pushed
            .iter()
            .filter(|&&(s, e)| s <= at && at < e)
            .map(|&(_, e)| e)
            .max();
        match reach {
            Some(e) => at = e,
            None => return Some(at),
        }
    }
    None
}

fn is_a8(format: &str) -> bool {
    matches!(format, "VK_FORMAT_A8_UNORM" | "VK_FORMAT_A8_UNORM_KHR")
}
