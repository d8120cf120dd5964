//! A run's output directory: a new run starts it clean (the files of an earlier run into the same
//! `--out` are removed, never mixed in); a resumed run must have been started with the same parameters
//! (`run.json`), and first repairs what a stop left (a torn last line of `results.jsonl` and of
//! `details.jsonl`, half-written failure files). Failure files are written whole or not at all (a
//! temporary file, then a rename).

use crate::compare::CaseReport;
use crate::error::SessionError;
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The most bytes read of one file a run folder holds whole (`run.json`, `summary.json`,
/// `caselist.txt`, `details.jsonl`, `results.jsonl` where a resumed run repairs it): a run of a
/// million cases writes some hundreds of megabytes.
pub const RUN_FILE_LIMIT: u64 = 2048 * vk_registry::input::MIB;

/// [`RUN_FILE_LIMIT`]'s read of a run folder's file.
pub fn read_run_file(path: &Path) -> std::io::Result<Vec<u8>> {
    vk_registry::input::read_at_most(path, RUN_FILE_LIMIT, "a file of a run folder")
}

/// [`read_run_file`] as text.
pub fn read_run_text(path: &Path) -> std::io::Result<String> {
    vk_registry::input::read_text_at_most(path, RUN_FILE_LIMIT, "a file of a run folder")
}

/// What makes a run the run it is: the parameters that decide which cases it makes and how it judges
/// them (not `--jobs`, `--timeout`, `--shrink`, which a resume may change). Field names are the
/// command line's flags.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RunParameters {
    pub driver: String,
    pub profile: String,
    /// `--command`, as given (empty: the default commands).
    pub command: Vec<String>,
    /// `--vuid`, as given.
    pub vuid: Vec<String>,
    pub valid_only: bool,
    pub seed: u64,
    pub count: usize,
    /// `--rendered`: rendered-scene cases per trace command.
    #[serde(default)]
    pub rendered: usize,
    /// `--from`, as given.
    pub from: Vec<String>,
    /// The registry version the rules were read from.
    pub registry: Option<String>,
    /// `--triage`, as given.
    pub triage: Vec<String>,
    /// `--cases`, `--shard`, `--baseline`, `--skips`, `--flakes`, as given.
    pub cases: Option<String>,
    pub shard: Option<String>,
    pub baseline: Option<String>,
    pub skips: Option<String>,
    pub flakes: Option<String>,
    /// `--inject KIND:SIZE`, as given.
    #[serde(default)]
    pub inject: Option<String>,
}

/// The files a run writes into its directory (besides its folders).
const RUN_FILES: [&str; 6] = [
    "results.jsonl",
    crate::details::DETAILS_FILE,
    "summary.json",
    "junit.xml",
    "run.json",
    "caselist.txt",
];

/// The file a run holds locked in its folder while it writes there ([`lock`]).
pub const LOCK_FILE: &str = ".rtconf-run.lock";

/// A run's hold on its folder: while it lives, another run into the same folder is refused.
#[derive(Debug)]
pub struct RunLock {
    _file: Option<std::fs::File>,
}

/// Makes `out` if it is not there and takes its [`LOCK_FILE`] for this process, or refuses where
/// another run holds it: two runs into one folder (the default `out/run`, two terminals) would clear
/// and append to each other's files. The lock goes with the process, however it ends. A folder no
/// run made ([`prepare`] refuses it) is left untouched, with no lock taken.
pub fn lock(out: &Path) -> Result<RunLock, SessionError> {
    use std::os::unix::io::AsRawFd;
    if !out.join("run.json").exists() && holds_anything(out)? {
        return Ok(RunLock { _file: None });
    }
    std::fs::create_dir_all(out).map_err(io(out))?;
    let path = out.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(io(&path))?;
    // SAFETY: flock on a descriptor this function owns; it reads no memory.
    if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
        let e = std::io::Error::last_os_error();
        return Err(if e.kind() == std::io::ErrorKind::WouldBlock {
            SessionError::Usage(format!(
                "--out {}: another rtconf run is writing this folder (it holds {LOCK_FILE}); wait for it to end or choose another --out",
                out.display()
            ))
        } else {
            io(&path)(e)
        });
    }
    Ok(RunLock { _file: Some(file) })
}

