//! `cargo xtask …`: developer tasks (see the library's documentation, `xtask/src/lib.rs`).

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

const USAGE: &str = "\
usage: cargo xtask new-codec NAME [--fourcc ABCD]
           create codec-NAME/ from the template codec (xtask/template/) and wire it into the workspace,
           the registry (animcodec/src/lib.rs) and the fuzz targets (fuzz/); prints the next steps
       cargo xtask write-generated
           write the golden streams, fuzz seeds and README codec tables a new codec (or stream
           version) needs, by running:";

/// The repository root: the folder above this crate's manifest.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask/ has a parent").to_path_buf()
}

fn usage() -> String {
    let mut text = USAGE.to_owned();
    for g in xtask::GENERATED {
        text.push_str(&format!("\n             {}", xtask::command_line(g)));
    }
    text
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("new-codec") => new_codec(&args[1..]),
        Some("write-generated") if args.len() == 1 => write_generated(),
        Some("-h" | "--help" | "help") => {
            println!("{}", usage());
            return ExitCode::SUCCESS;
        }
        _ => Err(usage()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn new_codec(args: &[String]) -> Result<(), String> {
    let (name, fourcc) = match args {
        [name] => (name, None),
        [name, flag, f] | [flag, f, name] if flag == "--fourcc" => (name, Some(f.as_str())),
        _ => return Err(usage()),
    };
    let root = root();
    let names = xtask::check_names(&root, &animcodec::registry(), name, fourcc)?;
    let files = xtask::new_codec(&root, &names)?;
    println!("created codec '{}' (FourCC {}, type {}):", names.name, names.fourcc, names.camel);
    for f in files {
        println!("  {f}");
    }
    println!("\n{}", xtask::next_steps(&names));
    Ok(())
}

fn write_generated() -> Result<(), String> {
    for g in xtask::GENERATED {
        println!("== {}: {}", xtask::command_line(g), g.2);
        let status = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
            .args(g.1)
            .env(g.0, "1")
            .current_dir(root())
            .status()
            .map_err(|e| format!("running cargo: {e}"))?;
        if !status.success() {
            return Err(format!("{} failed ({status})", xtask::command_line(g)));
        }
    }
    Ok(())
}
