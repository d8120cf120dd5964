//! Case files on the command line: errors of the case (a group the pipeline lacks, a dangling buffer
//! name, a build of u32::MAX primitives) exit 2 from `check` and `replay` with `file:line:col: path:
//! problem`; `check` reads build cases; `replay` runs the case in a worker process (a worker that dies
//! is the case's crash, as in a run); a buffer no device of the profile can hold is unsupported, not a
//! crash, as are push constant bytes past its maxPushConstantsSize.

mod common;
use common::*;

#[test]
fn a_group_the_pipeline_lacks_is_an_error_of_the_case_in_check_and_replay() {
    let dir = tempfile::tempdir().unwrap();
    let text = edited(
        &committed(HAND),
        "handles: [!group 3]",
        "handles: [!group 99]",
    );
    let path = write(dir.path(), "group99.yaml", &text);
    let want = format!(
        "{path}:{}: world.buffers[0].contents[2].handles[0]: the handle of group 99",
        line_col(&text, "!group 99")
    );
    for args in [vec!["check", &path], vec!["replay", &path]] {
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.all());
        assert!(r.stderr.contains(&want), "{args:?}: {}", r.all());
        assert!(!r.stdout.contains("Fail"), "{args:?}: {}", r.all());
    }
}

#[test]
fn a_dangling_buffer_name_is_an_error_of_the_case_in_check_and_replay() {
    let dir = tempfile::tempdir().unwrap();
    let text = edited(
        &committed(HAND),
        "indirect_address: { buffer: indirect",
        "indirect_address: { buffer: nosuch",
    );
    let path = write(dir.path(), "dangling.yaml", &text);
    let want = format!(
        "{path}:{}: call.indirect_address.buffer: names buffer `nosuch`",
        line_col(&text, "nosuch")
    );
    for args in [vec!["check", &path], vec!["replay", &path]] {
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.all());
        assert!(r.stderr.contains(&want), "{args:?}: {}", r.all());
    }
}

#[test]
fn a_build_of_u32_max_primitives_is_an_error_of_the_case_in_check_and_replay() {
    let dir = tempfile::tempdir().unwrap();
    let text = committed("cases/build/aabbs-valid.yaml")
        .replace("primitive_count: 1\n", "primitive_count: 4294967295\n")
        .replace("  - - 1\n", "  - - 4294967295\n");
    let path = write(dir.path(), "huge-count.yaml", &text);
    let want = format!(
        "{path}:{}: world.buffers[1].contents[0].ranges[0]: ",
        line_col(&text, "primitive_count: 4294967295")
    );
    for args in [vec!["check", &path], vec!["replay", &path]] {
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.all());
        assert!(r.stderr.contains(&want), "{args:?}: {}", r.all());
        assert!(
            r.stderr.contains("the model gives the build no meaning"),
            "{}",
            r.all()
        );
        assert!(!r.stdout.contains("outcome: fail"), "{args:?}: {}", r.all());
    }
}

#[test]
fn check_reads_build_cases() {
    let dir = root().join("cases/build");
    let mut paths: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path().display().to_string())
        .filter(|p| p.ends_with(".yaml"))
        .collect();
    paths.sort();
    assert!(paths.len() > 10);
    let mut args = vec!["check", "--json"];
    args.extend(paths.iter().map(String::as_str));
    let r = rtconf(&args);
    assert_eq!(r.code, 0, "{}", r.all());
    let results: Vec<serde_json::Value> = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(results.len(), paths.len());
    assert!(results.iter().all(|v| v["agrees"] == true), "{}", r.stdout);
    // Every committed build case violates at least lavapipe's missing indirect build.
    assert!(results
        .iter()
        .all(|v| v["vuids"].as_array().is_some_and(|a| !a.is_empty())));
}

#[test]
fn replay_runs_the_case_in_a_worker_so_a_dying_driver_is_the_case_s_crash() {
    let dir = tempfile::tempdir().unwrap();
    let text = edited(
        &committed(HAND),
        "name: hand-made-valid",
        "name: fault-abort-replay",
    );
    let path = write(dir.path(), "abort.yaml", &text);
    let r = rtconf_with(&["replay", &path], &[("RTCONF_WORKER_FAULTS", "1")]);
    assert_eq!(r.code, 1, "{}", r.all());
    assert!(
        r.stdout.contains("outcome: crash — the worker died"),
        "{}",
        r.all()
    );
    // The same case, named otherwise, passes through the same worker path.
    let r = rtconf(&["replay", HAND]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert!(r.stdout.contains("outcome: pass"), "{}", r.all());
}

#[test]
fn a_buffer_of_u64_max_bytes_is_unsupported_by_the_profile_not_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    let text = edited(
        &committed(HAND),
        "size: 64\n",
        "size: 18446744073709551615\n",
    );
    let path = write(dir.path(), "huge.yaml", &text);
    let r = rtconf(&["replay", &path]);
    assert_eq!(r.code, 1, "{}", r.all());
    assert!(
        r.stdout.contains("outcome: unsupported — world.buffers[1].size: buffer `indirect` of 18446744073709551615 bytes is larger than the profile's maxBufferSize"),
        "{}",
        r.all()
    );
    assert!(!r.stdout.contains("Crash"), "{}", r.all());
}

