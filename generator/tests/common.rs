//! Shared set-up for the generator's meta-tests: the rule table, the committed profiles, case counts.

#![allow(dead_code)]

use model::rules::RuleSet;
use model::{Case, DeviceProfile};
use std::sync::OnceLock;

pub fn rules() -> &'static RuleSet {
    static RULES: OnceLock<RuleSet> = OnceLock::new();
    RULES
        .get_or_init(|| generator::registry::default_rules().expect("the installed registry loads"))
}

/// Every committed profile (at least lavapipe).
pub fn profiles() -> Vec<(String, DeviceProfile)> {
    let names = generator::profiles::available();
    assert!(
        names.iter().any(|n| n == "lavapipe"),
        "profiles/lavapipe.json is committed: {names:?}"
    );
    names
        .into_iter()
        .map(|n| {
            (
                n.clone(),
                generator::profiles::load(&n).expect("committed profiles load"),
            )
        })
        .collect()
}

/// Cases per spec: ~200 in CI, thousands with RTCONF_SLOW=1.
pub fn per_spec() -> usize {
    if std::env::var("RTCONF_SLOW").is_ok_and(|v| v == "1") {
        3000
    } else {
        200
    }
}

pub fn judge(profile: &DeviceProfile, case: &Case) -> model::Verdict {
    model::validate(rules(), profile, case)
}
