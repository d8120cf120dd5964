//! Throughput on lavapipe: invalid cases (recorded under the layer, dropped, never submitted) and valid
//! cases (recorded, submitted, read back) per second, at small launch sizes, in one process with the
//! device, pipelines and scene cached as in `rtconf run`; reported as rates and as the ratio of the two
//! measured in the same run. The cases are the hand-made one of `cases/hand/` with its miss stride or
//! launch width changed.

use harness::{Driver, Execution, Executor, Status};
use model::call::Call;
use model::case::{Case, Intent};
use model::world::Contents;
use std::time::{Duration, Instant};

/// The hand-made case with the miss table's stride (not a multiple of 16: invalid) and the width of the
/// indirect launch set.
fn case(miss_stride: u64, width: u32) -> Case {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/hand/trace-indirect-records-32.yaml");
    let text = std::fs::read_to_string(&path).expect("the hand-made case");
    let mut case = Case::from_yaml("hand", &text).expect("the hand-made case parses");
    case.name = format!("bench-{miss_stride}-{width}");
    let t = case.as_trace_mut().expect("a trace case");
    if let Call::TraceRaysIndirect(c) = &mut t.call {
        c.miss.stride = miss_stride;
        c.miss.size = miss_stride * 2;
    }
    for b in &mut t.world.buffers {
        for c in &mut b.contents {
            if let Contents::TraceRaysIndirectCommand { width: w, .. } = c {
                *w = width;
            }
        }
    }
    if miss_stride % 16 != 0 {
        case.intent = Intent::Violates {
            vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
            also: vec![],
        };
    }
    case
}

fn run(ctx: &mut Executor, case: &Case) -> Status {
    let exec = Execution {
        run_valid: case.intent == Intent::Valid,
        ..Default::default()
    };
    ctx.execute(case, &exec).status
}

fn rate(ctx: &mut Executor, cases: &[Case], budget: Duration) -> f64 {
    let start = Instant::now();
    let mut n = 0usize;
    while start.elapsed() < budget {
        let status = run(ctx, &cases[n % cases.len()]);
        if status != Status::Ran {
            eprintln!("case did not run: {status:?}");
            std::process::exit(1);
        }
        n += 1;
    }
    n as f64 / start.elapsed().as_secs_f64()
}

fn main() {
    let mut ctx = match Executor::new(Driver::Lavapipe) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let invalid: Vec<Case> = [40, 24, 48 + 8].iter().map(|&s| case(s, 4)).collect();
    let valid: Vec<Case> = [4, 8, 16].iter().map(|&w| case(32, w)).collect();
    // Warm-up: device, pipeline and scene creation are paid once.
    for c in invalid.iter().chain(&valid) {
        run(&mut ctx, c);
    }
    let budget = Duration::from_secs(3);
    let inv = rate(&mut ctx, &invalid, budget);
    let val = rate(&mut ctx, &valid, budget);
    println!("invalid cases/s: {inv:.0}");
    println!("valid cases/s: {val:.0}");
    println!("valid / invalid: {:.2}", val / inv);
}
