//! Realises a case's resource state (issue 4) on a device: descriptor set layouts, pipeline layouts,
//! descriptor sets with their written descriptors, samplers, images and views, buffers and buffer views,
//! the binds and pushes recorded before the trace, and stage shaders that perform exactly the declared
//! accesses — so the validation layer's draw-time checks see the state the model judged.
//!
//! **Set numbering.** The harness's own set (scene, output, rays, callables) stays at set 0, where every
//! stage shader of the harness reads it; the case's set `n` is realised as set `n + 1`. Every realised
//! pipeline layout is `[harness set layout] ++ the case layout's sets` (with the case layout's push
//! constant ranges), so two realised layouts are compatible for set `n + 1` exactly when the case's are
//! compatible for set `n`, and the harness set, bound first with the pipeline's layout, is never disturbed
//! by the case's binds (its definition is the same in every layout).
//!
//! **Shaders.** Each stage that declares accesses (and the raygen always) is the harness's own shader of
//! that stage (`shaders/raygen.rgen`, `closest_hit.rchit`, `miss.rmiss`, `any_hit.rahit`,
//! `intersection.rint`, `callable.rcall`) with the stage's accesses injected at the start of `main`: one
//! GLSL declaration per access (aliases of one binding are allowed), the access itself in straight-line
//! code, and its result folded into a value that is consumed only under a condition that never holds at
//! run time (so every access is static use and none changes the output words; the stage's own code runs
//! after it). The templated module replaces the harness's in every stage of that kind in the pipeline
//! (`DeviceCache::create_pipeline_with`). Accesses in a stage the pipeline has no shader of are
//! unsupported (nothing bound would use them statically); a stage the pipeline has but the launch does
//! not reach still uses them statically, which is what these rules ask. Texel operands narrower than
//! four components, which GLSL's `imageStore` cannot express, are patched into the compiled module
//! (`OpImageWrite` with a narrow constant texel, see [`patch_narrow_writes`]). Sources are compiled with
//! glslangValidator at first use into a cache keyed by their hash, with `-DNV` for VK_NV_ray_tracing
//! pipelines (the same GLSL in GL_NV_ray_tracing names, as build.rs compiles the harness's shaders).
//!
//! What is not realised is reported unsupported by [`unsupported`] with the reason (vendor objects,
//! descriptor buffers, sparse and tile memory, implicit-LOD sampling, which ray tracing stages cannot do,
//! 64-bit images, accesses in a stage the pipeline lacks, sets statically used but never bound,
//! descriptors of the wrong kind).

use crate::error::SETUP_COMMAND;
use crate::realise::{Allocation, DeviceCache, RealiseError};
use crate::shaders::ShaderKind;
use ash::vk;
use model::resources::*;
use model::world::{PipelineApi, World};
use std::collections::HashMap;
use std::fmt::Write as _;

fn vkfail(what: &'static str) -> impl Fn(vk::Result) -> RealiseError {
    move |r| RealiseError::Failed(format!("{what} failed: {r:?}"))
}

fn unsup<T>(s: impl Into<String>) -> Result<T, RealiseError> {
    Err(RealiseError::Unsupported(s.into()))
}

/// The ray tracing stages every realised binding and push constant range is visible to.
pub fn rt_stages() -> vk::ShaderStageFlags {
    vk::ShaderStageFlags::RAYGEN_KHR
        | vk::ShaderStageFlags::ANY_HIT_KHR
        | vk::ShaderStageFlags::CLOSEST_HIT_KHR
        | vk::ShaderStageFlags::MISS_KHR
        | vk::ShaderStageFlags::INTERSECTION_KHR
        | vk::ShaderStageFlags::CALLABLE_KHR
}

/// Why the harness cannot realise this world's resource state, if it cannot (checked before any device
/// work; [`Realised::new`] may still find a reason in what the device or GLSL cannot express).
pub fn unsupported(world: &World) -> Option<String> {
    let st = &world.resources;
    if st.is_empty() {
        return None;
    }
    if st.descriptor_source == DescriptorSource::Buffers
        || st.pipeline_descriptor_buffer
        || st.descriptor_memory_not_resident
    {
        return Some("descriptor buffers (VK_EXT_descriptor_buffer) are not realised: the captured lavapipe lacks the extension".into());
    }
    if !st.tensors.is_empty() || !st.tensor_views.is_empty() {
        return Some(
            "tensors (VK_ARM_tensors) are not realised: no reachable driver has the extension"
                .into(),
        );
    }
    if st.tile != TileState::default()
        || st.images.iter().any(|i| i.tile_memory.is_some())
        || st.buffers.iter().any(|b| b.tile_memory.is_some())
    {
        return Some("tile shading and tile memory (VK_QCOM_tile_shading / _tile_memory_heap) are not realised: no reachable driver has them".into());
    }
    if st.images.iter().any(|i| i.sparse_residency) || st.buffers.iter().any(|b| b.sparse_residency)
    {
        return Some("sparse-resident images and descriptor buffers are not realised for resource states yet".into());
    }
    if st.images.iter().any(|i| i.corner_sampled) {
        return Some("corner-sampled images (VK_NV_corner_sampled_image) are not realised: lavapipe lacks the extension".into());
    }
    if st.samplers.iter().any(|s| {
        s.filters(Filter::CubicExt)
            || s.image_processing
            || s.ycbcr_conversion
            || s.reduction == Reduction::WeightedAverageRangeclampQcom
            || s.cubic_weights != CubicWeights::CatmullRom
    }) || st.image_views.iter().any(|v| v.ycbcr_conversion)
    {
        return Some("cubic filtering, QCOM image processing and YCbCr conversion samplers/views are not realised: lavapipe lacks those extensions".into());
    }
    if let Some(p) = world.pipeline.as_ref() {
        for s in st
            .stages
            .iter()
            .filter(|s| !s.accesses.is_empty() || s.push_constants.is_some())
        {
            if !pipeline_has(p, s.stage) {
                return Some(format!(
                    "the state declares accesses in the {:?} stage but the pipeline has no such shader, so nothing \
                     bound uses them statically (the model reads them as performed; the harness cannot place them)",
                    s.stage
                ));
            }
        }
    }
    if st
        .stages
        .iter()
        .any(|s| s.robustness != StageRobustness::default())
    {
        return Some(
            "per-stage pipeline robustness (VK_EXT_pipeline_robustness) is not realised yet".into(),
        );
    }
    for a in st.stages.iter().flat_map(|s| &s.accesses) {
        if a.op.is_qcom_processing() || matches!(a.op, Op::SampleWeightQcom | Op::Tensor) {
            return Some(format!(
                "{:?} accesses are vendor instructions no reachable driver has",
                a.op
            ));
        }
        if a.implicit_lod || a.lod_bias {
            return Some(
                "implicit-LOD sampling (and a LOD bias, which needs it) is not valid SPIR-V in a ray tracing stage: \
                 no shader the harness can build performs it"
                    .into(),
            );
        }
        if a.image.is_some_and(|t| t.width == 64) {
            return Some("64-bit image accesses (Int64ImageEXT) are not realised yet".into());
        }
    }
    if let Some(n) = st.used_sets().into_iter().find(|&n| st.bound(n).is_none()) {
        return Some(format!(
            "set {n} is statically used but never bound: VK_LAYER_KHRONOS_validation 1.3.239 crashes (SIGSEGV, or an \
             uncaught C++ exception) validating such a trace call on lavapipe, so the harness does not record it"
        ));
    }
    None
}

// ---------------------------------------------------------------------------------------------
// GLSL

