//! vk.xml reader on a small hand-written registry: values, attributes, api filtering, depends,
//! and located errors for unknown structure and truncated input.

mod common;

use vk_registry::error::Location;
use vk_registry::xml::{EnumKind, TypeCategory};
use vk_registry::{Condition, Registry, RegistryError};

fn mini() -> Registry {
    Registry::parse(&common::fixture_text("mini_vk.xml")).expect("mini registry parses")
}

#[test]
fn extension_enum_values_are_computed() {
    let r = mini();
    assert_eq!(
        r.enum_value("VK_STRUCTURE_TYPE_TOY_CREATE_INFO"),
        Some(1_000_150_015)
    );
    assert_eq!(
        r.enum_value("VK_STRUCTURE_TYPE_TOY_CREATE_INFO_KHR"),
        Some(1_000_150_015)
    );
    assert_eq!(r.enum_value("VK_ERROR_TOY_LOST_EXT"), Some(-1_000_150_003));
    assert_eq!(r.enum_value("VK_ERROR_TOY_POOL"), Some(-1_000_069_000));
    assert_eq!(
        r.enum_value("VK_STRUCTURE_TYPE_TOY_OTHER"),
        Some(1_000_299_016)
    );
    assert_eq!(
        r.enum_value("VK_STRUCTURE_TYPE_TOY_OLD"),
        Some(1_000_011_000)
    );
    assert_eq!(r.enum_value("VK_TOY_USAGE_TABLE_BIT_KHR"), Some(0x400));
    assert_eq!(r.enum_value("VK_TOY_USAGE_CORE11_BIT"), Some(0x10));
    assert_eq!(r.enum_value("VK_KHR_TOY_DISPATCH_SPEC_VERSION"), Some(2));
    assert_eq!(r.enum_value("VK_TOY_ALL"), Some(0xFFFF_FFFF));
    assert_eq!(r.enum_value("VK_TOY_ALL_KHR"), Some(0xFFFF_FFFF));
    assert_eq!(r.enum_value("VK_TOY_FLOAT"), None);
    assert_eq!(
        r.enum_entry("VK_TOY_FLOAT")
            .and_then(|v| v.raw.clone())
            .as_deref(),
        Some("1000.0F")
    );
    assert_eq!(
        r.enum_entry("VK_STRUCTURE_TYPE_TOY_CREATE_INFO")
            .unwrap()
            .added_by
            .as_deref(),
        Some("VK_KHR_toy_dispatch")
    );
    // vulkansc-only, disabled-extension values are not applied
    assert_eq!(r.enum_value("VK_ERROR_SC_ONLY"), None);
    assert_eq!(r.enum_value("VK_STRUCTURE_TYPE_TOY_SC"), None);
    assert_eq!(r.enum_value("VK_STRUCTURE_TYPE_TOY_DISABLED"), None);
    assert_eq!(r.enum_value("VK_TOY_USAGE_SC_BIT"), None);
    assert_eq!(
        r.enum_group("VkToyUsageFlagBits").unwrap().kind,
        EnumKind::Bitmask
    );
}

#[test]
fn bitmask_bits_by_flags_or_flagbits() {
    let r = mini();
    let bits = r.bitmask_bits("VkToyUsageFlags").unwrap();
    let names: Vec<_> = bits.iter().map(|(n, v)| (n.as_str(), *v)).collect();
    assert_eq!(
        names,
        vec![
            ("VK_TOY_USAGE_READ_BIT", 1),
            ("VK_TOY_USAGE_WRITE_BIT", 2),
            ("VK_TOY_USAGE_ALL", 3),
            ("VK_TOY_USAGE_CORE11_BIT", 0x10),
            ("VK_TOY_USAGE_TABLE_BIT_KHR", 0x400)
        ]
    );
    assert_eq!(r.bitmask_bits("VkToyUsageFlagBits").unwrap(), bits);
    assert!(r.bitmask_bits("VkNothing").is_none());
}

