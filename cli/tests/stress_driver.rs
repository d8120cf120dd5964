//! `rtconf stress` on the real lavapipe: the reduced set (`--size small`) runs every family, each
//! judging rays with its claims proven, `stress.json` agreeing with the console table and
//! `stress.png` decoding; records doctored after a real lavapipe launch — a second member of a
//! shared edge reported, a REQ hit on the wrong primitive, an unreadable record — are reported as a
//! double hit and REQ violations, and make the run's exit status a driver finding; bad input and a
//! family that judged nothing are exit 2.

mod common;

use common::rtconf;
use harness::{Driver, Execution, Executor};
use model::stress::{family, FamilyReport};
use model::tracer::record::RayRecord as R;
use model::tracer::record::RecordOutcome;
use session::stress::{judge_launch, trace_cases, FamilyResult, Size, StressSummary};

fn families_json(dir: &std::path::Path) -> StressSummary {
    let text = std::fs::read_to_string(dir.join("stress.json")).expect("stress.json written");
    serde_json::from_str(&text).expect("stress.json parses as the summary")
}

/// The console row of `family`, split on whitespace.
fn row<'a>(stdout: &'a str, family: &str) -> Vec<&'a str> {
    stdout
        .lines()
        .find(|l| l.split_whitespace().next() == Some(family))
        .unwrap_or_else(|| panic!("no console row for {family}:\n{stdout}"))
        .split_whitespace()
        .collect()
}

/// `median/p99/max` of the console against the JSON's numbers (an infinite one is `null` in the
/// JSON and named in the family's `infinite`).
fn agrees(text: &str, s: &model::stress::ErrorStats, name: &str, infinite: &[String]) -> bool {
    let parts: Vec<&str> = text.split('/').collect();
    let want = [("median", s.median), ("p99", s.p99), ("max", s.max)];
    parts.len() == 3
        && parts
            .iter()
            .zip(want)
            .all(|(p, (q, w))| match (p.parse::<f64>(), w) {
                (Err(_), None) => *p == "-",
                (Ok(v), None) => v.is_infinite() && infinite.contains(&format!("{name}.{q}")),
                (Ok(v), Some(w)) => (v - w).abs() <= 1e-3 * w.abs().max(1.0),
                _ => false,
            })
}

#[test]
fn the_small_set_runs_every_family_on_lavapipe_and_reports_it_twice_alike() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("stress");
    let ran = rtconf(&[
        "stress",
        "--driver",
        "lavapipe",
        "--size",
        "small",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(ran.code, 0, "{}", ran.all());
    let summary = families_json(&out);
    assert_eq!(summary.exit, 0);
    assert_eq!(summary.size, Size::Small);
    assert!(
        summary.profile.starts_with("probed:"),
        "{}",
        summary.profile
    );
    let all = model::stress::families();
    assert_eq!(summary.families.len(), all.len());
    for (f, fam) in summary.families.iter().zip(&all) {
        assert_eq!(f.family, fam.name);
        // Every ray of the family was judged, and the family's claims were proven first.
        assert_eq!(f.rays, fam.test_size as u64, "{}", f.family);
        assert!(f.claims > 0, "{}", f.family);
        assert_eq!(f.outcomes.get("pass").copied(), Some(f.cases), "{f:?}");
        assert_eq!(f.rays, f.report.rays());
        assert_eq!(f.req_violations, 0, "{}: {:?}", f.family, f.findings);
        assert_eq!(f.double_hits, 0, "{}: {:?}", f.family, f.findings);
        // The console row says what the JSON says.
        let r = row(&ran.stdout, &f.family);
        assert_eq!(r[1].parse::<u64>().unwrap(), f.cases, "{r:?}");
        assert_eq!(r[2].parse::<u64>().unwrap(), f.rays, "{r:?}");
        assert_eq!(r[3].parse::<u64>().unwrap(), f.req_violations, "{r:?}");
        assert_eq!(r[4].parse::<u64>().unwrap(), f.double_hits, "{r:?}");
        assert_eq!(r[5].parse::<u64>().unwrap(), f.holes, "{r:?}");
        assert_eq!(r[6].parse::<u64>().unwrap(), f.watertight_rays, "{r:?}");
        let vary: f64 = r[7].parse().unwrap();
        assert!((vary - 100.0 * f.vary_share).abs() < 0.006, "{r:?}");
        let v = &f.on_vary;
        assert_eq!(
            r[8],
            format!(
                "{}/{}/{}/{}",
                v.hit_required,
                v.hit_possible,
                v.miss,
                v.hit_other + v.no_shader + v.not_run
            )
        );
        assert!(
            agrees(r[9], &f.t_error_ulps, "t_error_ulps", &f.infinite),
            "{r:?} {:?}",
            f.t_error_ulps
        );
        assert!(
            agrees(r[10], &f.bary_error_eps, "bary_error_eps", &f.infinite),
            "{r:?}"
        );
    }
    // The watertight families aim at shared edges and vertices: those rays are counted.
    assert!(summary.families[0].watertight_rays > 0);
    let png = std::fs::File::open(out.join("stress.png")).expect("stress.png written");
    let mut reader = png::Decoder::new(std::io::BufReader::new(png))
        .read_info()
        .expect("stress.png decodes");
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).expect("a frame");
    assert!(info.width >= 1000 && info.height >= 500, "{info:?}");
    // Not blank: the charts drew something other than the background.
    assert!(buf.iter().any(|&b| b < 200));
}

