//! Merging the folders of a sharded run (`rtconf run --shard I/N` on N machines) into one: one
//! `results.jsonl`, `caselist.txt`, `summary.json`, `junit.xml`, the case files and details, and the
//! HTML report — what one unsharded run would have written.

use crate::details::{CASE_FOLDERS, DETAILS_FILE};
use crate::error::SessionError;
use crate::report::{summarise, write_junit, RunIdentity, Summary};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};

/// What a merge did, besides the files it wrote.
#[derive(Debug)]
pub struct Merged {
    pub summary: Summary,
    /// Things a person should know (shards not all present, inputs without a case list).
    pub notes: Vec<String>,
    /// Whether every shard of the sharded run is among the inputs, and every line of their results
    /// was read.
    pub complete: bool,
    /// Where the HTML report went, or why it could not be written.
    pub report: Result<PathBuf, String>,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> SessionError + '_ {
    move |e| SessionError::io(path.display().to_string(), e)
}

/// Copies every file of `from` into `to` (one level: the case folders hold files only).
fn copy_files(from: &Path, to: &Path) -> Result<(), SessionError> {
    let Ok(entries) = std::fs::read_dir(from) else {
        return Ok(());
    };
    std::fs::create_dir_all(to).map_err(io(to))?;
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_file() {
            let dest = to.join(entry.file_name());
            std::fs::copy(&path, &dest).map_err(io(&dest))?;
        }
    }
    Ok(())
}

