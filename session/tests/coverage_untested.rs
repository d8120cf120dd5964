//! Every executable row is tested or says why not: the rows no mutation violates each carry the
//! generator's reason (`rtconf coverage` fails on a row with neither), for the installed registry and,
//! where `scripts/fetch-registry.sh` unpacked it, the 1.4.309 one.

use model::RuleSet;
use session::plan::untested;

fn rules(from: &[std::path::PathBuf]) -> RuleSet {
    let set = session::sources::load_sources(from).expect("the registry loads");
    RuleSet::from_vuids(&set)
}

fn unsaid(rules: &RuleSet) -> Vec<String> {
    untested(rules, None)
        .into_iter()
        .filter(|(_, _, why)| why.is_none())
        .map(|(c, v, _)| format!("{v} ({c})"))
        .collect()
}

#[test]
fn every_executable_row_of_the_installed_registry_has_a_mutation_or_a_reason() {
    let r = rules(&[]);
    let all = untested(&r, None);
    assert!(
        all.iter()
            .all(|(_, _, why)| why.is_some_and(|w| !w.trim().is_empty())),
        "rows with no mutation and no reason: {:?}",
        unsaid(&r)
    );
    // The newer VUIDs of rules that have mutations under their older ones are tested, not excused.
    for tail in ["08606", "08608", "09458"] {
        assert!(
            !all.iter().any(|(_, v, _)| v.ends_with(tail)),
            "{tail} is untested"
        );
    }
}

#[test]
fn every_executable_row_of_the_fetched_1_4_309_registry_has_a_mutation_or_a_reason() {
    let dir =
        session::sources::repo_dir().join("target/registry/1.4.309/usr/share/vulkan/registry");
    if !dir.join("validusage.json").is_file() {
        // Without the fetched registry the installed one's test above is the whole check.
        assert!(unsaid(&rules(&[])).is_empty());
        return;
    }
    let r = rules(&[dir]);
    assert_eq!(r.version.as_deref(), Some("1.4.309"));
    assert_eq!(unsaid(&r), Vec::<String>::new());
    let all = untested(&r, None);
    for tail in ["08606", "08608", "09458"] {
        assert!(
            !all.iter().any(|(_, v, _)| v.ends_with(tail)),
            "{tail} is untested in 1.4.309"
        );
    }
}
