//! Valid-by-construction cases from every committed profile: the model judges them valid and their
//! launches read no shader binding table record outside its table (no undefined behaviour is ever
//! handed to a driver as a valid case).

use generator::CaseSpec;
use model::CommandId;
use rtconf_tests::{installed_rules, profile, profile_names};

#[test]
fn generated_valid_cases_are_valid_and_read_only_inside_their_tables() {
    let rules = installed_rules();
    let mut checked = 0;
    for name in profile_names() {
        let p = profile(&name);
        assert!(
            p.limit("shaderGroupHandleSize").is_some(),
            "profiles report shaderGroupHandleSize"
        );
        for command in CommandId::TRACE {
            for spec in [
                CaseSpec::valid(command),
                CaseSpec::valid(command).at_limits(),
            ] {
                let cases = match generator::generate(&p, &name, &rules, &spec, 150, 7) {
                    Ok(c) => c,
                    // A command the profile lacks (NV on lavapipe) is refused, never faked.
                    Err(generator::GenError::Unsupported(_)) => continue,
                    Err(e) => panic!("{name} {command:?}: {e}"),
                };
                for c in &cases {
                    let verdict = model::validate(&rules, &p, c);
                    assert!(
                        verdict.is_valid(),
                        "{name}: {} judged {:?}\n{}",
                        c.name,
                        verdict.vuids(),
                        c.to_yaml()
                    );
                    assert!(
                        c.runnable(&p).is_ok(),
                        "{name}: {} is not runnable: {:?}\n{}",
                        c.name,
                        c.runnable(&p),
                        c.to_yaml()
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked >= 900, "only {checked} valid cases checked");
}
