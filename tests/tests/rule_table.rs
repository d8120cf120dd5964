//! The rule table joined with the registry: every VUID of the modelled scopes has exactly one row, the
//! template compiler produces a fair share of the executable rows, and the table's structure is
//! snapshotted so any change in coverage shows in review.

use model::rules::{modelled_scope, Source, Status};
use rtconf_tests::{installed_rules, installed_vuids, seeds};
use std::collections::BTreeMap;

#[test]
fn every_modelled_vuid_of_the_installed_registry_has_exactly_one_row() {
    let set = installed_vuids();
    let rules = installed_rules();
    let expected: Vec<&str> = set
        .records
        .iter()
        .filter(|r| modelled_scope(&r.scope))
        .map(|r| r.id.as_str())
        .collect();
    let rows: Vec<&str> = rules.rows.iter().map(|r| r.vuid.as_str()).collect();
    assert_eq!(rows, expected);
    // Every row, of any command, executes through its predicate.
    for r in rules.rows.iter() {
        assert!(
            (r.status == Status::Executable) == r.predicate.is_some(),
            "{}",
            r.vuid
        );
    }
    assert!(rules
        .rows
        .iter()
        .filter(|r| r.status != Status::Executable)
        .all(|r| r.reason.is_some()));
}

#[test]
fn the_seeds_man_pages_and_the_registry_together_leave_no_vuid_without_a_row() {
    let mut paths = vec![std::path::PathBuf::from(
        vk_registry::source::DEFAULT_REGISTRY_DIR,
    )];
    let mut seed_files: Vec<_> = std::fs::read_dir(seeds())
        .expect("../shared/seeds")
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .collect();
    seed_files.retain(|p| p.extension().is_some_and(|e| e == "txt"));
    seed_files.sort();
    paths.extend(seed_files);
    let set = vk_registry::source::load_union(&paths).expect("registry and seeds load");
    let rules = model::RuleSet::from_vuids(&set);
    let modelled = set
        .records
        .iter()
        .filter(|r| modelled_scope(&r.scope))
        .count();
    assert_eq!(rules.rows.len(), modelled);
    // The three commands have about 360 VUIDs across versions (shared/seeds/README.md).
    let commands = [
        "vkCmdTraceRaysIndirectKHR",
        "vkCmdTraceRaysNV",
        "vkCmdBuildAccelerationStructuresIndirectKHR",
    ];
    let of_three = rules
        .rows
        .iter()
        .filter(|r| commands.contains(&r.scope.as_str()))
        .count();
    assert!(
        (340..=380).contains(&of_three),
        "{of_three} rows for the three commands"
    );
}

/// The template compiler's share of the trace commands' own rules (the resource-access rules shared
/// with draw/dispatch and the build command's rules are hand-written by design: their texts quantify
/// over descriptors and geometries, which no template shape reads).
#[test]
fn the_template_compiler_produces_at_least_forty_percent_of_the_trace_commands_rules() {
    let rules = installed_rules();
    let trace = |r: &&model::rules::Row| {
        model::CommandId::from_vk_name(&r.scope).is_some_and(model::CommandId::is_trace)
            || model::rules::TRACE_STRUCTURES.contains(&r.scope.as_str())
    };
    let executable: Vec<_> = rules
        .rows
        .iter()
        .filter(trace)
        .filter(|r| {
            r.status == Status::Executable
                && !matches!(
                    r.predicate,
                    Some(model::rules::predicate::Predicate::Resource(_))
                )
        })
        .collect();
    let template = executable
        .iter()
        .filter(|r| r.source == Some(Source::Template))
        .count();
    assert!(
        executable.len() >= 100,
        "{} executable trace-command rows",
        executable.len()
    );
    assert!(
        template * 100 >= executable.len() * 40,
        "{template} of {} executable rows compiled",
        executable.len()
    );
}

#[test]
fn rule_table_structure_snapshot() {
    let rules = installed_rules();
    let table: BTreeMap<String, String> = rules
        .rows
        .iter()
        .map(|r| {
            let source = match r.source {
                Some(Source::Template) => "template",
                Some(Source::Hand) => "hand",
                None => "-",
            };
            (r.vuid.clone(), format!("{:?}/{source}", r.status))
        })
        .collect();
    insta::assert_yaml_snapshot!(table);
}
