//! Choosing what a run runs: a deterministic shard of the cases by name (`--shard I/N`, for CI farms),
//! the skips list, and a folder of case files (`--cases DIR`) instead of generated cases.

use crate::baseline::Expectations;
use crate::error::SessionError;
use model::Case;
use std::path::{Path, PathBuf};

/// Which cases a run runs and what it expects of them.
#[derive(Debug, Clone, Default)]
pub struct Selection {
    /// Run the case files of this folder instead of generating cases.
    pub cases: Option<PathBuf>,
    /// Run only this shard of the cases.
    pub shard: Option<Shard>,
    /// Expected failures (see [`crate::baseline`]).
    pub baseline: Option<PathBuf>,
    /// Cases not to run.
    pub skips: Option<PathBuf>,
    /// Known flaky cases.
    pub flakes: Option<PathBuf>,
    /// Times a failing, crashing or timed-out case is run again to tell a flake.
    pub retries: usize,
}

impl Selection {
    /// The baseline, skips and flakes files, read.
    /// Whether every planned case runs (no case folder, no shard, no skips list): only such a run can
    /// call a triage entry stale.
    pub fn is_whole_plan(&self) -> bool {
        self.cases.is_none() && self.shard.is_none() && self.skips.is_none()
    }

    pub fn expectations(&self) -> Result<Expectations, SessionError> {
        Expectations::load(
            self.baseline.as_deref(),
            self.skips.as_deref(),
            self.flakes.as_deref(),
        )
    }
}

/// Shard `index` (from 1) of `count`: the cases whose name hashes to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// Parses `I/N` with 1 ≤ I ≤ N.
    pub fn parse(text: &str) -> Result<Shard, SessionError> {
        let bad = || {
            SessionError::Usage(format!(
                "--shard `{text}`: expected I/N with 1 <= I <= N (`--shard 2/4` runs the second of four shards)"
            ))
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<u32>().map_err(|_| bad())?,
            n.trim().parse::<u32>().map_err(|_| bad())?,
        );
        if index == 0 || count == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// Whether the case named `name` belongs to this shard: FNV-1a of the name, modulo the count —
    /// the same on every machine and for every order the cases come in.
    pub fn holds(&self, name: &str) -> bool {
        fnv1a(name.as_bytes()) % self.count as u64 == (self.index - 1) as u64
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// 64-bit FNV-1a.
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The case files under `dir` (every `*.yaml`, in subfolders too), sorted by path.
fn case_files(dir: &Path) -> Result<Vec<PathBuf>, SessionError> {
    use std::os::unix::fs::MetadataExt;
    let mut out = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    // Each folder is walked once, by its device and inode: a link back up the tree (or two links to
    // one folder) would otherwise be walked again and again, exponentially for two links per level.
    // Entries are taken in name order, depth first, so the path a folder is found by is the first in
    // that order whatever order the file system lists them in.
    let mut walked = std::collections::BTreeSet::new();
    while let Some(d) = pending.pop() {
        let meta =
            std::fs::metadata(&d).map_err(|e| SessionError::io(d.display().to_string(), e))?;
        if !walked.insert((meta.dev(), meta.ino())) {
            continue;
        }
        let mut entries = std::fs::read_dir(&d)
            .and_then(|list| {
                list.map(|e| e.map(|e| e.path()))
                    .collect::<Result<Vec<_>, _>>()
            })
            .map_err(|e| SessionError::io(d.display().to_string(), e))?;
        entries.sort();
        let mut folders = Vec::new();
        for path in entries {
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|x| x == "yaml" || x == "yml") {
                out.push(path);
            }
        }
        pending.extend(folders.into_iter().rev());
    }
    out.sort();
    Ok(out)
}

/// Every case of a folder, sorted by path; a file that does not parse is an error with its line, and
/// two files of one case name are an error (results are kept by name).
pub fn read_case_folder(dir: &Path) -> Result<Vec<Case>, SessionError> {
    let files = case_files(dir)?;
    if files.is_empty() {
        return Err(SessionError::Usage(format!(
            "--cases {}: no *.yaml case files there",
            dir.display()
        )));
    }
    // Parsed on every core (a rendered case's YAML is large), then taken in path order, so the first
    // file at fault is the one reported.
    let read = read_all(&files);
    let mut cases: Vec<Case> = Vec::with_capacity(files.len());
    let mut seen = std::collections::BTreeMap::new();
    for (f, case) in files.into_iter().zip(read) {
        let case = case?;
        if let Some(first) = seen.insert(case.name.clone(), f.clone()) {
            return Err(SessionError::Usage(format!(
                "case name `{}` is used by both {} and {}",
                case.name,
                first.display(),
                f.display()
            )));
        }
        cases.push(case);
    }
    Ok(cases)
}

/// Each file read as a case ([`crate::replay::read_case`]), in the order of `files`, the files
/// shared out among the machine's cores.
fn read_all(files: &[std::path::PathBuf]) -> Vec<Result<Case, SessionError>> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(files.len())
        .max(1);
    let chunk = files.len().div_ceil(workers);
    std::thread::scope(|scope| {
        let parts: Vec<_> = files
            .chunks(chunk.max(1))
            .map(|part| {
                scope.spawn(move || {
                    part.iter()
                        .map(|f| crate::replay::read_case(f))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        parts
            .into_iter()
            .flat_map(|p| p.join().expect("reading case files does not panic"))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_names_deterministically() {
        let names: Vec<String> = (0..300).map(|i| format!("case-{i}")).collect();
        let shards: Vec<Shard> = (1..=3).map(|i| Shard { index: i, count: 3 }).collect();
        for n in &names {
            assert_eq!(shards.iter().filter(|s| s.holds(n)).count(), 1, "{n}");
        }
        // Roughly balanced, and fixed: FNV-1a, not a per-process hash.
        for s in &shards {
            let k = names.iter().filter(|n| s.holds(n)).count();
            assert!((60..=140).contains(&k), "shard {s} holds {k}");
        }
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn shard_arguments_parse_or_say_the_form() {
        assert_eq!(Shard::parse("2/4").unwrap(), Shard { index: 2, count: 4 });
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains("expected I/N"), "{bad}: {e}");
        }
    }

    #[test]
    fn links_back_up_a_case_folder_are_walked_once() {
        // Two links per level back to the top: without the walked set, 2^40 paths before the
        // system's link limit ends them.
        let dir = tempfile::tempdir().unwrap();
        let top = dir.path();
        std::fs::create_dir(top.join("sub")).unwrap();
        std::fs::write(top.join("sub/one.yaml"), "").unwrap();
        std::os::unix::fs::symlink(top, top.join("sub/up")).unwrap();
        std::os::unix::fs::symlink(top, top.join("again")).unwrap();
        std::os::unix::fs::symlink(top.join("sub"), top.join("sub-again")).unwrap();
        let files = case_files(top).unwrap();
        assert_eq!(files, [top.join("sub/one.yaml")]);
    }
}
