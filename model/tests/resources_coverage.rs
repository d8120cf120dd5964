//! Coverage of the shared resource-access rules: in every registry version at hand, no row
//! of a trace command is left pending for lack of a resource model, each resource row is executable
//! or carries a reason, and the "not exercisable on a driver" notes name extensions that no
//! captured profile reports.

use model::resources::{rule_for, Entry};
use model::rules::{reasons, RuleSet, Status};
use model::CommandId;
use model::DeviceProfile;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The sources at hand: the installed registry always; 1.4.309 and the seeds' man pages when present.
fn sources() -> Vec<(String, Vec<PathBuf>)> {
    let mut v = vec![(
        "installed".to_string(),
        vec![PathBuf::from(vk_registry::source::DEFAULT_REGISTRY_DIR)],
    )];
    let r = root().join("target/registry/1.4.309/usr/share/vulkan/registry");
    if r.exists() {
        v.push(("1.4.309".into(), vec![r]));
    }
    let seeds = Path::new("/work/shared/seeds");
    let s: Vec<PathBuf> = ["000_1d54d370f31e08f5.txt", "003_da8701ff075bfd7b.txt"]
        .iter()
        .map(|f| seeds.join(f))
        .filter(|p| p.exists())
        .collect();
    if !s.is_empty() {
        v.push(("seeds".into(), s));
    }
    v
}

#[test]
fn no_trace_row_is_pending_for_lack_of_a_resource_model() {
    for (name, paths) in sources() {
        let set = vk_registry::source::load_union(&paths).expect("registry loads");
        let rules = RuleSet::from_vuids(&set);
        let mut resource_rows = 0;
        for cmd in CommandId::TRACE.map(CommandId::vk_name) {
            let rows: Vec<_> = rules.rows.iter().filter(|r| r.scope == cmd).collect();
            let count = |s: Status| rows.iter().filter(|r| r.status == s).count();
            println!(
                "{name} {cmd}: {} executable, {} not executable, {} pending",
                count(Status::Executable),
                count(Status::NotExecutable),
                count(Status::Pending)
            );
            for r in &rows {
                assert_ne!(
                    r.reason.as_deref(),
                    Some(reasons::RESOURCE_PENDING),
                    "{name}: {} is still pending",
                    r.vuid
                );
                if r.status == Status::Pending {
                    println!("  pending (not a resource rule): {}", r.vuid);
                }
            }
        }
        for rec in set
            .records
            .iter()
            .filter(|r| CommandId::from_vk_name(&r.scope).is_some_and(CommandId::is_trace))
        {
            if let Some(e) = rule_for(rec) {
                resource_rows += 1;
                let row = rules.row(&rec.id).unwrap();
                match e {
                    Entry::Executable { .. } => {
                        assert_eq!(row.status, Status::Executable, "{}", rec.id)
                    }
                    Entry::NotExecutable(why) => {
                        assert_eq!(row.status, Status::NotExecutable, "{}", rec.id);
                        assert!(why.len() > 40, "{}: a reason a reader can weigh", rec.id);
                    }
                }
            }
        }
        assert!(
            resource_rows >= 100,
            "{name}: only {resource_rows} resource rows"
        );
    }
}

#[test]
fn vendor_notes_name_extensions_no_captured_profile_has() {
    let profiles: Vec<DeviceProfile> = ["lavapipe", "nvidia-h100"]
        .iter()
        .map(|n| {
            let p = root().join(format!("profiles/{n}.json"));
            DeviceProfile::from_profiles_json(n, &std::fs::read_to_string(p).unwrap()).unwrap()
        })
        .collect();
    let set = vk_registry::source::load_vuids(Path::new(vk_registry::source::DEFAULT_REGISTRY_DIR))
        .unwrap();
    let mut noted = 0;
    for rec in &set.records {
        if let Some(Entry::Executable {
            note: Some(note), ..
        }) = rule_for(rec)
        {
            let exts = model::resources::rules::vendor_extensions(&note);
            assert!(!exts.is_empty(), "{}: {note}", rec.id);
            for p in &profiles {
                for e in &exts {
                    assert!(
                        !p.has_extension(e),
                        "{}: {} has {e}, so the rule is exercisable there",
                        rec.id,
                        p.name
                    );
                }
            }
            noted += 1;
        }
    }
    assert!(noted >= 20, "{noted} vendor rows");
}
