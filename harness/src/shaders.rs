//! The one shader path of the harness: the SPIR-V of its own shaders (compiled by build.rs from
//! `harness/shaders/`, or at first use when the build had no glslangValidator), every GLSL it compiles
//! at run time (resource-state stages, the build checks' shaders) through [`compile_glsl`] — one
//! glslangValidator invocation, cached by content — and the one place SPIR-V becomes a shader module
//! ([`module`]).

use crate::error::{vkfail, HarnessError, SETUP_COMMAND};
use crate::vk::VkDevice;
use ash::vk;
use std::collections::HashMap;
use std::process::Command;
use std::sync::Mutex;

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// Shader kinds: one SPIR-V module each per API, specialised per group by constant 0 (the group index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum ShaderKind {
    /// Raygen that traces into the scene at binding 0.
    RaygenTrace,
    /// Raygen without a scene binding (the case traces no rays).
    RaygenPlain,
    Miss,
    /// Closest-hit that traces its ray again while the launch's extra recursion allows (scene at binding 0).
    ClosestHitTrace,
    /// Closest-hit without a scene binding (pipelines of launches that trace no ray).
    ClosestHitPlain,
    AnyHit,
    Intersection,
    Callable,
}

/// Which ray tracing extension a module is written for: GL_EXT_ray_tracing (SPV_KHR_ray_tracing) for KHR
/// pipelines, GL_NV_ray_tracing (SPV_NV_ray_tracing, `-DNV`) for `vkCreateRayTracingPipelinesNV`.
pub use model::world::PipelineApi as ShaderApi;

impl ShaderKind {
    /// The name of the kind's SPIR-V (`raygen_trace`).
    pub fn output_name(self) -> &'static str {
        match self {
            ShaderKind::RaygenTrace => "raygen_trace",
            ShaderKind::RaygenPlain => "raygen_plain",
            ShaderKind::Miss => "miss",
            ShaderKind::ClosestHitTrace => "closest_hit_trace",
            ShaderKind::ClosestHitPlain => "closest_hit_plain",
            ShaderKind::AnyHit => "any_hit",
            ShaderKind::Intersection => "intersection",
            ShaderKind::Callable => "callable",
        }
    }

    /// The output name of the variant for `api` (`<name>_nv` for NV).
    pub(crate) fn variant_name(self, api: ShaderApi) -> String {
        match api {
            ShaderApi::Khr => self.output_name().to_string(),
            ShaderApi::Nv => format!("{}_nv", self.output_name()),
        }
    }

    /// The GLSL file, its text and the defines of the kind's variant.
    fn source(self) -> (&'static str, &'static str, &'static [&'static str]) {
        match self {
            ShaderKind::RaygenTrace => (
                "raygen.rgen",
                include_str!("../shaders/raygen.rgen"),
                &["-DTRACE"],
            ),
            ShaderKind::RaygenPlain => ("raygen.rgen", include_str!("../shaders/raygen.rgen"), &[]),
            ShaderKind::Miss => ("miss.rmiss", include_str!("../shaders/miss.rmiss"), &[]),
            ShaderKind::ClosestHitTrace => (
                "closest_hit.rchit",
                include_str!("../shaders/closest_hit.rchit"),
                &["-DTRACE"],
            ),
            ShaderKind::ClosestHitPlain => (
                "closest_hit.rchit",
                include_str!("../shaders/closest_hit.rchit"),
                &[],
            ),
            ShaderKind::AnyHit => (
                "any_hit.rahit",
                include_str!("../shaders/any_hit.rahit"),
                &[],
            ),
            ShaderKind::Intersection => (
                "intersection.rint",
                include_str!("../shaders/intersection.rint"),
                &[],
            ),
            ShaderKind::Callable => (
                "callable.rcall",
                include_str!("../shaders/callable.rcall"),
                &[],
            ),
        }
    }
}

/// The record layout the shaders write must be the model's (`RECORD_WORDS`, the outcome codes and the
/// word positions in `shaders/*.r*`).
const _: () = {
    use model::tracer::record::RayRecord as R;
    assert!(R::WORDS == 28 && R::SEEN_SLOTS == 4);
    assert!(R::MISS == 1 && R::HIT == 2 && R::NO_SHADER == 3 && R::NO_GROUP == 0xFFFF_FFFF);
    assert!(R::ANY_HIT_COUNT == 10 && R::INTERSECTION_COUNT == 11 && R::SEEN == 12);
    assert!(R::T == 7 && R::BARYCENTRICS == 8 && R::GEOMETRY_INDEX == 4);
};

/// The SPIR-V words of a shader kind for a pipeline API.
pub(crate) fn spirv(kind: ShaderKind, api: ShaderApi) -> Result<Vec<u32>, HarnessError> {
    let name = kind.variant_name(api);
    match PRECOMPILED
        .iter()
        .find(|(n, _)| *n == name)
        .and_then(|(_, b)| *b)
    {
        Some(b) => words(&name, b),
        None => {
            let (file, text, args) = kind.source();
            let ext = file.rsplit('.').next().unwrap_or(file);
            let mut defines: Vec<&str> = args.iter().map(|a| a.trim_start_matches("-D")).collect();
            if api == ShaderApi::Nv {
                defines.push("NV");
            }
            compile_glsl(file, ext, text, &defines)
        }
    }
}

