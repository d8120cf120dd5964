//! One mutation per executable resource rule: each edits a valid state so that exactly its rule fires,
//! and returns the co-violations the edit cannot avoid.

use super::edit::*;
use super::valid::*;
use super::*;

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
                        immutable_samplers: vec![],
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
                use_descriptor_buffers(profile, dev)?;
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
        "08115" => {
            st.pipeline_descriptor_buffer = true;
            use_descriptor_buffers(profile, dev)?;
        }
        "08117" => {
            st.descriptor_source = DescriptorSource::Buffers;
            use_descriptor_buffers(profile, dev)?;
        }
        "08119" => {
            // Descriptor memory that is not resident: a sparse descriptor buffer with no page bound.
            for f in ["sparseBinding", "sparseResidencyBuffer"] {
                if !profile.has_feature(f) {
                    return Err(format!(
                        "{f} is not supported, so no descriptor buffer memory can be left unbound"
                    ));
                }
                dev.features.insert(f.into());
            }
            st.descriptor_source = DescriptorSource::Buffers;
            use_descriptor_buffers(profile, dev)?;
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
            // A corner-sampled image needs VK_NV_corner_sampled_image on the device, whatever the
            // VUID's listed dependencies (1.4.309 lists it as core).
            const EXTENSION: &str = "VK_NV_corner_sampled_image";
            if !profile.has_extension(EXTENSION) {
                return Err(format!("the device lacks {EXTENSION}"));
            }
            dev.extensions.insert(EXTENSION.into());
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
        "04470" | "04471" | "04472" | "04473" | "04474" | "04475" => {
            super::wide::mutate_wide(m.tag, st, dev, profile, knob)?;
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
            // A conversion is valid only for a format that needs one and has a chroma sample position
            // bit, and only through a combined image sampler whose immutable sampler carries the same
            // conversion as the view: a written sampler or the view alone breaks vkUpdateDescriptorSets'
            // rules, so sampler and view both enable it.
            if !profile.has_feature("samplerYcbcrConversion") {
                return Err("the device lacks samplerYcbcrConversion".into());
            }
            let f = pick(&ycbcr_formats(profile), knob).ok_or(
                "the profile reports no format that needs a sampler Y′CbCr conversion and can be sampled \
                 with one (MIDPOINT_ or COSITED_CHROMA_SAMPLES_BIT)",
            )?;
            dev.features.insert("samplerYcbcrConversion".into());
            // Without SEPARATE_RECONSTRUCTION_FILTER the sampler filters as the conversion's chroma
            // filter, which is linear only with YCBCR_CONVERSION_LINEAR_FILTER.
            let fs = feats(profile, &f, Usage::Optimal);
            let filter = if knob / 2 % 2 == 1
                && fs.contains("SAMPLED_IMAGE_FILTER_LINEAR_BIT")
                && fs.contains("SAMPLED_IMAGE_YCBCR_CONVERSION_LINEAR_FILTER_BIT")
            {
                Filter::Linear
            } else {
                Filter::Nearest
            };
            let mut a = sampled_x(
                st,
                &f,
                ViewType::TwoD,
                Sampler {
                    mag_filter: filter,
                    min_filter: filter,
                    ycbcr_conversion: true,
                    ..Default::default()
                },
                Op::Sample,
            );
            st.image_views
                .iter_mut()
                .find(|v| v.name == "x")
                .unwrap()
                .ycbcr_conversion = true;
            immutable_sampler(st, 6, "xs");
            if m.tag == "06550" {
                // OpImageFetch is the one instruction other than a sample that a combined image
                // sampler's image can be used with.
                a.op = Op::Fetch;
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
            // The VUID lists sampled, storage and QCOM images and input attachments, not combined image
            // samplers: a storage image written GENERAL while the image is in another layout.
            let f = first(
                formats_with(profile, Usage::Optimal, &["STORAGE_IMAGE_BIT"], &[]),
                "for storage images",
            )?;
            let a = plain_y(
                st,
                DescriptorType::StorageImage,
                &f,
                ImageLayout::General,
                Op::Read,
            );
            st.images.iter_mut().find(|i| i.name == "y").unwrap().layout = [
                ImageLayout::Undefined,
                ImageLayout::TransferDstOptimal,
                ImageLayout::ShaderReadOnlyOptimal,
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

/// Enables what a world with descriptor buffers or a DESCRIPTOR_BUFFER_BIT_EXT pipeline needs:
/// VK_EXT_descriptor_buffer with its descriptorBuffer feature (a pipeline with the flag needs the feature,
/// VUID-VkRayTracingPipelineCreateInfoKHR-flags-08096) and bufferDeviceAddress (descriptor buffers are
/// bound by address). A registry whose descriptor-buffer VUIDs list no dependency (1.4.309 lists them as
/// core) still needs the extension on the device, so it is enabled here, not from the VUID's dependencies.
fn use_descriptor_buffers(profile: &DeviceProfile, dev: &mut DeviceState) -> Result<(), String> {
    const EXTENSION: &str = "VK_EXT_descriptor_buffer";
    if !profile.has_extension(EXTENSION) {
        return Err(format!("the device lacks {EXTENSION}"));
    }
    dev.extensions.insert(EXTENSION.into());
    dev.features.insert("descriptorBuffer".into());
    dev.features.insert("bufferDeviceAddress".into());
    Ok(())
}
