//! The images of a resource state, their memory and their views: each image's type, layers and
//! levels follow the views made of it, its usage the descriptors written with it and the layout it is
//! entered in.

use super::objects::{aspect_of, vk_format, vk_layout};
use super::*;
use crate::error::vkfail;

impl Realised {
    /// Makes the state's images (bound to memory of their own) and image views into `self`.
    ///
    /// # Safety
    /// `dev` is the device the case's objects are made on; the create infos reference locals alive
    /// for each call.
    pub(super) unsafe fn make_images(
        &mut self,
        dev: &crate::vk::VkDevice,
        st: &ResourceState,
    ) -> Result<(), HarnessError> {
        let d = &dev.device;
        // Usage of images and buffers from the descriptors written with them.
        let mut image_usage: HashMap<&str, vk::ImageUsageFlags> = HashMap::new();
        for set in &st.descriptor_sets {
            let Some(l) = st.set_layout(&set.layout) else {
                continue;
            };
            for w in &set.writes {
                let (Some(b), Descriptor::Image { view, .. }) =
                    (l.binding(w.binding), &w.descriptor)
                else {
                    continue;
                };
                let Some(v) = st.image_view(view) else {
                    continue;
                };
                let u = match b.ty {
                    DescriptorType::StorageImage => vk::ImageUsageFlags::STORAGE,
                    _ => vk::ImageUsageFlags::SAMPLED,
                };
                *image_usage.entry(v.image.as_str()).or_default() |= u;
            }
        }
        // Images: their type, layers and levels follow the views made of them.
        for img in &st.images {
            let views: Vec<&ImageView> = st
                .image_views
                .iter()
                .filter(|v| v.image == img.name)
                .collect();
            let vt = views.first().map_or(ViewType::TwoD, |v| v.view_type);
            let levels = views
                .iter()
                .map(|v| v.level_count)
                .max()
                .unwrap_or(1)
                .max(1);
            let mut layers = views
                .iter()
                .map(|v| v.layer_count)
                .max()
                .unwrap_or(1)
                .max(1);
            let [w, h, dd] = img.extent;
            let (ty, extent, mut flags) = match vt {
                ViewType::OneD | ViewType::OneDArray => (
                    vk::ImageType::TYPE_1D,
                    vk::Extent3D {
                        width: w.max(1),
                        height: 1,
                        depth: 1,
                    },
                    vk::ImageCreateFlags::empty(),
                ),
                ViewType::ThreeD => (
                    vk::ImageType::TYPE_3D,
                    vk::Extent3D {
                        width: w.max(1),
                        height: h.max(1),
                        depth: dd.max(2),
                    },
                    vk::ImageCreateFlags::empty(),
                ),
                ViewType::Cube | ViewType::CubeArray => {
                    layers = layers.max(6).div_ceil(6) * 6;
                    let s = w.max(h).max(1);
                    (
                        vk::ImageType::TYPE_2D,
                        vk::Extent3D {
                            width: s,
                            height: s,
                            depth: 1,
                        },
                        vk::ImageCreateFlags::CUBE_COMPATIBLE,
                    )
                }
                _ => (
                    vk::ImageType::TYPE_2D,
                    vk::Extent3D {
                        width: w.max(1),
                        height: h.max(1),
                        depth: 1,
                    },
                    vk::ImageCreateFlags::empty(),
                ),
            };
            if ty == vk::ImageType::TYPE_3D {
                layers = 1;
            }
            if super::ycbcr::Conversions::is_ycbcr_format(&img.format)
                && (ty != vk::ImageType::TYPE_2D || levels != 1 || layers != 1)
            {
                return unsup(format!(
                    "image `{}` of {} is not a 2D image of one level and one layer, which the harness makes of \
                     formats that need a Y′CbCr conversion",
                    img.name, img.format
                ));
            }
            if views.iter().any(|v| v.format != img.format) {
                flags |= vk::ImageCreateFlags::MUTABLE_FORMAT;
            }
            let mut extent = extent;
            if img.corner_sampled {
                // A corner-sampled image is 2D or 3D, not cube compatible, at least 2 texels along
                // each of its dimensions, and has at most ceil(log2(largest dimension)) levels
                // (VUID-VkImageCreateInfo-flags-02050 to -02053; the complete chain of -mipLevels-00958).
                if !matches!(vt, ViewType::TwoD | ViewType::TwoDArray | ViewType::ThreeD) {
                    return unsup(format!(
                        "image `{}` is corner-sampled but viewed as {vt:?}: such an image is 2D or 3D and not cube compatible",
                        img.name
                    ));
                }
                extent.width = extent.width.max(2);
                extent.height = extent.height.max(2);
                if ty == vk::ImageType::TYPE_3D {
                    extent.depth = extent.depth.max(2);
                }
                let largest = extent.width.max(extent.height).max(extent.depth);
                let corner_levels = u32::BITS - (largest - 1).leading_zeros();
                if levels > corner_levels {
                    return unsup(format!(
                        "image `{}` is corner-sampled with {levels} levels, more than its {largest} texels allow ({corner_levels})",
                        img.name
                    ));
                }
                flags |= vk::ImageCreateFlags::CORNER_SAMPLED_NV;
            }
            // The usage its descriptors need, and the one its layout needs to be entered validly.
            let usage = image_usage
                .get(img.name.as_str())
                .copied()
                .unwrap_or(vk::ImageUsageFlags::SAMPLED)
                | match img.layout {
                    ImageLayout::TransferDstOptimal => vk::ImageUsageFlags::TRANSFER_DST,
                    ImageLayout::ShaderReadOnlyOptimal | ImageLayout::ReadOnlyOptimal => {
                        vk::ImageUsageFlags::SAMPLED
                    }
                    _ => vk::ImageUsageFlags::empty(),
                };
            let info = vk::ImageCreateInfo::default()
                .flags(flags)
                .image_type(ty)
                .format(vk_format(&img.format)?)
                .extent(extent)
                .mip_levels(levels)
                .array_layers(layers)
                .samples(vk::SampleCountFlags::TYPE_1)
                .tiling(match img.tiling {
                    Tiling::Optimal => vk::ImageTiling::OPTIMAL,
                    Tiling::Linear => vk::ImageTiling::LINEAR,
                })
                .usage(usage)
                .initial_layout(vk::ImageLayout::UNDEFINED);
            let image = d
                .create_image(&info, None)
                .map_err(vkfail("vkCreateImage"))?;
            let req = d.get_image_memory_requirements(image);
            let Some(mt) = dev.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::empty())
            else {
                d.destroy_image(image, None);
                return unsup("no memory type for an image");
            };
            let memory = match d.allocate_memory(
                &vk::MemoryAllocateInfo::default()
                    .allocation_size(req.size)
                    .memory_type_index(mt),
                None,
            ) {
                Ok(m) => m,
                Err(e) => {
                    d.destroy_image(image, None);
                    return Err(HarnessError::Failed(format!(
                        "vkAllocateMemory for an image failed: {e:?}"
                    )));
                }
            };
            let layout = vk_layout(img.layout)?;
            self.images.push((
                img.name.clone(),
                image,
                memory,
                layout,
                aspect_of(&img.format),
                levels,
                layers,
            ));
            d.bind_image_memory(image, memory, 0)
                .map_err(vkfail("vkBindImageMemory"))?;
        }
        for v in &st.image_views {
            let Some(&(_, image, _, _, _, _, _)) = self.images.iter().find(|i| i.0 == v.image)
            else {
                return unsup(format!("view `{}` of image `{}`, which the state lacks (destroyed images are not realised)", v.name, v.image));
            };
            let aspect = match v.aspect {
                Aspect::Color => vk::ImageAspectFlags::COLOR,
                Aspect::Depth => vk::ImageAspectFlags::DEPTH,
                Aspect::Stencil => vk::ImageAspectFlags::STENCIL,
                Aspect::DepthStencil => vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL,
            };
            let vt = match v.view_type {
                ViewType::OneD => vk::ImageViewType::TYPE_1D,
                ViewType::TwoD => vk::ImageViewType::TYPE_2D,
                ViewType::ThreeD => vk::ImageViewType::TYPE_3D,
                ViewType::Cube => vk::ImageViewType::CUBE,
                ViewType::OneDArray => vk::ImageViewType::TYPE_1D_ARRAY,
                ViewType::TwoDArray => vk::ImageViewType::TYPE_2D_ARRAY,
                ViewType::CubeArray => vk::ImageViewType::CUBE_ARRAY,
            };
            let layers = match v.view_type {
                ViewType::Cube => 6,
                ViewType::CubeArray => v.layer_count.max(6).div_ceil(6) * 6,
                ViewType::ThreeD => 1,
                _ => v.layer_count.max(1),
            };
            let mut info = vk::ImageViewCreateInfo::default()
                .image(image)
                .view_type(vt)
                .format(vk_format(&v.format)?)
                .subresource_range(vk::ImageSubresourceRange {
                    aspect_mask: aspect,
                    base_mip_level: 0,
                    level_count: v.level_count.max(1),
                    base_array_layer: 0,
                    layer_count: layers,
                });
            let mut conversion = vk::SamplerYcbcrConversionInfo::default();
            if let Some(c) = self.ycbcr.of_view(&v.name) {
                conversion = conversion.conversion(c);
                info = info.push_next(&mut conversion);
            }
            let h = d
                .create_image_view(&info, None)
                .map_err(vkfail("vkCreateImageView"))?;
            self.views.insert(v.name.clone(), h);
        }
        Ok(())
    }
}