/// SPIR-V bytes as words, checked for the size of a module.
fn words(name: &str, bytes: &[u8]) -> Result<Vec<u32>, HarnessError> {
    if bytes.len() % 4 != 0 || bytes.len() < 20 {
        return Err(HarnessError::Shader(format!(
            "{name}: not SPIR-V ({} bytes)",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Compiles GLSL to SPIR-V words with glslangValidator (Vulkan 1.2 target): `ext` is the stage's file
/// extension (`rgen`, `rchit`, `comp`, …), `defines` the preprocessor names (`TRACE`, `NV`), `what`
/// names the shader in errors. Results are cached in this process and on disk by content, so worker
/// processes compile each source once.
pub(crate) fn compile_glsl(
    what: &str,
    ext: &str,
    text: &str,
    defines: &[&str],
) -> Result<Vec<u32>, HarnessError> {
    use std::hash::{Hash, Hasher};
    static MEMO: Mutex<Option<HashMap<u64, Vec<u32>>>> = Mutex::new(None);
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (text, ext, defines).hash(&mut h);
    let key = h.finish();
    if let Some(w) = MEMO
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get_or_insert_with(HashMap::new)
        .get(&key)
    {
        return Ok(w.clone());
    }
    let io =
        |p: &std::path::Path, e: std::io::Error| HarnessError::Io(format!("{}: {e}", p.display()));
    let dir = std::env::temp_dir().join("rtconf-shaders");
    std::fs::create_dir_all(&dir).map_err(|e| io(&dir, e))?;
    let spv = dir.join(format!("{key:016x}.spv"));
    if !spv.exists() {
        let _phase = crate::timing::span(crate::timing::Phase::Shaders);
        let pid = std::process::id();
        let src = dir.join(format!("{key:016x}-{pid}.{ext}"));
        std::fs::write(&src, text).map_err(|e| io(&src, e))?;
        let tmp = dir.join(format!("{key:016x}-{pid}.spv"));
        let out = Command::new("glslangValidator")
            .args(["--target-env", "vulkan1.2", "-V"])
            .args(defines.iter().map(|d| format!("-D{d}")))
            .arg(&src)
            .arg("-o")
            .arg(&tmp)
            .output()
            .map_err(|e| {
                HarnessError::Shader(format!(
                    "glslangValidator is not available ({e}); install it with `{SETUP_COMMAND}`"
                ))
            });
        let _ = std::fs::remove_file(&src);
        let out = out?;
        if !out.status.success() {
            return Err(HarnessError::Shader(format!(
                "glslangValidator failed on {what}: {}\n{text}",
                String::from_utf8_lossy(&out.stdout)
            )));
        }
        // Renamed into place whole, so another worker never reads a half-written module.
        std::fs::rename(&tmp, &spv).map_err(|e| io(&spv, e))?;
    }
    let bytes = std::fs::read(&spv).map_err(|e| io(&spv, e))?;
    let w = words(what, &bytes)?;
    MEMO.lock()
        .unwrap_or_else(|e| e.into_inner())
        .get_or_insert_with(HashMap::new)
        .insert(key, w.clone());
    Ok(w)
}

/// A shader module of SPIR-V words on a device; the caller destroys it.
pub(crate) fn module(dev: &VkDevice, code: &[u32]) -> Result<vk::ShaderModule, HarnessError> {
    // SAFETY: `code` is SPIR-V from glslangValidator (checked for a module's size).
    unsafe {
        dev.device
            .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(code), None)
    }
    .map_err(vkfail("vkCreateShaderModule"))
}

#[cfg(test)]
mod tests {
    const ALL: [ShaderKind; 8] = [
        ShaderKind::RaygenTrace,
        ShaderKind::RaygenPlain,
        ShaderKind::Miss,
        ShaderKind::ClosestHitTrace,
        ShaderKind::ClosestHitPlain,
        ShaderKind::AnyHit,
        ShaderKind::Intersection,
        ShaderKind::Callable,
    ];

    use super::*;

    /// The SPIR-V capability instruction (opcode 17) operands a module declares.
    fn capabilities(words: &[u32]) -> Vec<u32> {
        let mut out = Vec::new();
        let mut i = 5;
        while i < words.len() {
            let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xFFFF);
            if op == 17 && count == 2 {
                out.push(words[i + 1]);
            }
            i += count.max(1);
        }
        out
    }

    #[test]
    fn every_shader_kind_has_spirv_for_both_apis() {
        const RAY_TRACING_NV: u32 = 5340;
        const RAY_TRACING_KHR: u32 = 4479;
        for k in ALL {
            for api in [ShaderApi::Khr, ShaderApi::Nv] {
                let words = spirv(k, api).unwrap();
                assert_eq!(
                    words[0], 0x0723_0203,
                    "{k:?} {api:?} starts with the SPIR-V magic number"
                );
                let caps = capabilities(&words);
                let want = if api == ShaderApi::Nv {
                    RAY_TRACING_NV
                } else {
                    RAY_TRACING_KHR
                };
                assert!(
                    caps.contains(&want),
                    "{k:?} {api:?} declares capability {want}: {caps:?}"
                );
            }
        }
    }
}