#[test]
fn structures_members_and_handles() {
    let r = mini();
    let s = r.structure("VkToyCreateInfo").unwrap();
    assert_eq!(s.structextends, vec!["VkOtherInfo", "VkThirdInfo"]);
    let names: Vec<_> = s.members.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        ["sType", "pNext", "regionCount", "pRegions", "sel"],
        "vulkansc member dropped"
    );
    let p = &s.members[3];
    assert_eq!(
        (p.decl.as_str(), p.is_const, p.pointer_depth),
        ("const VkToyRegion* pRegions", true, 1)
    );
    assert_eq!(p.len.as_deref(), Some("regionCount"));
    assert!(p.noautovalidity);
    assert_eq!(
        s.members[0].values.as_deref(),
        Some("VK_STRUCTURE_TYPE_TOY_CREATE_INFO")
    );
    assert_eq!(s.members[4].selector.as_deref(), Some("regionCount"));
    assert_eq!(
        r.structure("VkToyCreateInfoKHR").unwrap().name,
        "VkToyCreateInfo"
    );
    assert!(
        r.structure("VkScOnlyInfo").is_none(),
        "vulkansc-only type dropped"
    );

    let region = r.structure("VkToyRegion").unwrap();
    assert_eq!(region.members[0].optional, vec![true]);
    assert_eq!(region.members[0].limittype.as_deref(), Some("noauto"));
    assert_eq!(region.members[2].array, vec!["VK_TOY_MAX", "2"]);
    assert_eq!(region.members[3].bitfield, Some(8));
    assert_eq!(
        region.members[1].decl, "VkDeviceSize stride",
        "comments are not part of the declaration"
    );

    let dev = r.type_def("VkDevice").unwrap();
    assert_eq!(
        (dev.category, dev.dispatchable),
        (TypeCategory::Handle, Some(true))
    );
    let w = r.type_def("VkWidget").unwrap();
    assert_eq!(
        (w.dispatchable, w.parent.clone()),
        (Some(false), vec!["VkDevice".to_string()])
    );
    assert_eq!(
        r.type_def("VkToyUsageFlags").unwrap().bitvalues.as_deref(),
        Some("VkToyUsageFlagBits")
    );
}

#[test]
fn commands_with_attributes() {
    let r = mini();
    let c = r.command("vkCmdToyDispatch").unwrap();
    assert_eq!(c.queues, ["compute"]);
    assert_eq!(c.renderpass.as_deref(), Some("outside"));
    assert_eq!(c.videocoding.as_deref(), Some("outside"));
    assert_eq!(c.cmdbufferlevel, ["primary", "secondary"]);
    assert_eq!(c.tasks, ["action"]);
    assert_eq!(c.params.len(), 3, "vulkansc param dropped");
    assert_eq!(c.params[0].externsync.as_deref(), Some("true"));
    assert_eq!(c.params[2].optional, [false, true]);
    let w = r.command("vkCreateWidget").unwrap();
    assert_eq!(w.return_type, "VkResult");
    assert_eq!(w.successcodes, ["VK_SUCCESS"]);
    assert_eq!(
        w.errorcodes,
        ["VK_ERROR_OUT_OF_HOST_MEMORY", "VK_ERROR_TOY_LOST_EXT"]
    );
    assert_eq!(w.implicit_externsync, ["the widget pool of pCreateInfo"]);
    assert_eq!(
        r.command("vkCreateWidgetKHR").unwrap().alias.as_deref(),
        Some("vkCreateWidget")
    );
    assert_eq!(
        r.command_resolved("vkCreateWidgetKHR").unwrap().name,
        "vkCreateWidget"
    );
}

#[test]
fn features_and_extensions() {
    let r = mini();
    assert_eq!(
        r.features
            .iter()
            .map(|f| f.name.as_str())
            .collect::<Vec<_>>(),
        ["VK_VERSION_1_0", "VK_VERSION_1_1"]
    );
    let f11 = r.feature("VK_VERSION_1_1").unwrap();
    assert_eq!(f11.depends, Some(Condition::Ext("VK_VERSION_1_0".into())));
    assert_eq!(
        f11.require[0].features[0].structure,
        "VkPhysicalDeviceToyFeatures"
    );
    let x = r.extension("VK_KHR_toy_dispatch").unwrap();
    assert_eq!(x.number, 151);
    assert_eq!(x.ext_type.as_deref(), Some("device"));
    assert_eq!(x.promotedto.as_deref(), Some("VK_VERSION_1_3"));
    let d = x.depends.clone().unwrap();
    assert_eq!(d.to_string(), "(VK_KHR_a,VK_VERSION_1_1)+VK_KHR_b");
    assert!(d.eval(&|n| n == "VK_VERSION_1_1" || n == "VK_KHR_b"));
    assert!(!d.eval(&|n| n == "VK_KHR_b"));
    assert_eq!(x.require.len(), 2, "vulkansc require block dropped");
    assert_eq!(
        x.require[1].depends,
        Some(Condition::Ext("VK_KHR_c".into()))
    );
    let old = r.extension("VK_EXT_toy_old").unwrap();
    assert_eq!(
        old.depends.as_ref().unwrap().to_string(),
        "VK_KHR_a+VK_KHR_b"
    );
    assert_eq!(
        old.require[0].depends,
        Some(Condition::Ext("VK_KHR_c".into()))
    );
    assert!(!r.extension("VK_NV_toy_disabled").unwrap().is_vulkan());
}

