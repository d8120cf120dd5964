//! The triage's directions: per kind, an entry explains its own direction and never the other one;
//! the files' form is checked with located errors; stale entries are the ones a run did not use.

use super::*;
use std::collections::BTreeSet;

const V: &str = "VUID-vkCmdTraceRaysIndirectKHR-flags-03512";
const W: &str = "VUID-vkCmdTraceRaysKHR-flags-03512";

fn triage(yaml: &str) -> Triage {
    Triage::from_yaml("triage/test.yaml", yaml).unwrap_or_else(|e| panic!("{e}"))
}

fn entry(observed: &str, kind: &str) -> String {
    format!("entries:\n  - {observed}\n    kind: {kind}\n    reason: what was seen\n    evidence: cases/hand/x.yaml\n")
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// The explanation of a case of the indirect command with these model and layer VUIDs.
fn explain(t: &Triage, model: &[&str], layer: &[&str]) -> Explanation {
    let (model, layer) = (strings(model), strings(layer));
    t.explain(&CaseFacts {
        name: "vkCmdTraceRaysIndirectKHR-flags-03512-1-0",
        command: CommandId::TraceRaysIndirect,
        target: Some(V),
        model: &model,
        layer: &layer,
        layer_other: &[],
        problems: &[],
    })
}

fn explained(e: &Explanation) -> Vec<(&str, &str)> {
    e.matched
        .iter()
        .map(|(m, _)| (m.observed.as_str(), m.vuid.as_str()))
        .collect()
}

fn unexplained(e: &Explanation) -> Vec<(&str, &str)> {
    e.unexplained
        .iter()
        .map(|u| (u.side, u.vuid.as_str()))
        .collect()
}

#[test]
fn a_layer_gap_explains_a_silent_layer_and_never_a_layer_that_reports() {
    let t = triage(&entry(&format!("layer-silent: {V}"), "layer-gap"));
    let e = explain(&t, &[V], &[]);
    assert_eq!(explained(&e), vec![("layer-silent", V)]);
    assert!(e.unexplained.is_empty());
    let e = explain(&t, &[], &[V]);
    assert!(e.matched.is_empty());
    assert_eq!(unexplained(&e), vec![("layer only", V)]);
    let note = e.unexplained[0].note.as_deref().unwrap_or("");
    assert!(note.contains("layer-silent"), "{note}");
}

#[test]
fn a_static_check_explains_an_extra_layer_report_and_never_a_silent_layer() {
    let t = triage(&entry(&format!("layer-extra: {W}"), "layer-static-check"));
    let case_of = |model: &[&str], layer: &[&str]| {
        let (model, layer) = (strings(model), strings(layer));
        t.explain(&CaseFacts {
            name: "vkCmdTraceRaysKHR-None-03429-1-0",
            command: CommandId::TraceRays,
            target: Some("VUID-vkCmdTraceRaysKHR-None-03429"),
            model: &model,
            layer: &layer,
            layer_other: &[],
            problems: &[],
        })
    };
    let e = case_of(&[], &[W]);
    assert_eq!(explained(&e), vec![("layer-extra", W)]);
    let e = case_of(&[W], &[]);
    assert!(e.matched.is_empty());
    assert_eq!(unexplained(&e), vec![("model only", W)]);
}

#[test]
fn a_mislabel_explains_one_pair_only_and_neither_half_alone_nor_the_reverse() {
    let t = triage(&entry(
        &format!("layer-renames: {{model: {V}, layer: {W}}}"),
        "layer-mislabel",
    ));
    let e = explain(&t, &[V], &[W]);
    assert_eq!(explained(&e), vec![("layer-renames", V)]);
    assert_eq!(e.matched[0].0.layer_vuid.as_deref(), Some(W));
    assert!(e.unexplained.is_empty());
    // The model half alone: the layer said nothing, which a rename does not explain.
    assert_eq!(
        unexplained(&explain(&t, &[V], &[])),
        vec![("model only", V)]
    );
    // The layer half alone.
    assert_eq!(
        unexplained(&explain(&t, &[], &[W])),
        vec![("layer only", W)]
    );
    // The reverse pair.
    let e = explain(&t, &[W], &[V]);
    assert!(e.matched.is_empty());
    assert_eq!(unexplained(&e), vec![("model only", W), ("layer only", V)]);
}

#[test]
fn renames_with_wildcards_pair_vuids_of_the_same_tail() {
    let t = triage(&entry(
        "layer-renames: {model: VUID-vkCmdTraceRaysIndirectKHR-*, layer: VUID-vkCmdTraceRaysKHR-*}",
        "layer-mislabel",
    ));
    let a = "VUID-vkCmdTraceRaysIndirectKHR-None-02691";
    let b = "VUID-vkCmdTraceRaysKHR-None-02697";
    let e = explain(&t, &[a], &[b]);
    assert!(e.matched.is_empty(), "{e:?}");
    assert_eq!(unexplained(&e).len(), 2);
    let e = explain(&t, &[a], &["VUID-vkCmdTraceRaysKHR-None-02691"]);
    assert_eq!(explained(&e), vec![("layer-renames", a)]);
}

#[test]
fn a_layer_bug_explains_only_the_direction_it_states() {
    let t = triage(&entry(
        "layer-silent: VUID-VkStridedDeviceAddressRegionKHR-size-04631",
        "layer-bug",
    ));
    let v = "VUID-VkStridedDeviceAddressRegionKHR-size-04631";
    assert_eq!(
        explained(&explain(&t, &[v], &[])),
        vec![("layer-silent", v)]
    );
    let e = explain(&t, &[], &[v]);
    assert!(e.matched.is_empty());
    assert_eq!(unexplained(&e), vec![("layer only", v)]);
}

#[test]
fn a_harness_limit_explains_only_the_direction_it_states() {
    let t = triage(&entry(&format!("layer-extra: {V}"), "harness-limit"));
    assert_eq!(explained(&explain(&t, &[], &[V])), vec![("layer-extra", V)]);
    let e = explain(&t, &[V], &[]);
    assert!(e.matched.is_empty());
    assert_eq!(unexplained(&e), vec![("model only", V)]);
}

#[test]
fn a_driver_bug_explains_output_deviations_and_no_vuid() {
    let t = triage(&entry(
        "output: \"vkCmdBuildAccelerationStructuresIndirectKHR:*first-vertex-applied-twice\"",
        "driver-bug",
    ));
    let facts = |model: &'static [String]| CaseFacts {
        name: "build-valid-1-0",
        command: CommandId::BuildAccelerationStructuresIndirect,
        target: None,
        model,
        layer: &[],
        layer_other: &[],
        problems: &[],
    };
    let key = "vkCmdBuildAccelerationStructuresIndirectKHR:first-vertex-applied-twice";
    assert!(t.explain_output(&facts(&[]), key).is_some());
    assert!(t
        .explain_output(
            &facts(&[]),
            "vkCmdBuildAccelerationStructuresIndirectKHR:rays"
        )
        .is_none());
    let model = vec![key.to_string()];
    let model: &'static [String] = Box::leak(model.into_boxed_slice());
    let e = t.explain(&facts(model));
    assert!(e.matched.is_empty());
    assert_eq!(e.unexplained.len(), 1);
}