/// The GLSL image format qualifier of a `VK_FORMAT_…`, if GLSL has one.
pub fn glsl_format(f: &str) -> Option<&'static str> {
    let n = f.strip_prefix("VK_FORMAT_").unwrap_or(f);
    Some(match n {
        "R32G32B32A32_SFLOAT" => "rgba32f",
        "R16G16B16A16_SFLOAT" => "rgba16f",
        "R32G32_SFLOAT" => "rg32f",
        "R16G16_SFLOAT" => "rg16f",
        "B10G11R11_UFLOAT_PACK32" => "r11f_g11f_b10f",
        "R32_SFLOAT" => "r32f",
        "R16_SFLOAT" => "r16f",
        "R16G16B16A16_UNORM" => "rgba16",
        "A2B10G10R10_UNORM_PACK32" => "rgb10_a2",
        "R8G8B8A8_UNORM" => "rgba8",
        "R16G16_UNORM" => "rg16",
        "R8G8_UNORM" => "rg8",
        "R16_UNORM" => "r16",
        "R8_UNORM" => "r8",
        "R16G16B16A16_SNORM" => "rgba16_snorm",
        "R8G8B8A8_SNORM" => "rgba8_snorm",
        "R16G16_SNORM" => "rg16_snorm",
        "R8G8_SNORM" => "rg8_snorm",
        "R16_SNORM" => "r16_snorm",
        "R8_SNORM" => "r8_snorm",
        "R32G32B32A32_SINT" => "rgba32i",
        "R16G16B16A16_SINT" => "rgba16i",
        "R8G8B8A8_SINT" => "rgba8i",
        "R32G32_SINT" => "rg32i",
        "R16G16_SINT" => "rg16i",
        "R8G8_SINT" => "rg8i",
        "R32_SINT" => "r32i",
        "R16_SINT" => "r16i",
        "R8_SINT" => "r8i",
        "R32G32B32A32_UINT" => "rgba32ui",
        "R16G16B16A16_UINT" => "rgba16ui",
        "A2B10G10R10_UINT_PACK32" => "rgb10_a2ui",
        "R8G8B8A8_UINT" => "rgba8ui",
        "R32G32_UINT" => "rg32ui",
        "R16G16_UINT" => "rg16ui",
        "R8G8_UINT" => "rg8ui",
        "R32_UINT" => "r32ui",
        "R16_UINT" => "r16ui",
        "R8_UINT" => "r8ui",
        _ => return None,
    })
}

fn prefix(n: Numeric) -> &'static str {
    match n {
        Numeric::Float => "",
        Numeric::Int => "i",
        Numeric::Uint => "u",
    }
}

fn dim_suffix(t: &ImageType) -> String {
    let d = match t.dim {
        Dim::OneD => "1D",
        Dim::TwoD => "2D",
        Dim::ThreeD => "3D",
        Dim::Cube => "Cube",
        Dim::Buffer => "Buffer",
    };
    format!("{d}{}", if t.arrayed { "Array" } else { "" })
}

/// Coordinate components of a dimension (without the array layer).
fn coord_len(dim: Dim) -> usize {
    match dim {
        Dim::OneD | Dim::Buffer => 1,
        Dim::TwoD => 2,
        Dim::ThreeD | Dim::Cube => 3,
    }
}

fn vec_of(base: &str, n: usize, v: &str) -> String {
    let (s, p) = match base {
        "float" => ("float", "vec"),
        "int" => ("int", "ivec"),
        _ => ("uint", "uvec"),
    };
    if n == 1 {
        format!("{s}({v})")
    } else {
        format!("{p}{n}({v})")
    }
}

/// `uint` of a scalar expression of the sampled type.
fn to_uint(n: Numeric, e: &str) -> String {
    match n {
        Numeric::Float => format!("floatBitsToUint({e})"),
        Numeric::Int => format!("uint({e})"),
        Numeric::Uint => e.to_string(),
    }
}

/// The descriptor the shader's access goes through: the declared type and array size.
fn binding_of(st: &ResourceState, a: &Access) -> (Option<DescriptorType>, u32) {
    let b = st
        .pipeline_layout
        .as_deref()
        .and_then(|p| st.pipeline_layout_named(p))
        .and_then(|p| p.sets.get(a.set as usize))
        .and_then(|s| st.set_layout(s))
        .and_then(|l| l.binding(a.binding));
    (b.map(|b| b.ty), b.map_or(a.element + 1, |b| b.count))
}

/// The view format the access goes through: the one written at its binding in the set bound there, else
/// (no set bound, or one without that descriptor) in a set of the pipeline's layout for that set number.
fn view_format(st: &ResourceState, a: &Access) -> Option<String> {
    let of = |set: &DescriptorSet| match set.written(a.binding, a.element)? {
        Descriptor::Image { view, .. } => st.image_view(view).map(|v| v.format.clone()),
        Descriptor::TexelBuffer { view } => st.buffer_view(view).map(|v| v.format.clone()),
        _ => None,
    };
    if let Some(f) = st
        .bound(a.set)
        .and_then(|b| st.descriptor_set(&b.descriptor_set))
        .and_then(of)
    {
        return Some(f);
    }
    let layout = st
        .pipeline_layout
        .as_deref()
        .and_then(|p| st.pipeline_layout_named(p))
        .and_then(|p| p.sets.get(a.set as usize))?;
    st.descriptor_sets
        .iter()
        .filter(|s| &s.layout == layout)
        .find_map(of)
}

/// Whether a pipeline has a shader of `stage` (in any group): only then can a stage's declared accesses
/// be statically used by a bound shader.
pub fn pipeline_has(p: &model::world::Pipeline, stage: Stage) -> bool {
    use model::world::{GeneralStage, ShaderGroup};
    p.groups.iter().any(|g| match (g, stage) {
        (ShaderGroup::General { stage: s }, _) => matches!(
            (s, stage),
            (GeneralStage::Raygen, Stage::Raygen)
                | (GeneralStage::Miss, Stage::Miss)
                | (GeneralStage::Callable, Stage::Callable)
        ),
        (ShaderGroup::TrianglesHit { closest_hit, .. }, Stage::ClosestHit)
        | (ShaderGroup::ProceduralHit { closest_hit, .. }, Stage::ClosestHit) => *closest_hit,
        (ShaderGroup::TrianglesHit { any_hit, .. }, Stage::AnyHit)
        | (ShaderGroup::ProceduralHit { any_hit, .. }, Stage::AnyHit) => *any_hit,
        (ShaderGroup::ProceduralHit { intersection, .. }, Stage::Intersection) => *intersection,
        _ => false,
    })
}

/// The harness shader a stage's accesses are injected into (`trace`: the launch traces rays, so the
/// raygen and closest-hit are the variants with the scene binding).
pub fn shader_kind(stage: Stage, trace: bool) -> ShaderKind {
    match (stage, trace) {
        (Stage::Raygen, true) => ShaderKind::RaygenTrace,
        (Stage::Raygen, false) => ShaderKind::RaygenPlain,
        (Stage::ClosestHit, true) => ShaderKind::ClosestHitTrace,
        (Stage::ClosestHit, false) => ShaderKind::ClosestHitPlain,
        (Stage::Miss, _) => ShaderKind::Miss,
        (Stage::AnyHit, _) => ShaderKind::AnyHit,
        (Stage::Intersection, _) => ShaderKind::Intersection,
        (Stage::Callable, _) => ShaderKind::Callable,
    }
}

/// The harness's GLSL source of a stage and the file extension glslangValidator infers the stage from.
pub fn stage_source(stage: Stage) -> (&'static str, &'static str) {
    match stage {
        Stage::Raygen => (include_str!("../shaders/raygen.rgen"), "rgen"),
        Stage::ClosestHit => (include_str!("../shaders/closest_hit.rchit"), "rchit"),
        Stage::Miss => (include_str!("../shaders/miss.rmiss"), "rmiss"),
        Stage::AnyHit => (include_str!("../shaders/any_hit.rahit"), "rahit"),
        Stage::Intersection => (include_str!("../shaders/intersection.rint"), "rint"),
        Stage::Callable => (include_str!("../shaders/callable.rcall"), "rcall"),
    }
}

