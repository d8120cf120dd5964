//! Triage: the written-down, diagnosed disagreements with the validation layer and the driver
//! (`triage/*.yaml`). An entry states what was observed — the layer silent where the model reports a
//! VUID, the layer reporting one the model does not, the layer naming W where the model names V (one
//! pair), or the device's output deviating as a named deviation says — with its kind, its reason and
//! its evidence. A disagreement is `triaged` only by an entry of its own direction (`explain`); an
//! entry that nothing matched in a full run is stale ([`unused`]).

mod explain;
mod pattern;

pub use explain::{unused, CaseFacts, Explanation, TriageMatch, Unexplained};
pub use pattern::Pattern;

use crate::error::SessionError;
use model::CommandId;
use std::collections::BTreeSet;

/// What an entry says was observed: the direction of the disagreement.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Observed {
    /// The model reports the VUID; the layer says nothing of it.
    LayerSilent(Pattern),
    /// The layer reports the VUID; the model does not.
    LayerExtra(Pattern),
    /// The layer reports `layer` where the model reports `model`, as one pair in one case.
    LayerRenames { model: Pattern, layer: Pattern },
    /// The device's output deviates from the model's as the named deviation says
    /// (`<command>:<deviation>`, see `model::accel::check::deviation`).
    Output(Pattern),
    /// The device crashed or hung (a lost device, or a launch that never finished) on a valid case of
    /// the named shape (`<command>:<shape>`, see `model::semantics::shapes`).
    Crash(Pattern),
}

impl Observed {
    /// The direction's name as the triage files write it.
    pub fn direction(&self) -> &'static str {
        match self {
            Observed::LayerSilent(_) => "layer-silent",
            Observed::LayerExtra(_) => "layer-extra",
            Observed::LayerRenames { .. } => "layer-renames",
            Observed::Output(_) => "output",
            Observed::Crash(_) => "crash",
        }
    }

    /// Whether a case of the run involved what the entry speaks of: its VUID pattern (for a rename,
    /// the model's) matches a VUID of `exercised`. Always true for `output` and `crash` entries (their
    /// keys are deviations and shapes, not VUIDs).
    pub fn touches(&self, exercised: &BTreeSet<String>) -> bool {
        let any = |p: &Pattern| exercised.iter().any(|v| p.matches(v));
        match self {
            Observed::LayerSilent(p) | Observed::LayerExtra(p) => any(p),
            // The situation is a case on the model's VUID; the layer's VUID alone is another case.
            Observed::LayerRenames { model, .. } => any(model),
            Observed::Output(_) | Observed::Crash(_) => true,
        }
    }

    /// The wildcard patterns the observation states (a rename's two, every other direction's one).
    pub fn patterns(&self) -> Vec<&Pattern> {
        match self {
            Observed::LayerSilent(p)
            | Observed::LayerExtra(p)
            | Observed::Output(p)
            | Observed::Crash(p) => vec![p],
            Observed::LayerRenames { model, layer } => vec![model, layer],
        }
    }

    /// The entry's key as a person reads it: `layer-silent VUID-…`, `layer-renames V -> W`.
    pub fn describe(&self) -> String {
        match self {
            Observed::LayerSilent(p)
            | Observed::LayerExtra(p)
            | Observed::Output(p)
            | Observed::Crash(p) => format!("{} {p}", self.direction()),
            Observed::LayerRenames { model, layer } => {
                format!("{} {model} -> {layer}", self.direction())
            }
        }
    }
}

