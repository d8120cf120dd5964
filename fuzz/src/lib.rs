//! Fuzz entry points for every parser a user can feed rtconf, shared by the libFuzzer binaries
//! (`fuzz/libfuzzer/`) and the short deterministic run of `cargo test -p rtconf-fuzz`.
//!
//! Each [`Target`] is one parser: [`run`] hands it the input and, for the inputs the model then
//! works on (cases and device profiles), does what `rtconf check` and `rtconf run` do next with what
//! was read, so a size or limit that the input states reaches the model. Every arm of [`run`] is a
//! few lines, so re-pointing a target at a moved parser is a one-line change.

pub mod mutate;

use model::{Body, Case, DeviceProfile, RuleSet};
use std::sync::OnceLock;

/// The origin named in the errors of fuzzed inputs.
pub const ORIGIN: &str = "<fuzz>";

/// One parser a user can feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// vk.xml: `vk_registry::Registry::parse_named`, then `report::show` of a few names.
    VkXml,
    /// validusage.json, both schemas: `vk_registry::validusage::parse`.
    Validusage,
    /// Man page, Markdown rendering of the HTML page: `vk_registry::manpage::parse`.
    ManpageMarkdown,
    /// Man page, pandoc Markdown with raw anchors: `vk_registry::manpage::parse`.
    ManpagePandoc,
    /// Man page, plain text: `vk_registry::manpage::parse`.
    ManpagePlain,
    /// A case file of a trace command: `model::Case::read`, then judged as `rtconf check` and
    /// `rtconf run` do.
    TraceCase,
    /// A case file of the build command: the same reader and judging as [`Target::TraceCase`],
    /// seeded with build cases so that mutations reach the build world.
    BuildCase,
    /// A triage file: `session::triage::Triage::from_yaml`, then each entry's id and patterns.
    Triage,
    /// A device profile: `model::DeviceProfile::from_profiles_json`, then a trace case and a build
    /// case judged on it.
    DeviceProfile,
    /// A baseline file of expected failures (`--baseline`): `session::baseline::parse_baseline`, then
    /// its `*` patterns matched against case names and VUIDs.
    Baseline,
    /// A skips or flakes file (`--skips`, `--flakes`): `session::baseline::parse_patterns`, then its
    /// regular expressions matched against case names and VUIDs.
    CasePatterns,
}

impl Target {
    pub const ALL: [Target; 11] = [
        Target::VkXml,
        Target::Validusage,
        Target::ManpageMarkdown,
        Target::ManpagePandoc,
        Target::ManpagePlain,
        Target::TraceCase,
        Target::BuildCase,
        Target::Triage,
        Target::DeviceProfile,
        Target::Baseline,
        Target::CasePatterns,
    ];

    /// The name of the target's libFuzzer binary and of its folders under `fuzz/corpus/` and
    /// `fuzz/regressions/`.
    pub fn name(self) -> &'static str {
        match self {
            Target::VkXml => "vk_xml",
            Target::Validusage => "validusage_json",
            Target::ManpageMarkdown => "manpage_markdown",
            Target::ManpagePandoc => "manpage_pandoc",
            Target::ManpagePlain => "manpage_plain",
            Target::TraceCase => "trace_case",
            Target::BuildCase => "build_case",
            Target::Triage => "triage",
            Target::DeviceProfile => "device_profile",
            Target::Baseline => "baseline",
            Target::CasePatterns => "case_patterns",
        }
    }

    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// What a parser made of one input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Read (and, for cases and profiles, judged) without error.
    Accepted,
    /// Refused with an error; `location` is where the error says the problem is, if it says.
    Rejected {
        location: Option<String>,
        message: String,
    },
    /// Not UTF-8: every reader refuses such a file before its parser sees it.
    NotText,
}