/// Whether `dir` exists and has an entry besides a run's [`LOCK_FILE`] (a file where a folder should
/// be counts).
fn holds_anything(dir: &Path) -> Result<bool, SessionError> {
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(io(dir)(e)),
        Ok(m) if !m.is_dir() => Ok(true),
        Ok(_) => {
            for entry in std::fs::read_dir(dir).map_err(io(dir))? {
                if entry.map_err(io(dir))?.file_name() != LOCK_FILE {
                    return Ok(true);
                }
            }
            Ok(false)
        }
    }
}

/// The folders a run writes into its directory: the case files it keeps, the report.
fn run_folders() -> impl Iterator<Item = &'static str> {
    crate::details::CASE_FOLDERS.into_iter().chain(["report"])
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SessionError + '_ {
    move |e| SessionError::io(path.display().to_string(), e)
}

/// Makes `out` ready for a run with `params` and returns the cases already done (empty unless
/// `resume`). A new run removes the files an earlier run left; a resumed one refuses parameters that
/// differ from `run.json`'s, naming the first that does. A folder that holds anything but no
/// `run.json` is refused before anything in it is touched: the files and folders a run clears
/// (`failures/`, `report/`, `summary.json`, ...) are then not known to be a run's.
pub fn prepare(
    out: &Path,
    params: &RunParameters,
    resume: bool,
) -> Result<BTreeSet<String>, SessionError> {
    let failures = out.join("failures");
    let results = out.join("results.jsonl");
    let run_json = out.join("run.json");
    if resume && run_json.exists() {
        std::fs::create_dir_all(&failures).map_err(io(&failures))?;
        let text = read_run_text(&run_json).map_err(io(&run_json))?;
        let before: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            SessionError::Usage(format!(
                "{}: {e}; start the run again without --resume",
                run_json.display()
            ))
        })?;
        differing(&before, params).map_or(Ok(()), |(flag, was, now)| {
            Err(SessionError::Usage(format!(
                "--resume with {flag} {now}, but the run in {} was started with {flag} {was}; resume with the same {flag}, or start again without --resume",
                out.display()
            )))
        })?;
        for folder in run_folders() {
            let dir = out.join(folder);
            if dir.is_dir() {
                clear_partial_failures(&dir)?;
            }
        }
        repair_results(&results)?;
        cut_torn_line(&out.join(crate::details::DETAILS_FILE))?;
        return Ok(done_cases(&results));
    }
    if resume && results.exists() {
        return Err(SessionError::Usage(format!(
            "--resume: {} has results but no run.json, so which run they belong to is unknown; start again without --resume",
            out.display()
        )));
    }
    if !run_json.exists() && holds_anything(out)? {
        return Err(SessionError::Usage(format!(
            "--out {}: the folder holds files but no run.json, so no rtconf run made it; a run clears \
             its own files and folders there (failures/, report/, summary.json, ...), so it writes \
             only into a new or empty folder or one an earlier run made",
            out.display()
        )));
    }
    for f in RUN_FILES {
        let p = out.join(f);
        match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io(&p)(e)),
            _ => {}
        }
    }
    for folder in run_folders() {
        let dir = out.join(folder);
        match std::fs::remove_dir_all(&dir) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io(&dir)(e)),
            _ => {}
        }
    }
    std::fs::create_dir_all(&failures).map_err(io(&failures))?;
    let text = serde_json::to_string_pretty(params).unwrap_or_default() + "\n";
    write_atomically(&run_json, text.as_bytes()).map_err(io(&run_json))?;
    Ok(BTreeSet::new())
}

