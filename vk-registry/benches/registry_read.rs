//! Benchmark: the installed vk.xml read into the typed registry and with vk-parse (median of
//! several runs each), then validusage.json read into indexed VUIDs.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn median(mut v: Vec<Duration>) -> f64 {
    v.sort();
    v[v.len() / 2].as_secs_f64() * 1000.0
}

/// Median time of `iters` runs of `f`, result construction only (not its drop).
fn time<T>(iters: usize, mut f: impl FnMut() -> T) -> f64 {
    // one warm-up run, not counted
    std::hint::black_box(f());
    let runs = (0..iters)
        .map(|_| {
            let t = Instant::now();
            let v = std::hint::black_box(f());
            let d = t.elapsed();
            // the result is dropped outside the timed region
            drop(v);
            d
        })
        .collect();
    median(runs)
}

fn main() {
    let dir = std::env::var_os("RTCONF_REGISTRY_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(vk_registry::DEFAULT_REGISTRY_DIR));
    let vk_xml = dir.join("vk.xml");
    let vu_json = dir.join("validusage.json");
    for p in [&vk_xml, &vu_json] {
        assert!(Path::new(p).exists(), "{} not found", p.display());
    }

    let a = time(9, || {
        let r = vk_registry::Registry::load(&vk_xml).expect("vk-registry reads vk.xml");
        assert!(r.command("vkCmdTraceRaysIndirectKHR").is_some());
        r
    });
    let b = time(5, || {
        let (r, _errors) = vk_parse::parse_file(&vk_xml).expect("vk-parse reads vk.xml");
        r
    });
    let c = time(9, || {
        let s = vk_registry::validusage::load(&vu_json).expect("validusage.json");
        assert!(!s.records.is_empty());
        s
    });
    println!(
        "vk.xml: vk-registry {a:.1} ms, vk-parse {b:.1} ms, ratio {:.3}",
        a / b
    );
    println!("validusage.json: {c:.1} ms");
}
