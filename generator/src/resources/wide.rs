//! The 64-bit image-access mutations (04470–04475): a view or buffer view of one of the profile's
//! 64-bit integer formats read through a 32-bit `Sampled Type`, a 32-bit integer format read through a
//! 64-bit one, and 64-bit atomics on sparse-residency resources. Every access is valid SPIR-V: a
//! `Sampled Type` whose width is not the view format's goes through an Unknown `Image Format` (or a
//! sampled image, whose format is always Unknown), and 64-bit integer types come with the features
//! their capabilities need (`Int64ImageEXT`: `shaderImageInt64Atomics`; `Int64`: `shaderInt64`).

use super::edit::*;
use super::valid::*;
use super::*;

/// The extension and features a shader with a 64-bit integer `Sampled Type` needs.
const INT64_IMAGE_EXTENSION: &str = "VK_EXT_shader_image_atomic_int64";
const INT64_IMAGE_FEATURES: &[&str] = &["shaderImageInt64Atomics", "shaderInt64"];

/// The profile's 64-bit integer formats with every bit of `need` for a usage.
fn wide_formats(profile: &DeviceProfile, u: Usage, need: &[&str]) -> Vec<String> {
    formats::reported(profile)
        .into_iter()
        .filter(|f| formats::info(f).is_some_and(|i| i.width == 64 && i.numeric != Numeric::Float))
        .filter(|f| {
            let s = feats(profile, f, u);
            need.iter().all(|b| s.contains(*b))
        })
        .map(String::from)
        .collect()
}

/// The profile's integer formats of 32-bit or narrower components with every bit of `need`.
fn narrow_integer_formats(profile: &DeviceProfile, u: Usage, need: &[&str]) -> Vec<String> {
    formats_with(profile, u, need, &[])
        .into_iter()
        .filter(|f| numeric(f) != Numeric::Float)
        .collect()
}

/// Enables what a shader with a 64-bit integer `Sampled Type` needs on the case's device; `Err` (the
/// device's lack) when the profile lacks it.
fn enable_int64_images(dev: &mut DeviceState, profile: &DeviceProfile) -> Result<(), String> {
    if !profile.has_extension(INT64_IMAGE_EXTENSION) {
        return Err(format!(
            "the profile lacks {INT64_IMAGE_EXTENSION}, which a 64-bit integer Sampled Type (Int64ImageEXT) needs"
        ));
    }
    for f in INT64_IMAGE_FEATURES {
        if !profile.has_feature(f) {
            return Err(format!(
                "the profile lacks the {f} feature, which a shader with a 64-bit integer Sampled Type needs"
            ));
        }
    }
    dev.extensions.insert(INT64_IMAGE_EXTENSION.into());
    dev.features
        .extend(INT64_IMAGE_FEATURES.iter().map(|f| f.to_string()));
    Ok(())
}

/// Enables the sparse features a sparse-residency image (`image: true`) or buffer needs.
fn enable_sparse(
    dev: &mut DeviceState,
    profile: &DeviceProfile,
    image: bool,
) -> Result<(), String> {
    let need = [
        "sparseBinding",
        if image {
            "sparseResidencyImage2D"
        } else {
            "sparseResidencyBuffer"
        },
    ];
    for f in need {
        if !profile.has_feature(f) {
            return Err(format!(
                "the profile lacks the {f} feature, which a sparse-residency {} needs",
                if image { "image" } else { "buffer" }
            ));
        }
        dev.features.insert(f.into());
    }
    Ok(())
}

/// Picks one of the variants the profile allows (`knob` chooses); `Err` names what the profile lacks.
fn choose<T>(mut v: Vec<T>, knob: u32, lack: &str) -> Result<T, String> {
    if v.is_empty() {
        return Err(format!("the profile reports no {lack}"));
    }
    let i = knob as usize % v.len();
    Ok(v.swap_remove(i))
}