/// Runs `data` through the target's parser, and what follows it.
pub fn run(target: Target, data: &[u8]) -> Outcome {
    let Ok(text) = std::str::from_utf8(data) else {
        return Outcome::NotText;
    };
    match target {
        Target::VkXml => match vk_registry::Registry::parse_named(text, ORIGIN) {
            Ok(reg) => {
                // what `rtconf registry show NAME` prints, for a few names of each kind
                let names = (reg.commands.iter().map(|c| c.name.as_str()).take(4))
                    .chain(reg.types.iter().map(|t| t.name.as_str()).take(4))
                    .chain(reg.enum_groups.iter().map(|g| g.name.as_str()).take(4));
                for name in names {
                    let _ = vk_registry::report::show(&reg, name);
                }
                Outcome::Accepted
            }
            Err(e) => registry::<()>(Err(e)),
        },
        Target::Validusage => registry(vk_registry::validusage::parse(text, ORIGIN)),
        Target::ManpageMarkdown | Target::ManpagePandoc | Target::ManpagePlain => {
            registry(vk_registry::manpage::parse(text, ORIGIN))
        }
        Target::TraceCase | Target::BuildCase => match Case::read(ORIGIN, text) {
            Ok(case) => {
                judge(&case, profile_named(&case.profile));
                Outcome::Accepted
            }
            Err(e) => case_error(e),
        },
        Target::Triage => match session::triage::Triage::from_yaml(ORIGIN, text) {
            Ok(triage) => {
                // what a run asks of an entry: its id, and whether its patterns match a VUID
                for e in &triage.entries {
                    let _ = (e.id(), e.observed.describe());
                    for p in e.observed.patterns() {
                        let _ = p.captures(MATCHED_NAMES[2]);
                    }
                }
                Outcome::Accepted
            }
            // An entry that is not one (two directions, a kind that cannot explain its direction, a key
            // written twice) is named by its YAML path (`entries[3]`), without line:column.
            Err(session::SessionError::Case(e)) if e.location.is_none() && !e.at.is_empty() => {
                Outcome::Rejected {
                    location: Some(e.at.clone()),
                    message: e.to_string(),
                }
            }
            Err(session::SessionError::Case(e)) => case_error(e),
            Err(e) => Outcome::Rejected {
                location: None,
                message: e.to_string(),
            },
        },
        Target::DeviceProfile => match DeviceProfile::from_profiles_json(ORIGIN, text) {
            Ok(profile) => {
                for case in &fixed().cases {
                    judge(case, &profile);
                }
                Outcome::Accepted
            }
            Err(e) => Outcome::Rejected {
                location: profile_location(&e.location),
                message: e.problem,
            },
        },
        Target::Baseline => {
            let (entries, errors) = session::baseline::parse_baseline(ORIGIN, text);
            for e in &entries {
                for name in MATCHED_NAMES {
                    let _ = session::baseline::wildcard_match(&e.key, name);
                }
            }
            lines(&errors)
        }
        Target::CasePatterns => {
            let (patterns, errors) = session::baseline::parse_patterns(ORIGIN, text);
            for p in &patterns {
                for name in MATCHED_NAMES {
                    let _ = p.regex.is_match(name);
                }
            }
            lines(&errors)
        }
    }
}

/// A panic of a parser or of the model: where and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Panic {
    pub location: String,
    pub message: String,
}

thread_local! {
    static LAST_PANIC: std::cell::RefCell<Option<Panic>> = const { std::cell::RefCell::new(None) };
    static CATCHING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// [`run`] with panics caught and returned. Installs a panic hook that records the panics of a run
/// instead of printing them (others go to the hook that was there before).
pub fn run_catching(target: Target, data: &[u8]) -> Result<Outcome, Panic> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let before = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !CATCHING.with(|c| c.get()) {
                return before(info);
            }
            let payload = info.payload();
            let message = (payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(no message)".into());
            let location = info.location().map(|l| l.to_string()).unwrap_or_default();
            LAST_PANIC.with(|p| *p.borrow_mut() = Some(Panic { location, message }));
        }))
    });
    CATCHING.with(|c| c.set(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(target, data)));
    CATCHING.with(|c| c.set(false));
    result.map_err(|_| {
        LAST_PANIC.with(|p| p.borrow_mut().take()).unwrap_or(Panic {
            location: String::new(),
            message: "(no message)".into(),
        })
    })
}

/// The entry of a libFuzzer binary: [`run`]; a panic is handed on to libFuzzer as a crash.
pub fn fuzz_one(target: Target, data: &[u8]) {
    let _ = run(target, data);
}

fn registry<T>(r: Result<T, vk_registry::RegistryError>) -> Outcome {
    match r {
        Ok(_) => Outcome::Accepted,
        Err(e) => Outcome::Rejected {
            location: e.location().map(|l| l.to_string()),
            message: e.to_string(),
        },
    }
}

/// Names that baseline, skips and flakes entries are matched against: case names and VUIDs.
const MATCHED_NAMES: [&str; 3] = [
    "trace-indirect-valid-3-7",
    "build-0-0-valid",
    "VUID-vkCmdTraceRaysIndirectKHR-None-03429",
];

