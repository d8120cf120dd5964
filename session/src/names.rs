//! Names given on the command line, resolved before anything runs: a `--vuid` is a full id, a glob
//! (`VUID-vkCmdTraceRaysIndirectKHR-*`, `*-03686`) or a short id (`03686`, `stride-03686`) that
//! expands to the matching VUIDs; a `--command` of `rtconf registry` is a scope the registry has. A
//! name that matches nothing is an error naming the nearest known names, never a run of 0 cases.

use crate::error::SessionError;

/// One `--vuid` and the VUIDs it stands for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Expanded {
    pub pattern: String,
    pub vuids: Vec<String>,
}

/// Expands each pattern against `known` (sorted, unique ids); an error for the first that matches
/// none.
pub fn expand_vuids(patterns: &[String], known: &[String]) -> Result<Vec<Expanded>, SessionError> {
    patterns
        .iter()
        .map(|p| {
            let vuids: Vec<String> = known.iter().filter(|k| matches(p, k)).cloned().collect();
            if vuids.is_empty() {
                Err(SessionError::Usage(format!(
                    "--vuid `{}` matches no VUID of the rule table{}",
                    vk_registry::error::excerpt(p),
                    nearest_hint(p, known.iter().map(String::as_str))
                )))
            } else {
                Ok(Expanded {
                    pattern: p.clone(),
                    vuids,
                })
            }
        })
        .collect()
}

/// Whether `pattern` names `id`: a glob (`*` any run, `?` one character) against the whole id, a full
/// id exactly, or a short id (no `VUID-` prefix) as the id's last dash-separated parts.
pub fn matches(pattern: &str, id: &str) -> bool {
    if pattern.contains(['*', '?']) {
        glob(pattern.as_bytes(), id.as_bytes())
    } else if pattern.starts_with("VUID-") {
        pattern == id
    } else {
        id.ends_with(pattern) && id[..id.len() - pattern.len()].ends_with('-')
    }
}

fn glob(p: &[u8], s: &[u8]) -> bool {
    // Iterative matching with one backtrack point for the last `*`.
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < s.len() {
        if i < p.len() && (p[i] == b'?' || p[i] == s[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == b'*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == b'*')
}

/// Checks a `--command` of `rtconf registry` against the scopes the registry defines VUIDs for.
pub fn known_scope<'a>(
    name: &str,
    scopes: impl Iterator<Item = &'a str> + Clone,
) -> Result<(), SessionError> {
    if scopes.clone().any(|s| s == name) {
        Ok(())
    } else {
        Err(SessionError::Usage(format!(
            "--command `{}` is no command or structure the registry defines VUIDs for{}",
            vk_registry::error::excerpt(name),
            nearest_hint(name, scopes)
        )))
    }
}

/// The longest name a hint is looked for: every VUID, command and structure name is far shorter, and
/// the edit distance takes time in proportion to the name's length for every known name.
const HINTED_NAME_LEN: usize = 256;

/// `; nearest: A, B, C` with the known names closest to `name` (edit distance), or nothing (also for a
/// name longer than [`HINTED_NAME_LEN`] characters, which no known name is near).
fn nearest_hint<'a>(name: &str, known: impl Iterator<Item = &'a str>) -> String {
    if name.chars().count() > HINTED_NAME_LEN {
        return String::new();
    }
    let mut scored: Vec<(usize, &str)> = known.map(|k| (distance(name, k), k)).collect();
    scored.sort();
    scored.dedup();
    let near: Vec<&str> = scored.iter().take(3).map(|(_, k)| *k).collect();
    if near.is_empty() {
        String::new()
    } else {
        format!("; nearest: {}", near.join(", "))
    }
}

/// Levenshtein distance between two names, by characters; for short ids the distance to the id's tail
/// of the same length counts, so `0368` is near `...-stride-03686`.
fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let full = levenshtein(&a, &b);
    if b.len() > a.len() && !a.starts_with(&['V', 'U', 'I', 'D', '-']) {
        full.min(levenshtein(&a, &b[b.len() - a.len()..]))
    } else {
        full
    }
}

fn levenshtein(a: &[char], b: &[char]) -> usize {
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let here = row[j + 1];
            row[j + 1] = (prev + (ca != cb) as usize).min(row[j] + 1).min(here + 1);
            prev = here;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_far_longer_than_any_known_is_quoted_cut_and_given_no_hint_at_once() {
        // 100,000 characters against every known name took 49 s for `registry vuids --command`.
        let long = "x".repeat(100_000);
        let known: Vec<String> = (0..2000).map(|i| format!("VkStructureNumber{i}")).collect();
        let started = std::time::Instant::now();
        let e = known_scope(&long, known.iter().map(String::as_str))
            .unwrap_err()
            .to_string();
        assert!(started.elapsed().as_secs() < 2, "{:?}", started.elapsed());
        assert!(!e.contains("nearest"), "{e}");
        assert!(e.len() < 400, "the name is quoted whole: {} bytes", e.len());
        let e = expand_vuids(&[long], &known).unwrap_err().to_string();
        assert!(e.len() < 400, "{} bytes", e.len());
    }

    fn known() -> Vec<String> {
        [
            "VUID-vkCmdTraceRaysIndirectKHR-stride-03686",
            "VUID-vkCmdTraceRaysIndirectKHR-stride-03694",
            "VUID-vkCmdTraceRaysKHR-stride-03686x",
            "VUID-vkCmdTraceRaysNV-None-02700",
        ]
        .map(String::from)
        .to_vec()
    }

    #[test]
    fn full_ids_globs_and_short_ids_expand() {
        let k = known();
        let e = expand_vuids(
            &[
                "VUID-vkCmdTraceRaysNV-None-02700".into(),
                "VUID-vkCmdTraceRaysIndirectKHR-*".into(),
                "03686".into(),
                "stride-03694".into(),
                "*-0369?".into(),
            ],
            &k,
        )
        .unwrap();
        let n: Vec<usize> = e.iter().map(|x| x.vuids.len()).collect();
        assert_eq!(n, [1, 2, 1, 1, 1]);
        assert_eq!(e[2].vuids, ["VUID-vkCmdTraceRaysIndirectKHR-stride-03686"]);
    }

    #[test]
    fn a_name_that_matches_nothing_is_an_error_with_the_nearest_names() {
        let e = expand_vuids(
            &["VUID-vkCmdTraceRaysIndirectKHR-stride-03868".into()],
            &known(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("matches no VUID"), "{e}");
        assert!(
            e.contains("nearest: VUID-vkCmdTraceRaysIndirectKHR-stride-03686"),
            "{e}"
        );
        let e = expand_vuids(&["0368".into()], &known())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("nearest: VUID-vkCmdTraceRaysIndirectKHR-stride-03686"),
            "{e}"
        );
        assert!(expand_vuids(&["VUID-x-*-99999".into()], &known()).is_err());
    }

    #[test]
    fn unknown_scopes_are_errors_with_the_nearest_scopes() {
        let scopes = ["vkCmdTraceRaysKHR", "vkCmdTraceRaysNV"];
        assert!(known_scope("vkCmdTraceRaysNV", scopes.iter().copied()).is_ok());
        let e = known_scope("vkCmdBogus", scopes.iter().copied())
            .unwrap_err()
            .to_string();
        assert!(e.contains("`vkCmdBogus`") && e.contains("nearest: "), "{e}");
    }
}
