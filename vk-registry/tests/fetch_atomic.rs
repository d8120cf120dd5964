//! scripts/fetch-registry.sh under concurrency: several fetches into one fresh directory at once
//! (as parallel tests do) must leave a registry that parses the moment each of them returns, and a
//! reader polling meanwhile must never see a partial file.

mod common;

use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;
use vk_registry::{load_vuids, Registry};

const FETCHES: usize = 4;

#[test]
fn concurrent_fetches_never_expose_a_partial_registry() {
    let root = common::manifest_dir().join("..");
    let parent = tempfile::tempdir().unwrap();
    let dest = parent.path().join("1.4.309");
    let reg = dest.join("usr/share/vulkan/registry");

    let done = Arc::new(AtomicBool::new(false));
    // A reader that parses whatever it finds while the fetches run.
    let reader = {
        let (reg, done) = (reg.clone(), done.clone());
        thread::spawn(move || {
            let mut parsed = 0usize;
            while !done.load(Ordering::SeqCst) {
                if reg.join("validusage.json").exists() {
                    let set = load_vuids(&reg).unwrap_or_else(|e| {
                        panic!("validusage.json visible but does not parse: {e}")
                    });
                    assert_eq!(set.version.as_deref(), Some("1.4.309"));
                    parsed += 1;
                }
                thread::sleep(Duration::from_millis(20));
            }
            parsed
        })
    };

    let fetches: Vec<_> = (0..FETCHES)
        .map(|_| {
            let child = Command::new("bash")
                .arg(root.join("scripts/fetch-registry.sh"))
                .arg(&dest)
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("starting scripts/fetch-registry.sh");
            let reg = reg.clone();
            thread::spawn(move || {
                let out = child.wait_with_output().unwrap();
                let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
                assert!(
                    out.status.success(),
                    "fetch failed: {stdout}{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                // The moment this fetch returns, the registry it reported must be whole.
                let set = load_vuids(&reg).expect("validusage.json parses after the fetch");
                assert!(set.len() > 20_000, "{}", set.len());
                let xml =
                    Registry::load(reg.join("vk.xml")).expect("vk.xml parses after the fetch");
                assert!(xml.command("vkCmdTraceRaysIndirectKHR").is_some());
                stdout
            })
        })
        .collect();
    let outputs: Vec<String> = fetches.into_iter().map(|t| t.join().unwrap()).collect();
    done.store(true, Ordering::SeqCst);
    let polled = reader.join().unwrap();
    assert!(polled > 0, "the reader never saw the finished registry");

    // Serialised: one fetch downloaded and unpacked, the others waited and found it complete.
    let unpacked = outputs.iter().filter(|o| o.contains("unpacked")).count();
    assert_eq!(unpacked, 1, "{outputs:#?}");
    assert_eq!(
        outputs
            .iter()
            .filter(|o| o.contains("already present"))
            .count(),
        FETCHES - 1,
        "{outputs:#?}"
    );
    // No staging or stale directory is left beside the result.
    let leftovers: Vec<String> = std::fs::read_dir(parent.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "1.4.309" && n != "1.4.309.lock")
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn an_incomplete_destination_is_replaced_whole() {
    let root = common::manifest_dir().join("..");
    let parent = tempfile::tempdir().unwrap();
    let dest = parent.path().join("1.4.309");
    let reg = dest.join("usr/share/vulkan/registry");
    // What an interrupted unpack of the old script left: both files there, both truncated.
    std::fs::create_dir_all(&reg).unwrap();
    std::fs::write(reg.join("vk.xml"), "<?xml version=\"1.0\"?><registry><ty").unwrap();
    std::fs::write(reg.join("validusage.json"), "{\"version info\": {\"api ver").unwrap();
    let out = Command::new("bash")
        .arg(root.join("scripts/fetch-registry.sh"))
        .arg(&dest)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("unpacked"));
    let set = load_vuids(&reg).expect("the replaced validusage.json parses");
    assert_eq!(set.version.as_deref(), Some("1.4.309"));
    Registry::load(reg.join("vk.xml")).expect("the replaced vk.xml parses");
}
