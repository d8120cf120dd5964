//! `rtconf-fuzz-one TARGET FILE...`: runs files through one fuzz target and prints each
//! outcome, so a crashing input reproduces on stable Rust.

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(target) = args.first().and_then(|t| rtconf_fuzz::Target::from_name(t)) else {
        let names: Vec<&str> = rtconf_fuzz::Target::ALL.iter().map(|t| t.name()).collect();
        eprintln!(
            "usage: rtconf-fuzz-one TARGET FILE...   (TARGET: {})",
            names.join(", ")
        );
        std::process::exit(2);
    };
    for path in &args[1..] {
        match std::fs::read(path) {
            Ok(data) => println!("{path}: {:?}", rtconf_fuzz::run(target, &data)),
            Err(e) => {
                eprintln!("{path}: {e}");
                std::process::exit(2);
            }
        }
    }
}