#[test]
fn parsing_is_deterministic() {
    let a = serde_json::to_string(&mini()).unwrap();
    let b = serde_json::to_string(&mini()).unwrap();
    assert_eq!(a, b);
}

fn line_col(e: &RegistryError) -> (usize, usize) {
    match e.location() {
        Some(Location::LineCol { line, column }) => (*line, *column),
        other => panic!("expected a line:column location, got {other:?} for {e}"),
    }
}

#[test]
fn unknown_element_is_a_located_error() {
    let text = common::fixture_text("mini_vk.xml").replace(
        "<member><type>uint32_t</type> <name>regionCount</name></member>",
        "<member><type>uint32_t</type> <name>regionCount</name></member>\n            <gadget/>",
    );
    let e = Registry::parse(&text).unwrap_err();
    let (line, col) = line_col(&e);
    let expected_line = text.lines().position(|l| l.contains("<gadget/>")).unwrap() + 1;
    assert_eq!((line, col), (expected_line, 13), "{e}");
    assert!(
        e.to_string()
            .contains("unexpected element <gadget> inside <type>"),
        "{e}"
    );

    let text =
        common::fixture_text("mini_vk.xml").replace("<commands comment=\"commands\">", "<widgets>");
    let e = Registry::parse(&text).unwrap_err();
    assert!(e.to_string().contains("<widgets>"), "{e}");
}

#[test]
fn bad_values_are_located_errors() {
    let text = common::fixture_text("mini_vk.xml").replace("bitpos=\"10\"", "bitpos=\"ten\"");
    let e = Registry::parse(&text).unwrap_err();
    let line = text
        .lines()
        .position(|l| l.contains("bitpos=\"ten\""))
        .unwrap()
        + 1;
    assert_eq!(line_col(&e).0, line, "{e}");
    let text = common::fixture_text("mini_vk.xml")
        .replace("depends=\"VK_KHR_c\"", "depends=\"(VK_KHR_c\"");
    let e = Registry::parse(&text).unwrap_err();
    assert!(e.to_string().contains("bad depends"), "{e}");
}

#[test]
fn truncated_xml_gives_located_errors_and_never_panics() {
    let text = common::fixture_text("mini_vk.xml");
    let total_lines = text.lines().count();
    // every cut point on a char boundary in steps, plus a few chosen ones
    let mut cuts: Vec<usize> = (1..text.len()).step_by(37).collect();
    for marker in [
        "<types",
        "<member optional",
        "</command>",
        "<extension name=\"VK_EXT",
        "</registry>",
    ] {
        cuts.push(text.find(marker).unwrap() + 3);
    }
    for cut in cuts {
        if !text.is_char_boundary(cut) {
            continue;
        }
        let e = Registry::parse(&text[..cut]).expect_err(&format!("cut at {cut} must fail"));
        let (line, col) = line_col(&e);
        assert!(
            line >= 1 && line <= total_lines + 1 && col >= 1,
            "cut {cut}: {e}"
        );
    }
    let e = Registry::parse("").unwrap_err();
    assert!(e.to_string().contains("no <registry>"), "{e}");
}

#[test]
fn missing_file_says_so() {
    let e = Registry::load("/nonexistent/vk.xml").unwrap_err();
    assert!(matches!(e, RegistryError::NotFound { .. }), "{e:?}");
    assert_eq!(e.to_string(), "/nonexistent/vk.xml: file not found");
}

#[test]
fn show_describes_entries() {
    let r = mini();
    let s = vk_registry::report::show(&r, "vkCmdToyDispatch").unwrap();
    assert!(s.starts_with("command vkCmdToyDispatch\n"), "{s}");
    assert!(s.contains("queues: compute"), "{s}");
    assert!(s.contains("provided by: VK_KHR_toy_dispatch"), "{s}");
    let s = vk_registry::report::show(&r, "VkToyUsageFlags").unwrap();
    assert!(s.contains("VK_TOY_USAGE_TABLE_BIT_KHR = 0x400"), "{s}");
    let s = vk_registry::report::show(&r, "VK_ERROR_TOY_LOST_EXT").unwrap();
    assert!(
        s.contains("= -1000150003") && s.contains("group: VkResult"),
        "{s}"
    );
    assert!(vk_registry::report::show(&r, "vkNothing").is_err());
}
