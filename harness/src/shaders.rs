//! The SPIR-V of the harness's shaders: compiled by build.rs from `harness/shaders/*.glsl`, or at first use
//! when the build had no glslangValidator, with an error naming the set-up command when it is still missing.

use crate::error::{HarnessError, SETUP_COMMAND};
use std::process::Command;

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// Shader kinds: one SPIR-V module each, specialised per group by constant 0 (the group index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ShaderKind {
    /// Raygen that traces into the scene at binding 0.
    RaygenTrace,
    /// Raygen without a scene binding (the case traces no rays).
    RaygenPlain,
    Miss,
    ClosestHit,
    AnyHit,
    Intersection,
    Callable,
}

impl ShaderKind {
    pub fn output_name(self) -> &'static str {
        match self {
            ShaderKind::RaygenTrace => "raygen_trace",
            ShaderKind::RaygenPlain => "raygen_plain",
            ShaderKind::Miss => "miss",
            ShaderKind::ClosestHit => "closest_hit",
            ShaderKind::AnyHit => "any_hit",
            ShaderKind::Intersection => "intersection",
            ShaderKind::Callable => "callable",
        }
    }

    fn source(self) -> (&'static str, &'static str, &'static [&'static str]) {
        match self {
            ShaderKind::RaygenTrace => ("raygen.rgen", include_str!("../shaders/raygen.rgen"), &["-DTRACE"]),
            ShaderKind::RaygenPlain => ("raygen.rgen", include_str!("../shaders/raygen.rgen"), &[]),
            ShaderKind::Miss => ("miss.rmiss", include_str!("../shaders/miss.rmiss"), &[]),
            ShaderKind::ClosestHit => ("closest_hit.rchit", include_str!("../shaders/closest_hit.rchit"), &[]),
            ShaderKind::AnyHit => ("any_hit.rahit", include_str!("../shaders/any_hit.rahit"), &[]),
            ShaderKind::Intersection => ("intersection.rint", include_str!("../shaders/intersection.rint"), &[]),
            ShaderKind::Callable => ("callable.rcall", include_str!("../shaders/callable.rcall"), &[]),
        }
    }
}

/// The payload tags the shaders write must be the model's.
const _: () = assert!(model::semantics::MISS_TAG == 0x0001_0000 && model::semantics::HIT_TAG == 0x0002_0000);
const _: () = assert!(model::semantics::UNTOUCHED == 0xFFFF_FFFE);

/// The SPIR-V words of a shader kind.
pub fn spirv(kind: ShaderKind) -> Result<Vec<u32>, HarnessError> {
    let bytes = match PRECOMPILED.iter().find(|(n, _)| *n == kind.output_name()).and_then(|(_, b)| *b) {
        Some(b) => b.to_vec(),
        None => compile_now(kind)?,
    };
    if bytes.len() % 4 != 0 || bytes.len() < 20 {
        return Err(HarnessError::Shader(format!("{}: not SPIR-V ({} bytes)", kind.output_name(), bytes.len())));
    }
    Ok(bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

fn compile_now(kind: ShaderKind) -> Result<Vec<u8>, HarnessError> {
    let (file, text, args) = kind.source();
    let dir = std::env::temp_dir().join(format!("rtconf-shaders-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| HarnessError::Io(format!("{}: {e}", dir.display())))?;
    let src = dir.join(file);
    let spv = dir.join(format!("{}.spv", kind.output_name()));
    std::fs::write(&src, text).map_err(|e| HarnessError::Io(format!("{}: {e}", src.display())))?;
    let out = Command::new("glslangValidator")
        .args(["--target-env", "vulkan1.2", "-V"])
        .args(args)
        .arg(&src)
        .arg("-o")
        .arg(&spv)
        .output()
        .map_err(|e| {
            HarnessError::Shader(format!("glslangValidator is not available ({e}); install it with `{SETUP_COMMAND}`"))
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

    #[test]
    fn every_shader_kind_has_spirv() {
        for k in [
            ShaderKind::RaygenTrace,
            ShaderKind::RaygenPlain,
            ShaderKind::Miss,
            ShaderKind::ClosestHit,
            ShaderKind::AnyHit,
            ShaderKind::Intersection,
            ShaderKind::Callable,
        ] {
            let words = spirv(k).unwrap();
            assert_eq!(words[0], 0x0723_0203, "{k:?} starts with the SPIR-V magic number");
        }
    }
}
