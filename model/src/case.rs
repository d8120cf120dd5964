//! A case: the unit that is generated, judged, executed, reported, shrunk and replayed — one serde type,
//! written as YAML a person can read and edit.

use crate::call::Call;
use crate::world::World;

/// What a case is meant to be.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Intent {
    /// Valid by construction: the verdict must be empty.
    Valid,
    /// Violates exactly `vuid`, plus the declared co-violations that the device makes unavoidable.
    Violates {
        vuid: String,
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        also: Vec<String>,
    },
}

/// A generated or hand-written case.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    pub name: String,
    /// The device profile it was made for (`lavapipe`, `nvidia-h100`, or a path).
    pub profile: String,
    /// The proptest seed that produced it, when generated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<String>,
    pub intent: Intent,
    pub world: World,
    pub call: Call,
}

/// A case file that could not be read: the line and what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("{path}{}: {problem}", location.map(|(l, c)| format!(":{l}:{c}")).unwrap_or_default())]
pub struct CaseError {
    pub path: String,
    pub location: Option<(usize, usize)>,
    pub problem: String,
}

/// Parses any case type from YAML, reporting the line and column of what is wrong.
pub fn parse_yaml<T: serde::de::DeserializeOwned>(path: &str, text: &str) -> Result<T, CaseError> {
    serde_yaml::from_str(text).map_err(|e| CaseError {
        path: path.to_string(),
        location: e.location().map(|l| (l.line(), l.column())),
        problem: e.to_string(),
    })
}

impl Intent {
    /// The VUIDs a verdict must hold for this intent, sorted.
    pub fn expected_vuids(&self) -> Vec<String> {
        match self {
            Intent::Valid => vec![],
            Intent::Violates { vuid, also } => {
                let mut v: Vec<String> = std::iter::once(vuid.clone())
                    .chain(also.iter().cloned())
                    .collect();
                v.sort();
                v.dedup();
                v
            }
        }
    }
}

impl Case {
    /// Parses a case from YAML, reporting the line and column of what is wrong.
    pub fn from_yaml(path: &str, text: &str) -> Result<Case, CaseError> {
        parse_yaml(path, text)
    }

    pub fn to_yaml(&self) -> String {
        serde_yaml::to_string(self).expect("a case always serialises")
    }

    /// The VUIDs the case expects its verdict to hold, sorted.
    pub fn expected_vuids(&self) -> Vec<String> {
        self.intent.expected_vuids()
    }
}
