//! Shared helpers for the workspace-level tests (see tests/tests/): the repository's paths, the
//! installed registry's rule table, and the committed device profiles.

use model::{DeviceProfile, RuleSet};
use std::path::{Path, PathBuf};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The seeds folder beside the repository (`../shared/seeds`; for a worktree deeper down, the nearest
/// ancestor's `shared/seeds`).
pub fn seeds() -> PathBuf {
    repo()
        .ancestors()
        .map(|a| a.join("shared").join("seeds"))
        .find(|p| p.is_dir())
        .unwrap_or_else(|| repo().join("..").join("shared").join("seeds"))
}

/// The installed registry's VUIDs (1.3.239 on Debian 12; `bash scripts/setup.sh` installs it).
pub fn installed_vuids() -> vk_registry::vuid::VuidSet {
    vk_registry::source::load_vuids(Path::new(vk_registry::source::DEFAULT_REGISTRY_DIR))
        .expect("the installed registry: run `bash scripts/setup.sh`")
}

pub fn installed_rules() -> RuleSet {
    RuleSet::from_vuids(&installed_vuids())
}

/// A committed profile by name (`lavapipe`, `nvidia-h100`).
pub fn profile(name: &str) -> DeviceProfile {
    let path = repo().join("profiles").join(format!("{name}.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    DeviceProfile::from_profiles_json(name, &text).expect("a committed profile parses")
}

/// Every committed profile's name.
pub fn profile_names() -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(repo().join("profiles"))
        .expect("profiles/")
        .filter_map(|e| {
            e.ok()?
                .path()
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
        })
        .collect();
    v.sort();
    v
}

/// The 1.4.309 registry from trixie (`target/registry/1.4.309`), fetched with
/// scripts/fetch-registry.sh when missing.
pub fn registry_1_4_309() -> PathBuf {
    let dest = repo().join("target/registry/1.4.309");
    let reg = dest.join("usr/share/vulkan/registry");
    if !reg.join("validusage.json").exists() {
        let status = std::process::Command::new("bash")
            .arg(repo().join("scripts/fetch-registry.sh"))
            .arg(&dest)
            .status()
            .expect("running scripts/fetch-registry.sh");
        assert!(status.success(), "scripts/fetch-registry.sh failed");
    }
    reg
}

/// The rule table of the 1.4.309 registry ([`registry_1_4_309`]).
pub fn rules_1_4_309() -> RuleSet {
    let set = vk_registry::source::load_vuids(&registry_1_4_309()).expect("the 1.4.309 registry");
    RuleSet::from_vuids(&set)
}

/// A case's declared VUIDs (its target and co-violations) and the VUIDs the model judges it to
/// violate on `profile`, for tests that check a generator declares exactly what the model finds.
pub fn declared_and_judged(
    rules: &RuleSet,
    profile: &DeviceProfile,
    case: &model::case::Case,
) -> (
    std::collections::BTreeSet<String>,
    std::collections::BTreeSet<String>,
) {
    let declared = case.expected_vuids().into_iter().collect();
    let judged = rules
        .judge(profile, &case.body)
        .vuids()
        .into_iter()
        .map(String::from)
        .collect();
    (declared, judged)
}

/// lavapipe under the validation layer, with the installed registry's rules, the lavapipe profile and
/// the triage files of the layer's own version: cases generated, run and judged as a run does.
pub struct Lavapipe {
    pub rules: RuleSet,
    pub profile: DeviceProfile,
    pub triage: session::Triage,
    pub executor: harness::Executor,
}

impl Lavapipe {
    pub fn new() -> Lavapipe {
        std::env::set_var("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json");
        let layer =
            harness::validation_layer().expect("the validation layer: `bash scripts/setup.sh`");
        let driver = harness::Driver::Lavapipe;
        Lavapipe {
            rules: installed_rules(),
            profile: profile("lavapipe"),
            triage: session::sources::triage_for(&[], Some(&layer.version), &driver)
                .expect("triage files parse"),
            executor: harness::Executor::new(driver)
                .expect("lavapipe and the validation layer: run `bash scripts/setup.sh`"),
        }
    }

    pub fn generate(
        &self,
        spec: &generator::CaseSpec,
        count: usize,
        seed: u64,
    ) -> Result<Vec<model::Case>, generator::GenError> {
        generator::generate(&self.profile, "lavapipe", &self.rules, spec, count, seed)
    }

    /// One case run and judged as a run does (the gate, the execution, one verdict, the comparison).
    pub fn run(&mut self, case: &model::Case) -> session::CaseReport {
        let judging = session::run::Judging::new(&self.rules, &self.profile, &self.triage);
        judging
            .run_here(&mut self.executor, case, harness::TraceCheck::Auto)
            .report
    }
}

impl Default for Lavapipe {
    fn default() -> Lavapipe {
        Lavapipe::new()
    }
}
