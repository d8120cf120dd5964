//! The worker pool on real lavapipe: results for every case, a crashed worker replaced and its case
//! reported `crash`, a hung one killed and reported `timeout`, and the rest unaffected.

mod common;

use harness::{run_in_workers_with, worker_main, Execution, Request, Status, WorkerCommand};
use std::time::Duration;

const WORKER_ENV: &str = "RTCONF_TEST_AS_WORKER";

/// Entry point of the worker processes this test binary starts (a plain test when run normally).
#[test]
fn worker_entry() {
    if std::env::var_os(WORKER_ENV).is_some() {
        std::process::exit(worker_main());
    }
    assert!(std::env::var_os(WORKER_ENV).is_none());
}

#[test]
fn crashes_and_hangs_cost_one_case_each() {
    let me = std::env::current_exe().unwrap();
    let cmd = WorkerCommand {
        program: me,
        args: ["worker_entry", "--exact", "--nocapture", "--test-threads=1"]
            .map(String::from)
            .into(),
        env: vec![
            (WORKER_ENV.into(), "1".into()),
            (harness::worker::FAULTS_ENV.into(), "1".into()),
            (harness::worker::DRIVER_ENV.into(), "lavapipe".into()),
        ],
    };
    let valid = common::valid_case();
    let mut abort = valid.clone();
    abort.name = "fault-abort".into();
    let mut hang = valid.clone();
    hang.name = "fault-hang".into();
    let cases = vec![
        valid.clone(),
        abort,
        valid.clone(),
        hang,
        common::bad_miss_stride_case(),
        valid.clone(),
    ];
    let requests: Vec<Request> = cases
        .into_iter()
        .enumerate()
        .map(|(index, case)| Request {
            index,
            execution: Execution {
                run_valid: case.intent == model::Intent::Valid,
                ..Default::default()
            },
            case,
        })
        .collect();
    let mut results = Vec::new();
    run_in_workers_with(&cmd, &requests, 2, Duration::from_secs(8), |r| {
        results.push(r)
    });
    results.sort_by_key(|r| r.index);
    assert_eq!(
        results.iter().map(|r| r.index).collect::<Vec<_>>(),
        vec![0, 1, 2, 3, 4, 5]
    );
    for i in [0, 2, 5] {
        assert_eq!(
            results[i].observation.status,
            Status::Ran,
            "{:?}",
            results[i]
        );
        common::assert_records(&valid, &results[i].observation);
    }
    assert!(
        matches!(&results[1].observation.status, Status::Crash { message } if message.contains("died")),
        "{:?}",
        results[1]
    );
    assert!(
        matches!(results[3].observation.status, Status::Timeout { .. }),
        "{:?}",
        results[3]
    );
    assert_eq!(
        results[4].observation.layer_vuids,
        vec!["VUID-vkCmdTraceRaysIndirectKHR-stride-03686".to_string()]
    );
}
