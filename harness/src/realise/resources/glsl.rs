//! The GLSL of a resource state: one declaration per declared access, the access in straight-line code
//! at the start of the stage's `main`, folded into a value consumed under a condition that never holds;
//! narrow texel writes patched into the compiled module; compiled through [`crate::shaders`].

use super::*;
use crate::shaders;
use model::world::PipelineApi;
use std::fmt::Write as _;

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
        "R64_UINT" => "r64ui",
        "R64_SINT" => "r64i",
        _ => return None,
    })
}

/// The GLSL type prefix of a `Sampled Type` (`u64` for 64-bit unsigned: GL_EXT_shader_image_int64).
fn prefix(t: &ImageType) -> &'static str {
    match (t.sampled_type, t.width == 64) {
        (Numeric::Float, _) => "",
        (Numeric::Int, false) => "i",
        (Numeric::Uint, false) => "u",
        (Numeric::Int, true) => "i64",
        (Numeric::Uint, true) => "u64",
    }
}

/// The GLSL scalar type of a `Sampled Type`.
fn scalar(t: &ImageType) -> &'static str {
    match (t.sampled_type, t.width == 64) {
        (Numeric::Float, _) => "float",
        (Numeric::Int, false) => "int",
        (Numeric::Uint, false) => "uint",
        (Numeric::Int, true) => "int64_t",
        (Numeric::Uint, true) => "uint64_t",
    }
}

/// Whether a stage's accesses need GL_EXT_shader_image_int64 (a 64-bit `Sampled Type`).
fn uses_int64_images(accesses: &[Access]) -> bool {
    accesses
        .iter()
        .any(|a| a.image.is_some_and(|t| t.width == 64))
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
        "int64_t" => ("int64_t", "i64vec"),
        "uint64_t" => ("uint64_t", "u64vec"),
        _ => ("uint", "uvec"),
    };
    if n == 1 {
        format!("{s}({v})")
    } else {
        format!("{p}{n}({v})")
    }
}