#[test]
fn bad_input_is_exit_2_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let out = out.to_str().unwrap();
    let ran = rtconf(&["stress", "--family", "no-such-family", "--out", out]);
    assert_eq!(ran.code, 2, "{}", ran.all());
    assert!(
        ran.stderr.contains("no-such-family") && ran.stderr.contains("watertight-edges"),
        "{}",
        ran.all()
    );
    let ran = rtconf(&["stress", "--size", "medium", "--out", out]);
    assert_eq!(ran.code, 2, "{}", ran.all());
    assert!(ran.stderr.contains("--size medium"), "{}", ran.all());
    assert!(!std::path::Path::new(out).join("stress.json").exists());
}

/// A family's first small case on lavapipe, run here: the trace case and its words.
fn on_lavapipe(name: &str) -> (model::Case, Vec<u32>) {
    std::env::set_var("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json");
    let f = family(name).unwrap();
    let stress = f.case(1, f.test_size);
    assert!(stress.check_claims().is_empty());
    let profile = session::sources::profile_for("lavapipe").unwrap();
    let launches = trace_cases(&stress, &profile, "lavapipe", 1).unwrap();
    assert_eq!(launches.len(), 1);
    let case = launches[0].case.clone();
    let mut ex = Executor::new(Driver::parse("lavapipe")).expect("lavapipe");
    let obs = ex.execute(&case, &Execution::for_case(&case, &profile));
    let words = obs.words().expect("records read back").to_vec();
    assert_eq!(words.len(), f.test_size * R::WORDS);
    (case, words)
}

fn report_of(case: &model::Case, words: &[u32]) -> (FamilyReport, u64) {
    let mut r = FamilyReport::new("planted");
    let unreadable = judge_launch(&mut r, case, words).unwrap();
    (r, unreadable)
}

fn summary_with(result: FamilyResult) -> StressSummary {
    StressSummary {
        driver: "lavapipe".into(),
        profile: "lavapipe".into(),
        device: String::new(),
        layer: String::new(),
        registry: None,
        size: Size::Small,
        seed: 1,
        seeds: 1,
        families: vec![result],
        seconds: 0.0,
        exit: 0,
        verdict: String::new(),
    }
}