#[test]
fn an_output_entry_explains_a_key_by_any_one_of_its_alternatives() {
    let entry_for = |pattern: &str| {
        triage(&entry(
            &format!("output: \"vkCmdBuildAccelerationStructuresIndirectKHR:{pattern}\""),
            "driver-bug",
        ))
    };
    let facts = CaseFacts {
        name: "build-valid-1-0",
        command: CommandId::BuildAccelerationStructuresIndirect,
        target: None,
        model: &[],
        layer: &[],
        layer_other: &[],
        problems: &[],
    };
    let key = |names: &str| format!("vkCmdBuildAccelerationStructuresIndirectKHR:{names}");
    let twice_hidden = key(
        "indexed-first-vertex-ignored|first-vertex-applied-twice+inactive-triangle-drops-primitives",
    );
    // The second alternative, by its own name, not the key's end.
    let exact = entry_for("first-vertex-applied-twice+inactive-triangle-drops-primitives");
    assert!(exact.explain_output(&facts, &twice_hidden).is_some());
    let first = entry_for("indexed-first-vertex-ignored");
    assert!(first.explain_output(&facts, &twice_hidden).is_some());
    // A name that is part of an alternative only matches where the pattern says so.
    let bare = entry_for("first-vertex-applied-twice");
    assert!(bare.explain_output(&facts, &twice_hidden).is_none());
    assert!(bare
        .explain_output(
            &facts,
            &key("indexed-first-vertex-ignored|first-vertex-applied-twice")
        )
        .is_some());
    // A key without alternatives is matched whole, as before.
    assert!(first
        .explain_output(&facts, &key("first-vertex-applied-twice"))
        .is_none());
    assert!(first
        .explain_output(&facts, &key("indexed-first-vertex-ignored"))
        .is_some());
}

