//! Coverage of `vkCmdBuildAccelerationStructuresIndirectKHR` in every registry version the project
//! reads: each VUID has a row, at least 90% are executable, and the rest carry a reason.

use model::rules::{RuleSet, Status};
use std::path::{Path, PathBuf};

const COMMAND: model::CommandId = model::CommandId::BuildAccelerationStructuresIndirect;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The sources that exist on this machine (the installed registry, the fetched 1.4.309, the seeds).
fn sources() -> Vec<PathBuf> {
    let mut v = vec![
        PathBuf::from("/usr/share/vulkan/registry"),
        root().join("target/registry/1.4.309/usr/share/vulkan/registry"),
    ];
    for seed in ["002_12e97309a51e20bc.txt", "004_f017a595566d4eea.txt"] {
        v.push(PathBuf::from("/work/shared/seeds").join(seed));
    }
    v.into_iter().filter(|p| p.exists()).collect()
}

fn check(paths: &[&Path]) -> (usize, usize) {
    let set =
        vk_registry::source::load_union(&paths.iter().map(|p| p.to_path_buf()).collect::<Vec<_>>())
            .unwrap();
    let rules = RuleSet::from_vuids(&set);
    let rows = rules.coverage(Some(COMMAND));
    let want = set
        .records
        .iter()
        .filter(|r| r.scope == COMMAND.vk_name())
        .count();
    assert_eq!(rows.len(), want, "every VUID of the command has a row");
    for r in &rows {
        assert_ne!(r.status, Status::Pending, "{} is pending", r.vuid);
        if r.status == Status::NotExecutable {
            assert!(
                r.reason.as_ref().is_some_and(|s| s.len() > 40),
                "{} has no written reason",
                r.vuid
            );
        }
    }
    let exec = rows
        .iter()
        .filter(|r| r.status == Status::Executable)
        .count();
    assert!(
        exec * 10 >= rows.len() * 9,
        "{exec}/{} executable in {paths:?}",
        rows.len()
    );
    (exec, rows.len())
}

#[test]
fn every_source_alone_and_the_union_are_at_least_ninety_percent_executable() {
    let srcs = sources();
    assert!(
        !srcs.is_empty(),
        "no registry source found; run scripts/setup.sh"
    );
    for s in &srcs {
        let (e, n) = check(&[s.as_path()]);
        eprintln!("{}: {e}/{n} executable", s.display());
    }
    let all: Vec<&Path> = srcs.iter().map(|p| p.as_path()).collect();
    let (e, n) = check(&all);
    eprintln!("union: {e}/{n} executable");
}
