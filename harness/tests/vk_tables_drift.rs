//! Drift check for the generated `harness/src/vk/tables.rs`: regenerating it from the installed vk.xml
//! with `vk_registry::tables` (the `vk-tables` binary) must give the committed file byte for byte.

use std::path::PathBuf;
use vk_registry::tables::{generate, HARNESS_STRUCTURES, REGENERATE};

const VK_XML: &str = "/usr/share/vulkan/registry/vk.xml";

#[test]
fn vk_tables_match_the_installed_registry() {
    let registry = vk_registry::Registry::load(VK_XML).unwrap_or_else(|e| {
        panic!("{VK_XML}: {e} (install libvulkan-dev with `bash scripts/setup.sh`)")
    });
    let fresh = generate(&registry, HARNESS_STRUCTURES).unwrap_or_else(|e| panic!("{e}"));
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src/vk/tables.rs");
    let committed = std::fs::read_to_string(&path).expect("tables.rs is committed");
    if fresh != committed {
        let line = fresh
            .lines()
            .zip(committed.lines())
            .position(|(a, b)| a != b)
            .map_or_else(
                || "the files differ in length".to_string(),
                |i| format!("first difference at line {}", i + 1),
            );
        panic!(
            "harness/src/vk/tables.rs is out of date with {VK_XML} ({line}); regenerate it with\n\n    \
             {REGENERATE}\n\nrun from the workspace root, and commit the result"
        );
    }
}