#[test]
fn kinds_admit_only_their_directions_with_a_located_error() {
    for (observed, kind) in [
        (format!("layer-extra: {V}"), "layer-gap"),
        (format!("layer-silent: {V}"), "layer-static-check"),
        (format!("layer-silent: {V}"), "layer-mislabel"),
        (
            format!("layer-renames: {{model: {V}, layer: {W}}}"),
            "layer-gap",
        ),
        (format!("output: {V}"), "layer-bug"),
        (format!("layer-silent: {V}"), "driver-bug"),
        (
            format!("layer-renames: {{model: {V}, layer: {W}}}"),
            "harness-limit",
        ),
    ] {
        let err = Triage::from_yaml("triage/test.yaml", &entry(&observed, kind))
            .expect_err(&format!("{kind} with {observed}"))
            .to_string();
        assert!(
            err.contains("triage/test.yaml") && err.contains("entries[0]") && err.contains(kind),
            "{err}"
        );
    }
}

#[test]
fn entries_state_one_observation_evidence_and_no_twin() {
    let two = format!(
        "entries:\n  - layer-silent: {V}\n    layer-extra: {V}\n    kind: layer-bug\n    reason: r\n    evidence: e\n"
    );
    let err = Triage::from_yaml("t.yaml", &two).unwrap_err().to_string();
    assert!(err.contains("2 observations"), "{err}");
    let none = "entries:\n  - kind: layer-gap\n    reason: r\n    evidence: e\n";
    let err = Triage::from_yaml("t.yaml", none).unwrap_err().to_string();
    assert!(err.contains("no observation"), "{err}");
    let bare = format!("entries:\n  - layer-silent: {V}\n    kind: layer-gap\n    reason: r\n");
    let err = Triage::from_yaml("t.yaml", &bare).unwrap_err().to_string();
    assert!(err.contains("no evidence"), "{err}");
    let twice = entry(&format!("layer-silent: {V}"), "layer-gap")
        + &entry(&format!("layer-silent: {V}"), "layer-gap").replace("entries:\n", "");
    let err = Triage::from_yaml("t.yaml", &twice).unwrap_err().to_string();
    assert!(err.contains("entries[1]") && err.contains("twice"), "{err}");
    // Refused after parsing, still located: the line and column of the entry at fault.
    let second = twice.match_indices("  - ").nth(1).map(|(i, _)| i).unwrap();
    let line = twice[..second].matches('\n').count() + 1;
    assert!(err.starts_with(&format!("t.yaml:{line}:")), "{err}");
    let err = Triage::from_yaml("t.yaml", &bare).unwrap_err().to_string();
    assert!(err.starts_with("t.yaml:2:"), "{err}");
    let unknown = format!("entries:\n  - layer-silent: {V}\n    kind: layer-gap\n    reason: r\n    evidence: e\n    case: x\n");
    let err = Triage::from_yaml("t.yaml", &unknown)
        .unwrap_err()
        .to_string();
    assert!(err.contains("t.yaml:") && err.contains("case"), "{err}");
}