/// The outcome of a line-based file: accepted, or refused at the line of its first error.
fn lines(errors: &[session::baseline::LineError]) -> Outcome {
    match errors.first() {
        None => Outcome::Accepted,
        Some(e) => Outcome::Rejected {
            location: Some(e.line.to_string()),
            message: e.to_string(),
        },
    }
}

fn case_error(e: model::case::CaseError) -> Outcome {
    Outcome::Rejected {
        location: e.location.map(|(l, c)| format!("{l}:{c}")),
        message: e.to_string(),
    }
}

/// A profile error's location without the origin: `line:column` or a JSON path.
fn profile_location(loc: &str) -> Option<String> {
    let rest = loc.strip_prefix(ORIGIN)?.trim_start_matches([':', ' ']);
    let is_line_col = rest
        .split_once(':')
        .is_some_and(|(l, c)| l.parse::<usize>().is_ok() && c.parse::<usize>().is_ok());
    (is_line_col || rest.starts_with('$')).then(|| rest.to_string())
}

/// What `rtconf check` and `rtconf run` compute from a case that was read, on the way to a driver and
/// back: the undefined-reads gate, the verdict, the expected launch of a trace and the ray of its last launch ID, the
/// build's primitives and the rays that check the built structure.
fn judge(case: &Case, profile: &DeviceProfile) {
    let _ = case.runnable(profile);
    let _ = case.runs_as_valid(profile);
    let _ = model::validate(&fixed().rules, profile, case);
    match &case.body {
        Body::Trace(t) => {
            if let Some(e) = model::semantics::expected_launch(&t.world, &t.call) {
                let last = e.invocations().saturating_sub(1);
                let _ = e.ray_of(usize::try_from(last).unwrap_or(usize::MAX));
            }
        }
        Body::Accel(a) => {
            let _ = model::accel::indirect_build(&a.world, &a.call);
            let _ = model::accel::check::BuildCheck::of(a);
        }
    }
}

/// What every run shares: the rule table of the installed registry, the committed profiles, and a
/// valid case of each command family for judging fuzzed profiles.
struct Fixed {
    rules: RuleSet,
    profiles: Vec<DeviceProfile>,
    cases: Vec<Case>,
}

fn fixed() -> &'static Fixed {
    static FIXED: OnceLock<Fixed> = OnceLock::new();
    FIXED.get_or_init(|| {
        let dir = std::path::Path::new(vk_registry::DEFAULT_REGISTRY_DIR);
        let set = vk_registry::load_vuids(dir)
            .unwrap_or_else(|_| vk_registry::VuidSet::new("<none>", None, Vec::new()));
        let profiles = [
            ("lavapipe", include_str!("../../profiles/lavapipe.json")),
            (
                "nvidia-h100",
                include_str!("../../profiles/nvidia-h100.json"),
            ),
            (
                "nvidia-h200",
                include_str!("../../profiles/nvidia-h200.json"),
            ),
        ]
        .into_iter()
        .filter_map(|(name, text)| DeviceProfile::from_profiles_json(name, text).ok())
        .collect();
        let cases = [
            (
                "trace seed",
                include_str!("../corpus/trace_case/basic.yaml"),
            ),
            (
                "build seed",
                include_str!("../corpus/build_case/aabbs.yaml"),
            ),
        ]
        .into_iter()
        .filter_map(|(name, text)| Case::read(name, text).ok())
        .collect();
        Fixed {
            rules: RuleSet::from_vuids(&set),
            profiles,
            cases,
        }
    })
}

/// The committed profile a case names, or the first one (a fuzzed input never names a file to read).
fn profile_named(name: &str) -> &'static DeviceProfile {
    static EMPTY: OnceLock<DeviceProfile> = OnceLock::new();
    let f = fixed();
    f.profiles
        .iter()
        .find(|p| p.name == name)
        .or(f.profiles.first())
        .unwrap_or_else(|| EMPTY.get_or_init(DeviceProfile::default))
}

/// Loads the inputs of every file directly in `dir`, sorted by name (none if it does not exist).
pub fn inputs_in(dir: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().is_file())
        .filter_map(|e| {
            let p = e.path();
            let name = p.file_name()?.to_string_lossy().into_owned();
            (!name.starts_with('.') && name != "README.md")
                .then(|| Some((name, std::fs::read(&p).ok()?)))
                .flatten()
        })
        .collect();
    out.sort();
    out
}

/// `fuzz/` of this checkout.
pub fn fuzz_dir() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