/// `uint` of a scalar expression of the sampled type (64-bit integers are truncated).
fn to_uint(t: &ImageType, e: &str) -> String {
    match (t.sampled_type, t.width == 64) {
        (Numeric::Float, _) => format!("floatBitsToUint({e})"),
        (Numeric::Uint, false) => e.to_string(),
        (Numeric::Int, _) | (Numeric::Uint, true) => format!("uint({e})"),
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
pub(super) fn view_format(st: &ResourceState, a: &Access) -> Option<String> {
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
pub(crate) fn pipeline_has(p: &model::world::Pipeline, stage: Stage) -> bool {
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
pub(crate) fn shader_kind(stage: Stage, trace: bool) -> ShaderKind {
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

/// The harness's GLSL source of a stage and the file extension the compiler takes the stage from.
pub fn stage_source(stage: Stage) -> (&'static str, &'static str) {
    match stage {
        Stage::Raygen => (include_str!("../../../shaders/raygen.rgen"), "rgen"),
        Stage::ClosestHit => (include_str!("../../../shaders/closest_hit.rchit"), "rchit"),
        Stage::Miss => (include_str!("../../../shaders/miss.rmiss"), "rmiss"),
        Stage::AnyHit => (include_str!("../../../shaders/any_hit.rahit"), "rahit"),
        Stage::Intersection => (include_str!("../../../shaders/intersection.rint"), "rint"),
        Stage::Callable => (include_str!("../../../shaders/callable.rcall"), "rcall"),
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
            "    if (acc == 0x9E3779B9u && payload.depth == 0x5EEDu) { payload.outcome = acc; }\n"
        }
        Stage::Callable => "    if (acc == 0x9E3779B9u && data == 0x5EEDu) { data = acc; }\n",
        Stage::Intersection => {
            "    if (acc == 0x9E3779B9u && gl_RayTminEXT < -1.0) { reportIntersectionEXT(gl_RayTminEXT, 0u); }\n"
        }
    }
}

/// The GLSL of one stage for a state: `base` (the harness's source of that stage, [`stage_source`])
/// with the stage's accesses and push constant reads injected at the start of `main` (so the stage's
/// own code, which writes the payload, runs after them). Errors name what GLSL cannot express.
pub fn stage_glsl(
    st: &ResourceState,
    which: Stage,
    base: &str,
) -> Result<(String, Vec<NarrowWrite>), HarnessError> {
    let mut narrow = Vec::new();
    let mut exts = String::from(
        "#extension GL_EXT_shader_image_load_formatted : require\n\
         #extension GL_EXT_samplerless_texture_functions : require\n#extension GL_EXT_nonuniform_qualifier : enable\n",
    );
    let mut decls = String::new();
    let mut body = String::from("    uint acc = 0u;\n");
    let stage = st.stages.iter().find(|s| s.stage == which);
    let accesses: &[Access] = stage.map_or(&[], |s| &s.accesses);
    if uses_int64_images(accesses) {
        exts.push_str(
            "#extension GL_EXT_shader_image_int64 : require\n\
             #extension GL_EXT_shader_explicit_arithmetic_types_int64 : require\n",
        );
    }
    for (i, a) in accesses.iter().enumerate() {
        let set = a.set + 1;
        let (ty, count) = binding_of(st, a);
        let past_end = a.element >= count;
        let arr = if count > 1 || past_end {
            format!("[{count}]")
        } else {
            String::new()
        };
        let idx = if past_end {
            // GLSL refuses a constant index past the array's end but takes it as a specialisation
            // constant's default, which `compile_stage` makes an ordinary constant: the module
            // indexes the binding with the constant element the access states.
            writeln!(
                decls,
                "layout(constant_id = {}) const uint E{i} = {}u;",
                shaders::FIXED_SPEC_ID_BASE as usize + i,
                a.element
            )
            .unwrap();
            format!("[E{i}]")
        } else if count > 1 {
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
                        return Err(HarnessError::NotRealised(format!(
                            "access {i} loads or stores through a {t:?} binding"
                        )))
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
                        return Err(HarnessError::NotRealised(format!(
                            "access {i} stores to a uniform buffer"
                        )));
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
            return Err(HarnessError::NotRealised(format!(
                "access {i} ({:?}) names no OpTypeImage",
                a.op
            )));
        };
        if t.width == 64 && t.sampled_type == Numeric::Float {
            return Err(HarnessError::NotRealised(format!(
                "access {i}: a 64-bit float Sampled Type is not valid SPIR-V"
            )));
        }
        let p = prefix(&t);
        let base_ty = scalar(&t);
        let n = coord_len(t.dim) + t.arrayed as usize;
        let fcoord = vec_of("float", n, "0.5");
        let icoord = vec_of("int", n, "0");
        let ds = dim_suffix(&t);
        match a.op {
            Op::Sample | Op::Fetch => {
                if t.width == 64 {
                    return Err(HarnessError::NotRealised(format!("access {i}: GLSL has no 64-bit sampler or texture types (GL_EXT_shader_image_int64 adds storage images only)")));
                }
                let shadow = if a.dref { "Shadow" } else { "" };
                let combined = match (ty, a.sampler_at) {
                    (Some(DescriptorType::CombinedImageSampler), _) | (None, None) => true,
                    (Some(DescriptorType::SampledImage), _) => false,
                    (Some(DescriptorType::UniformTexelBuffer), _) if t.dim == Dim::Buffer => true,
                    (None, Some(_)) => false,
                    (Some(other), _) => {
                        return Err(HarnessError::NotRealised(format!(
                            "access {i} samples or fetches through a {other:?} binding"
                        )))
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
                            return Err(HarnessError::NotRealised(format!(
                                "access {i} samples a sampled image with no sampler"
                            )))
                        }
                    }
                };
                let e = if a.op == Op::Fetch {
                    if a.dref || t.dim == Dim::Cube {
                        return Err(HarnessError::NotRealised(format!("access {i} fetches from a cube or depth-compare image, which GLSL cannot")));
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
                        return Err(HarnessError::NotRealised(format!(
                            "access {i} samples a buffer"
                        )));
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
                    to_uint(&t, &e)
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
                        return Err(HarnessError::NotRealised(format!(
                            "access {i} ({:?}) goes through a {other:?} binding",
                            a.op
                        )))
                    }
                }
                let fmt = if a.op == Op::Atomic {
                    if t.format_unknown {
                        return Err(HarnessError::NotRealised(format!("access {i}: GLSL image atomics need an r32 format qualifier, not Unknown")));
                    }
                    Some(match (t.sampled_type, t.width == 64) {
                        (Numeric::Float, _) => "r32f",
                        (Numeric::Int, false) => "r32i",
                        (Numeric::Uint, false) => "r32ui",
                        (Numeric::Int, true) => "r64i",
                        (Numeric::Uint, true) => "r64ui",
                    })
                } else if t.format_unknown {
                    None
                } else {
                    let f = view_format(st, a).ok_or_else(|| {
                        HarnessError::NotRealised(format!(
                            "access {i}: no view format to declare the image with"
                        ))
                    })?;
                    Some(glsl_format(&f).ok_or_else(|| {
                        HarnessError::NotRealised(format!(
                            "access {i}: format {f} has no GLSL image format qualifier"
                        ))
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
                        to_uint(&t, &format!("imageLoad({name}{idx}, {c}).x"))
                    )
                    .unwrap(),
                    Op::Atomic => {
                        let one = match (t.sampled_type, t.width == 64) {
                            (Numeric::Float, _) => "1.0",
                            (Numeric::Int, false) => "1",
                            (Numeric::Uint, false) => "1u",
                            (Numeric::Int, true) => "1l",
                            (Numeric::Uint, true) => "1ul",
                        };
                        let f = if t.sampled_type == Numeric::Float {
                            "imageAtomicExchange"
                        } else {
                            "imageAtomicAdd"
                        };
                        let e = format!("{f}({name}{idx}, {c}, {one})");
                        writeln!(body, "    acc += {};", to_uint(&t, &e)).unwrap();
                    }
                    _ => {
                        let k = a.texel_components.unwrap_or(4);
                        if !(1..=4).contains(&k) {
                            return Err(HarnessError::NotRealised(format!(
                                "access {i} writes a texel of {k} components"
                            )));
                        }
                        writeln!(
                            body,
                            "    imageStore({name}{idx}, {c}, {});",
                            vec_of(base_ty, 4, "0")
                        )
                        .unwrap();
                        if k < 4 && t.width == 64 {
                            return Err(HarnessError::NotRealised(format!(
                                "access {i} writes a 64-bit texel of {k} components, which the module patch does not write"
                            )));
                        }
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
                                to_uint(&t, &format!("n{i}{}", if k > 1 { ".x" } else { "" }))
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
            other => {
                return Err(HarnessError::NotRealised(format!(
                    "access {i}: {other:?} is not realised"
                )))
            }
        }
    }
    if let Some([off, size]) = stage.and_then(|s| s.push_constants) {
        if off % 4 != 0 || size == 0 {
            return Err(HarnessError::NotRealised(format!(
                "push constant bytes [{off}, +{size}) are not whole words"
            )));
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
    let at = base.find(main).ok_or_else(|| {
        HarnessError::NotRealised("the stage's source has no `void main() {`".into())
    })?;
    let version = base.find("#version 460\n").ok_or_else(|| {
        HarnessError::NotRealised("the stage's source has no #version line".into())
    })? + "#version 460\n".len();
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
    pub(crate) variable: String,
    pub(crate) component: Numeric,
    pub(crate) components: u32,
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
pub(crate) fn patch_narrow_writes(
    words: &mut [u32],
    narrow: &[NarrowWrite],
) -> Result<(), HarnessError> {
    if narrow.is_empty() {
        return Ok(());
    }
    // (offset, opcode, operands range) of each instruction.
    let mut insts = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xFFFF);
        if count == 0 || i + count > words.len() {
            return Err(HarnessError::Failed("malformed SPIR-V".into()));
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
            .ok_or_else(|| HarnessError::Failed(format!("no OpName {}", n.variable)))?;
        // The scalar type, the texel type, and a constant of it.
        let scalar = insts
            .iter()
            .find(|&&(at, op, _)| match n.component {
                Numeric::Float => op == 22 && words[at + 2] == 32,
                Numeric::Int => op == 21 && words[at + 2] == 32 && words[at + 3] == 1,
                Numeric::Uint => op == 21 && words[at + 2] == 32 && words[at + 3] == 0,
            })
            .map(|&(at, ..)| words[at + 1])
            .ok_or_else(|| HarnessError::Failed("no scalar type".into()))?;
        let texel_type = if n.components == 1 {
            scalar
        } else {
            insts
                .iter()
                .find(|&&(at, op, _)| {
                    op == 23 && words[at + 2] == scalar && words[at + 3] == n.components
                })
                .map(|&(at, ..)| words[at + 1])
                .ok_or_else(|| HarnessError::Failed("no vector type".into()))?
        };
        let constant = insts
            .iter()
            .find(|&&(at, op, _)| (op == 43 || op == 44) && words[at + 1] == texel_type)
            .map(|&(at, ..)| words[at + 2])
            .ok_or_else(|| HarnessError::Failed("no texel constant".into()))?;
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
            return Err(HarnessError::Failed(format!(
                "no OpImageWrite through {}",
                n.variable
            )));
        }
    }
    Ok(())
}

/// Compiles a stage's GLSL to SPIR-V words (with `-DTRACE` when `trace`, `-DNV` for
/// VK_NV_ray_tracing pipelines and `-DINTERFACE_ONLY` for the interface-only body, as build.rs
/// compiles the harness's own shaders) through the one shader path, `shaders::compile_glsl`, its
/// fixed specialisation constants made ordinary ones (`shaders::with_fixed_spec_defaults`). The
/// injected accesses come before the body, whichever it is.
pub fn compile_stage(
    glsl: &str,
    stage: Stage,
    trace: bool,
    api: PipelineApi,
    body: shaders::ShaderBody,
) -> Result<Vec<u32>, HarnessError> {
    let (_, ext) = stage_source(stage);
    let mut defines = Vec::new();
    if trace {
        defines.push("TRACE");
    }
    if api == PipelineApi::Nv {
        defines.push("NV");
    }
    defines.extend(body.defines());
    shaders::compile_glsl(
        &format!("the resource {stage:?} shader"),
        ext,
        glsl,
        &defines,
    )
    .map(|w| body.module_words(shaders::with_fixed_spec_defaults(&w)))
}

// ---------------------------------------------------------------------------------------------
// Vulkan objects

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
            "R64_UINT",
            "R64_SINT",
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
