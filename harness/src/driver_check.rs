//! The driver checked once, before a run or a replay hands it any case: its ICD manifest is read and
//! must name a library that exists and is a shared object, and an instance made with it (under the
//! validation layer) must enumerate a device. What is wrong names the file and the problem, instead of
//! every case crashing (a missing library), failing with `ERROR_OUT_OF_HOST_MEMORY` (a garbled
//! manifest) or the driver's path being taken for a profile's name.

use crate::error::HarnessError;
use crate::vk::{Driver, VkInstance};
use std::path::{Path, PathBuf};

/// What the check found: the manifest, the library it names, and the device the instance enumerates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CheckedDriver {
    pub manifest: PathBuf,
    pub library: String,
    pub device: String,
}

/// Checks `driver` (see the module documentation).
pub fn check_driver(driver: &Driver) -> Result<CheckedDriver, HarnessError> {
    let (manifest, library) = check_manifest(driver)?;
    let _turn = crate::vk::turn::take();
    let instance = VkInstance::new(driver.clone(), true)
        .map_err(|e| instance_failure(&manifest, &library, e))?;
    Ok(CheckedDriver {
        manifest,
        library,
        device: instance.device_name(),
    })
}

/// What the check says of an instance that could not be made with the manifest's library: a Vulkan
/// error names the manifest and the library; any other error is itself.
pub fn instance_failure(manifest: &Path, library: &str, e: HarnessError) -> HarnessError {
    match e {
        HarnessError::Vulkan { what, result } => HarnessError::Manifest {
            path: manifest.display().to_string(),
            problem: format!("names the library `{library}`, with which {what} fails ({result:?})"),
        },
        e => e,
    }
}

/// The check's first half, which loads nothing: the manifest exists, is JSON and names a library
/// that exists and is a shared object (a bare name is left to the dynamic loader). The manifest's
/// path and the library it names.
pub fn check_manifest(driver: &Driver) -> Result<(PathBuf, String), HarnessError> {
    let manifest = driver.icd_path();
    let shown = manifest.display().to_string();
    let bad = |problem: String| HarnessError::Manifest {
        path: shown.clone(),
        problem,
    };
    if !manifest.exists() {
        return Err(HarnessError::IcdMissing(shown));
    }
    // A manifest is a few hundred bytes.
    let text = vk_registry::input::read_text_at_most(
        &manifest,
        16 * vk_registry::input::MIB,
        "an ICD manifest",
    )
    .map_err(|e| bad(format!("cannot be read: {e}")))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("is not JSON: {e}")))?;
    let library = json
        .pointer("/ICD/library_path")
        .ok_or_else(|| bad("has no ICD.library_path".into()))?
        .as_str()
        .ok_or_else(|| bad("ICD.library_path is not a string".into()))?
        .to_string();
    if library.contains('/') {
        // A path is taken relative to the manifest; a bare name is found by the dynamic loader.
        let lib = Path::new(&library);
        let lib = if lib.is_absolute() {
            lib.to_path_buf()
        } else {
            manifest.parent().unwrap_or(Path::new(".")).join(lib)
        };
        let mut head = [0u8; 4];
        let read = std::fs::File::open(&lib)
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head));
        match read {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(bad(format!(
                    "names the library {}, which does not exist",
                    lib.display()
                )))
            }
            Err(e) => return Err(bad(format!("names the library {}: {e}", lib.display()))),
            Ok(()) if &head != b"\x7fELF" => {
                return Err(bad(format!(
                    "names the library {}, which is not a shared object",
                    lib.display()
                )))
            }
            Ok(()) => {}
        }
    }
    Ok((manifest, library))
}
