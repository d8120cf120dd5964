//! The short deterministic fuzz run: every corpus seed and regression input of every target, and a
//! few thousand structured mutations of the seeds, through the parsers; none may panic or abort, and
//! every error must say where the problem is. The process runs in a bounded address space, so an input
//! that makes the model allocate from a size it states aborts this test instead of the machine.

use rtconf_fuzz::mutate::{mutate, Rng};
use rtconf_fuzz::{fuzz_dir, inputs_in, run, run_catching, Outcome, Target};

/// Mutations of each target's seeds (eleven targets); `RTCONF_FUZZ_MUTATIONS` raises it for a longer
/// hunt (`RTCONF_FUZZ_SEED` varies the sequence).
const MUTATIONS_PER_TARGET: usize = 400;

/// The address space of this test binary: far below the sizes the regression inputs state (100 GB,
/// u64::MAX, a word per one of 34 billion invocations), far above what judging a case needs.
const ADDRESS_SPACE: u64 = 6 << 30;

fn bounded() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let limit = libc::rlimit {
            rlim_cur: ADDRESS_SPACE,
            rlim_max: libc::RLIM_INFINITY,
        };
        // SAFETY: setrlimit with a valid struct; it only lowers this process's soft limit.
        let rc = unsafe { libc::setrlimit(libc::RLIMIT_AS, &limit) };
        assert_eq!(rc, 0, "setrlimit(RLIMIT_AS)");
    });
}

fn mutations_per_target() -> usize {
    std::env::var("RTCONF_FUZZ_MUTATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(MUTATIONS_PER_TARGET)
}

fn seed_base() -> u64 {
    std::env::var("RTCONF_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0x5eed_0000)
}

/// The outcome of one input, or what is wrong with it: a panic, or an error without a location.
fn check(target: Target, data: &[u8]) -> Result<Outcome, String> {
    match run_catching(target, data) {
        Err(p) => Err(format!("panicked at {}: {}", p.location, p.message)),
        Ok(Outcome::Rejected {
            location: None,
            message,
        }) => Err(format!("error without a location: {message}")),
        Ok(outcome) => Ok(outcome),
    }
}

#[test]
fn corpus_and_mutations_neither_panic_nor_lose_the_location() {
    bounded();
    let out_dir = fuzz_dir().join("work").join("failures");
    let mut failures = Vec::new();
    for (k, target) in Target::ALL.into_iter().enumerate() {
        let seeds = inputs_in(&fuzz_dir().join("corpus").join(target.name()));
        assert!(!seeds.is_empty(), "{}: no corpus seeds", target.name());
        let mut record = |what: &str, data: &[u8], problem: String| {
            let file = out_dir.join(target.name()).join(what);
            let _ = std::fs::create_dir_all(file.parent().unwrap());
            let _ = std::fs::write(&file, data);
            failures.push(format!(
                "{}: {problem} (input saved as {})",
                target.name(),
                file.display()
            ));
        };
        for (name, data) in &seeds {
            if let Err(p) = check(target, data) {
                record(name, data, p);
            }
        }
        let started = std::time::Instant::now();
        let (mut accepted, mut rejected) = (0usize, 0usize);
        let mut rng = Rng::new(seed_base() + k as u64);
        for i in 0..mutations_per_target() {
            let (_, a) = rng.pick(&seeds).clone();
            let (_, b) = rng.pick(&seeds).clone();
            let m = mutate(target, &a, &b, &mut rng);
            let one = std::time::Instant::now();
            let outcome = check(target, &m);
            if one.elapsed() > std::time::Duration::from_millis(500) {
                let file = out_dir
                    .join("slow")
                    .join(target.name())
                    .join(format!("mutation-{i}"));
                let _ = std::fs::create_dir_all(file.parent().unwrap());
                let _ = std::fs::write(&file, &m);
                eprintln!(
                    "{}: slow input saved as {} ({:.1?})",
                    target.name(),
                    file.display(),
                    one.elapsed()
                );
            }
            match outcome {
                Ok(Outcome::Accepted) => accepted += 1,
                Ok(_) => rejected += 1,
                Err(p) => record(&format!("mutation-{i}"), &m, p),
            }
        }
        eprintln!(
            "{}: {accepted} accepted, {rejected} refused in {:.1?}",
            target.name(),
            started.elapsed()
        );
        // the mutations reach both what follows a parser (the model judges what was read) and its
        // errors
        assert!(
            accepted > 0 && rejected > 0,
            "{}: {accepted} mutation(s) accepted, {rejected} refused",
            target.name()
        );
    }
    assert!(
        failures.is_empty(),
        "{} input(s) mishandled:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Every input under `fuzz/regressions/` once panicked, aborted or lost its location (see
/// fuzz/README.md); each must now be read and judged, or refused with a located error.
#[test]
fn regression_inputs_are_judged_or_refused_with_a_location() {
    bounded();
    let mut seen = 0;
    let mut failures = Vec::new();
    for target in Target::ALL {
        for (name, data) in inputs_in(&fuzz_dir().join("regressions").join(target.name())) {
            seen += 1;
            if let Err(p) = check(target, &data) {
                failures.push(format!("{}/{name}: {p}", target.name()));
            }
        }
    }
    assert!(seen >= 20, "only {seen} regression inputs found");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The regression inputs that are not one document must be refused where the second document
/// starts: its `---` line, or where libyaml ended the first one early (an anchor or a tag with no
/// node after it).
#[test]
fn regression_inputs_that_are_not_valid_input_are_refused_where_they_are_wrong() {
    let refused = [
        ("trace_case", "two-documents.yaml", "51:1"),
        ("build_case", "two-documents.yaml", "95:1"),
        ("triage", "two-documents.yaml", "2:1"),
        ("triage", "anchor-then-alias.yaml", "1:4"),
        ("triage", "empty-anchored-nodes.yaml", "2:1"),
        ("triage", "tag-before-a-key.yaml", "2:18"),
        ("triage", "empty-first-document.yaml", "2:1"),
        // The 65th flow collection's bracket, wherever quotes and lines put it.
        (
            "triage",
            "nesting-after-a-quote-inside-a-word.yaml",
            "1:267",
        ),
        ("triage", "nesting-over-lines.yaml", "66:3"),
        (
            "triage",
            "nesting-after-a-quote-in-a-block-scalar.yaml",
            "3:138",
        ),
    ];
    for (target, file, at) in refused {
        let path = fuzz_dir().join("regressions").join(target).join(file);
        let data = std::fs::read(&path).expect("regression input exists");
        match run(Target::from_name(target).expect("a target"), &data) {
            Outcome::Rejected {
                location: Some(location),
                message,
            } => assert_eq!(location, at, "{}: {message}", path.display()),
            other => panic!("{}: {other:?}", path.display()),
        }
    }
}

#[test]
fn seeds_are_accepted() {
    // A seed that its own parser refuses exercises only the error path: each must be read whole.
    for target in Target::ALL {
        for (name, data) in inputs_in(&fuzz_dir().join("corpus").join(target.name())) {
            assert_eq!(
                run(target, &data),
                Outcome::Accepted,
                "{}/{name}",
                target.name()
            );
        }
    }
}