/// The first parameter whose value differs: its flag, the value in `run.json`, the value now.
fn differing(before: &serde_json::Value, now: &RunParameters) -> Option<(String, String, String)> {
    let now = serde_json::to_value(now).ok()?;
    let now = now.as_object()?;
    for (k, v) in now {
        let was = before.get(k).cloned().unwrap_or(serde_json::Value::Null);
        if &was != v {
            let show = |v: &serde_json::Value| match v {
                serde_json::Value::String(s) => s.clone(),
                serde_json::Value::Null => "(none)".into(),
                other => other.to_string(),
            };
            return Some((format!("--{}", k.replace('_', "-")), show(&was), show(v)));
        }
    }
    None
}

/// The length of the whole lines at the start of `bytes`: up to and with its last newline.
pub(crate) fn whole_lines(bytes: &[u8]) -> usize {
    bytes
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |at| at + 1)
}

/// Cuts a file of lines after its last newline (a line an interrupted run left unfinished), so
/// that lines appended next start on a line of their own. A missing file is left missing.
fn cut_torn_line(path: &Path) -> Result<(), SessionError> {
    let bytes = match read_run_file(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io(path)(e)),
    };
    let whole = whole_lines(&bytes);
    if whole < bytes.len() {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io(path))?;
        f.set_len(whole as u64).map_err(io(path))?;
    }
    Ok(())
}

/// Cuts `results.jsonl` after its last complete line that is a case's report: a stop in the middle of
/// a write (a kill, a full disk) leaves a torn last line, and a resumed run must append after a whole
/// one. Returns the bytes dropped.
pub fn repair_results(path: &Path) -> Result<u64, SessionError> {
    let bytes = match read_run_file(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io(path)(e)),
    };
    let mut keep = 0usize;
    let mut at = 0usize;
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        at += line.len();
        let whole = line.ends_with(b"\n");
        let parses = std::str::from_utf8(line)
            .ok()
            .is_some_and(|l| serde_json::from_str::<CaseReport>(l.trim_end()).is_ok());
        if whole && parses {
            keep = at;
        } else if whole && line.iter().all(|b| b.is_ascii_whitespace()) {
            continue;
        }
    }
    let dropped = (bytes.len() - keep) as u64;
    if dropped > 0 {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io(path))?;
        f.set_len(keep as u64).map_err(io(path))?;
        f.sync_all().map_err(io(path))?;
    }
    Ok(dropped)
}

/// Removes what a stopped run may have left in one of its folders: temporary files and empty files.
fn clear_partial_failures(failures: &Path) -> Result<(), SessionError> {
    for e in std::fs::read_dir(failures).map_err(io(failures))? {
        let p = e.map_err(io(failures))?.path();
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let empty = std::fs::metadata(&p).is_ok_and(|m| m.is_file() && m.len() == 0);
        if name.ends_with(".tmp") || empty {
            std::fs::remove_file(&p).map_err(io(&p))?;
        }
    }
    Ok(())
}

/// The cases `results.jsonl` holds.
fn done_cases(results: &Path) -> BTreeSet<String> {
    match crate::report::reports(results) {
        Ok(r) => r.map(|r| r.case).collect(),
        Err(_) => BTreeSet::new(),
    }
}