#[test]
fn case_patterns_and_conditions_narrow_an_entry() {
    let yaml = format!(
        "entries:\n  - layer-silent: {V}\n    kind: layer-gap\n    reason: r\n    evidence: e\n    cases: \"other-*\"\n  - layer-extra: {W}\n    kind: layer-static-check\n    reason: r\n    evidence: e\n    command: [vkCmdTraceRaysIndirectKHR]\n    when: {{layer-also: [VUID-vkCmdTraceRaysIndirectKHR-flags-03696]}}\n"
    );
    let t = triage(&yaml);
    let e = explain(&t, &[V], &[]);
    assert!(e.matched.is_empty());
    let note = e.unexplained[0].note.as_deref().unwrap_or("");
    assert!(note.contains("not for this case"), "{note}");
    assert_eq!(
        unexplained(&explain(&t, &[], &[W])),
        vec![("layer only", W)]
    );
    let also = "VUID-vkCmdTraceRaysIndirectKHR-flags-03696";
    let e = explain(&t, &[also], &[W, also]);
    assert_eq!(explained(&e), vec![("layer-extra", W)]);
}

#[test]
fn entries_no_case_used_are_stale_for_the_commands_that_ran() {
    let yaml = entry(&format!("layer-silent: {V}"), "layer-gap")
        + &entry(
            "layer-silent: VUID-vkCmdTraceRaysNV-maxRecursionDepth-03625",
            "layer-gap",
        )
        .replace("entries:\n", "");
    let t = triage(&yaml);
    let ran: BTreeSet<CommandId> = [CommandId::TraceRaysIndirect].into();
    let none = BTreeSet::new();
    let exercised: BTreeSet<String> = [V.to_string()].into();
    assert_eq!(
        unused(&t, &none, &ran, &exercised).0,
        vec![format!("test.yaml: layer-silent {V}")]
    );
    let used: BTreeSet<String> = [t.entries[0].id()].into();
    assert!(unused(&t, &used, &ran, &exercised).0.is_empty());
    assert_eq!(t.entries[1].commands, [CommandId::TraceRaysNv].into());
}

#[test]
fn structure_vuids_concern_the_commands_that_take_the_structure() {
    let t = triage(&entry(
        "layer-silent: VUID-VkStridedDeviceAddressRegionKHR-size-04631",
        "layer-bug",
    ));
    assert_eq!(
        t.entries[0].commands,
        [CommandId::TraceRaysIndirect, CommandId::TraceRays].into()
    );
}

#[test]
fn a_problem_condition_explains_only_the_form_of_the_violation_it_names() {
    let v = "VUID-VkStridedDeviceAddressRegionKHR-size-04631";
    let yaml = format!(
        "entries:\n  - layer-silent: {v}\n    kind: layer-bug\n    reason: r\n    evidence: e\n    when: {{problem: \"* by 1 byte\"}}\n"
    );
    let t = triage(&yaml);
    let model = vec![v.to_string()];
    let facts = |problem: &str| {
        let problems = vec![(v.to_string(), problem.to_string())];
        t.explain(&CaseFacts {
            name: "c",
            command: CommandId::TraceRays,
            target: Some(v),
            model: &model,
            layer: &[],
            layer_other: &[],
            problems: &problems,
        })
    };
    assert_eq!(
        facts("[64, 64+64) passes the end of `b` (127 bytes) by 1 byte")
            .matched
            .len(),
        1
    );
    let e = facts("[64, 64+64) passes the end of `b` (100 bytes) by 28 bytes");
    assert!(e.matched.is_empty());
    assert_eq!(e.unexplained.len(), 1);
}

