//! Integration tests against the registry installed on this machine (1.3.239), the 1.4.309
//! copy fetched by scripts/fetch-registry.sh, and the seed man pages; YAML snapshots of the
//! structured form of the ray tracing commands and structures.

mod common;

use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::OnceLock;
use vk_registry::xml::{Command, TypeDef};
use vk_registry::{load_vuids, manpage, Registry, VuidSet};

fn installed() -> &'static Registry {
    static R: OnceLock<Registry> = OnceLock::new();
    R.get_or_init(|| Registry::load(common::installed_vk_xml()).expect("installed vk.xml parses"))
}

fn installed_vuids() -> &'static VuidSet {
    static S: OnceLock<VuidSet> = OnceLock::new();
    S.get_or_init(|| {
        load_vuids(&common::installed_dir()).expect("installed validusage.json parses")
    })
}

#[test]
fn extension_enum_values_in_installed_registry() {
    let r = installed();
    assert_eq!(
        r.enum_value("VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR"),
        Some(0x400)
    );
    assert_eq!(
        r.enum_value("VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR"),
        Some(1_000_150_015)
    );
    assert_eq!(
        r.enum_value("VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_NV"),
        Some(1_000_165_000)
    );
    assert_eq!(
        r.enum_value("VK_ERROR_OUT_OF_POOL_MEMORY"),
        Some(-1_000_069_000)
    );
    assert_eq!(
        r.enum_value("VK_ERROR_OUT_OF_POOL_MEMORY_KHR"),
        Some(-1_000_069_000)
    );
    assert_eq!(
        r.enum_value("VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR"),
        Some(1_000_165_000)
    );
    assert_eq!(r.enum_value("VK_SHADER_UNUSED_KHR"), Some(0xFFFF_FFFF));
    assert_eq!(
        r.enum_value("VK_KHR_RAY_TRACING_PIPELINE_SPEC_VERSION"),
        Some(1)
    );
    let bits = r.bitmask_bits("VkBufferUsageFlags").unwrap();
    assert!(bits.contains(&(
        "VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR".to_string(),
        0x400
    )));
    assert!(r.command("vkCmdTraceRaysIndirectKHR").is_some());
    assert!(r.type_def("VkCommandBuffer").unwrap().dispatchable == Some(true));
}

#[test]
fn per_command_vuid_counts_equal_the_json() {
    // count the json entries independently, with serde_json's generic value
    let text = std::fs::read_to_string(common::installed_validusage()).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut expected: BTreeMap<String, usize> = BTreeMap::new();
    let mut total = 0;
    for (_, conds) in v["validation"].as_object().unwrap() {
        for (_, entries) in conds.as_object().unwrap() {
            for e in entries.as_array().unwrap() {
                let id = e["vuid"].as_str().unwrap();
                let scope = id.split('-').nth(1).unwrap();
                *expected.entry(scope.to_string()).or_default() += 1;
                total += 1;
            }
        }
    }
    let set = installed_vuids();
    assert_eq!(set.version.as_deref(), Some("1.3.239"));
    assert_eq!(set.len(), total);
    let mut got: BTreeMap<String, usize> = BTreeMap::new();
    for r in &set.records {
        *got.entry(r.scope.clone()).or_default() += 1;
    }
    assert_eq!(got, expected);
    for cmd in [
        "vkCmdTraceRaysIndirectKHR",
        "vkCmdTraceRaysNV",
        "vkCmdBuildAccelerationStructuresIndirectKHR",
    ] {
        assert!(got[cmd] > 20, "{cmd}");
        assert_eq!(
            vk_registry::report::vuids_plain(set, Some(cmd))
                .lines()
                .count(),
            expected[cmd]
        );
    }
}

#[test]
fn registry_1_4_309_newer_schema() {
    let dir = common::registry_1_4_309();
    let set = load_vuids(&dir).unwrap();
    assert_eq!(set.version.as_deref(), Some("1.4.309"));
    assert!(set.len() > 20_000, "{}", set.len());
    let r = set
        .get("VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634")
        .unwrap();
    assert_eq!(r.text, "`indirectDeviceAddress` must be a multiple of `4`");
    let reg = Registry::load(dir.join("vk.xml")).unwrap();
    assert_eq!(
        reg.enum_value("VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR"),
        Some(0x400)
    );
    assert!(reg.feature("VK_VERSION_1_4").is_some());
    assert!(reg
        .features
        .iter()
        .all(|f| f.api.iter().any(|a| a == "vulkan")));
    // texts of a VUID compare across versions
    let old = installed_vuids()
        .get("VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634")
        .unwrap();
    assert_eq!(old.text, r.text);
    let d = vk_registry::report::diff(installed_vuids(), &set, Some("vkCmdTraceRaysIndirectKHR"));
    assert!(
        d.contains("\nadded:\n+ VUID-vkCmdTraceRaysIndirectKHR-"),
        "{d}"
    );
}