/// Writes `bytes` to `path` whole or not at all: into `.NAME.tmp` beside it, then renamed over it;
/// on any error the temporary file is removed and `path` is untouched. Not synced to the disk: the
/// rename is whole for every reader and survives the process being killed, which is what a run
/// folder needs (it is not kept across a power loss), and a sync per kept case made the run wait on
/// the disk for every case that did not pass.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp: PathBuf = path.with_file_name(format!(".{name}.tmp"));
    let written = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> RunParameters {
        RunParameters {
            driver: "lavapipe".into(),
            profile: "lavapipe".into(),
            command: vec![],
            vuid: vec![],
            valid_only: false,
            seed: 1,
            count: 4,
            rendered: 0,
            from: vec![],
            registry: Some("1.3.239".into()),
            triage: vec![],
            cases: None,
            shard: None,
            baseline: None,
            skips: None,
            flakes: None,
            inject: None,
        }
    }

    const LINE: &str = r#"{"case":"a","command":"vkCmdTraceRaysKHR","target":null,"outcome":"pass","model":[],"layer":[],"millis":1.0}"#;

    /// A folder whose run wrote run.json and stopped: no result yet is an error naming how to finish
    /// the run; with results, the summary of those (not finished), from run.json's identity; a
    /// merge refuses it either way; once summary.json is there the folder is a finished run's.
    #[test]
    fn a_stopped_run_is_summarised_from_its_results_and_never_taken_for_finished() {
        use crate::report::Summary;
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        prepare(out, &params(), false).unwrap();
        let e = Summary::of_folder(out).unwrap_err().to_string();
        assert!(
            e.contains("did not finish") && e.contains("no result yet"),
            "{e}"
        );
        std::fs::write(out.join("results.jsonl"), format!("{LINE}\n")).unwrap();
        let (s, finished) = Summary::of_folder(out).unwrap();
        assert!(!finished);
        assert_eq!((s.cases, s.passed), (1, 1));
        assert_eq!(
            (s.driver.as_str(), s.registry.as_deref()),
            ("lavapipe", Some("1.3.239"))
        );
        let e = Summary::read_finished(out).unwrap_err().to_string();
        assert!(e.contains("--resume"), "{e}");
        s.write(&out.join("summary.json")).unwrap();
        assert!(Summary::of_folder(out).unwrap().1);
        assert_eq!(Summary::read_finished(out).unwrap(), s);
    }

    #[test]
    fn a_torn_last_line_is_cut_and_whole_lines_are_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("results.jsonl");
        let torn = &LINE[..40];
        std::fs::write(&p, format!("{LINE}\n{LINE}\n{torn}")).unwrap();
        assert_eq!(repair_results(&p).unwrap(), torn.len() as u64);
        assert_eq!(
            std::fs::read_to_string(&p).unwrap(),
            format!("{LINE}\n{LINE}\n")
        );
        assert_eq!(repair_results(&p).unwrap(), 0, "a whole file is left alone");
        // A last line that ends but is not a report (written half, then a newline) goes too.
        std::fs::write(&p, format!("{LINE}\n{torn}\n")).unwrap();
        repair_results(&p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), format!("{LINE}\n"));
    }

    #[test]
    fn a_torn_details_line_is_cut_so_the_next_line_starts_whole() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(crate::details::DETAILS_FILE);
        let line = crate::details::details_line("a", &Default::default());
        std::fs::write(&p, format!("{line}{}", &line[..10])).unwrap();
        cut_torn_line(&p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), line);
        cut_torn_line(&p).unwrap();
        assert_eq!(
            std::fs::read_to_string(&p).unwrap(),
            line,
            "whole lines stay"
        );
        let read = crate::details::read_details(dir.path());
        assert_eq!(read.len(), 1);
        assert!(read.contains_key("a"));
    }

    #[test]
    fn a_new_run_removes_what_an_earlier_run_left() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        std::fs::create_dir_all(out.join("failures")).unwrap();
        for f in [
            "results.jsonl",
            "details.jsonl",
            "summary.json",
            "junit.xml",
            "failures/old-case.yaml",
        ] {
            std::fs::write(out.join(f), "x").unwrap();
        }
        std::fs::write(out.join("keep.txt"), "not the run's").unwrap();
        // The run that left them.
        std::fs::write(out.join("run.json"), "{}").unwrap();
        assert!(prepare(out, &params(), false).unwrap().is_empty());
        assert!(!out.join("results.jsonl").exists());
        assert!(!out.join("details.jsonl").exists());
        assert!(!out.join("failures/old-case.yaml").exists());
        assert!(
            out.join("keep.txt").exists(),
            "only the run's own files are removed"
        );
        let stored: RunParameters =
            serde_json::from_str(&std::fs::read_to_string(out.join("run.json")).unwrap()).unwrap();
        assert_eq!(stored, params());
    }

    #[test]
    fn a_second_run_into_a_locked_folder_is_refused_until_the_first_ends() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        let first = lock(&out).unwrap();
        // The lock file alone does not make the folder someone else's.
        assert!(prepare(&out, &params(), false).unwrap().is_empty());
        let e = lock(&out).unwrap_err().to_string();
        assert!(
            e.contains("another rtconf run is writing this folder"),
            "{e}"
        );
        drop(first);
        let again = lock(&out).unwrap();
        assert!(prepare(&out, &params(), false).unwrap().is_empty());
        drop(again);
        // A folder no run made gets no lock file: prepare refuses it untouched.
        let foreign = dir.path().join("foreign");
        std::fs::create_dir(&foreign).unwrap();
        std::fs::write(foreign.join("mine.txt"), "a user's own").unwrap();
        let _none = lock(&foreign).unwrap();
        assert!(!foreign.join(LOCK_FILE).exists());
        assert!(prepare(&foreign, &params(), false).is_err());
    }

    #[test]
    fn a_folder_no_run_made_is_refused_and_left_as_it_is() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        std::fs::create_dir_all(out.join("report")).unwrap();
        std::fs::write(out.join("report/mine.html"), "a user's own").unwrap();
        std::fs::write(out.join("summary.json"), "a user's own").unwrap();
        let e = prepare(out, &params(), false).unwrap_err().to_string();
        assert!(e.contains("holds files but no run.json"), "{e}");
        assert!(out.join("report/mine.html").exists());
        assert!(out.join("summary.json").exists());
        assert!(!out.join("failures").exists());
        // A file where the folder should be is refused the same way.
        let file = out.join("summary.json");
        assert!(prepare(&file, &params(), false).is_err());
        // An empty folder, or one that is not there yet, is a new run's.
        let empty = out.join("empty");
        std::fs::create_dir(&empty).unwrap();
        assert!(prepare(&empty, &params(), false).unwrap().is_empty());
        assert!(prepare(&out.join("new/run"), &params(), false)
            .unwrap()
            .is_empty());
    }

    #[test]
    fn a_resume_with_other_parameters_is_refused_naming_the_parameter() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        prepare(out, &params(), false).unwrap();
        std::fs::write(out.join("results.jsonl"), format!("{LINE}\n")).unwrap();
        let e = prepare(
            out,
            &RunParameters {
                seed: 2,
                ..params()
            },
            true,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("--resume with --seed 2") && e.contains("started with --seed 1"),
            "{e}"
        );
        let e = prepare(
            out,
            &RunParameters {
                count: 9,
                ..params()
            },
            true,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--count 9") && e.contains("--count 4"), "{e}");
        let e = prepare(
            out,
            &RunParameters {
                valid_only: true,
                ..params()
            },
            true,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--valid-only"), "{e}");
        let done = prepare(out, &params(), true).unwrap();
        assert_eq!(done.into_iter().collect::<Vec<_>>(), ["a"]);
    }

    #[test]
    fn a_resume_clears_empty_and_temporary_failure_files() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        prepare(out, &params(), false).unwrap();
        std::fs::write(out.join("failures/empty.yaml"), "").unwrap();
        std::fs::write(out.join("failures/.half.yaml.tmp"), "name: ha").unwrap();
        std::fs::write(out.join("failures/whole.yaml"), "name: whole").unwrap();
        prepare(out, &params(), true).unwrap();
        assert!(!out.join("failures/empty.yaml").exists());
        assert!(!out.join("failures/.half.yaml.tmp").exists());
        assert!(out.join("failures/whole.yaml").exists());
    }

    #[test]
    fn results_without_run_json_are_not_resumed() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("results.jsonl"), format!("{LINE}\n")).unwrap();
        let e = prepare(dir.path(), &params(), true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no run.json"), "{e}");
    }

    #[test]
    fn an_atomic_write_that_fails_leaves_no_file() {
        // /dev/full accepts the open and refuses the bytes: the rename target is never made.
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("case.yaml");
        std::os::unix::fs::symlink("/dev/full", dir.path().join(".case.yaml.tmp")).unwrap();
        assert!(write_atomically(&target, b"name: x\n").is_err());
        assert!(!target.exists());
        write_atomically(&target, b"name: x\n").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "name: x\n");
    }
}
