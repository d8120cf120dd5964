//! `vk-tables [VK_XML [OUT]]`: writes the harness's structure tables (`vk_registry::tables`) generated
//! from vk.xml (default: the installed registry) to OUT (default: standard output).

fn main() {
    let mut args = std::env::args().skip(1);
    let xml = args
        .next()
        .unwrap_or_else(|| format!("{}/vk.xml", vk_registry::DEFAULT_REGISTRY_DIR));
    let text = vk_registry::Registry::load(&xml)
        .map_err(|e| e.to_string())
        .and_then(|r| {
            vk_registry::tables::generate(&r, vk_registry::tables::HARNESS_STRUCTURES)
                .map_err(|e| e.to_string())
        });
    let text = match text {
        Ok(t) => t,
        Err(e) => {
            eprintln!("vk-tables: {xml}: {e}");
            std::process::exit(1);
        }
    };
    let written = match args.next() {
        Some(out) => std::fs::write(&out, text).map_err(|e| format!("{out}: {e}")),
        None => {
            print!("{text}");
            Ok(())
        }
    };
    if let Err(e) = written {
        eprintln!("vk-tables: {e}");
        std::process::exit(1);
    }
}
