//! The SPIR-V of the harness's shaders: compiled by build.rs from `harness/shaders/*.glsl`, or at first use
//! when the build had no glslangValidator, with an error naming the set-up command when it is still missing.

use crate::error::{HarnessError, SETUP_COMMAND};
use std::process::Command;

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// Shader kinds: one SPIR-V module each per API, specialised per group by constant 0 (the group index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
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
    pub const ALL: [ShaderKind; 8] = [
        ShaderKind::RaygenTrace,
        ShaderKind::RaygenPlain,
        ShaderKind::Miss,
        ShaderKind::ClosestHitTrace,
        ShaderKind::ClosestHitPlain,
        ShaderKind::AnyHit,
        ShaderKind::Intersection,
        ShaderKind::Callable,
    ];

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
    pub fn variant_name(self, api: ShaderApi) -> String {
        match api {
            ShaderApi::Khr => self.output_name().to_string(),
            ShaderApi::Nv => format!("{}_nv", self.output_name()),
        }
    }

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

/// The payload tags the shaders write must be the model's.
const _: () =
    assert!(model::semantics::MISS_TAG == 0x0001_0000 && model::semantics::HIT_TAG == 0x0002_0000);
const _: () = assert!(model::semantics::UNTOUCHED == 0xFFFF_FFFE);

/// The SPIR-V words of a shader kind for a pipeline API.
pub fn spirv(kind: ShaderKind, api: ShaderApi) -> Result<Vec<u32>, HarnessError> {
    let name = kind.variant_name(api);
    let bytes = match PRECOMPILED
        .iter()
        .find(|(n, _)| *n == name)
        .and_then(|(_, b)| *b)
    {
        Some(b) => b.to_vec(),
        None => compile_now(kind, api)?,
    };
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

fn compile_now(kind: ShaderKind, api: ShaderApi) -> Result<Vec<u8>, HarnessError> {
    let (file, text, args) = kind.source();
    let nv: &[&str] = if api == ShaderApi::Nv { &["-DNV"] } else { &[] };
    let dir = std::env::temp_dir().join(format!("rtconf-shaders-{}", std::process::id()));
    std::fs::create_dir_all(&dir)
        .map_err(|e| HarnessError::Io(format!("{}: {e}", dir.display())))?;
    let src = dir.join(file);
    let spv = dir.join(format!("{}.spv", kind.variant_name(api)));
    std::fs::write(&src, text).map_err(|e| HarnessError::Io(format!("{}: {e}", src.display())))?;
    let out = Command::new("glslangValidator")
        .args(["--target-env", "vulkan1.2", "-V"])
        .args(args)
        .args(nv)
        .arg(&src)
        .arg("-o")
        .arg(&spv)
        .output()
        .map_err(|e| {
            HarnessError::Shader(format!(
                "glslangValidator is not available ({e}); install it with `{SETUP_COMMAND}`"
            ))
        })?;
    if !out.status.success() {
        return Err(HarnessError::Shader(format!(
            "glslangValidator failed on {file}: {}",
            String::from_utf8_lossy(&out.stdout)
        )));
    }
    std::fs::read(&spv).map_err(|e| HarnessError::Io(format!("{}: {e}", spv.display())))
}

#[cfg(test)]
mod tests {
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
        for k in ShaderKind::ALL {
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