/// What kind of departure an entry diagnoses; each kind admits only the directions it can explain.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// The layer does not check the rule (it cannot see device memory or the launch, or the check is
    /// missing): only `layer-silent`.
    LayerGap,
    /// The layer checks statically, from the recorded call, a rule the specification states of what
    /// the command accesses, and so reports it where nothing is accessed: only `layer-extra`.
    LayerStaticCheck,
    /// The layer reports the violation under another VUID: only `layer-renames`.
    LayerMislabel,
    /// The layer checks the rule wrongly (an off-by-one, a check of another condition): any layer
    /// direction, with the layer's source as evidence.
    LayerBug,
    /// The driver departs from the specification: only `output` and `crash`.
    DriverBug,
    /// The harness cannot put the device in the state the model's world describes, so the layer sees
    /// another world: `layer-silent` or `layer-extra`, with what the harness lacks in the reason.
    HarnessLimit,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::LayerGap => "layer-gap",
            Kind::LayerStaticCheck => "layer-static-check",
            Kind::LayerMislabel => "layer-mislabel",
            Kind::LayerBug => "layer-bug",
            Kind::DriverBug => "driver-bug",
            Kind::HarnessLimit => "harness-limit",
        }
    }

    /// Whether an entry of this kind may state `observed`.
    pub fn admits(self, observed: &Observed) -> bool {
        matches!(
            (self, observed),
            (Kind::LayerGap, Observed::LayerSilent(_))
                | (Kind::LayerStaticCheck, Observed::LayerExtra(_))
                | (Kind::LayerMislabel, Observed::LayerRenames { .. })
                | (
                    Kind::LayerBug,
                    Observed::LayerSilent(_)
                        | Observed::LayerExtra(_)
                        | Observed::LayerRenames { .. }
                )
                | (Kind::DriverBug, Observed::Output(_) | Observed::Crash(_))
                | (
                    Kind::HarnessLimit,
                    Observed::LayerSilent(_) | Observed::LayerExtra(_)
                )
        )
    }

    /// The directions the kind admits, for error messages.
    fn directions(self) -> &'static str {
        match self {
            Kind::LayerGap => "layer-silent",
            Kind::LayerStaticCheck => "layer-extra",
            Kind::LayerMislabel => "layer-renames",
            Kind::LayerBug => "layer-silent, layer-extra or layer-renames",
            Kind::DriverBug => "output or crash",
            Kind::HarnessLimit => "layer-silent or layer-extra",
        }
    }
}

/// A condition on the case an entry applies to, beside its direction.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct When {
    /// The case's target VUID matches this pattern (`valid` for cases run as valid).
    #[serde(default)]
    pub target: Option<Pattern>,
    /// The model also reports each of these in the case.
    #[serde(default)]
    pub model_also: Vec<Pattern>,
    /// The layer also reports each of these in the case.
    #[serde(default)]
    pub layer_also: Vec<Pattern>,
    /// The model's problem with the explained VUID matches (`*by 1 byte`): for a layer that misses
    /// one form of a violation only.
    #[serde(default)]
    pub problem: Option<Pattern>,
}

/// One diagnosed disagreement.
#[derive(Debug, Clone, PartialEq)]
pub struct TriageEntry {
    pub observed: Observed,
    pub kind: Kind,
    pub reason: String,
    /// What shows it: a reproducing case (`cases/…`), the layer's source line or upstream commit.
    pub evidence: Vec<String>,
    /// Only cases whose name matches.
    pub cases: Option<Pattern>,
    /// Only cases where this holds.
    pub when: When,
    /// The commands whose cases the entry is about (stated, or read from its VUIDs' scopes).
    pub commands: BTreeSet<CommandId>,
    /// The file it came from (for reports and stale lists).
    pub file: String,
}

impl TriageEntry {
    /// The entry's identity in reports: file, direction, VUID pattern(s) and case pattern.
    pub fn id(&self) -> String {
        let mut s = format!("{}: {}", self.file, self.observed.describe());
        if let Some(c) = &self.cases {
            s.push_str(&format!(" (cases {c})"));
        }
        if let Some(t) = &self.when.target {
            s.push_str(&format!(" (target {t})"));
        }
        s
    }
}

/// The form an entry is written in.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
struct WrittenEntry {
    #[serde(default)]
    layer_silent: Option<Pattern>,
    #[serde(default)]
    layer_extra: Option<Pattern>,
    #[serde(default)]
    layer_renames: Option<WrittenRename>,
    #[serde(default)]
    output: Option<Pattern>,
    #[serde(default)]
    crash: Option<Pattern>,
    kind: Kind,
    reason: String,
    #[serde(default)]
    evidence: OneOrMany,
    #[serde(default)]
    cases: Option<Pattern>,
    #[serde(default)]
    when: When,
    /// The commands the entry is about, when its VUIDs do not say (a mislabel naming another command).
    #[serde(default)]
    command: Vec<CommandId>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct WrittenRename {
    model: Pattern,
    layer: Pattern,
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    #[default]
    None,
    One(String),
    Many(Vec<String>),
}

impl OneOrMany {
    fn into_vec(self) -> Vec<String> {
        match self {
            OneOrMany::None => vec![],
            OneOrMany::One(s) => vec![s],
            OneOrMany::Many(v) => v,
        }
    }
}

/// A triage file as written.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
struct WrittenFile {
    /// The validation layer version the entries were diagnosed with (`1.3.239`).
    #[serde(default, alias = "layer_version")]
    layer: Option<String>,
    /// The driver the entries were diagnosed on.
    #[serde(default)]
    driver: Option<String>,
    #[serde(default)]
    entries: Vec<WrittenEntry>,
}

/// The entries of a run's triage files.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Triage {
    pub entries: Vec<TriageEntry>,
    /// The files read, in order.
    pub files: Vec<String>,
}