/// Breaks the 64-bit rule `tag` in `st` (see [`super::mutate`]); no co-violation is declared: the
/// formats are chosen with the bits each access needs.
pub(super) fn mutate_wide(
    tag: &str,
    st: &mut ResourceState,
    dev: &mut DeviceState,
    profile: &DeviceProfile,
    knob: u32,
) -> Result<(), String> {
    let read_unknown = |f: &str, u: Usage| {
        let bit = match u {
            Usage::Buffer => "STORAGE_TEXEL_BUFFER_BIT",
            _ => "STORAGE_IMAGE_BIT",
        };
        feats(profile, f, u).is_superset(
            &[bit, "STORAGE_READ_WITHOUT_FORMAT_BIT"]
                .map(String::from)
                .into(),
        )
    };
    let access = match tag {
        // A 64-bit view read through a 32-bit Sampled Type: an Unknown-format storage read, or a fetch
        // through a combined image sampler.
        "04470" => {
            let mut v: Vec<(String, bool)> = vec![];
            for f in wide_formats(profile, Usage::Optimal, &["STORAGE_IMAGE_BIT"]) {
                if read_unknown(&f, Usage::Optimal) {
                    v.push((f, true));
                }
            }
            for f in wide_formats(profile, Usage::Optimal, &["SAMPLED_IMAGE_BIT"]) {
                v.push((f, false));
            }
            let (f, storage) = choose(
                v,
                knob,
                "64-bit integer format that can be read without a format or sampled",
            )?;
            if storage {
                let mut a = plain_y(
                    st,
                    DescriptorType::StorageImage,
                    &f,
                    ImageLayout::General,
                    Op::Read,
                );
                a.image.as_mut().unwrap().format_unknown = true;
                a
            } else {
                let nearest = Sampler {
                    mag_filter: Filter::Nearest,
                    min_filter: Filter::Nearest,
                    ..Default::default()
                };
                sampled_x(st, &f, ViewType::TwoD, nearest, Op::Fetch)
            }
        }
        // A 64-bit buffer view read through a 32-bit Sampled Type: an Unknown-format storage texel
        // buffer read, or a uniform texel buffer fetch.
        "04472" => {
            let mut v: Vec<(String, bool)> = vec![];
            for f in wide_formats(profile, Usage::Buffer, &["STORAGE_TEXEL_BUFFER_BIT"]) {
                if read_unknown(&f, Usage::Buffer) {
                    v.push((f, true));
                }
            }
            for f in wide_formats(profile, Usage::Buffer, &["UNIFORM_TEXEL_BUFFER_BIT"]) {
                v.push((f, false));
            }
            let (f, storage) = choose(
                v,
                knob,
                "64-bit integer format for texel buffers that can be read without a format or fetched",
            )?;
            if storage {
                let mut a = texel_z(st, DescriptorType::StorageTexelBuffer, &f, false, Op::Read);
                a.image.as_mut().unwrap().format_unknown = true;
                a
            } else {
                texel_z(st, DescriptorType::UniformTexelBuffer, &f, false, Op::Fetch)
            }
        }
        // A 32-bit integer view read through a 64-bit Sampled Type (GLSL has 64-bit storage images only,
        // and a known Image Format would have to be 64-bit: Unknown).
        "04471" | "04473" => {
            let u = if tag == "04471" {
                Usage::Optimal
            } else {
                Usage::Buffer
            };
            let storage_bit = match u {
                Usage::Buffer => "STORAGE_TEXEL_BUFFER_BIT",
                _ => "STORAGE_IMAGE_BIT",
            };
            let v: Vec<String> = narrow_integer_formats(profile, u, &[storage_bit])
                .into_iter()
                .filter(|f| read_unknown(f, u))
                .collect();
            let f = choose(
                v,
                knob,
                "integer format of 32-bit components that can be read without a format",
            )?;
            enable_int64_images(dev, profile)?;
            let mut a = if u == Usage::Optimal {
                plain_y(
                    st,
                    DescriptorType::StorageImage,
                    &f,
                    ImageLayout::General,
                    Op::Read,
                )
            } else {
                texel_z(st, DescriptorType::StorageTexelBuffer, &f, false, Op::Read)
            };
            let t = a.image.as_mut().unwrap();
            t.width = 64;
            t.format_unknown = true;
            a
        }
        // A 64-bit atomic on a sparse-residency image or texel buffer of a 64-bit format, without
        // sparseImageInt64Atomics.
        "04474" | "04475" => {
            let image = tag == "04474";
            let f = if image {
                choose(
                    wide_formats(
                        profile,
                        Usage::Optimal,
                        &["STORAGE_IMAGE_BIT", "STORAGE_IMAGE_ATOMIC_BIT"],
                    ),
                    knob,
                    "64-bit integer format for storage image atomics",
                )?
            } else {
                choose(
                    wide_formats(
                        profile,
                        Usage::Buffer,
                        &[
                            "STORAGE_TEXEL_BUFFER_BIT",
                            "STORAGE_TEXEL_BUFFER_ATOMIC_BIT",
                        ],
                    ),
                    knob,
                    "64-bit integer format for storage texel buffer atomics",
                )?
            };
            enable_int64_images(dev, profile)?;
            enable_sparse(dev, profile, image)?;
            dev.features.remove("sparseImageInt64Atomics");
            let mut a = if image {
                let a = plain_y(
                    st,
                    DescriptorType::StorageImage,
                    &f,
                    ImageLayout::General,
                    Op::Atomic,
                );
                st.images
                    .iter_mut()
                    .find(|i| i.name == "y")
                    .unwrap()
                    .sparse_residency = true;
                a
            } else {
                texel_z(st, DescriptorType::StorageTexelBuffer, &f, true, Op::Atomic)
            };
            a.image.as_mut().unwrap().width = 64;
            a
        }
        other => return Err(format!("{other} is not a 64-bit image rule")),
    };
    access_mut(st).push(access);
    Ok(())
}
