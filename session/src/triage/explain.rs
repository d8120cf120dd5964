//! Which entries explain a case's disagreements: each VUID the model reports and the layer does not
//! (model only) can be explained only by a `layer-silent` entry or as the model half of a
//! `layer-renames` pair, each VUID only the layer reports only by a `layer-extra` entry or as the layer
//! half of a pair; a pair needs both halves in the same case. What no entry of its direction explains
//! stays a failure, with a note when an entry of the other direction names it. Entries that explained
//! nothing in a full run are stale.

use super::{Kind, Observed, Pattern, Triage, TriageEntry};
use model::CommandId;
use std::collections::BTreeSet;

/// What matching needs to know of one case.
#[derive(Debug, Clone, Copy)]
pub struct CaseFacts<'a> {
    pub name: &'a str,
    pub command: CommandId,
    /// The VUID an invalid case targets; None for a case run as valid.
    pub target: Option<&'a str>,
    /// The model's VUIDs.
    pub model: &'a [String],
    /// The layer's VUIDs of the modelled scopes.
    pub layer: &'a [String],
    /// The layer's other message ids (`UNASSIGNED-…`, other commands' VUIDs): a rename's layer half
    /// may be one of them.
    pub layer_other: &'a [String],
    /// The model's violations as (VUID, problem), for entries that name a problem.
    pub problems: &'a [(String, String)],
}

/// One disagreement an entry explains, as `results.jsonl` records it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TriageMatch {
    /// The entry's id ([`TriageEntry::id`]).
    pub entry: String,
    pub kind: Kind,
    /// `layer-silent`, `layer-extra`, `layer-renames` or `output`.
    pub observed: String,
    /// The VUID explained (for a rename, the model's; for an output, the deviation's key).
    pub vuid: String,
    /// For a rename: the layer's VUID.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layer_vuid: Option<String>,
}

/// A disagreement no entry of its direction explains.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unexplained {
    pub vuid: String,
    /// `model only` or `layer only`.
    pub side: &'static str,
    /// An entry of another direction that names the VUID, said so the reader sees why it did not apply.
    pub note: Option<String>,
}

/// The disagreements of one case, explained or not.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Explanation {
    /// Each explained disagreement with the entry's reason.
    pub matched: Vec<(TriageMatch, String)>,
    pub unexplained: Vec<Unexplained>,
}

impl TriageEntry {
    /// Whether the entry is about this case at all: its command, case pattern and condition.
    fn concerns(&self, case: &CaseFacts) -> bool {
        let any =
            |ps: &[Pattern], vs: &[String]| ps.iter().all(|p| vs.iter().any(|v| p.matches(v)));
        self.commands.contains(&case.command)
            && self.cases.as_ref().is_none_or(|p| p.matches(case.name))
            && self.when.target.as_ref().is_none_or(|p| match case.target {
                Some(t) => p.matches(t),
                None => p.as_str() == "valid",
            })
            && any(&self.when.model_also, case.model)
            && any(&self.when.layer_also, case.layer)
    }

    /// Whether the model's problem with `vuid` is the one the entry names, if it names one.
    fn problem_matches(&self, case: &CaseFacts, vuid: &str) -> bool {
        self.when.problem.as_ref().is_none_or(|p| {
            case.problems
                .iter()
                .any(|(v, problem)| v == vuid && p.matches(problem))
        })
    }

    fn matched(&self, vuid: &str, layer_vuid: Option<&str>) -> (TriageMatch, String) {
        (
            TriageMatch {
                entry: self.id(),
                kind: self.kind,
                observed: self.observed.direction().into(),
                vuid: vuid.into(),
                layer_vuid: layer_vuid.map(String::from),
            },
            self.reason.clone(),
        )
    }
}

/// Whether two renamed VUIDs pair up: each must match its pattern, and where both patterns have the
/// same number of `*`, the runs they stand for must be equal (`…IndirectKHR-*` → `…KHR-*` pairs a
/// VUID with the one of the same tail only).
fn pairs(model: &Pattern, layer: &Pattern, v: &str, w: &str) -> bool {
    match (model.captures(v), layer.captures(w)) {
        (Some(a), Some(b)) => a.len() != b.len() || a == b,
        _ => false,
    }
}

