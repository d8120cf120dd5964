//! Valid-by-construction cases from every committed profile: the model judges them valid and their
//! launches read no shader binding table record outside its table (no undefined behaviour is ever
//! handed to a driver as a valid case).

use generator::{CaseSpec, Command};
use rtconf_tests::{installed_rules, profile, profile_names};

#[test]
fn generated_valid_cases_are_valid_and_read_only_inside_their_tables() {
    let rules = installed_rules();
    let mut checked = 0;
    for name in profile_names() {
        let p = profile(&name);
        let handle = p
            .limit("shaderGroupHandleSize")
            .expect("profiles report shaderGroupHandleSize");
        for command in Command::ALL {
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
                    let verdict = model::validate(&rules, &p, &c.world, &c.call);
                    assert!(
                        verdict.is_valid(),
                        "{name}: {} judged {:?}\n{}",
                        c.name,
                        verdict.vuids(),
                        c.to_yaml()
                    );
                    let ub = model::semantics::undefined_reads(handle, &c.world, &c.call);
                    assert!(
                        ub.is_empty(),
                        "{name}: {} reads {ub:?}\n{}",
                        c.name,
                        c.to_yaml()
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked >= 900, "only {checked} valid cases checked");
}
