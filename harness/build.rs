//! Links the shaderc library (libshaderc-dev) statically into the harness, so a run compiles GLSL in
//! its own process and needs no compiler on PATH; and compiles the GLSL ray tracing shaders in
//! `shaders/` (the trace pipelines' and the build check's) to SPIR-V in OUT_DIR with glslangValidator
//! (glslang-tools, the same glslang release). When glslangValidator is missing the build still
//! succeeds: the harness then compiles those shaders at first use with the linked library. A missing
//! libshaderc-dev fails the build with the set-up command.

use std::path::{Path, PathBuf};
use std::process::Command;

/// (source file, output name, extra glslang arguments). Each is compiled four times: as is
/// (GL_EXT_ray_tracing, for KHR pipelines), with `-DNV` into `<name>_nv` (GL_NV_ray_tracing, for
/// VK_NV_ray_tracing pipelines), and both again with `-DINTERFACE_ONLY` into `<name>_interface` and
/// `<name>_nv_interface` (the bodies of cases that are recorded and never run; the harness removes
/// their trace instructions as it loads them, `shaders::ShaderBody::module_words`).
const SHADERS: &[(&str, &str, &[&str])] = &[
    ("raygen.rgen", "raygen_trace", &["-DTRACE"]),
    ("raygen.rgen", "raygen_plain", &[]),
    ("miss.rmiss", "miss", &[]),
    ("closest_hit.rchit", "closest_hit_trace", &["-DTRACE"]),
    ("closest_hit.rchit", "closest_hit_plain", &[]),
    ("any_hit.rahit", "any_hit", &[]),
    ("intersection.rint", "intersection", &[]),
    ("callable.rcall", "callable", &[]),
];

/// The build check's shaders (`src/accel_check`), KHR only: (source file, output name).
const CHECK_SHADERS: &[(&str, &str)] = &[
    ("check_query.comp", "check_query"),
    ("check.rgen", "check_raygen"),
    ("check.rmiss", "check_miss"),
    ("check.rchit", "check_closest_hit"),
    ("check.rint", "check_intersection"),
];

/// Debian's libshaderc_combined.a holds shaderc alone: the glslang and SPIRV-Tools archives it
/// needs follow it, each after the ones that use it.
const SHADERC_ARCHIVES: &[&str] = &[
    "shaderc_combined",
    "SPIRV",
    "MachineIndependent",
    "OSDependent",
    "OGLCompiler",
    "GenericCodeGen",
    "SPIRV-Tools-opt",
    "SPIRV-Tools",
];

/// The folder that holds every archive of [`SHADERC_ARCHIVES`]: `$SHADERC_LIB_DIR`, else the
/// system's library folders (Debian's multiarch one first).
fn shaderc_lib_dir() -> Result<PathBuf, String> {
    println!("cargo:rerun-if-env-changed=SHADERC_LIB_DIR");
    let arch = std::env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let candidates: Vec<PathBuf> = match std::env::var_os("SHADERC_LIB_DIR") {
        Some(d) => vec![PathBuf::from(d)],
        None => vec![
            PathBuf::from(format!("/usr/lib/{arch}-linux-gnu")),
            PathBuf::from("/usr/lib64"),
            PathBuf::from("/usr/lib"),
        ],
    };
    let missing = |d: &Path| -> Vec<String> {
        SHADERC_ARCHIVES
            .iter()
            .map(|a| format!("lib{a}.a"))
            .filter(|f| !d.join(f).is_file())
            .collect()
    };
    if let Some(d) = candidates.iter().find(|d| missing(d).is_empty()) {
        return Ok(d.clone());
    }
    let first = &candidates[0];
    Err(format!(
        "the shaderc library is missing ({} not in {}): install libshaderc-dev with `bash scripts/setup.sh`, or set SHADERC_LIB_DIR",
        missing(first).join(", "),
        first.display()
    ))
}

fn main() {
    match shaderc_lib_dir() {
        Ok(lib) => {
            for a in SHADERC_ARCHIVES {
                println!(
                    "cargo:rerun-if-changed={}",
                    lib.join(format!("lib{a}.a")).display()
                );
            }
            println!("cargo:rustc-link-search=native={}", lib.display());
            // Not bundled into the rlib: the archives are named on the final link, after the objects
            // that call them, in this order.
            for a in SHADERC_ARCHIVES {
                println!("cargo:rustc-link-lib=static:-bundle={a}");
            }
            println!("cargo:rustc-link-lib=dylib=stdc++");
            // What the SPIR-V disk cache keys its entries by besides the source: the linked archives'
            // sizes and modification times (a new shaderc package makes new entries).
            let identity: Vec<String> = SHADERC_ARCHIVES
                .iter()
                .map(|a| {
                    let m = std::fs::metadata(lib.join(format!("lib{a}.a")));
                    let (len, modified) = m
                        .map(|m| {
                            let t = m
                                .modified()
                                .ok()
                                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                                .map_or(0, |d| d.as_secs());
                            (m.len(), t)
                        })
                        .unwrap_or((0, 0));
                    format!("{a}:{len}:{modified}")
                })
                .collect();
            println!(
                "cargo:rustc-env=RTCONF_SHADERC_IDENTITY={}",
                identity.join(",")
            );
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into()))
        .join("shaders");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_else(|_| ".".into()));
    println!("cargo:rerun-if-changed=shaders");
    let mut table = String::from(
        "// generated by build.rs\npub(crate) const PRECOMPILED: &[(&str, Option<&[u8]>)] = &[\n",
    );
    let variants = SHADERS
        .iter()
        .flat_map(|&(src, name, args)| {
            let mut nv_args: Vec<&str> = args.to_vec();
            nv_args.push("-DNV");
            let interface = |a: &[&'static str]| {
                let mut a = a.to_vec();
                a.push("-DINTERFACE_ONLY");
                a
            };
            [
                (src, name.to_string(), args.to_vec()),
                (src, format!("{name}_interface"), interface(args)),
                (src, format!("{name}_nv_interface"), interface(&nv_args)),
                (src, format!("{name}_nv"), nv_args),
            ]
        })
        .chain(
            CHECK_SHADERS
                .iter()
                .map(|&(src, name)| (src, name.to_string(), vec![])),
        );
    for (src, name, args) in variants {
        println!("cargo:rerun-if-changed=shaders/{src}");
        let spv = out.join(format!("{name}.spv"));
        if compile(&dir.join(src), &spv, &args) {
            table.push_str(&format!(
                "    ({name:?}, Some(include_bytes!({:?}))),\n",
                spv.display().to_string()
            ));
        } else {
            println!("cargo:warning=glslangValidator could not compile shaders/{src}; the harness compiles it at first use (install glslang-tools with `bash scripts/setup.sh`)");
            table.push_str(&format!("    ({name:?}, None),\n"));
        }
    }
    table.push_str("];\n");
    if let Err(e) = std::fs::write(out.join("shaders.rs"), table) {
        println!("cargo:warning=could not write the shader table: {e}");
    }
}

fn compile(src: &Path, spv: &Path, args: &[&str]) -> bool {
    Command::new("glslangValidator")
        .args(["--target-env", "vulkan1.2", "-V"])
        .args(args)
        .arg(src)
        .arg("-o")
        .arg(spv)
        .output()
        .is_ok_and(|o| o.status.success())
}
