//! The committed triage files: each parses in the directional form, every entry states evidence, and
//! every reproducing case it names (`cases/…yaml`) exists and reads as a case of the profile the file
//! was diagnosed on — the cases a full run replays for an entry its generated cases did not use.

use session::replay::read_case;
use session::Triage;

fn triage_files() -> Vec<std::path::PathBuf> {
    let dir = session::sources::repo_dir().join("triage");
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .expect("triage/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    v.sort();
    v
}

#[test]
fn every_triage_file_parses_and_every_evidence_case_reads() {
    let files = triage_files();
    assert!(
        files.iter().any(|f| f.ends_with("layer-1.3.239.yaml")),
        "{files:?}"
    );
    let root = session::sources::repo_dir();
    let mut cases = 0;
    for f in &files {
        let text = std::fs::read_to_string(f).expect("readable");
        let t = Triage::from_yaml(&f.display().to_string(), &text)
            .unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert!(!t.entries.is_empty(), "{}: no entries", f.display());
        for e in &t.entries {
            assert!(!e.evidence.is_empty(), "{}: no evidence", e.id());
            for ev in e.evidence.iter().filter(|ev| ev.starts_with("cases/")) {
                let case = read_case(&root.join(ev))
                    .unwrap_or_else(|err| panic!("{}: evidence {ev}: {err}", e.id()));
                assert_eq!(case.profile, "lavapipe", "{}: {ev}", e.id());
                assert!(
                    e.commands.contains(&case.command()),
                    "{}: {ev} is a case of {}, not of the entry's commands",
                    e.id(),
                    case.command()
                );
                cases += 1;
            }
        }
    }
    assert!(cases >= 20, "only {cases} reproducing cases named");
}