/// The commands an entry is about, from its VUID patterns' scopes (`VUID-<scope>-…`) or its output or
/// crash key (`<command>:<deviation>`, `<command>:<shape>`).
fn commands_of(observed: &Observed) -> BTreeSet<CommandId> {
    let scope_commands = |p: &Pattern| -> BTreeSet<CommandId> {
        let text = p.as_str();
        let scope = text
            .strip_prefix("VUID-")
            .and_then(|r| r.split('-').next())
            .unwrap_or("");
        CommandId::ALL
            .into_iter()
            .filter(|c| {
                let scopes = [
                    c.vk_name(),
                    "VkStridedDeviceAddressRegionKHR",
                    "VkTraceRaysIndirectCommandKHR",
                ];
                scopes
                    .iter()
                    .any(|s| Pattern::new(scope).matches(s) && model::rules::applies_to(s, *c))
            })
            .collect()
    };
    match observed {
        Observed::LayerSilent(p) | Observed::LayerExtra(p) => scope_commands(p),
        Observed::LayerRenames { model, .. } => scope_commands(model),
        Observed::Output(p) | Observed::Crash(p) => {
            let command = p.as_str().split(':').next().unwrap_or("");
            CommandId::ALL
                .into_iter()
                .filter(|c| Pattern::new(command).matches(c.vk_name()))
                .collect()
        }
    }
}

