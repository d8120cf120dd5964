//! `rtconf export CASE.yaml --out DIR`: the case as a standalone C program (`DIR/repro.c`) for a bug
//! report, and the one-line command that builds it.
//!
//! A trace case's program builds its scene (bottom and top levels from the plan's bytes), pipeline
//! (SPIR-V embedded) and shader binding tables and records the plan's steps: an invalid case's call
//! under the validation layer, which drops it (it prints the layer's VUIDs beside the model's and
//! exits 0 when they agree); a valid one submitted, its ray records read back and judged per launch
//! ID against the model's expectation embedded as tables (exit 1 on a REQ violation; `./repro
//! --records FILE` also writes the records, `./repro --judge FILE` judges a records file and runs
//! nothing). A build case records its build under the layer; one run as valid then repeats the
//! harness's traced check: info 0 built directly with the ranges the model reads, the check's rays
//! traced at it (ray query, else the check pipeline) and each record judged (exit 1 when the device's
//! build departs).

use clap::Args;
use std::path::PathBuf;

/// What `rtconf export --help` says the program does.
const PROGRAM: &str = "\
The program (build: cd DIR && cc repro.c -lvulkan -o repro) makes the case's device, buffers, pipeline \
(SPIR-V embedded), shader binding tables and, for a trace case, its scene from the plan's bytes, then \
records the harness's steps under the validation layer.
  invalid case:  the layer drops the call; prints the layer's VUIDs beside the model's, exit 0 when they agree.
  valid trace:   submits the launch, reads its ray records back and judges each launch ID against the \
model's expectation embedded as tables; exit 1 on a REQ violation, naming the launch IDs.
  valid build:   records the indirect build under the layer, then builds info 0 directly with the ranges \
the model reads and traces the check's rays at it with ray query, or a ray tracing pipeline where the device \
lacks it or RTCONF_REPRO_CHECK=pipeline asks (as rtconf's harness does), judging each ray's record; exit 1 \
when the device's build departs from the model. A valid build of several infos is recorded only (the \
harness's check handles one info), as the run line says.
  ./repro --records FILE   also writes the records read back (as `rtconf replay --records FILE`)
  ./repro --judge FILE     judges a records file against the tables and runs nothing
Exit status of the program: 0 agrees with the model, 1 does not (a lost device included), 2 cannot run.
Not exported (exit 2 with the reason): resource states, sparse or partly bound buffers, vkCmdTraceRaysNV.";

#[derive(Args)]
#[command(after_help = PROGRAM)]
pub struct ExportArgs {
    /// The case file (YAML) of a trace or build case. Refused with exit 2 and the reason: cases with a
    /// resource state, sparse or partly bound buffers, and vkCmdTraceRaysNV cases.
    case: PathBuf,
    /// The folder repro.c goes to.
    #[arg(long)]
    out: PathBuf,
    /// Registry sources for the model's verdict written into the program (default: the installed
    /// registry).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
}

pub fn run(a: ExportArgs) -> super::Exit {
    let case = session::replay::read_case(&a.case)?;
    let exported = session::export::export(&case, &a.from, &a.out)?;
    println!("wrote {}", exported.source.display());
    println!(
        "build: cd {} && {}",
        a.out.display(),
        exported.build_command
    );
    println!(
        "run:   ./repro   ({})",
        if exported.checks_build {
            "records the indirect build under the validation layer, then builds info 0 directly, traces the check's rays at it (ray query, else a pipeline) and judges each record against the model's; --records FILE writes them"
        } else if exported.run_valid && case.as_accel().is_some() {
            "records the indirect build under the validation layer and prints the VUIDs reported; a valid build of several infos is not checked by tracing, as rtconf's harness checks one info"
        } else if exported.run_valid {
            "runs the call for real and judges its records per launch ID against the model's; --records FILE writes them"
        } else {
            "records the call under the validation layer, which drops it, and prints the VUIDs reported"
        }
    );
    Ok(0)
}