#[test]
fn seeds_yield_expected_counts() {
    let dir = common::seeds_dir();
    let newest = load_vuids(&common::registry_1_4_309()).unwrap();
    for (file, command, count) in [
        ("000_1d54d370f31e08f5.txt", "vkCmdTraceRaysIndirectKHR", 117),
        (
            "002_12e97309a51e20bc.txt",
            "vkCmdBuildAccelerationStructuresIndirectKHR",
            92,
        ),
        ("003_da8701ff075bfd7b.txt", "vkCmdTraceRaysNV", 103),
        (
            "004_f017a595566d4eea.txt",
            "vkCmdBuildAccelerationStructuresIndirectKHR",
            80,
        ),
    ] {
        let path = dir.join(file);
        assert!(path.exists(), "seed {} missing", path.display());
        let (page, set) = manpage::load(&path).unwrap();
        assert_eq!(set.len(), count, "{file}");
        assert_eq!(page.command, command, "{file}");
        assert!(
            page.prototype
                .starts_with(&format!("void {command}(VkCommandBuffer commandBuffer,")),
            "{file}: {}",
            page.prototype
        );
        assert!(
            set.records
                .iter()
                .all(|r| r.scope == command && !r.text.is_empty()),
            "{file}"
        );
        assert_eq!(load_vuids(&path).unwrap(), set);
        if file.starts_with("004") {
            // same spec generation as 1.4.309: every text matches the json's
            for r in &set.records {
                assert_eq!(
                    Some(&r.text),
                    newest.get(&r.id).map(|n| &n.text),
                    "{}",
                    r.id
                );
            }
        }
    }
}

#[derive(Serialize)]
struct VuidSummary {
    id: String,
    field: String,
    implicit: bool,
    condition: String,
}

#[derive(Serialize)]
struct CommandSnapshot<'a> {
    command: &'a Command,
    vuids: Vec<VuidSummary>,
}

#[derive(Serialize)]
struct TypeSnapshot<'a> {
    structure: &'a TypeDef,
    vuids: Vec<VuidSummary>,
}

fn vuids_of(scope: &str) -> Vec<VuidSummary> {
    installed_vuids()
        .for_scope(scope)
        .map(|r| VuidSummary {
            id: r.id.clone(),
            field: r.field.clone(),
            implicit: r.implicit,
            condition: r.condition.to_string(),
        })
        .collect()
}

#[test]
fn snapshot_ray_tracing_commands() {
    for name in [
        "vkCmdTraceRaysIndirectKHR",
        "vkCmdTraceRaysNV",
        "vkCmdBuildAccelerationStructuresIndirectKHR",
    ] {
        let command = installed().command(name).unwrap();
        let snap = CommandSnapshot {
            command,
            vuids: vuids_of(name),
        };
        assert!(!snap.vuids.is_empty());
        insta::assert_yaml_snapshot!(name, snap);
    }
}

#[test]
fn snapshot_ray_tracing_structures() {
    for name in [
        "VkStridedDeviceAddressRegionKHR",
        "VkTraceRaysIndirectCommandKHR",
    ] {
        let structure = installed().structure(name).unwrap();
        let snap = TypeSnapshot {
            structure,
            vuids: vuids_of(name),
        };
        assert!(!structure.members.is_empty());
        insta::assert_yaml_snapshot!(name, snap);
    }
}

#[test]
fn truncated_installed_vk_xml_never_panics() {
    let text = std::fs::read_to_string(common::installed_vk_xml()).unwrap();
    for frac in [0.01, 0.2, 0.5, 0.73, 0.9, 0.999] {
        let mut cut = (text.len() as f64 * frac) as usize;
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        let e = Registry::parse(&text[..cut]).unwrap_err();
        assert!(e.location().is_some(), "{e}");
    }
}

/// Reading only some scopes gives exactly the full reading's records of those scopes (and its
/// version), for the ray tracing scopes, one other scope, and no scope at all.
#[test]
fn a_scoped_reading_is_the_full_one_filtered() {
    let full = installed_vuids();
    let path = common::installed_dir();
    type Keep<'a> = &'a dyn Fn(&str) -> bool;
    let pickers: [(&str, Keep); 3] = [
        ("ray tracing", &|s: &str| {
            s.starts_with("vkCmdTraceRays")
                || s == "vkCmdBuildAccelerationStructuresIndirectKHR"
                || s == "VkStridedDeviceAddressRegionKHR"
        }),
        ("one struct", &|s: &str| s == "VkImageViewCreateInfo"),
        ("none", &|_: &str| false),
    ];
    for (name, keep) in pickers {
        let scoped = vk_registry::source::load_vuids_where(&path, keep)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let want: Vec<_> = full.records.iter().filter(|r| keep(&r.scope)).collect();
        let got: Vec<_> = scoped.records.iter().collect();
        assert_eq!(got, want, "{name}");
        assert_eq!(scoped.version, full.version, "{name}");
        assert!(name == "none" || !got.is_empty(), "{name} keeps records");
    }
}

/// `validusage::load_where` on the installed validusage.json is `validusage::load` restricted to
/// the kept scopes: the same records in the same order, the same origin and version.
#[test]
fn validusage_load_where_is_load_restricted_to_the_kept_scopes() {
    let path = common::installed_validusage();
    let full = vk_registry::validusage::load(&path).expect("installed validusage.json parses");
    let ray_tracing = |s: &str| {
        matches!(
            s,
            "vkCmdTraceRaysIndirectKHR"
                | "vkCmdTraceRaysKHR"
                | "vkCmdTraceRaysNV"
                | "vkCmdBuildAccelerationStructuresIndirectKHR"
        )
    };
    type Keep<'a> = &'a dyn Fn(&str) -> bool;
    let pickers: [(&str, Keep); 3] = [
        ("ray tracing", &ray_tracing),
        ("structures", &|s: &str| s.starts_with("Vk")),
        ("all but ray tracing", &|s: &str| !ray_tracing(s)),
    ];
    for (name, keep) in pickers {
        let scoped = vk_registry::validusage::load_where(&path, keep)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let want = VuidSet {
            origin: full.origin.clone(),
            version: full.version.clone(),
            records: full
                .records
                .iter()
                .filter(|r| keep(&r.scope))
                .cloned()
                .collect(),
        };
        assert!(!want.records.is_empty(), "{name} keeps records");
        assert!(scoped == want, "{name}: the scoped reading differs");
    }
}