impl WrittenEntry {
    /// The entry, or what is wrong with it.
    fn into_entry(self, file: &str) -> Result<TriageEntry, String> {
        let mut observed: Vec<Observed> = Vec::new();
        if let Some(p) = self.layer_silent {
            observed.push(Observed::LayerSilent(p));
        }
        if let Some(p) = self.layer_extra {
            observed.push(Observed::LayerExtra(p));
        }
        if let Some(r) = self.layer_renames {
            observed.push(Observed::LayerRenames {
                model: r.model,
                layer: r.layer,
            });
        }
        if let Some(p) = self.output {
            observed.push(Observed::Output(p));
        }
        if let Some(p) = self.crash {
            observed.push(Observed::Crash(p));
        }
        let observed = match observed.len() {
            1 => observed.remove(0),
            0 => {
                return Err(
                    "states no observation: give one of layer-silent, layer-extra, layer-renames, output, crash"
                        .into(),
                )
            }
            _ => {
                return Err(format!(
                    "states {} observations ({}); an entry states exactly one",
                    observed.len(),
                    observed
                        .iter()
                        .map(Observed::direction)
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            }
        };
        if let Some(p) = observed
            .patterns()
            .iter()
            .find(|p| p.as_str().contains(['?', '[', ']']))
        {
            return Err(format!(
                "{}: `{p}` has a wildcard other than `*` (`?` and `[...]` would match only themselves)",
                observed.describe()
            ));
        }
        if !self.kind.admits(&observed) {
            return Err(format!(
                "{}: kind {} explains only {}, not {}",
                observed.describe(),
                self.kind.name(),
                self.kind.directions(),
                observed.direction()
            ));
        }
        if self.reason.trim().is_empty() {
            return Err(format!("{}: the reason is empty", observed.describe()));
        }
        let evidence = self.evidence.into_vec();
        if evidence.iter().all(|e| e.trim().is_empty()) {
            return Err(format!(
                "{}: no evidence (a reproducing case under cases/, or the layer's source line or commit)",
                observed.describe()
            ));
        }
        let commands = if self.command.is_empty() {
            commands_of(&observed)
        } else {
            self.command.into_iter().collect()
        };
        if commands.is_empty() {
            return Err(format!(
                "{}: names no modelled command (give `command:`)",
                observed.describe()
            ));
        }
        Ok(TriageEntry {
            observed,
            kind: self.kind,
            reason: self.reason,
            evidence,
            cases: self.cases,
            when: self.when,
            commands,
            file: file.to_string(),
        })
    }
}

impl Triage {
    /// A triage file's entries; `path` names it in errors and in the entries' ids.
    pub fn from_yaml(path: &str, text: &str) -> Result<Triage, SessionError> {
        let written: WrittenFile =
            model::case::parse_yaml(path, text).map_err(SessionError::Case)?;
        let file = std::path::Path::new(path)
            .file_name()
            .map_or(path.to_string(), |f| f.to_string_lossy().into_owned());
        let mut t = Triage {
            entries: Vec::new(),
            files: vec![path.to_string()],
        };
        let _ = (&written.layer, &written.driver);
        for (i, w) in written.entries.into_iter().enumerate() {
            let entry = w.into_entry(&file).map_err(|problem| {
                SessionError::Case(model::case::CaseError {
                    path: path.to_string(),
                    location: model::locate::locate(text, &format!("entries[{i}]")),
                    at: format!("entries[{i}]"),
                    problem: problem.to_string(),
                })
            })?;
            t.entries.push(entry);
        }
        let mut ids = BTreeSet::new();
        for (i, e) in t.entries.iter().enumerate() {
            if !ids.insert(e.id()) {
                return Err(SessionError::Case(model::case::CaseError {
                    path: path.to_string(),
                    location: model::locate::locate(text, &format!("entries[{i}]")),
                    at: format!("entries[{i}]"),
                    problem: format!(
                        "{} is written twice (give the second a `cases:` or `when:` that tells them apart)",
                        e.observed.describe()
                    ),
                }));
            }
        }
        Ok(t)
    }

    /// The entries of the named files; with none named, of `dir/<driver>.yaml` and
    /// `dir/layer-<layer version>.yaml` where they exist.
    pub fn load(
        dir: &std::path::Path,
        named: &[std::path::PathBuf],
        layer_version: Option<&str>,
        driver: &str,
    ) -> Result<Triage, SessionError> {
        let (paths, must_exist) = if named.is_empty() {
            let mut v = vec![dir.join(format!("{driver}.yaml"))];
            if let Some(ver) = layer_version {
                v.push(dir.join(format!("layer-{ver}.yaml")));
            }
            (v, false)
        } else {
            (named.to_vec(), true)
        };
        let mut all = Triage::default();
        for p in paths {
            match vk_registry::input::read_text_at_most(
                &p,
                model::case::YAML_FILE_LIMIT,
                "a triage file",
            ) {
                Ok(t) => {
                    let one = Triage::from_yaml(&p.display().to_string(), &t)?;
                    all.entries.extend(one.entries);
                    all.files.extend(one.files);
                }
                Err(_) if !must_exist => {}
                Err(e) => return Err(SessionError::io(format!("triage file {}", p.display()), e)),
            }
        }
        Ok(all)
    }
}

/// The reproducing cases (`cases/…` evidence, under the repository root) of the entries about a
/// planned command that `used` does not hold, written for `profile`: what a full run replays so that an
/// entry its generated cases did not exercise is judged on its own evidence. Unreadable files are left
/// out (a test checks that every evidence file reads).
pub fn evidence_cases(
    triage: &Triage,
    used: &BTreeSet<String>,
    planned: &BTreeSet<CommandId>,
    profile: &str,
) -> Vec<model::Case> {
    let root = crate::sources::repo_dir();
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    for e in &triage.entries {
        if used.contains(&e.id()) || !e.commands.iter().any(|c| planned.contains(c)) {
            continue;
        }
        for ev in e
            .evidence
            .iter()
            .filter(|ev| ev.starts_with("cases/") && ev.ends_with(".yaml"))
        {
            if !seen.insert(ev.clone()) {
                continue;
            }
            let Ok(case) = crate::replay::read_case(&root.join(ev)) else {
                continue;
            };
            if case.profile == profile && planned.contains(&case.command()) {
                out.push(case);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests;
