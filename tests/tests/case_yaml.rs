//! The fast case writer (`model::case_yaml`) against the slow path it stands in for, on generated
//! cases of every command and committed profile (valid, at the limits, rendered, and violating each
//! executable VUID): the same text byte for byte, and the fast path taken for nearly all of them.

use generator::CaseSpec;
use model::case_yaml::{fast, slow};
use model::CommandId;
use rtconf_tests::{installed_rules, profile, profile_names};

#[test]
fn generated_cases_are_written_as_the_slow_path_writes_them() {
    let rules = installed_rules();
    let mut written = 0;
    let mut gave_up = Vec::new();
    for name in profile_names() {
        let p = profile(&name);
        for command in CommandId::ALL {
            let mut specs = vec![
                CaseSpec::valid(command),
                CaseSpec::valid(command).at_limits(),
            ];
            if command.is_trace() {
                specs.push(CaseSpec::rendered(command));
            }
            specs.extend(
                generator::executable_vuids(&rules, command)
                    .iter()
                    .map(|v| CaseSpec::for_vuid(v, command)),
            );
            for spec in &specs {
                // A spec the profile or the generator cannot make (NV on lavapipe, a VUID without a
                // mutation) has no cases to write.
                let Ok(cases) = generator::generate(&p, &name, &rules, spec, 3, 11) else {
                    continue;
                };
                for c in &cases {
                    let reference = slow(c);
                    match fast(c) {
                        Ok(text) => {
                            assert_eq!(text, reference, "{name}: {}", c.name);
                            written += 1;
                        }
                        Err(e) => gave_up.push(format!("{name}: {}: {e}", c.name)),
                    }
                    assert_eq!(c.to_yaml(), reference, "{name}: {}", c.name);
                }
            }
        }
    }
    assert!(written >= 1_000, "only {written} generated cases written");
    assert!(
        gave_up.len() * 50 <= written,
        "the fast writer gave up on {} cases (written {written}): {gave_up:#?}",
        gave_up.len()
    );
}