#[test]
fn a_second_member_of_a_shared_edge_reported_is_a_double_hit_and_a_driver_finding() {
    let (case, words) = on_lavapipe("watertight-edges");
    let (clean, _) = report_of(&case, &words);
    assert_eq!(clean.rays(), 48);
    assert_eq!((clean.double_hits, clean.summary.fail), (0, 0));
    let body = case.as_trace().unwrap();
    let expected = model::semantics::expected_launch(&body.world, &body.call).unwrap();
    // A ray through a shared edge whose record saw one member: the other member is planted in the
    // next seen slot, at the same t.
    let mut doctored = words.clone();
    let planted = (0..48)
        .find_map(|id| {
            let rec = R::from_words(&words[id * R::WORDS..(id + 1) * R::WORDS]).ok()?;
            let group = expected.allowed[id]
                .watertight
                .iter()
                .find(|g| g.expect_hit && g.members.len() >= 2)?;
            let seen = rec.seen.first()?;
            let other = group.members.iter().find(|m| {
                (m.instance, m.geometry, m.primitive)
                    != (seen.instance, seen.geometry, seen.primitive)
            })?;
            let n = rec.any_hit_count as usize;
            (n < R::SEEN_SLOTS).then_some((id, n, *other, seen.t))
        })
        .expect("a shared-edge ray with a free seen slot");
    let (id, n, other, t) = planted;
    let base = id * R::WORDS;
    doctored[base + R::ANY_HIT_COUNT] += 1;
    let slot = base + R::SEEN + 4 * n;
    doctored[slot] = other.instance;
    doctored[slot + 1] = other.geometry;
    doctored[slot + 2] = other.primitive;
    doctored[slot + 3] = t.to_bits();
    let (r, _) = report_of(&case, &doctored);
    assert_eq!(r.double_hits, 1, "{:?}", r.findings);
    assert!(r.summary.fail >= 1, "{:?}", r.findings);
    let fam = family("watertight-edges").unwrap();
    let mut result = FamilyResult::new(&fam, vec![1]);
    result.report = r;
    result.refresh();
    assert!(result.driver_finding());
    assert_eq!(summary_with(result).judge().0, 1);
}

#[test]
fn a_req_hit_on_the_wrong_primitive_and_an_unreadable_record_are_req_violations() {
    let (case, words) = on_lavapipe("mirrored");
    let (clean, unreadable) = report_of(&case, &words);
    assert_eq!((clean.summary.fail, unreadable), (0, 0));
    let body = case.as_trace().unwrap();
    let expected = model::semantics::expected_launch(&body.world, &body.call).unwrap();
    // A ray whose outcome the spec fixes (no VARY part) and that hit: its primitive is changed.
    let id = (0..48)
        .find(|&id| {
            let rec = R::from_words(&words[id * R::WORDS..(id + 1) * R::WORDS]).unwrap();
            !expected.allowed[id].vary && rec.outcome == RecordOutcome::Hit
        })
        .expect("a REQ hit among mirrored's interior rays");
    let mut doctored = words.clone();
    doctored[id * R::WORDS + R::PRIMITIVE_ID] ^= 1;
    // And another launch ID's record made unreadable.
    let other = (id + 1) % 48;
    doctored[other * R::WORDS + R::OUTCOME] = 7;
    let (r, unreadable) = report_of(&case, &doctored);
    assert_eq!(unreadable, 1);
    assert_eq!(r.summary.fail, 1, "{:?}", r.findings);
    assert_eq!(r.other_failures, 1);
    assert_eq!(r.double_hits, 0);
    let fam = family("mirrored").unwrap();
    let mut result = FamilyResult::new(&fam, vec![1]);
    result.report = r;
    result.unreadable_records = unreadable;
    result.refresh();
    assert_eq!(result.req_violations, 2);
    assert_eq!(summary_with(result).judge().0, 1);
}

#[test]
fn a_family_that_judged_no_ray_is_exit_2_never_0() {
    let fam = family("grazing").unwrap();
    let mut result = FamilyResult::new(&fam, vec![1]);
    result.refresh();
    let (code, why) = summary_with(result).judge();
    assert_eq!(code, 2, "{why}");
    assert!(why.contains("grazing"), "{why}");
}
