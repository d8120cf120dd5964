//! The resource state resolved for the rules: each stage access with the binding, descriptor, view,
//! image and sampler it reaches, and what makes a descriptor unfit for its binding.

use super::super::formats::Usage;
use super::super::*;
use super::NOT_ON_DRIVERS;
use crate::rules::Context;

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
    pub(super) fn at(&self) -> String {
        format!(
            "world.resources.stages[{:?}].accesses[{}] (set {}, binding {}[{}])",
            self.stage, self.index, self.access.set, self.access.binding, self.access.element
        )
    }
    pub(super) fn image_format(&self) -> Option<&str> {
        self.view.map(|v| v.format.as_str())
    }
    pub(super) fn view_features(
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
    pub(super) fn buffer_view_features(
        &self,
        profile: &crate::DeviceProfile,
    ) -> Option<std::collections::BTreeSet<String>> {
        formats::features(profile, &self.buffer_view?.format, Usage::Buffer)
    }
    pub(super) fn ty(&self) -> ImageType {
        self.access.image.unwrap_or_default()
    }
    pub(super) fn is_texel_buffer(&self) -> bool {
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
                    // An immutable sampler of the binding is the one used, whatever was written.
                    let immutable = binding
                        .and_then(|b| b.immutable_samplers.get(a.element as usize))
                        .filter(|_| {
                            binding.is_some_and(|b| b.ty == DescriptorType::CombinedImageSampler)
                        });
                    r.sampler = immutable.or(sampler.as_ref()).and_then(|s| rs.sampler(s));
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
pub(super) fn kind_fits(d: &Descriptor, ty: DescriptorType) -> bool {
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
pub(super) fn descriptor_problem(rs: &ResourceState, r: &Resolved) -> Option<String> {
    let set = r.set?; // unbound sets are SetsBound's concern
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
    // A combined image sampler written without a sampler takes its binding's immutable one.
    let immutable_combined = binding.ty == DescriptorType::CombinedImageSampler
        && binding
            .immutable_samplers
            .get(r.access.element as usize)
            .is_some()
        && matches!(d, Descriptor::Image { .. });
    if !kind_fits(d, binding.ty) && !immutable_combined {
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

pub(super) fn launches_anything(cx: &Context) -> bool {
    cx.call
        .dimensions(cx.world)
        .is_none_or(|d| d.iter().all(|&x| x > 0))
}

pub(super) fn has(set: &Option<std::collections::BTreeSet<String>>, bit: &str) -> bool {
    set.as_ref().is_none_or(|s| s.contains(bit))
}
