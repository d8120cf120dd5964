//! `rtconf export CASE.yaml --out DIR`: the case as a standalone C program (`DIR/repro.c`) for a bug
//! report, and the one-line command that builds it.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportArgs {
    /// The case file (YAML): a build case (a trace case is refused with exit 2: the call plan does not
    /// yet describe rendered scenes).
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
        if exported.run_valid {
            "runs the call for real and compares its output with the model's"
        } else {
            "records the call under the validation layer, which drops it, and prints the VUIDs reported"
        }
    );
    Ok(0)
}
