//! Drift check for the generated `harness/src/vk_tables.rs`: regenerating it from the installed vk.xml with
//! `harness/src/gen_vk_tables.py` must give the committed file byte for byte.

use std::path::{Path, PathBuf};
use std::process::Command;

const VK_XML: &str = "/usr/share/vulkan/registry/vk.xml";

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn regenerate(vk_xml: &Path, out: &Path) -> Result<(), String> {
    let script = manifest().join("src/gen_vk_tables.py");
    let o = Command::new("python3")
        .arg(&script)
        .arg(vk_xml)
        .arg(out)
        .output()
        .map_err(|e| {
            format!("python3 could not be started ({e}); install it with `bash scripts/setup.sh`")
        })?;
    if o.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&o.stderr)
        ))
    }
}

#[test]
fn vk_tables_match_the_installed_registry() {
    assert!(
        Path::new(VK_XML).is_file(),
        "{VK_XML} is missing: install libvulkan-dev with `bash scripts/setup.sh`"
    );
    let dir = tempfile::tempdir().expect("a temporary directory");
    let fresh = dir.path().join("vk_tables.rs");
    regenerate(Path::new(VK_XML), &fresh).unwrap_or_else(|e| panic!("{e}"));
    let fresh = std::fs::read_to_string(&fresh).expect("the script wrote its output");
    let committed = std::fs::read_to_string(manifest().join("src/vk_tables.rs"))
        .expect("vk_tables.rs is committed");
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
            "harness/src/vk_tables.rs is out of date with {VK_XML} ({line}); regenerate it with\n\n    \
             python3 harness/src/gen_vk_tables.py {VK_XML}\n\nrun from the workspace root, and commit the result"
        );
    }
}

#[test]
fn the_generator_fails_loudly_on_a_registry_it_cannot_read() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bad = dir.path().join("vk.xml");
    std::fs::write(&bad, "<registry><types></types></registry>").expect("write");
    let out = dir.path().join("out.rs");
    let r = regenerate(&bad, &out);
    assert!(
        r.is_err(),
        "a registry without the structures must not produce a table"
    );
    assert!(!out.exists() || std::fs::read_to_string(&out).unwrap_or_default().is_empty());
}