/// The statement that consumes the accumulated value `acc` of a stage's accesses under a condition that
/// never holds at run time, so every access is used without changing what the stage writes: the
/// raygen's rays header word is 0 (the harness writes it), a payload's depth is at least 1, the
/// callable data is 0 when the raygen calls, and no ray has a negative `tMin`.
fn sink(stage: Stage) -> &'static str {
    match stage {
        Stage::Raygen => {
            "    if (acc == 0x9E3779B9u && rays.pad1 == 0x5EEDu) { outp.words[0] = acc; }\n"
        }
        Stage::ClosestHit | Stage::Miss | Stage::AnyHit => {
            "    if (acc == 0x9E3779B9u && payload.depth == 0x5EEDu) { payload.word = acc; }\n"
        }
        Stage::Callable => "    if (acc == 0x9E3779B9u && data == 0x5EEDu) { data = acc; }\n",
        Stage::Intersection => {
            "    if (acc == 0x9E3779B9u && gl_RayTminEXT < -1.0) { reportIntersectionEXT(gl_RayTminEXT, 0u); }\n"
        }
    }
}

/// The raygen GLSL for a state: `base` (the harness's raygen source) with the raygen stage's accesses
/// and push constant reads injected. Errors name what GLSL cannot express.
pub fn raygen_glsl(st: &ResourceState, base: &str) -> Result<(String, Vec<NarrowWrite>), String> {
    stage_glsl(st, Stage::Raygen, base)
}

/// The GLSL of one stage for a state: `base` (the harness's source of that stage, [`stage_source`])
/// with the stage's accesses and push constant reads injected at the start of `main` (so the stage's
/// own code, which writes the payload, runs after them). Errors name what GLSL cannot express.
pub fn stage_glsl(
    st: &ResourceState,
    which: Stage,
    base: &str,
) -> Result<(String, Vec<NarrowWrite>), String> {
    let mut narrow = Vec::new();
    let exts = String::from(
        "#extension GL_EXT_shader_image_load_formatted : require\n\
         #extension GL_EXT_samplerless_texture_functions : require\n#extension GL_EXT_nonuniform_qualifier : enable\n",
    );
    let mut decls = String::new();
    let mut body = String::from("    uint acc = 0u;\n");
    let stage = st.stages.iter().find(|s| s.stage == which);
    let accesses: &[Access] = stage.map_or(&[], |s| &s.accesses);
    for (i, a) in accesses.iter().enumerate() {
        let set = a.set + 1;
        let (ty, count) = binding_of(st, a);
        if a.element >= count {
            return Err(format!("access {i} indexes element {} of a binding of {count}: GLSL refuses a constant index out of bounds", a.element));
        }
        let arr = if count > 1 {
            format!("[{count}]")
        } else {
            String::new()
        };
        let idx = if count > 1 {
            format!("[{}]", a.element)
        } else {
            String::new()
        };
        let name = format!("r{i}");
        let lay = |extra: &str| format!("layout(set = {set}, binding = {}{extra})", a.binding);
        match a.op {
            Op::Load | Op::Store => {
                let end = a.bytes.map_or(4, |[o, s]| o + s.max(1));
                let words: Vec<u64> = match a.bytes {
                    Some([o, s]) => (o / 4..(o + s.max(1)).div_ceil(4)).collect(),
                    None => vec![0],
                };
                let storage = match ty {
                    Some(DescriptorType::StorageBuffer) => true,
                    Some(DescriptorType::UniformBuffer) => false,
                    None => a.op == Op::Store,
                    Some(t) => {
                        return Err(format!(
                            "access {i} loads or stores through a {t:?} binding"
                        ))
                    }
                };
                if storage {
                    writeln!(
                        decls,
                        "{} buffer B{i} {{ uint w[]; }} {name}{arr};",
                        lay(", std430")
                    )
                    .unwrap();
                    for k in words {
                        if a.op == Op::Store {
                            writeln!(body, "    {name}{idx}.w[{k}] = acc;").unwrap();
                        } else {
                            writeln!(body, "    acc += {name}{idx}.w[{k}];").unwrap();
                        }
                    }
                } else {
                    if a.op == Op::Store {
                        return Err(format!("access {i} stores to a uniform buffer"));
                    }
                    let n = end.div_ceil(16).max(1);
                    writeln!(
                        decls,
                        "{} uniform U{i} {{ uvec4 v[{n}]; }} {name}{arr};",
                        lay(", std140")
                    )
                    .unwrap();
                    for k in words {
                        writeln!(body, "    acc += {name}{idx}.v[{}][{}];", k / 4, k % 4).unwrap();
                    }
                }
                continue;
            }
            _ => {}
        }
        let Some(t) = a.image else {
            return Err(format!("access {i} ({:?}) names no OpTypeImage", a.op));
        };
        let p = prefix(t.sampled_type);
        let base_ty = match t.sampled_type {
            Numeric::Float => "float",
            Numeric::Int => "int",
            Numeric::Uint => "uint",
        };
        let n = coord_len(t.dim) + t.arrayed as usize;
        let fcoord = vec_of("float", n, "0.5");
        let icoord = vec_of("int", n, "0");
        let ds = dim_suffix(&t);
        match a.op {
            Op::Sample | Op::Fetch => {
                let shadow = if a.dref { "Shadow" } else { "" };
                let combined = match (ty, a.sampler_at) {
                    (Some(DescriptorType::CombinedImageSampler), _) | (None, None) => true,
                    (Some(DescriptorType::SampledImage), _) => false,
                    (Some(DescriptorType::UniformTexelBuffer), _) if t.dim == Dim::Buffer => true,
                    (None, Some(_)) => false,
                    (Some(other), _) => {
                        return Err(format!(
                            "access {i} samples or fetches through a {other:?} binding"
                        ))
                    }
                };
                let sampler_expr = if combined {
                    writeln!(
                        decls,
                        "{} uniform {p}sampler{ds}{shadow} {name}{arr};",
                        lay("")
                    )
                    .unwrap();
                    format!("{name}{idx}")
                } else {
                    writeln!(decls, "{} uniform {p}texture{ds} {name}{arr};", lay("")).unwrap();
                    match a.sampler_at {
                        Some([s, b]) => {
                            writeln!(
                                decls,
                                "layout(set = {}, binding = {b}) uniform sampler{shadow} {name}s;",
                                s + 1
                            )
                            .unwrap();
                            format!("{p}sampler{ds}{shadow}({name}{idx}, {name}s)")
                        }
                        None if a.op == Op::Fetch => format!("{name}{idx}"),
                        None => {
                            return Err(format!(
                                "access {i} samples a sampled image with no sampler"
                            ))
                        }
                    }
                };
                let e = if a.op == Op::Fetch {
                    if a.dref || t.dim == Dim::Cube {
                        return Err(format!("access {i} fetches from a cube or depth-compare image, which GLSL cannot"));
                    }
                    if t.dim == Dim::Buffer {
                        format!("texelFetch({sampler_expr}, 0).x")
                    } else if a.offset {
                        format!(
                            "texelFetchOffset({sampler_expr}, {icoord}, 0, {}).x",
                            vec_of("int", coord_len(t.dim), "0")
                        )
                    } else {
                        format!("texelFetch({sampler_expr}, {icoord}, 0).x")
                    }
                } else {
                    if t.dim == Dim::Buffer {
                        return Err(format!("access {i} samples a buffer"));
                    }
                    let c = if a.dref || a.proj {
                        vec_of("float", n + a.dref as usize + a.proj as usize, "0.5")
                    } else {
                        fcoord.clone()
                    };
                    let f = if a.proj {
                        "textureProjLod"
                    } else {
                        "textureLod"
                    };
                    let comp = if a.dref { "" } else { ".x" };
                    if a.offset {
                        format!(
                            "{f}Offset({sampler_expr}, {c}, 0.0, {}){comp}",
                            vec_of("int", coord_len(t.dim), "0")
                        )
                    } else {
                        format!("{f}({sampler_expr}, {c}, 0.0){comp}")
                    }
                };
                let e = if a.dref {
                    format!("floatBitsToUint({e})")
                } else {
                    to_uint(t.sampled_type, &e)
                };
                writeln!(body, "    acc += {e};").unwrap();
            }
            Op::Read | Op::Write | Op::Atomic => {
                let buffer = t.dim == Dim::Buffer;
                match ty {
                    Some(DescriptorType::StorageImage) if !buffer => {}
                    Some(DescriptorType::StorageTexelBuffer) if buffer => {}
                    None => {}
                    Some(other) => {
                        return Err(format!(
                            "access {i} ({:?}) goes through a {other:?} binding",
                            a.op
                        ))
                    }
                }
                let fmt = if a.op == Op::Atomic {
                    if t.format_unknown {
                        return Err(format!("access {i}: GLSL image atomics need an r32 format qualifier, not Unknown"));
                    }
                    Some(match t.sampled_type {
                        Numeric::Float => "r32f",
                        Numeric::Int => "r32i",
                        Numeric::Uint => "r32ui",
                    })
                } else if t.format_unknown {
                    None
                } else {
                    let f = view_format(st, a).ok_or_else(|| {
                        format!("access {i}: no view format to declare the image with")
                    })?;
                    Some(glsl_format(&f).ok_or_else(|| {
                        format!("access {i}: format {f} has no GLSL image format qualifier")
                    })?)
                };
                let q = match (a.op, fmt) {
                    (Op::Write, None) => "writeonly ",
                    (Op::Read, _) => "readonly ",
                    _ => "",
                };
                let l = match fmt {
                    Some(f) => lay(&format!(", {f}")),
                    None => lay(""),
                };
                writeln!(decls, "{l} uniform {q}{p}image{ds} {name}{arr};").unwrap();
                let c = if buffer {
                    "0".to_string()
                } else {
                    icoord.clone()
                };
                match a.op {
                    Op::Read => writeln!(
                        body,
                        "    acc += {};",
                        to_uint(t.sampled_type, &format!("imageLoad({name}{idx}, {c}).x"))
                    )
                    .unwrap(),
                    Op::Atomic => {
                        let e = match t.sampled_type {
                            Numeric::Float => format!("imageAtomicExchange({name}{idx}, {c}, 1.0)"),
                            Numeric::Int => format!("imageAtomicAdd({name}{idx}, {c}, 1)"),
                            Numeric::Uint => format!("imageAtomicAdd({name}{idx}, {c}, 1u)"),
                        };
                        writeln!(body, "    acc += {};", to_uint(t.sampled_type, &e)).unwrap();
                    }
                    _ => {
                        let k = a.texel_components.unwrap_or(4);
                        if !(1..=4).contains(&k) {
                            return Err(format!("access {i} writes a texel of {k} components"));
                        }
                        writeln!(
                            body,
                            "    imageStore({name}{idx}, {c}, {});",
                            vec_of(base_ty, 4, "0")
                        )
                        .unwrap();
                        if k < 4 {
                            // GLSL's imageStore always writes four components: the module is patched
                            // after compilation (see `patch_narrow_writes`) so this OpImageWrite's texel
                            // is a constant of `k` components, which this variable makes sure exists.
                            writeln!(
                                body,
                                "    {} n{i} = {};",
                                vec_of(base_ty, k as usize, "0")
                                    .split('(')
                                    .next()
                                    .unwrap_or("float"),
                                vec_of(base_ty, k as usize, narrow_value(base_ty))
                            )
                            .unwrap();
                            writeln!(
                                body,
                                "    acc += {};",
                                to_uint(
                                    t.sampled_type,
                                    &format!("n{i}{}", if k > 1 { ".x" } else { "" })
                                )
                            )
                            .unwrap();
                            narrow.push(NarrowWrite {
                                variable: name.clone(),
                                component: t.sampled_type,
                                components: k,
                            });
                        }
                    }
                }
            }
            other => return Err(format!("access {i}: {other:?} is not realised")),
        }
    }
    if let Some([off, size]) = stage.and_then(|s| s.push_constants) {
        if off % 4 != 0 || size == 0 {
            return Err(format!(
                "push constant bytes [{off}, +{size}) are not whole words"
            ));
        }
        let n = size.div_ceil(4);
        writeln!(
            decls,
            "layout(push_constant) uniform PC {{ layout(offset = {off}) uint w[{n}]; }} pc;"
        )
        .unwrap();
        for k in 0..n {
            writeln!(body, "    acc += pc.w[{k}];").unwrap();
        }
    }
    // Never true at run time: the accesses stay static use without changing the output.
    body.push_str(sink(which));
    let main = "void main() {\n";
    let at = base
        .find(main)
        .ok_or("the stage's source has no `void main() {`")?;
    let version = base
        .find("#version 460\n")
        .ok_or("the stage's source has no #version line")?
        + "#version 460\n".len();
    Ok((
        format!(
            "{}{exts}{}{decls}{main}{body}{}",
            &base[..version],
            &base[version..at],
            &base[at + main.len()..]
        ),
        narrow,
    ))
}