/// Merges the run folders `inputs` into `out`; see the module documentation. The inputs must be runs
/// of one driver, profile and registry, and no case may appear in two of them.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<Merged, SessionError> {
    if inputs.is_empty() {
        return Err(SessionError::Usage("merge: no run folders given".into()));
    }
    let mut notes = Vec::new();
    let mut summaries = Vec::new();
    for dir in inputs {
        if dir.canonicalize().ok() == out.canonicalize().ok() {
            return Err(SessionError::Usage(format!(
                "merge: --out {} is one of the inputs",
                out.display()
            )));
        }
        summaries.push(Summary::read_finished(dir)?);
    }
    let first = &summaries[0];
    for (dir, s) in inputs.iter().zip(&summaries) {
        if (&s.driver, &s.profile, &s.registry) != (&first.driver, &first.profile, &first.registry)
        {
            return Err(SessionError::Usage(format!(
                "merge: {} is a run of driver {} profile {} registry {}, {} one of driver {} profile {} registry {}",
                dir.display(),
                s.driver,
                s.profile,
                s.registry.as_deref().unwrap_or("?"),
                inputs[0].display(),
                first.driver,
                first.profile,
                first.registry.as_deref().unwrap_or("?"),
            )));
        }
    }
    let shards: BTreeSet<String> = summaries.iter().filter_map(|s| s.shard.clone()).collect();
    let mut complete = true;
    if let Some(count) = shards
        .iter()
        .next()
        .and_then(|s| s.split_once('/'))
        .and_then(|(_, n)| n.parse::<u32>().ok())
    {
        let want: BTreeSet<String> = (1..=count).map(|i| format!("{i}/{count}")).collect();
        let absent: Vec<&String> = want.difference(&shards).collect();
        if !absent.is_empty() {
            complete = false;
            notes.push(format!(
                "shard(s) {} of {count} are not among the inputs",
                absent
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    std::fs::create_dir_all(out).map_err(io(out))?;
    let results_path = out.join("results.jsonl");
    let mut results =
        std::io::BufWriter::new(std::fs::File::create(&results_path).map_err(io(&results_path))?);
    let mut seen: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut left_out = false;
    for dir in inputs {
        let path = dir.join("results.jsonl");
        for (n, line) in crate::results::text_lines(&path)?.enumerate() {
            let line = match line {
                Ok(line) => line,
                Err(e) if vk_registry::input::is_not_utf8(&e) => {
                    notes.push(format!(
                        "{}:{}: not a result line ({e}); left out",
                        path.display(),
                        n + 1
                    ));
                    left_out = true;
                    continue;
                }
                Err(e) => return Err(SessionError::io(format!("{}:{}", path.display(), n + 1), e)),
            };
            if line.trim().is_empty() {
                continue;
            }
            let Ok(parsed) = serde_json::from_str::<crate::results::ResultLine>(&line) else {
                notes.extend(
                    crate::results::unreadable_line(&path, n + 1, &line)
                        .map(|problem| format!("{problem}; left out")),
                );
                // A case the merged run cannot show: it is not complete.
                left_out = true;
                continue;
            };
            if let Some(other) = seen.insert(parsed.report.case.clone(), dir.clone()) {
                return Err(SessionError::Usage(format!(
                    "merge: case {} is in both {} and {} (the shards overlap)",
                    parsed.report.case,
                    other.display(),
                    dir.display()
                )));
            }
            writeln!(results, "{line}").map_err(io(&results_path))?;
        }
    }
    results.flush().map_err(io(&results_path))?;
    drop(results);
    let mut planned: Option<Vec<String>> = Some(Vec::new());
    for dir in inputs {
        match crate::outdir::read_run_text(&dir.join("caselist.txt")) {
            Ok(text) => {
                if let Some(p) = planned.as_mut() {
                    p.extend(text.lines().filter(|l| !l.is_empty()).map(String::from));
                }
            }
            Err(e) => {
                notes.push(if e.kind() == std::io::ErrorKind::NotFound {
                    format!(
                        "{} has no caselist.txt: missing cases are not counted",
                        dir.display()
                    )
                } else {
                    format!(
                        "{}: {e}: missing cases are not counted",
                        dir.join("caselist.txt").display()
                    )
                });
                planned = None;
            }
        }
    }
    if let Some(p) = &planned {
        let path = out.join("caselist.txt");
        std::fs::write(
            &path,
            p.iter().map(|n| format!("{n}\n")).collect::<String>(),
        )
        .map_err(io(&path))?;
    }
    let mut details = Vec::new();
    for dir in inputs {
        for folder in CASE_FOLDERS {
            copy_files(&dir.join(folder), &out.join(folder))?;
        }
        // Whole lines only: a torn last line of one input must not run into the next one's first.
        if let Ok(text) = crate::outdir::read_run_file(&dir.join(DETAILS_FILE)) {
            details.extend_from_slice(&text[..crate::outdir::whole_lines(&text)]);
        }
    }
    if !details.is_empty() {
        let path = out.join(DETAILS_FILE);
        crate::outdir::write_atomically(&path, &details).map_err(io(&path))?;
    }
    let who = RunIdentity {
        driver: first.driver.clone(),
        profile: first.profile.clone(),
        registry: first.registry.clone(),
        shard: None,
    };
    let mut summary = summarise(&results_path, planned.as_deref(), &who)?;
    summary.skipped = summaries.iter().map(|s| s.skipped).sum();
    let mut files: Vec<String> = summaries
        .iter()
        .flat_map(|s| s.expectations.clone())
        .collect();
    files.sort();
    files.dedup();
    summary.expectations = files;
    // The farm's wall time is its slowest shard's; memory is per machine.
    summary.seconds = summaries.iter().map(|s| s.seconds).fold(0.0, f64::max);
    summary.runner_peak_rss_kib = summaries.iter().filter_map(|s| s.runner_peak_rss_kib).max();
    // CPU adds up over the shards' runners (a shard without the figure leaves the sum unknown).
    summary.runner_cpu_seconds = summaries.iter().map(|s| s.runner_cpu_seconds).sum();
    summary.write(&out.join("summary.json"))?;
    write_junit(&results_path, &out.join("junit.xml"), &summary)?;
    let report = crate::html::write_report(out).map_err(|e| e.to_string());
    Ok(Merged {
        summary,
        notes,
        complete: complete && !left_out,
        report,
    })
}
