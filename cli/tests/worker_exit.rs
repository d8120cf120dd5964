//! `rtconf worker` driven as the runner drives it, on lavapipe: its first frame says it is ready, a
//! valid case runs and is answered, and once its stdin closes it ends by itself with status 0 — with
//! its device still made, which it leaves to the process's exit.

use harness::worker::{frame, Ready, Request, Response};
use harness::{Execution, Status};
use std::io::{BufReader, Read};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

#[test]
fn a_worker_that_ran_a_case_ends_by_itself_with_status_0_once_its_stdin_closes() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rtconf"))
        .arg("worker")
        .current_dir(common::root())
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .env(harness::worker::DRIVER_ENV, "lavapipe")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("rtconf worker starts");
    let mut stdin = child.stdin.take().expect("piped");
    let mut stdout = BufReader::new(child.stdout.take().expect("piped"));
    let ready: Ready =
        frame::decode(&frame::read(&mut stdout).unwrap().expect("a Ready frame")).unwrap();
    assert!(ready.executor.is_ok(), "{ready:?}");
    let path = "cases/hand/trace-indirect-basic.yaml";
    let case = model::case::Case::read(path, &common::committed(path)).expect("the case reads");
    let request = Request {
        index: 7,
        case,
        execution: Execution {
            run_valid: true,
            ..Default::default()
        },
    };
    frame::write(&mut stdin, &request).expect("the request is written");
    let response: Response =
        frame::decode(&frame::read(&mut stdout).unwrap().expect("a response")).unwrap();
    assert_eq!(response.index, 7);
    assert_eq!(response.observation.status, Status::Ran, "{response:?}");
    assert!(
        response.observation.output.is_some(),
        "the launch was read back"
    );
    drop(stdin);
    let closed = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("the worker can be waited for") {
            break s;
        }
        if closed.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            panic!("the worker did not end within 30 s of its stdin closing");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert_eq!(status.code(), Some(0), "{status:?}");
    let mut rest = Vec::new();
    stdout.read_to_end(&mut rest).unwrap();
    assert!(rest.is_empty(), "nothing follows the last answer: {rest:?}");
}