/// An `OpImageWrite` through the variable named `variable` whose texel must have `components` (< 4)
/// components of class `component`.
#[derive(Debug, Clone, PartialEq)]
pub struct NarrowWrite {
    pub variable: String,
    pub component: Numeric,
    pub components: u32,
}

fn narrow_value(base: &str) -> &'static str {
    match base {
        "float" => "0.25",
        "int" => "7",
        _ => "7u",
    }
}

/// Rewrites the texel operand of each narrow write's `OpImageWrite` to a constant of the declared width
/// (the module holds one, from the `n<i>` variable [`raygen_glsl`] adds). Errors when the module lacks
/// what the patch needs.
pub fn patch_narrow_writes(words: &mut [u32], narrow: &[NarrowWrite]) -> Result<(), String> {
    if narrow.is_empty() {
        return Ok(());
    }
    // (offset, opcode, operands range) of each instruction.
    let mut insts = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xFFFF);
        if count == 0 || i + count > words.len() {
            return Err("malformed SPIR-V".into());
        }
        insts.push((i, op, count));
        i += count;
    }
    fn string_at(words: &[u32], from: usize, to: usize) -> String {
        let bytes: Vec<u8> = words[from..to]
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .take_while(|b| *b != 0)
            .collect();
        String::from_utf8_lossy(&bytes).into_owned()
    }
    for n in narrow {
        let var = insts
            .iter()
            .find(|&&(at, op, count)| op == 5 && string_at(words, at + 2, at + count) == n.variable)
            .map(|&(at, ..)| words[at + 1])
            .ok_or_else(|| format!("no OpName {}", n.variable))?;
        // The scalar type, the texel type, and a constant of it.
        let scalar = insts
            .iter()
            .find(|&&(at, op, _)| match n.component {
                Numeric::Float => op == 22 && words[at + 2] == 32,
                Numeric::Int => op == 21 && words[at + 2] == 32 && words[at + 3] == 1,
                Numeric::Uint => op == 21 && words[at + 2] == 32 && words[at + 3] == 0,
            })
            .map(|&(at, ..)| words[at + 1])
            .ok_or("no scalar type")?;
        let texel_type = if n.components == 1 {
            scalar
        } else {
            insts
                .iter()
                .find(|&&(at, op, _)| {
                    op == 23 && words[at + 2] == scalar && words[at + 3] == n.components
                })
                .map(|&(at, ..)| words[at + 1])
                .ok_or("no vector type")?
        };
        let constant = insts
            .iter()
            .find(|&&(at, op, _)| (op == 43 || op == 44) && words[at + 1] == texel_type)
            .map(|&(at, ..)| words[at + 2])
            .ok_or("no texel constant")?;
        let mut via: Vec<u32> = vec![var];
        for &(at, op, _) in &insts {
            if op == 65 && via.contains(&words[at + 3]) {
                via.push(words[at + 2]);
            }
        }
        let loads: Vec<u32> = insts
            .iter()
            .filter(|&&(at, op, _)| op == 61 && via.contains(&words[at + 3]))
            .map(|&(at, ..)| words[at + 2])
            .collect();
        let mut patched = 0;
        for &(at, op, _) in &insts {
            if op == 99 && loads.contains(&words[at + 1]) {
                words[at + 3] = constant;
                patched += 1;
            }
        }
        if patched == 0 {
            return Err(format!("no OpImageWrite through {}", n.variable));
        }
    }
    Ok(())
}