#[test]
fn a_rename_pairs_with_an_id_outside_the_modelled_scopes() {
    let v = "VUID-vkCmdTraceRaysNV-raygenShaderBindingTableBuffer-parameter";
    let w = "UNASSIGNED-GeneralParameterError-RequiredParameter";
    let t = triage(&entry(
        &format!("layer-renames: {{model: {v}, layer: {w}}}"),
        "layer-mislabel",
    ));
    let (model, other) = (strings(&[v]), strings(&[w]));
    let facts = |layer_other: &[String]| {
        t.explain(&CaseFacts {
            name: "nv",
            command: CommandId::TraceRaysNv,
            target: Some(v),
            model: &model,
            layer: &[],
            layer_other,
            problems: &[],
        })
    };
    assert_eq!(facts(&other).matched.len(), 1);
    assert_eq!(facts(&[]).unexplained.len(), 1, "the layer said nothing");
}

#[test]
fn an_entry_whose_vuids_no_case_involved_is_unexercised_not_stale() {
    let t = triage(&entry(&format!("layer-silent: {V}"), "layer-gap"));
    let ran: BTreeSet<CommandId> = [CommandId::TraceRaysIndirect].into();
    let none = BTreeSet::new();
    let other: BTreeSet<String> = ["VUID-vkCmdTraceRaysIndirectKHR-None-02697".to_string()].into();
    assert!(unused(&t, &none, &ran, &other).0.is_empty());
    assert_eq!(
        unused(&t, &none, &ran, &other).1,
        vec![format!("test.yaml: layer-silent {V}")]
    );
    // Once a case with its VUID ran, the same entry explaining nothing is stale.
    let with_v: BTreeSet<String> = [V.to_string()].into();
    assert_eq!(unused(&t, &none, &ran, &with_v).0.len(), 1);
    assert!(unused(&t, &none, &ran, &with_v).1.is_empty());
}

#[test]
fn the_1_3_239_gap_for_sampled_type_widths_explains_the_h200_cases_of_every_command() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../triage/layer-1.3.239.yaml");
    let text = std::fs::read_to_string(path).expect("the 1.3.239 triage file");
    let t = triage(&text);
    for (command, scope) in [
        (CommandId::TraceRays, "vkCmdTraceRaysKHR"),
        (CommandId::TraceRaysIndirect, "vkCmdTraceRaysIndirectKHR"),
        (CommandId::TraceRaysNv, "vkCmdTraceRaysNV"),
    ] {
        let v = format!("VUID-{scope}-SampledType-04470");
        let model = strings(&[&v]);
        let e = t.explain(&CaseFacts {
            name: &format!("{scope}-SampledType-04470-1-0"),
            command,
            target: Some(&v),
            model: &model,
            layer: &[],
            layer_other: &[],
            problems: &[],
        });
        assert_eq!(explained(&e), vec![("layer-silent", v.as_str())], "{scope}");
        // The other direction is never absorbed.
        let layer = strings(&[&v]);
        let e = t.explain(&CaseFacts {
            name: &format!("{scope}-valid-1-0"),
            command,
            target: None,
            model: &[],
            layer: &layer,
            layer_other: &[],
            problems: &[],
        });
        assert!(e.matched.is_empty(), "{scope}: {:?}", explained(&e));
    }
}

#[test]
fn a_pattern_with_a_wildcard_other_than_star_is_a_located_error() {
    let text = entry(
        "layer-silent: VUID-vkCmdTraceRays*-SampledType-0447?",
        "layer-gap",
    );
    let err = Triage::from_yaml("triage/test.yaml", &text).expect_err("`?` is refused");
    let err = err.to_string();
    assert!(
        err.contains("triage/test.yaml") && err.contains("other than `*`"),
        "{err}"
    );
}