#[test]
fn push_constants_past_the_profiles_limit_are_unsupported_not_run() {
    const PUSHED: &str = "cases/layer-1.4.309/vkCmdTraceRaysIndirectKHR-None-08601-22-0.yaml";
    let dir = tempfile::tempdir().unwrap();
    let pushed = committed(PUSHED);
    let edits = [
        (
            "    pushes:\n    - layout: pl-push\n      offset: 0\n      size: 16\n",
            "    pushes:\n    - layout: pl-push\n      offset: 0\n      size: 4096\n",
            "world.resources.pushes[0]: push constant bytes [0, 4096) end past the profile's maxPushConstantsSize (256)",
        ),
        (
            "      push_ranges:\n      - offset: 0\n        size: 16\n",
            "      push_ranges:\n      - offset: 252\n        size: 16\n",
            "world.resources.pipeline_layouts[0].push_ranges[0]: push constant bytes [252, 268) end past the profile's maxPushConstantsSize (256)",
        ),
    ];
    for (i, (from, to, want)) in edits.into_iter().enumerate() {
        let path = write(
            dir.path(),
            &format!("push{i}.yaml"),
            &edited(&pushed, from, to),
        );
        let r = rtconf(&["replay", &path]);
        assert_eq!(r.code, 1, "{}", r.all());
        assert!(
            r.stdout.contains(&format!("outcome: unsupported — {want}")),
            "{}",
            r.all()
        );
        assert!(r.stdout.contains("not run"), "{}", r.all());
    }
}

#[test]
fn a_case_named_like_a_path_is_refused_before_anything_is_written() {
    // A run keeps a case that did not pass as `FOLDER/NAME.yaml`: a name with `/` and `..` wrote a
    // file outside the run folder.
    let dir = tempfile::tempdir().unwrap();
    let escaped = dir.path().join("escaped");
    let name = format!("../../../../{}", escaped.display());
    let text = edited(
        &committed("cases/hand/trace-indirect-miss-stride-unaligned.yaml"),
        "name: trace-indirect-miss-stride-unaligned",
        &format!("name: \"{name}\""),
    );
    // Run as valid, so the run keeps it as a case error.
    let text = edited(
        &text,
        "intent: !violates { vuid: VUID-vkCmdTraceRaysIndirectKHR-stride-03686 }",
        "intent: valid",
    );
    let cases = dir.path().join("cases");
    std::fs::create_dir(&cases).unwrap();
    let path = write(&cases, "escape.yaml", &text);
    let r = rtconf(&["check", &path]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(
        r.stderr.contains(&format!(
            "{path}:{}: name: the case name holds '/'",
            line_col(&text, "\"../")
        )),
        "{}",
        r.all()
    );
    let out = dir.path().join("run").display().to_string();
    let r = rtconf(&[
        "run",
        "--cases",
        &cases.display().to_string(),
        "--out",
        &out,
    ]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(r.stderr.contains("the case name holds '/'"), "{}", r.all());
    assert!(!dir.path().join("escaped.yaml").exists());
}

#[test]
fn control_characters_a_case_holds_are_escaped_in_its_errors() {
    // A name with an escape sequence, quoted in the error: written as `\u{1b}`, not sent to the
    // terminal.
    let dir = tempfile::tempdir().unwrap();
    let text = edited(
        &committed(HAND),
        "indirect_address: { buffer: indirect",
        "indirect_address: { buffer: \"no\\x1b[31mred\\x07\"",
    );
    let path = write(dir.path(), "escapes.yaml", &text);
    for args in [vec!["check", &path], vec!["replay", &path]] {
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.all());
        assert!(
            r.stderr.contains("names buffer `no\\u{1b}[31mred\\u{7}`"),
            "{args:?}: {}",
            r.all()
        );
        assert!(!r.stderr.contains('\u{1b}'), "{args:?}: {}", r.all());
    }
}

/// A profile whose limit no case can be laid out with (an alignment the specification requires to be
/// a power of two, given as 24) is refused at its JSON path with exit 2 by `gen` and `run`, before
/// anything is generated; the committed lavapipe profile reads, with its two limits below the
/// specification's minimum named as warnings.
#[test]
fn a_profile_with_an_unusable_limit_is_refused_at_its_path() {
    let dir = tempfile::tempdir().unwrap();
    let text = edited(
        &committed("profiles/lavapipe.json"),
        "\"shaderGroupHandleAlignment\": 16",
        "\"shaderGroupHandleAlignment\": 24",
    );
    let path = write(dir.path(), "odd.json", &text);
    let out = dir.path().join("cases");
    let want = format!(
        "{path}: $.capabilities.device.properties.VkPhysicalDeviceRayTracingPipelinePropertiesKHR.shaderGroupHandleAlignment: 24 is not a power of two"
    );
    for args in [
        vec![
            "gen",
            "--profile",
            &path,
            "--valid",
            "--count",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        vec!["run", "--profile", &path, "--list", "--count", "2"],
    ] {
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.all());
        assert!(r.stderr.contains(&want), "{args:?}: {}", r.all());
    }
    assert!(!out.exists());
    let r = rtconf(&[
        "gen",
        "--profile",
        "lavapipe",
        "--valid",
        "--count",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert!(
        r.stderr.contains("warning: profile lavapipe: the device reports VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayDispatchInvocationCount = 67108864; the specification requires at least 1073741824"),
        "{}",
        r.all()
    );
}