/// Compiles raygen GLSL (with `-DTRACE` when `trace`) for a KHR pipeline; see [`compile_stage`].
pub fn compile_raygen(glsl: &str, trace: bool) -> Result<Vec<u32>, RealiseError> {
    compile_stage(glsl, Stage::Raygen, trace, PipelineApi::Khr)
}

/// Compiles a stage's GLSL to SPIR-V words (with `-DTRACE` when `trace`, and `-DNV` for
/// VK_NV_ray_tracing pipelines, as build.rs compiles the harness's own shaders), cached on disk by
/// content hash.
pub fn compile_stage(
    glsl: &str,
    stage: Stage,
    trace: bool,
    api: PipelineApi,
) -> Result<Vec<u32>, RealiseError> {
    use std::hash::{Hash, Hasher};
    let (_, ext) = stage_source(stage);
    let nv = api == PipelineApi::Nv;
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (glsl, trace, ext, nv).hash(&mut h);
    let key = format!("{:016x}", h.finish());
    let dir = std::env::temp_dir().join("rtconf-resource-shaders");
    std::fs::create_dir_all(&dir)
        .map_err(|e| RealiseError::Failed(format!("{}: {e}", dir.display())))?;
    let spv = dir.join(format!("{key}.spv"));
    if !spv.exists() {
        let src = dir.join(format!("{key}-{}.{ext}", std::process::id()));
        std::fs::write(&src, glsl)
            .map_err(|e| RealiseError::Failed(format!("{}: {e}", src.display())))?;
        let tmp = dir.join(format!("{key}-{}.spv", std::process::id()));
        let mut cmd = std::process::Command::new("glslangValidator");
        cmd.args(["--target-env", "vulkan1.2", "-V"]);
        if trace {
            cmd.arg("-DTRACE");
        }
        if nv {
            cmd.arg("-DNV");
        }
        let out = cmd.arg(&src).arg("-o").arg(&tmp).output().map_err(|e| {
            RealiseError::Failed(format!(
                "glslangValidator is not available ({e}); install it with `{SETUP_COMMAND}`"
            ))
        })?;
        let _ = std::fs::remove_file(&src);
        if !out.status.success() {
            return Err(RealiseError::Failed(format!(
                "glslangValidator failed on the resource {stage:?} shader: {}\n{glsl}",
                String::from_utf8_lossy(&out.stdout)
            )));
        }
        std::fs::rename(&tmp, &spv)
            .map_err(|e| RealiseError::Failed(format!("{}: {e}", spv.display())))?;
    }
    let bytes =
        std::fs::read(&spv).map_err(|e| RealiseError::Failed(format!("{}: {e}", spv.display())))?;
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

// ---------------------------------------------------------------------------------------------
// Vulkan objects

fn descriptor_type(t: DescriptorType) -> Result<vk::DescriptorType, RealiseError> {
    Ok(match t {
        DescriptorType::Sampler => vk::DescriptorType::SAMPLER,
        DescriptorType::CombinedImageSampler => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        DescriptorType::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
        DescriptorType::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
        DescriptorType::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
        DescriptorType::StorageTexelBuffer => vk::DescriptorType::STORAGE_TEXEL_BUFFER,
        DescriptorType::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
        DescriptorType::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
        other => {
            return unsup(format!(
                "{other:?} descriptors are not realised (vendor or input attachment)"
            ))
        }
    })
}

/// `VK_FORMAT_…` name to `vk::Format`, through ash's names of the core and extension ranges.
fn vk_format(name: &str) -> Result<vk::Format, RealiseError> {
    let n = name.strip_prefix("VK_FORMAT_").unwrap_or(name);
    let ranges = [
        (0, 185),
        (1_000_054_000, 1_000_054_008),
        (1_000_066_000, 1_000_066_014),
        (1_000_156_000, 1_000_156_034),
        (1_000_330_000, 1_000_330_004),
        (1_000_340_000, 1_000_340_002),
        (1_000_470_000, 1_000_470_002),
    ];
    ranges
        .iter()
        .flat_map(|&(a, b)| a..b)
        .map(vk::Format::from_raw)
        .find(|f| format!("{f:?}") == n)
        .ok_or_else(|| {
            RealiseError::Unsupported(format!("format {name} is unknown to the harness"))
        })
}

fn vk_layout(l: ImageLayout) -> Result<vk::ImageLayout, RealiseError> {
    Ok(match l {
        ImageLayout::Undefined => vk::ImageLayout::UNDEFINED,
        ImageLayout::General => vk::ImageLayout::GENERAL,
        ImageLayout::ShaderReadOnlyOptimal => vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        ImageLayout::ReadOnlyOptimal => vk::ImageLayout::READ_ONLY_OPTIMAL,
        ImageLayout::DepthStencilReadOnlyOptimal => {
            vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL
        }
        ImageLayout::TransferDstOptimal => vk::ImageLayout::TRANSFER_DST_OPTIMAL,
        ImageLayout::AttachmentFeedbackLoopOptimal => {
            return unsup("the attachment feedback loop layout is not realised")
        }
    })
}

fn filter(f: Filter) -> vk::Filter {
    match f {
        Filter::Nearest => vk::Filter::NEAREST,
        Filter::Linear => vk::Filter::LINEAR,
        Filter::CubicExt => vk::Filter::CUBIC_EXT,
    }
}

fn address(m: AddressMode) -> vk::SamplerAddressMode {
    match m {
        AddressMode::Repeat => vk::SamplerAddressMode::REPEAT,
        AddressMode::MirroredRepeat => vk::SamplerAddressMode::MIRRORED_REPEAT,
        AddressMode::ClampToEdge => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        AddressMode::ClampToBorder => vk::SamplerAddressMode::CLAMP_TO_BORDER,
        AddressMode::MirrorClampToEdge => vk::SamplerAddressMode::MIRROR_CLAMP_TO_EDGE,
    }
}

fn aspect_of(format: &str) -> vk::ImageAspectFlags {
    let n = format.strip_prefix("VK_FORMAT_").unwrap_or(format);
    match (
        n.starts_with('D') || n.contains("_D"),
        n.contains('S') && (n.starts_with('S') || n.contains("S8")),
    ) {
        (true, true) => vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL,
        (true, false) => vk::ImageAspectFlags::DEPTH,
        (false, true) if n.starts_with("S8") => vk::ImageAspectFlags::STENCIL,
        _ => vk::ImageAspectFlags::COLOR,
    }
}

/// Replaces the cache's command buffers with fresh ones. The 1.3.239 layer keeps a command buffer's
/// push-constant state across vkResetCommandBuffer/vkBeginCommandBuffer, so an earlier case's push would
/// hide a later case's "push constants never set" (VUID-…-maintenance4-06425) on a reused one.
fn renew_command_buffers(cache: &mut DeviceCache) -> Result<(), RealiseError> {
    let d = &cache.dev.device;
    // SAFETY: the old command buffers are not pending (earlier cases waited or never submitted).
    unsafe {
        let alloc = |level| {
            d.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(cache.command_pool)
                    .level(level)
                    .command_buffer_count(1),
            )
            .map(|v| v[0])
            .map_err(vkfail("vkAllocateCommandBuffers"))
        };
        let primary = alloc(vk::CommandBufferLevel::PRIMARY)?;
        let secondary = match alloc(vk::CommandBufferLevel::SECONDARY) {
            Ok(s) => s,
            Err(e) => {
                d.free_command_buffers(cache.command_pool, &[primary]);
                return Err(e);
            }
        };
        d.free_command_buffers(cache.command_pool, &[cache.primary, cache.secondary]);
        cache.primary = primary;
        cache.secondary = secondary;
    }
    Ok(())
}

