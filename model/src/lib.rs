//! rtconf's executable reference model: device profiles, the world and the call, the rule table built
//! from the registry's VUIDs, verdicts, and the meaning of a valid launch.
//!
//! Pure and deterministic: the same case always gets the same verdict and the same expected output.

pub mod accel;
pub mod bulk;
pub mod call;
pub mod case;
pub mod case_yaml;
pub mod command;
pub mod compact;
pub mod expected;
pub mod fingerprint;
pub mod flags;
pub(crate) mod helpers;
pub mod integrity;
pub mod locate;
pub mod profile;
pub mod rendered;
pub mod required_limits;
pub mod resources;
pub mod rules;
pub mod semantics;
pub mod stress;
pub mod verdict;
pub mod world;

pub use call::{Address, Call, StridedRegion, Table};
pub use case::{AccelBody, Body, Case, Intent, NotRunnable, TraceBody};
pub use command::CommandId;
pub use profile::DeviceProfile;
pub use rules::{validate, RuleSet};
pub use verdict::{Verdict, Violation};
pub use world::World;
pub mod scene;
pub mod tracer;

/// What the crate's unit tests share: the repository's case files.
#[cfg(test)]
pub(crate) mod test_cases {
    /// Every `*.yaml` under the repository's `cases/`, in no particular order.
    pub(crate) fn repository_case_files() -> Vec<std::path::PathBuf> {
        fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
            for entry in std::fs::read_dir(dir).expect("the cases folder reads") {
                let path = entry.expect("a folder entry").path();
                if path.is_dir() {
                    walk(&path, out);
                } else if path.extension().is_some_and(|e| e == "yaml") {
                    out.push(path);
                }
            }
        }
        let mut out = Vec::new();
        walk(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases"),
            &mut out,
        );
        out
    }

    /// The hand-made vkCmdTraceRaysIndirectKHR case, `cases/hand/trace-indirect-records-32.yaml`.
    pub(crate) fn hand_case() -> crate::Case {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../cases/hand/trace-indirect-records-32.yaml");
        let text = std::fs::read_to_string(path).expect("the hand-made case reads");
        crate::Case::from_yaml("hand", &text).expect("the hand-made case parses")
    }
}