impl Triage {
    /// Explains a case's disagreements (see the module documentation). Renames pair first, then
    /// `layer-silent` and `layer-extra` entries take what is left, in file order.
    pub fn explain(&self, case: &CaseFacts) -> Explanation {
        let m: BTreeSet<&str> = case.model.iter().map(String::as_str).collect();
        let l: BTreeSet<&str> = case.layer.iter().map(String::as_str).collect();
        let mut model_only: Vec<&str> = m.difference(&l).copied().collect();
        let mut layer_only: Vec<&str> = l.difference(&m).copied().collect();
        let mut other: Vec<&str> = case.layer_other.iter().map(String::as_str).collect();
        let concerned: Vec<&TriageEntry> =
            self.entries.iter().filter(|e| e.concerns(case)).collect();
        let mut out = Explanation::default();
        for e in &concerned {
            let Observed::LayerRenames { model, layer } = &e.observed else {
                continue;
            };
            let mut i = 0;
            while i < model_only.len() {
                let v = model_only[i];
                let fits = |w: &&str| {
                    model.matches(v) && pairs(model, layer, v, w) && e.problem_matches(case, v)
                };
                if let Some(j) = layer_only.iter().position(fits) {
                    let w = layer_only.remove(j);
                    model_only.remove(i);
                    out.matched.push(e.matched(v, Some(w)));
                } else if let Some(j) = other.iter().position(fits) {
                    let w = other.remove(j);
                    model_only.remove(i);
                    out.matched.push(e.matched(v, Some(w)));
                } else {
                    i += 1;
                }
            }
        }
        for e in &concerned {
            match &e.observed {
                Observed::LayerSilent(p) => model_only.retain(|v| {
                    let hit = p.matches(v) && e.problem_matches(case, v);
                    if hit {
                        out.matched.push(e.matched(v, None));
                    }
                    !hit
                }),
                Observed::LayerExtra(p) => layer_only.retain(|w| {
                    let hit = p.matches(w);
                    if hit {
                        out.matched.push(e.matched(w, None));
                    }
                    !hit
                }),
                _ => {}
            }
        }
        let note = |v: &str, side: &str| -> Option<String> {
            self.entries
                .iter()
                .find(|e| match &e.observed {
                    Observed::LayerSilent(p) => side == "layer only" && p.matches(v),
                    Observed::LayerExtra(p) => side == "model only" && p.matches(v),
                    Observed::LayerRenames { model, layer } => model.matches(v) || layer.matches(v),
                    Observed::Output(_) | Observed::Crash(_) => false,
                })
                .or_else(|| {
                    // An entry of the right direction whose case pattern or condition excludes the case.
                    self.entries.iter().find(|e| {
                        !e.concerns(case)
                            && match &e.observed {
                                Observed::LayerSilent(p) => side == "model only" && p.matches(v),
                                Observed::LayerExtra(p) => side == "layer only" && p.matches(v),
                                _ => false,
                            }
                    })
                })
                .map(|e| {
                    if e.concerns(case) {
                        format!(
                            "`{}` names it, but for another direction; not absorbed",
                            e.id()
                        )
                    } else {
                        format!("`{}` names it, but not for this case", e.id())
                    }
                })
        };
        for v in model_only {
            out.unexplained.push(Unexplained {
                vuid: v.into(),
                side: "model only",
                note: note(v, "model only"),
            });
        }
        for w in layer_only {
            out.unexplained.push(Unexplained {
                vuid: w.into(),
                side: "layer only",
                note: note(w, "layer only"),
            });
        }
        out
    }

    /// The `output` entry that explains a build's rays under the named deviation (`key` is
    /// `<command>:<deviation>`), with its reason.
    pub fn explain_output(&self, case: &CaseFacts, key: &str) -> Option<(TriageMatch, String)> {
        self.explain_key(case, key, |o| match o {
            Observed::Output(p) => Some(p),
            _ => None,
        })
    }

    /// The `crash` entry that explains a crash or hang of a valid case of shape `key`
    /// (`<command>:<shape>`), with its reason.
    pub fn explain_crash(&self, case: &CaseFacts, key: &str) -> Option<(TriageMatch, String)> {
        self.explain_key(case, key, |o| match o {
            Observed::Crash(p) => Some(p),
            _ => None,
        })
    }

    /// The first entry about `case` whose keyed pattern (`pattern` of its observation) explains `key`.
    fn explain_key(
        &self,
        case: &CaseFacts,
        key: &str,
        pattern: impl Fn(&Observed) -> Option<&Pattern>,
    ) -> Option<(TriageMatch, String)> {
        self.entries
            .iter()
            .filter(|e| e.concerns(case))
            .find(|e| pattern(&e.observed).is_some_and(|p| output_matches(p, key)))
            .map(|e| e.matched(key, None))
    }
}

/// The entries about a command of `ran` (commands whose cases ran) that explained nothing, as two lists
/// of ids: **stale** ones, although the run exercised what they speak of, and **unexercised** ones. A
/// VUID entry is judged only when some case that ran involved one of its VUIDs (`exercised`: the targets
/// and the VUIDs model or layer reported); one whose VUIDs no case touched (the profile cannot express
/// them, or their cases were not realised) is unexercised, not stale. An `output` entry is judged
/// whenever its command ran.
pub fn unused(
    triage: &Triage,
    matched: &BTreeSet<String>,
    ran: &BTreeSet<CommandId>,
    exercised: &BTreeSet<String>,
) -> (Vec<String>, Vec<String>) {
    let (stale, unexercised): (Vec<&TriageEntry>, Vec<&TriageEntry>) = triage
        .entries
        .iter()
        .filter(|e| e.commands.iter().any(|c| ran.contains(c)))
        .filter(|e| !matched.contains(&e.id()))
        .partition(|e| e.observed.touches(exercised));
    let ids = |v: Vec<&TriageEntry>| v.into_iter().map(TriageEntry::id).collect();
    (ids(stale), ids(unexercised))
}

/// Whether an output entry's pattern explains `key`: the key whole, or one of the alternatives it
/// names (`COMMAND:A|B`, each deviation explaining the records on its own, see
/// `model::accel::check::deviation`) with its command, `COMMAND:A` or `COMMAND:B`.
fn output_matches(pattern: &Pattern, key: &str) -> bool {
    pattern.matches(key)
        || key.split_once(':').is_some_and(|(command, names)| {
            names.contains('|')
                && names
                    .split('|')
                    .any(|name| pattern.matches(&format!("{command}:{name}")))
        })
}