/// A case's resource state realised on a device. Destroy with [`Realised::destroy`] once nothing
/// recorded with it is pending.
pub struct Realised {
    set_layouts: HashMap<String, vk::DescriptorSetLayout>,
    pipeline_layouts: HashMap<String, vk::PipelineLayout>,
    /// The realised layout of the case's pipeline (`[harness set] ++ its sets`), which the harness binds
    /// its own set with.
    pub harness_layout: vk::PipelineLayout,
    own_harness_layout: bool,
    pool: vk::DescriptorPool,
    sets: HashMap<String, vk::DescriptorSet>,
    samplers: HashMap<String, vk::Sampler>,
    images: Vec<(
        String,
        vk::Image,
        vk::DeviceMemory,
        vk::ImageLayout,
        vk::ImageAspectFlags,
        u32,
        u32,
    )>,
    views: HashMap<String, vk::ImageView>,
    buffers: HashMap<String, Allocation>,
    buffer_views: HashMap<String, vk::BufferView>,
    /// The templated module of each stage kind the pipeline gets (the raygen always; other stages when
    /// the state declares accesses or push constant reads in them).
    modules: Vec<(ShaderKind, vk::ShaderModule)>,
    binds: Vec<(vk::PipelineLayout, u32, vk::DescriptorSet)>,
    pushes: Vec<(vk::PipelineLayout, u32, u32)>,
}

impl Realised {
    fn empty() -> Realised {
        Realised {
            set_layouts: HashMap::new(),
            pipeline_layouts: HashMap::new(),
            harness_layout: vk::PipelineLayout::null(),
            own_harness_layout: false,
            pool: vk::DescriptorPool::null(),
            sets: HashMap::new(),
            samplers: HashMap::new(),
            images: Vec::new(),
            views: HashMap::new(),
            buffers: HashMap::new(),
            buffer_views: HashMap::new(),
            modules: Vec::new(),
            binds: Vec::new(),
            pushes: Vec::new(),
        }
    }

    /// Realises `world.resources`: every object, the descriptor writes, and — when the world has a
    /// pipeline — the case's pipeline with the templated raygen, installed as `cache.resource_pipeline`.
    /// `harness_set` is the harness's own set layout (set 0 of every realised pipeline layout).
    pub fn new(
        cache: &mut DeviceCache,
        world: &World,
        trace: bool,
        harness_set: vk::DescriptorSetLayout,
    ) -> Result<Realised, RealiseError> {
        renew_command_buffers(cache)?;
        let mut r = Realised::empty();
        match r.build(cache, world, trace, harness_set) {
            Ok(()) => Ok(r),
            Err(e) => {
                if let Some(p) = cache.resource_pipeline.take() {
                    // SAFETY: never used by a command buffer.
                    unsafe { cache.dev.device.destroy_pipeline(p.pipeline, None) };
                }
                r.destroy(cache);
                Err(e)
            }
        }
    }

