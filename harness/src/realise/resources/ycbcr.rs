//! Sampler Y′CbCr conversions of a resource state: which sampler and view share one, what the
//! state must hold for them to be created validly, and the `VkSamplerYcbcrConversion` objects.
//!
//! A sampler that enables a conversion is only ever an immutable sampler of a combined image sampler
//! binding, and a view written with it carries an identically defined conversion (the rules of
//! `vkUpdateDescriptorSets`); the harness makes one conversion per (format, chroma filter) and gives it
//! to both. Its format is the view's; the chroma offsets are cosited where the device reports
//! COSITED_CHROMA_SAMPLES_BIT for the format and midpoint otherwise; the chroma filter is the
//! sampler's filter (both its filters must be that one unless the format has
//! SEPARATE_RECONSTRUCTION_FILTER_BIT), linear only with YCBCR_CONVERSION_LINEAR_FILTER_BIT.

use super::*;
use crate::error::vkfail;
use model::resources::formats;

/// The conversions of a state: the key of each sampler and view that enables one.
#[derive(Default)]
pub(super) struct Conversions {
    samplers: HashMap<String, Key>,
    views: HashMap<String, Key>,
    made: HashMap<Key, vk::SamplerYcbcrConversion>,
}

/// What tells two conversions apart here: the format and whether the chroma filter is linear.
type Key = (String, bool);

/// Why the harness cannot give the state's Y′CbCr samplers and views their conversions validly, if it
/// cannot (checked before any device work).
pub(super) fn unsupported(world: &World) -> Option<String> {
    let st = &world.resources;
    if let Some(v) = st
        .image_views
        .iter()
        .find(|v| !v.ycbcr_conversion && formats::needs_ycbcr_conversion(&v.format))
    {
        return Some(format!(
            "view `{}` of {} enables no Y′CbCr conversion, which a sampled view of that format must",
            v.name, v.format
        ));
    }
    let any = st.samplers.iter().any(|s| s.ycbcr_conversion)
        || st.image_views.iter().any(|v| v.ycbcr_conversion);
    if !any {
        return None;
    }
    if !world.device.feature("samplerYcbcrConversion") {
        return Some("Y′CbCr conversions are created only with the samplerYcbcrConversion feature, which the case does not enable".into());
    }
    if st.descriptor_source == DescriptorSource::Buffers {
        return Some("Y′CbCr conversion samplers in descriptor buffers are not realised".into());
    }
    if let Some(s) = st.samplers.iter().find(|s| {
        s.ycbcr_conversion
            && (s
                .address_modes
                .iter()
                .any(|m| *m != AddressMode::ClampToEdge)
                || s.unnormalized_coordinates
                || s.compare_enable
                || s.reduction != Reduction::WeightedAverage)
    }) {
        return Some(format!(
            "sampler `{}` enables a Y′CbCr conversion but is not clamp-to-edge, normalized, weighted-average \
             and without comparison, which such a sampler must be",
            s.name
        ));
    }
    pairs(st).err()
}

/// The (sampler, view) pairs that share a conversion: every write of a view at a combined image sampler
/// binding whose immutable sampler enables one. Errors name a Y′CbCr sampler or view no such write
/// pairs, and a pair of which only one enables a conversion.
fn pairs(st: &ResourceState) -> Result<Vec<(&Sampler, &ImageView)>, String> {
    let mut out = Vec::new();
    for set in &st.descriptor_sets {
        let Some(l) = st.set_layout(&set.layout) else {
            continue;
        };
        for w in &set.writes {
            let (Some(b), Descriptor::Image { view, .. }) = (l.binding(w.binding), &w.descriptor)
            else {
                continue;
            };
            let s = b
                .immutable_samplers
                .get(w.element as usize)
                .and_then(|n| st.sampler(n))
                .filter(|_| b.ty == DescriptorType::CombinedImageSampler);
            let v = st.image_view(view);
            match (s, v) {
                (Some(s), Some(v)) if s.ycbcr_conversion && v.ycbcr_conversion => out.push((s, v)),
                (Some(s), Some(v)) if s.ycbcr_conversion || v.ycbcr_conversion => {
                    return Err(format!(
                        "set `{}` binding {} pairs sampler `{}` and view `{}`, of which only one enables a Y′CbCr \
                         conversion (a write must pair identically defined conversions)",
                        set.name, w.binding, s.name, v.name
                    ))
                }
                _ => {}
            }
        }
    }
    if let Some(s) = st
        .samplers
        .iter()
        .find(|s| s.ycbcr_conversion && !out.iter().any(|(p, _)| p.name == s.name))
    {
        return Err(format!(
            "sampler `{}` enables a Y′CbCr conversion but is the immutable sampler of no combined image sampler \
             written with a Y′CbCr view (the only way such a sampler is used validly)",
            s.name
        ));
    }
    if let Some(v) = st
        .image_views
        .iter()
        .find(|v| v.ycbcr_conversion && !out.iter().any(|(_, p)| p.name == v.name))
    {
        return Err(format!(
            "view `{}` enables a Y′CbCr conversion but is written with no immutable Y′CbCr sampler (the only \
             descriptor such a view may be written in)",
            v.name
        ));
    }
    if let Some((_, v)) = out
        .iter()
        .find(|(_, v)| !formats::needs_ycbcr_conversion(&v.format))
    {
        return Err(format!(
            "view `{}` enables a Y′CbCr conversion of {}, which is no Y′CbCr format",
            v.name, v.format
        ));
    }
    Ok(out)
}

