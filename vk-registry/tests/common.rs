//! Helpers shared by the integration tests: paths of the installed registry, the seeds and the
//! fetched 1.4.309 registry.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn fixture(name: &str) -> PathBuf {
    manifest_dir().join("tests/fixtures").join(name)
}

pub fn fixture_text(name: &str) -> String {
    std::fs::read_to_string(fixture(name)).unwrap_or_else(|e| panic!("fixture {name}: {e}"))
}

pub fn seeds_dir() -> PathBuf {
    // The seeds sit in `shared/` beside the checkout (`/work/shared` for `/work/main`); a worktree may sit
    // deeper (`/work/wt/NAME`), so the nearest ancestor that has them is taken.
    manifest_dir()
        .ancestors()
        .map(|a| a.join("shared/seeds"))
        .find(|p| p.is_dir())
        .unwrap_or_else(|| manifest_dir().join("../../shared/seeds"))
}

pub fn installed_dir() -> PathBuf {
    PathBuf::from(vk_registry::DEFAULT_REGISTRY_DIR)
}

pub fn installed_vk_xml() -> PathBuf {
    installed_dir().join("vk.xml")
}

pub fn installed_validusage() -> PathBuf {
    installed_dir().join("validusage.json")
}

/// The 1.4.309 registry from trixie, fetched with scripts/fetch-registry.sh when missing.
pub fn registry_1_4_309() -> PathBuf {
    let root = manifest_dir().join("..");
    let dest = root.join("target/registry/1.4.309");
    let reg = dest.join("usr/share/vulkan/registry");
    if !reg.join("validusage.json").exists() {
        let status = Command::new("bash")
            .arg(root.join("scripts/fetch-registry.sh"))
            .arg(&dest)
            .status()
            .expect("running scripts/fetch-registry.sh");
        assert!(
            status.success(),
            "scripts/fetch-registry.sh could not fetch the 1.4.309 registry into {}",
            dest.display()
        );
    }
    assert!(
        reg.join("validusage.json").exists() && reg.join("vk.xml").exists(),
        "1.4.309 registry missing in {}",
        reg.display()
    );
    reg
}

pub fn exists(p: &Path) -> bool {
    p.exists()
}