    fn build(
        &mut self,
        cache: &mut DeviceCache,
        world: &World,
        trace: bool,
        harness_set: vk::DescriptorSetLayout,
    ) -> Result<(), RealiseError> {
        if let Some(why) = unsupported(world) {
            return unsup(why);
        }
        let st = &world.resources;
        // The stages templated: the raygen, and every other stage that declares accesses or pushes.
        let api = world.pipeline.as_ref().map_or(PipelineApi::Khr, |p| p.api);
        let mut templated = vec![Stage::Raygen];
        for s in &st.stages {
            if s.stage != Stage::Raygen
                && (!s.accesses.is_empty() || s.push_constants.is_some())
                && !templated.contains(&s.stage)
            {
                templated.push(s.stage);
            }
        }
        let mut sources = Vec::new();
        for &stage in &templated {
            let (glsl, narrow) = stage_glsl(st, stage, stage_source(stage).0)
                .map_err(|e| RealiseError::Unsupported(format!("{stage:?} stage: {e}")))?;
            sources.push((stage, glsl, narrow));
        }
        let dev = &cache.dev;
        let d = &dev.device;
        // SAFETY (whole block): create infos reference live locals and objects of this device.
        unsafe {
            // Set layouts.
            for l in &st.set_layouts {
                let mut bs = Vec::new();
                for b in &l.bindings {
                    bs.push(
                        vk::DescriptorSetLayoutBinding::default()
                            .binding(b.binding)
                            .descriptor_type(descriptor_type(b.ty)?)
                            .descriptor_count(b.count)
                            .stage_flags(rt_stages()),
                    );
                }
                let h = d
                    .create_descriptor_set_layout(
                        &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bs),
                        None,
                    )
                    .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
                self.set_layouts.insert(l.name.clone(), h);
            }
            // Pipeline layouts: the harness set, then the case's.
            for p in &st.pipeline_layouts {
                let mut sl = vec![harness_set];
                for s in &p.sets {
                    sl.push(*self.set_layouts.get(s).ok_or_else(|| {
                        RealiseError::Unsupported(format!(
                            "pipeline layout `{}` names set layout `{s}`, which the state lacks",
                            p.name
                        ))
                    })?);
                }
                let ranges: Vec<vk::PushConstantRange> = p
                    .push_ranges
                    .iter()
                    .map(|r| vk::PushConstantRange {
                        stage_flags: rt_stages(),
                        offset: r.offset,
                        size: r.size,
                    })
                    .collect();
                let h = d
                    .create_pipeline_layout(
                        &vk::PipelineLayoutCreateInfo::default()
                            .set_layouts(&sl)
                            .push_constant_ranges(&ranges),
                        None,
                    )
                    .map_err(vkfail("vkCreatePipelineLayout"))?;
                self.pipeline_layouts.insert(p.name.clone(), h);
            }
            match st.pipeline_layout.as_deref() {
                Some(n) => {
                    self.harness_layout = *self.pipeline_layouts.get(n).ok_or_else(|| {
                        RealiseError::Unsupported(format!(
                            "the pipeline's layout `{n}` is not in the state"
                        ))
                    })?;
                }
                None => {
                    if !st.used_sets().is_empty()
                        || st.stages.iter().any(|s| s.push_constants.is_some())
                    {
                        return unsup("the state's shaders use sets or push constants but the pipeline names no layout");
                    }
                    let sl = [harness_set];
                    self.harness_layout = d
                        .create_pipeline_layout(
                            &vk::PipelineLayoutCreateInfo::default().set_layouts(&sl),
                            None,
                        )
                        .map_err(vkfail("vkCreatePipelineLayout"))?;
                    self.own_harness_layout = true;
                }
            }
            // Samplers.
            for s in &st.samplers {
                let mut red = vk::SamplerReductionModeCreateInfo::default().reduction_mode(match s
                    .reduction
                {
                    Reduction::Min => vk::SamplerReductionMode::MIN,
                    Reduction::Max => vk::SamplerReductionMode::MAX,
                    _ => vk::SamplerReductionMode::WEIGHTED_AVERAGE,
                });
                let mut info = vk::SamplerCreateInfo::default()
                    .mag_filter(filter(s.mag_filter))
                    .min_filter(filter(s.min_filter))
                    .mipmap_mode(match s.mipmap_mode {
                        MipmapMode::Nearest => vk::SamplerMipmapMode::NEAREST,
                        MipmapMode::Linear => vk::SamplerMipmapMode::LINEAR,
                    })
                    .address_mode_u(address(s.address_modes[0]))
                    .address_mode_v(address(s.address_modes[1]))
                    .address_mode_w(address(s.address_modes[2]))
                    .compare_enable(s.compare_enable)
                    .compare_op(vk::CompareOp::LESS_OR_EQUAL)
                    .unnormalized_coordinates(s.unnormalized_coordinates)
                    .min_lod(0.0)
                    .max_lod(if s.unnormalized_coordinates {
                        0.0
                    } else {
                        vk::LOD_CLAMP_NONE
                    });
                if s.reduction != Reduction::WeightedAverage {
                    info = info.push_next(&mut red);
                }
                let h = d
                    .create_sampler(&info, None)
                    .map_err(vkfail("vkCreateSampler"))?;
                self.samplers.insert(s.name.clone(), h);
            }
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
                if views.iter().any(|v| v.format != img.format) {
                    flags |= vk::ImageCreateFlags::MUTABLE_FORMAT;
                }
                let usage = image_usage
                    .get(img.name.as_str())
                    .copied()
                    .unwrap_or(vk::ImageUsageFlags::SAMPLED);
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
                let Some(mt) =
                    dev.memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::empty())
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
                        return Err(RealiseError::Failed(format!(
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
                    Aspect::DepthStencil => {
                        vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
                    }
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
                let info = vk::ImageViewCreateInfo::default()
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
                let h = d
                    .create_image_view(&info, None)
                    .map_err(vkfail("vkCreateImageView"))?;
                self.views.insert(v.name.clone(), h);
            }
            // Buffers and buffer views.
            let usage = vk::BufferUsageFlags::UNIFORM_BUFFER
                | vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                | vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER
                | if dev.has_feature("bufferDeviceAddress") {
                    vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
                } else {
                    vk::BufferUsageFlags::empty()
                };
            for b in &st.buffers {
                let a =
                    Allocation::new(dev, b.size.max(4), usage, vk::BufferCreateFlags::empty(), 1)?;
                self.buffers.insert(b.name.clone(), a);
            }
            for v in &st.buffer_views {
                let Some(b) = self.buffers.get(&v.buffer) else {
                    return unsup(format!(
                        "buffer view `{}` of buffer `{}`, which the state lacks",
                        v.name, v.buffer
                    ));
                };
                let info = vk::BufferViewCreateInfo::default()
                    .buffer(b.buffer)
                    .format(vk_format(&v.format)?)
                    .offset(0)
                    .range(vk::WHOLE_SIZE);
                let h = d
                    .create_buffer_view(&info, None)
                    .map_err(vkfail("vkCreateBufferView"))?;
                self.buffer_views.insert(v.name.clone(), h);
            }
            // Descriptor pool and sets.
            let mut counts: HashMap<vk::DescriptorType, u32> = HashMap::new();
            for s in &st.descriptor_sets {
                let Some(l) = st.set_layout(&s.layout) else {
                    return unsup(format!(
                        "descriptor set `{}` has layout `{}`, which the state lacks",
                        s.name, s.layout
                    ));
                };
                for b in &l.bindings {
                    *counts.entry(descriptor_type(b.ty)?).or_default() += b.count;
                }
            }
            if !st.descriptor_sets.is_empty() {
                let sizes: Vec<vk::DescriptorPoolSize> = counts
                    .iter()
                    .map(|(t, n)| vk::DescriptorPoolSize {
                        ty: *t,
                        descriptor_count: (*n).max(1),
                    })
                    .collect();
                let sizes = if sizes.is_empty() {
                    vec![vk::DescriptorPoolSize {
                        ty: vk::DescriptorType::SAMPLER,
                        descriptor_count: 1,
                    }]
                } else {
                    sizes
                };
                self.pool = d
                    .create_descriptor_pool(
                        &vk::DescriptorPoolCreateInfo::default()
                            .max_sets(st.descriptor_sets.len() as u32)
                            .pool_sizes(&sizes),
                        None,
                    )
                    .map_err(vkfail("vkCreateDescriptorPool"))?;
            }
            for s in &st.descriptor_sets {
                let l = [self.set_layouts[&s.layout]];
                let h = d
                    .allocate_descriptor_sets(
                        &vk::DescriptorSetAllocateInfo::default()
                            .descriptor_pool(self.pool)
                            .set_layouts(&l),
                    )
                    .map_err(vkfail("vkAllocateDescriptorSets"))?[0];
                self.sets.insert(s.name.clone(), h);
            }
            // Writes, one vkUpdateDescriptorSets each; destroyed objects are made, written and destroyed.
            let mut doomed: Vec<Allocation> = Vec::new();
            for s in &st.descriptor_sets {
                let l = st.set_layout(&s.layout).expect("checked above");
                for w in &s.writes {
                    let Some(b) = l.binding(w.binding) else {
                        return unsup(format!(
                            "set `{}` writes binding {}, which its layout lacks",
                            s.name, w.binding
                        ));
                    };
                    if w.element >= b.count {
                        return unsup(format!(
                            "set `{}` writes element {} of binding {} (count {})",
                            s.name, w.element, w.binding, b.count
                        ));
                    }
                    let ty = descriptor_type(b.ty)?;
                    let base = vk::WriteDescriptorSet::default()
                        .dst_set(self.sets[&s.name])
                        .dst_binding(w.binding)
                        .dst_array_element(w.element)
                        .descriptor_type(ty);
                    let wrong = || {
                        RealiseError::Unsupported(format!("set `{}` binding {} ({:?}) is written with {:?}, which a write of that type cannot carry", s.name, w.binding, b.ty, w.descriptor))
                    };
                    match (&w.descriptor, b.ty) {
                        (
                            Descriptor::Image {
                                view,
                                sampler,
                                layout,
                            },
                            DescriptorType::CombinedImageSampler
                            | DescriptorType::SampledImage
                            | DescriptorType::StorageImage,
                        ) => {
                            let v = *self.views.get(view).ok_or_else(|| RealiseError::Unsupported(format!("descriptor names view `{view}`, which the state lacks (destroyed views are not realised)")))?;
                            let smp = match (b.ty, sampler) {
                                (DescriptorType::CombinedImageSampler, Some(n)) => *self.samplers.get(n).ok_or_else(|| RealiseError::Unsupported(format!("descriptor names sampler `{n}`, which the state lacks")))?,
                                (DescriptorType::CombinedImageSampler, None) => return unsup("a combined image sampler written without a sampler (immutable samplers are not modelled)"),
                                _ => vk::Sampler::null(),
                            };
                            let info = [vk::DescriptorImageInfo {
                                sampler: smp,
                                image_view: v,
                                image_layout: vk_layout(*layout)?,
                            }];
                            d.update_descriptor_sets(&[base.image_info(&info)], &[]);
                        }
                        (Descriptor::Sampler { sampler }, DescriptorType::Sampler) => {
                            let smp = *self.samplers.get(sampler).ok_or_else(|| {
                                RealiseError::Unsupported(format!(
                                    "descriptor names sampler `{sampler}`, which the state lacks"
                                ))
                            })?;
                            let info = [vk::DescriptorImageInfo {
                                sampler: smp,
                                ..Default::default()
                            }];
                            d.update_descriptor_sets(&[base.image_info(&info)], &[]);
                        }
                        (
                            Descriptor::TexelBuffer { view },
                            DescriptorType::UniformTexelBuffer | DescriptorType::StorageTexelBuffer,
                        ) => {
                            let v = [*self.buffer_views.get(view).ok_or_else(|| {
                                RealiseError::Unsupported(format!(
                                    "descriptor names buffer view `{view}`, which the state lacks"
                                ))
                            })?];
                            d.update_descriptor_sets(&[base.texel_buffer_view(&v)], &[]);
                        }
                        (
                            Descriptor::Buffer {
                                buffer,
                                offset,
                                range,
                            },
                            DescriptorType::UniformBuffer | DescriptorType::StorageBuffer,
                        ) => {
                            let buf = match self.buffers.get(buffer) {
                                Some(a) => a.buffer,
                                None => {
                                    // A buffer the state does not hold: destroyed after the write.
                                    let a = Allocation::new(
                                        dev,
                                        256,
                                        usage,
                                        vk::BufferCreateFlags::empty(),
                                        1,
                                    )?;
                                    let h = a.buffer;
                                    doomed.push(a);
                                    h
                                }
                            };
                            let info = [vk::DescriptorBufferInfo {
                                buffer: buf,
                                offset: *offset,
                                range: range.unwrap_or(vk::WHOLE_SIZE),
                            }];
                            d.update_descriptor_sets(&[base.buffer_info(&info)], &[]);
                        }
                        _ => return Err(wrong()),
                    }
                }
            }
            for a in doomed {
                a.destroy(dev);
            }
            // Binds and pushes, recorded by `record_binds`.
            for b in &st.bound_sets {
                let layout = *self.pipeline_layouts.get(&b.layout).ok_or_else(|| {
                    RealiseError::Unsupported(format!(
                        "a set is bound with layout `{}`, which the state lacks",
                        b.layout
                    ))
                })?;
                let set = *self.sets.get(&b.descriptor_set).ok_or_else(|| {
                    RealiseError::Unsupported(format!(
                        "descriptor set `{}` is bound but the state lacks it",
                        b.descriptor_set
                    ))
                })?;
                self.binds.push((layout, b.set + 1, set));
            }
            for p in &st.pushes {
                let layout = *self.pipeline_layouts.get(&p.layout).ok_or_else(|| {
                    RealiseError::Unsupported(format!(
                        "constants are pushed with layout `{}`, which the state lacks",
                        p.layout
                    ))
                })?;
                self.pushes.push((layout, p.offset, p.size));
            }
        }
        // The pipeline with the templated stages (KHR or NV GLSL by the pipeline's API).
        for (stage, glsl, narrow) in &sources {
            let mut code = compile_stage(glsl, *stage, trace, api)?;
            patch_narrow_writes(&mut code, narrow).map_err(|e| {
                RealiseError::Failed(format!(
                    "patching the {stage:?} shader's narrow writes: {e}"
                ))
            })?;
            // SAFETY: valid SPIR-V words.
            let m = unsafe {
                cache
                    .dev
                    .device
                    .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None)
            }
            .map_err(vkfail("vkCreateShaderModule"))?;
            self.modules.push((shader_kind(*stage, trace), m));
        }
        if let Some(p) = world.pipeline.as_ref() {
            let rp = cache.create_pipeline_with(p, trace, self.harness_layout, &self.modules)?;
            cache.resource_pipeline = Some(rp);
        }
        Ok(())
    }

    /// Records the images' transitions from UNDEFINED to the layouts the state says they are in (before
    /// any render pass begins).
    ///
    /// # Safety
    /// `cb` is recording on `d`, outside a render pass.
    pub unsafe fn record_transitions(&self, d: &ash::Device, cb: vk::CommandBuffer) {
        let barriers: Vec<vk::ImageMemoryBarrier> = self
            .images
            .iter()
            .filter(|i| i.3 != vk::ImageLayout::UNDEFINED)
            .map(|&(_, image, _, layout, aspect, levels, layers)| {
                vk::ImageMemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::empty())
                    .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE)
                    .old_layout(vk::ImageLayout::UNDEFINED)
                    .new_layout(layout)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(image)
                    .subresource_range(vk::ImageSubresourceRange {
                        aspect_mask: aspect,
                        base_mip_level: 0,
                        level_count: levels,
                        base_array_layer: 0,
                        layer_count: layers,
                    })
            })
            .collect();
        if !barriers.is_empty() {
            d.cmd_pipeline_barrier(
                cb,
                vk::PipelineStageFlags::TOP_OF_PIPE,
                vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &barriers,
            );
        }
    }

    /// Records the state's binds (case set `n` at set `n + 1`) and pushes (zero bytes), in order, after
    /// the harness bound its own set with [`Realised::harness_layout`].
    ///
    /// # Safety
    /// `cb` is recording on `d`.
    pub unsafe fn record_binds(&self, d: &ash::Device, cb: vk::CommandBuffer) {
        for &(layout, set, ds) in &self.binds {
            d.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::RAY_TRACING_KHR,
                layout,
                set,
                &[ds],
                &[],
            );
        }
        for &(layout, offset, size) in &self.pushes {
            let zeros = vec![0u8; size as usize];
            d.cmd_push_constants(cb, layout, rt_stages(), offset, &zeros);
        }
    }

    /// Destroys every object (the case's pipeline in `cache.resource_pipeline` included).
    pub fn destroy(self, cache: &mut DeviceCache) {
        let d = &cache.dev.device;
        // SAFETY: nothing recorded with these objects is pending (the caller's contract).
        unsafe {
            if let Some(p) = cache.resource_pipeline.take() {
                d.destroy_pipeline(p.pipeline, None);
            }
            for (_, m) in self.modules {
                d.destroy_shader_module(m, None);
            }
            if self.pool != vk::DescriptorPool::null() {
                d.destroy_descriptor_pool(self.pool, None);
            }
            for (_, h) in self.buffer_views {
                d.destroy_buffer_view(h, None);
            }
            for (_, a) in self.buffers {
                a.destroy(&cache.dev);
            }
            for (_, h) in self.views {
                d.destroy_image_view(h, None);
            }
            for (_, image, memory, ..) in self.images {
                d.destroy_image(image, None);
                d.free_memory(memory, None);
            }
            for (_, h) in self.samplers {
                d.destroy_sampler(h, None);
            }
            for (_, h) in self.pipeline_layouts {
                d.destroy_pipeline_layout(h, None);
            }
            if self.own_harness_layout {
                d.destroy_pipeline_layout(self.harness_layout, None);
            }
            for (_, h) in self.set_layouts {
                d.destroy_descriptor_set_layout(h, None);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::resources::formats;

    #[test]
    fn glsl_formats_follow_the_vk_names() {
        assert_eq!(glsl_format("VK_FORMAT_R32_UINT"), Some("r32ui"));
        assert_eq!(glsl_format("VK_FORMAT_R16G16_SNORM"), Some("rg16_snorm"));
        assert_eq!(glsl_format("VK_FORMAT_B8G8R8A8_UNORM"), None);
        // Every qualifier's numeric class is the format's.
        for f in [
            "R32G32B32A32_SFLOAT",
            "R8G8B8A8_UINT",
            "R16_SINT",
            "R8_SNORM",
        ] {
            let q = glsl_format(f).unwrap();
            let n = formats::info(f).unwrap().numeric;
            assert_eq!(q.ends_with("ui"), n == Numeric::Uint, "{f}");
            assert_eq!(
                q.ends_with('i') && !q.ends_with("ui"),
                n == Numeric::Int,
                "{f}"
            );
        }
    }
}
