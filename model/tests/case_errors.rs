//! The errors of a case itself — a group the pipeline lacks, a buffer or structure name that resolves
//! to nothing, two buffers of one name — are refused by `Case::read` with the file, line, column and
//! YAML path of the value at fault, instead of being judged as violations a driver could be blamed for.

use model::Case;

fn root() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn committed(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap()
}

/// `text` with `from` replaced once by `to`.
fn edited(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "{from}");
    text.replacen(from, to, 1)
}

/// The 1-based line and column of the first occurrence of `needle`.
fn position_of(text: &str, needle: &str) -> (usize, usize) {
    let at = text.find(needle).unwrap();
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

const TRACE: &str = "cases/hand/trace-indirect-records-32.yaml";
const BUILD: &str = "cases/build/aabbs-valid.yaml";

#[test]
fn a_record_of_a_group_the_pipeline_lacks_is_an_error_of_the_case_at_its_handle() {
    let text = edited(
        &committed(TRACE),
        "handles: [!group 3]",
        "handles: [!group 99]",
    );
    let e = Case::read("t.yaml", &text).unwrap_err();
    assert_eq!(e.at, "world.buffers[0].contents[2].handles[0]", "{e}");
    assert_eq!(e.location, Some(position_of(&text, "!group 99")), "{e}");
    assert!(
        e.problem.contains("group 99") && e.problem.contains("4 group"),
        "{e}"
    );
    let (l, c) = e.location.unwrap();
    assert!(
        e.to_string().starts_with(&format!(
            "t.yaml:{l}:{c}: world.buffers[0].contents[2].handles[0]: "
        )),
        "{e}"
    );
    // The same text is still a case to the parser: the error is the case's, found after reading.
    assert!(Case::from_yaml("t.yaml", &text).is_ok());
}

#[test]
fn a_dangling_buffer_name_in_the_call_is_an_error_of_the_case() {
    let text = edited(
        &committed(TRACE),
        "indirect_address: { buffer: indirect",
        "indirect_address: { buffer: nosuch",
    );
    let e = Case::read("t.yaml", &text).unwrap_err();
    assert_eq!(e.at, "call.indirect_address.buffer", "{e}");
    assert_eq!(e.location, Some(position_of(&text, "nosuch")), "{e}");
    assert!(e.problem.contains("`nosuch`"), "{e}");
}

#[test]
fn dangling_names_in_a_build_case_are_errors_of_the_case() {
    let base = committed(BUILD);
    let e = Case::read(
        "b.yaml",
        &edited(&base, "buffer: storage", "buffer: nowhere"),
    )
    .unwrap_err();
    assert_eq!(e.at, "world.structures[0].buffer", "{e}");
    assert!(e.location.is_some(), "{e}");
    let e = Case::read("b.yaml", &edited(&base, "dst: dst", "dst: missing")).unwrap_err();
    assert_eq!(e.at, "call.infos[0].dst", "{e}");
    assert!(e.problem.contains("`missing`"), "{e}");
}

#[test]
fn two_buffers_of_one_name_are_an_error_of_the_case() {
    let text = edited(&committed(TRACE), "name: indirect", "name: sbt");
    let e = Case::read("t.yaml", &text).unwrap_err();
    assert_eq!(e.at, "world.buffers[1].name", "{e}");
    assert!(e.problem.contains("second buffer named `sbt`"), "{e}");
}

#[test]
fn every_committed_case_reads_without_errors_of_its_own() {
    let mut n = 0;
    for dir in [
        "cases/hand",
        "cases/edge",
        "cases/build",
        "cases/resources",
        "cases/regressions",
    ] {
        for e in std::fs::read_dir(root().join(dir)).unwrap() {
            let path = e.unwrap().path();
            if path.extension().is_none_or(|x| x != "yaml") {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            if let Err(e) = Case::read(&path.display().to_string(), &text) {
                panic!("{e}");
            }
            n += 1;
        }
    }
    assert!(n > 50, "{n}");
}

#[test]
fn a_parse_error_says_file_line_column_path_and_problem_once() {
    let text = edited(&committed(TRACE), "size: 256", "size: lots");
    let e = Case::read("t.yaml", &text).unwrap_err();
    assert_eq!(
        e.location.map(|l| l.0),
        Some(position_of(&text, "lots").0),
        "{e}"
    );
    assert!(e.at.starts_with("world.buffers[0]"), "{e:?}");
    assert!(
        !e.problem.contains(" at line "),
        "the position is said once: {e}"
    );
}
