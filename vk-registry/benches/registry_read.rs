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

    let text = std::fs::read_to_string(&vk_xml).unwrap();
    let raw = time(9, || {
        let mut r = quick_xml::Reader::from_str(&text);
        let mut n = 0usize;
        loop { match r.read_event().unwrap() { quick_xml::events::Event::Eof => break, quick_xml::events::Event::Start(e) | quick_xml::events::Event::Empty(e) => { n += e.attributes().with_checks(false).count(); } _ => n += 1 } }
        n
    });
    let parse_only = time(9, || vk_registry::Registry::parse(&text).unwrap());
    let read_only = time(9, || std::fs::read_to_string(&vk_xml).unwrap());
    eprintln!("raw quick-xml {raw:.1} ms, parse-from-str {parse_only:.1} ms, read {read_only:.1}");
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
    println!("vk.xml: vk-registry {a:.1} ms, vk-parse {b:.1} ms, ratio {:.3}", a / b);
    println!("validusage.json: {c:.1} ms");
}