fn ycbcr_features(dev: &crate::vk::VkDevice, format: vk::Format) -> vk::FormatFeatureFlags {
    // SAFETY: plain query on the device's physical device.
    unsafe {
        dev.inst
            .instance
            .get_physical_device_format_properties(dev.inst.physical, format)
    }
    .optimal_tiling_features
}

impl Conversions {
    /// Creates the state's conversions (none when no sampler or view enables one).
    pub(super) fn new(
        dev: &crate::vk::VkDevice,
        st: &ResourceState,
    ) -> Result<Conversions, HarnessError> {
        let mut c = Conversions::default();
        let pairs = pairs(st).map_err(HarnessError::NotRealised)?;
        for (s, v) in pairs {
            let key = (v.format.clone(), s.min_filter == Filter::Linear);
            let clash = [(&c.samplers, &s.name), (&c.views, &v.name)]
                .into_iter()
                .find(|(map, name)| map.get(*name).is_some_and(|k| *k != key));
            if let Some((_, name)) = clash {
                c.destroy(dev);
                return unsup(format!(
                    "`{name}` is paired with Y′CbCr conversions of different formats or filters"
                ));
            }
            c.samplers.insert(s.name.clone(), key.clone());
            c.views.insert(v.name.clone(), key.clone());
            if c.made.contains_key(&key) {
                continue;
            }
            match c.create(dev, s, &v.format) {
                Ok(h) => {
                    c.made.insert(key, h);
                }
                Err(e) => {
                    c.destroy(dev);
                    return Err(e);
                }
            }
        }
        Ok(c)
    }

    fn create(
        &self,
        dev: &crate::vk::VkDevice,
        s: &Sampler,
        format: &str,
    ) -> Result<vk::SamplerYcbcrConversion, HarnessError> {
        let f = super::objects::vk_format(format)?;
        let ff = ycbcr_features(dev, f);
        let offset = if ff.contains(vk::FormatFeatureFlags::COSITED_CHROMA_SAMPLES) {
            vk::ChromaLocation::COSITED_EVEN
        } else if ff.contains(vk::FormatFeatureFlags::MIDPOINT_CHROMA_SAMPLES) {
            vk::ChromaLocation::MIDPOINT
        } else {
            return unsup(format!(
                "the device reports neither COSITED_ nor MIDPOINT_CHROMA_SAMPLES_BIT for {format}, so no Y′CbCr \
                 conversion of it can be created"
            ));
        };
        let chroma = match s.min_filter {
            Filter::Nearest => vk::Filter::NEAREST,
            Filter::Linear
                if ff.contains(
                    vk::FormatFeatureFlags::SAMPLED_IMAGE_YCBCR_CONVERSION_LINEAR_FILTER,
                ) =>
            {
                vk::Filter::LINEAR
            }
            other => {
                return unsup(format!(
                    "sampler `{}` filters {other:?}, which no Y′CbCr conversion of {format} can have as its chroma filter",
                    s.name
                ))
            }
        };
        if s.mag_filter != s.min_filter
            && !ff.contains(
                vk::FormatFeatureFlags::SAMPLED_IMAGE_YCBCR_CONVERSION_SEPARATE_RECONSTRUCTION_FILTER,
            )
        {
            return unsup(format!(
                "sampler `{}` has different min and mag filters, which a Y′CbCr sampler of {format} cannot \
                 (SEPARATE_RECONSTRUCTION_FILTER_BIT is missing)",
                s.name
            ));
        }
        let info = vk::SamplerYcbcrConversionCreateInfo::default()
            .format(f)
            .ycbcr_model(vk::SamplerYcbcrModelConversion::YCBCR_709)
            .ycbcr_range(vk::SamplerYcbcrRange::ITU_FULL)
            .components(vk::ComponentMapping::default())
            .x_chroma_offset(offset)
            .y_chroma_offset(offset)
            .chroma_filter(chroma)
            .force_explicit_reconstruction(false);
        // SAFETY: a plain create info; the device has samplerYcbcrConversion (checked in `unsupported`).
        unsafe { dev.device.create_sampler_ycbcr_conversion(&info, None) }
            .map_err(vkfail("vkCreateSamplerYcbcrConversion"))
    }

    /// The conversion sampler `name` is created with, if it enables one.
    pub(super) fn of_sampler(&self, name: &str) -> Option<vk::SamplerYcbcrConversion> {
        self.samplers
            .get(name)
            .and_then(|k| self.made.get(k))
            .copied()
    }

    /// The conversion view `name` is created with, if it enables one.
    pub(super) fn of_view(&self, name: &str) -> Option<vk::SamplerYcbcrConversion> {
        self.views.get(name).and_then(|k| self.made.get(k)).copied()
    }

    /// Whether an image of this format is one the conversions are for (one mip level, one layer).
    pub(super) fn is_ycbcr_format(format: &str) -> bool {
        formats::needs_ycbcr_conversion(format)
    }

    /// Destroys the conversions (after the samplers and views made with them).
    pub(super) fn destroy(&mut self, dev: &crate::vk::VkDevice) {
        for (_, h) in self.made.drain() {
            // SAFETY: no sampler or view made with it is alive (the caller's contract).
            unsafe { dev.device.destroy_sampler_ycbcr_conversion(h, None) };
        }
    }
}
