//! Developer tasks of the animcodec repository, run as `cargo xtask …` (alias in
//! `.cargo/config.toml`). A workspace package, not a subcommand of the `animcodec` binary: it
//! edits the source tree, which is a developer's business, not a user's.
//!
//! - `new-codec NAME [--fourcc ABCD]` ([`new_codec`]): creates `codec-NAME/` from the template
//!   codec in `xtask/template/` (a real codec, compiled and linted as a workspace member, and
//!   run through the whole conformance suite by `xtask/tests/scaffold.rs`), and wires it into
//!   the workspace, the registry and the fuzz targets. Prints the next steps ([`NEXT_STEPS`]).
//! - `write-generated` ([`GENERATED`]): runs the commands that write the generated files a new
//!   codec needs — its golden stream, its fuzz seeds, the README codec tables.
//!
//! Every edit of an existing file inserts lines above a marker comment ([`MARKER`]), so it does
//! not depend on the file's other contents; a missing marker is an error naming the file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use animcodec::core::CodecRegistry;

/// The marker comment new lines are inserted above, in every file `new-codec` edits.
pub const MARKER: &str = "cargo xtask new-codec inserts above this line";

/// The template codec's identifiers, replaced in every file copied from `xtask/template/`.
const TEMPLATE_NAME: &str = "template";
const TEMPLATE_TYPE: &str = "Template";
const TEMPLATE_FOURCC: &str = "TMPL";

/// A command that writes generated files: `(environment variable, cargo arguments, what)`.
pub type Generated = (&'static str, &'static [&'static str], &'static str);

/// The commands that write what a new codec (or a new stream version) needs besides its code,
/// in the order to run them. `--workspace` (not `-p conformance-tests`, which runs the same
/// test): cargo then resolves dependency features as `cargo test --workspace` does, so the
/// dependencies it built are reused instead of rebuilt (measured: 5.5 min of rebuilding faer,
/// serde, … otherwise). Run them when the codec's bitstream is settled: a golden stream
/// freezes the bytes of its stream version. `cargo xtask write-generated` runs all three; the
/// scaffold test (`xtask/tests/scaffold.rs`) runs exactly these.
pub const GENERATED: &[Generated] = &[
    (
        "ANIMCODEC_WRITE_GOLDEN",
        &["test", "--workspace", "--test", "golden"],
        "the golden stream of every codec or stream version that has none (tests/golden/)",
    ),
    (
        "ANIMCODEC_WRITE_FUZZ_SEEDS",
        &["test", "--workspace", "--test", "fuzz_corpus"],
        "the fuzz seeds of every target (fuzz/corpus/TARGET/seed-*)",
    ),
    (
        "ANIMCODEC_WRITE_CODEC_TABLES",
        &["test", "--workspace", "--test", "codec_tables"],
        "the codec tables of README.md and python/README.md (`animcodec list --markdown`)",
    ),
];

/// One [`GENERATED`] command as a shell line.
pub fn command_line(generated: &Generated) -> String {
    format!("{}=1 cargo {}", generated.0, generated.1.join(" "))
}

/// What `new-codec` prints after creating a codec (`{name}` replaced by the codec's name).
pub const NEXT_STEPS: &str = "\
Next steps:
  1. cargo test -p codec-{name}                        # the new crate's own tests
  2. ANIMCODEC_CODECS={name} cargo test --workspace --test conformance --test corruption --test encoder_input
                                                       # the conformance suite on this codec only
  3. Make it your codec: codec-{name}/src/lib.rs (method, bitstream, error bound),
     codec-{name}/src/params.rs (parameters), codec-{name}/README.md (paper, choices, measurements);
     describe it on its registry line in animcodec/src/lib.rs. README \"Adding a codec\" lists the
     toolkit and the error-bound contract.
  4. When the bitstream is settled (a golden stream freezes it):
       cargo xtask write-generated                      # golden stream, fuzz seeds, README codec tables
  5. cargo test --workspace, then commit codec-{name}/, the edited files, tests/golden/{name}-v1.anim,
     tests/golden/hashes.txt, fuzz/corpus/codec_{snake}/ and the README tables.
";

/// A validated new codec: its names in every spelling the files need.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CodecNames {
    /// Codec name (`my-codec`), as on the command line.
    pub name: String,
    /// Rust spelling (`my_codec`): crate `codec_my_codec`, fuzz target `codec_my_codec`.
    pub snake: String,
    /// Type name (`MyCodec`).
    pub camel: String,
    /// FourCC (`MYCO`).
    pub fourcc: String,
}

/// Checks `name` and `fourcc` (default: from the name) against the rules and against what is
/// already in `root` and `registry`; every refusal says why and what to do.
pub fn check_names(
    root: &Path,
    registry: &CodecRegistry,
    name: &str,
    fourcc: Option<&str>,
) -> Result<CodecNames, String> {
    let valid_chars = name.bytes().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == b'-');
    if !(2..=24).contains(&name.len())
        || !valid_chars
        || !name.as_bytes()[0].is_ascii_lowercase()
        || name.ends_with('-')
        || name.contains("--")
    {
        return Err(format!(
            "'{name}' is not a valid codec name: 2 to 24 characters, lowercase ASCII letters, digits and single \
             hyphens, starting with a letter and not ending with a hyphen (e.g. 'wavelet' or 'pca-lite'); the crate \
             is codec-NAME"
        ));
    }
    if name == TEMPLATE_NAME {
        return Err(format!("'{name}' is the template codec's own name (xtask/template); choose another"));
    }
    if let Ok(codec) = registry.by_name(name) {
        return Err(format!("a codec named '{}' is already registered (animcodec/src/lib.rs)", codec.name()));
    }
    let snake = name.replace('-', "_");
    let camel: String = name
        .split('-')
        .map(|part| {
            let mut c = part.chars();
            c.next().map(|f| f.to_ascii_uppercase().to_string() + c.as_str()).unwrap_or_default()
        })
        .collect();
    let crate_dir = root.join(format!("codec-{name}"));
    if crate_dir.exists() {
        return Err(format!("{} already exists; remove it or choose another name", crate_dir.display()));
    }
    let manifest = read(&root.join("Cargo.toml"))?;
    if manifest.contains(&format!("\"codec-{name}\"")) || manifest.contains(&format!("\ncodec-{name} ")) {
        return Err(format!("the root Cargo.toml already names a crate codec-{name}; choose another name"));
    }
    // The type name must not collide with a type the template's code already uses (`Error`,
    // `Packet`, …), or the generated crate would not compile.
    let template_types = template_identifiers(root)?;
    if template_types.iter().any(|t| t == &camel) {
        return Err(format!(
            "'{name}' would name the codec type `{camel}`, which the template's code already uses for something \
             else; choose another name"
        ));
    }
    let fourcc = match fourcc {
        Some(f) => f.to_owned(),
        None => default_fourcc(name),
    };
    if fourcc.len() != 4 || !fourcc.bytes().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit()) {
        return Err(format!(
            "FourCC '{fourcc}' must be exactly 4 characters, uppercase ASCII letters or digits (e.g. --fourcc WAVL)"
        ));
    }
    if fourcc == TEMPLATE_FOURCC {
        return Err(format!("FourCC {fourcc} is the template codec's; choose another with --fourcc"));
    }
    let code = animcodec::core::FourCc::new(&[
        fourcc.as_bytes()[0],
        fourcc.as_bytes()[1],
        fourcc.as_bytes()[2],
        fourcc.as_bytes()[3],
    ]);
    if let Ok(codec) = registry.by_fourcc(code) {
        return Err(format!(
            "FourCC {fourcc} is already used by codec '{}' (streams name their codec by FourCC); choose another \
             with --fourcc",
            codec.name()
        ));
    }
    Ok(CodecNames { name: name.to_owned(), snake, camel, fourcc })
}

/// The default FourCC of a codec name: its first four letters and digits, upper-cased, padded
/// with `0` so it stays alphanumeric (`wavelet` → `WAVE`, `ab` → `AB00`).
pub fn default_fourcc(name: &str) -> String {
    let mut f: String =
        name.chars().filter(|c| c.is_ascii_alphanumeric()).take(4).collect::<String>().to_ascii_uppercase();
    while f.len() < 4 {
        f.push('0');
    }
    f
}

/// Capitalised words in the template's Rust code other than the template's own type names.
fn template_identifiers(root: &Path) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    for (path, _) in template_files(root)? {
        if path.extension().is_some_and(|e| e == "rs") {
            let text = read(&path)?;
            for word in text.split(|c: char| !c.is_ascii_alphanumeric() && c != '_') {
                if word.starts_with(|c: char| c.is_ascii_uppercase()) && !word.starts_with(TEMPLATE_TYPE) {
                    out.push(word.to_owned());
                }
            }
        }
    }
    out.sort();
    out.dedup();
    Ok(out)
}

/// Every file of `xtask/template/` (no build output), with its path relative to that folder.
pub fn template_files(root: &Path) -> Result<Vec<(PathBuf, PathBuf)>, String> {
    let base = root.join("xtask").join("template");
    let mut out = Vec::new();
    let mut dirs = vec![base.clone()];
    while let Some(dir) = dirs.pop() {
        let entries = std::fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for entry in entries {
            let path = entry.map_err(|e| format!("{}: {e}", dir.display()))?.path();
            if path.file_name().is_some_and(|n| n == "target") {
                continue;
            }
            if path.is_dir() {
                dirs.push(path);
            } else {
                let relative = path.strip_prefix(&base).expect("below the template folder").to_path_buf();
                out.push((path, relative));
            }
        }
    }
    out.sort();
    if out.is_empty() {
        return Err(format!("{}: no template files", base.display()));
    }
    Ok(out)
}

/// The template's text with the codec's names in place of the template's.
pub fn instantiate(text: &str, names: &CodecNames) -> String {
    text.replace("codec-template", &format!("codec-{}", names.name))
        .replace("codec_template", &format!("codec_{}", names.snake))
        .replace(TEMPLATE_TYPE, &names.camel)
        .replace(TEMPLATE_FOURCC, &names.fourcc)
        .replace(TEMPLATE_NAME, &names.name)
}

/// The cargo-fuzz target of codec target `target` (`codec_my_codec`).
fn fuzz_target_source(target: &str) -> String {
    format!(
        "#![no_main]\n//! Fuzz target `{target}`: see `conformance_tests::fuzz` (tests/src/fuzz.rs).\n\nuse \
         libfuzzer_sys::fuzz_target;\n\nfuzz_target!(|data: &[u8]| conformance_tests::fuzz::run(\"{target}\", \
         data));\n"
    )
}

fn read(path: &Path) -> Result<String, String> {
    std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))
}

fn write(path: &Path, text: &str) -> Result<(), String> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// `text` with `lines` inserted above the (only) line containing [`MARKER`], indented like the
/// line above them.
pub fn insert_above_marker(text: &str, lines: &[String], file: &str) -> Result<String, String> {
    let hits: Vec<usize> = text.lines().enumerate().filter(|(_, l)| l.contains(MARKER)).map(|(i, _)| i).collect();
    let [at] = hits[..] else {
        return Err(format!(
            "{file}: expected exactly one line containing the marker comment \"{MARKER}\", found {}; put it back \
             where new entries go (see README \"Adding a codec\")",
            hits.len()
        ));
    };
    let all: Vec<&str> = text.lines().collect();
    // Indented like the entry above (the marker's own indentation may be a formatter's
    // alignment), and the marker put at that indentation too, so the result is as rustfmt
    // writes it.
    let above = all[..at].iter().rev().find(|l| !l.trim().is_empty()).unwrap_or(&all[at]);
    let indent: String = above.chars().take_while(|c| c.is_whitespace()).collect();
    let mut out = String::new();
    for (i, line) in all.iter().enumerate() {
        if i == at {
            for new in lines {
                if new.is_empty() {
                    out.push('\n');
                } else {
                    let _ = writeln!(out, "{indent}{new}");
                }
            }
            let _ = writeln!(out, "{indent}{}", line.trim_start());
        } else {
            let _ = writeln!(out, "{line}");
        }
    }
    Ok(out)
}

/// One planned edit: the file (relative to the root) and its new contents.
struct Edit {
    file: String,
    text: String,
}

/// `cargo xtask new-codec`: creates `codec-NAME/` from the template and wires it in. Every
/// file is computed first and written only when all succeeded, so a refusal (bad name, missing
/// marker) leaves the tree as it was. Returns the created and edited files, relative to `root`.
pub fn new_codec(root: &Path, names: &CodecNames) -> Result<Vec<String>, String> {
    let mut edits = Vec::new();
    for (path, relative) in template_files(root)? {
        let text = read(&path)?;
        edits.push(Edit {
            file: format!("codec-{}/{}", names.name, relative.to_string_lossy().replace('\\', "/")),
            text: instantiate(&text, names),
        });
    }
    let name = &names.name;
    let krate = format!("codec-{name}");
    let target = format!("codec_{}", names.snake);
    // The root manifest has two markers (members and [workspace.dependencies]); they are told
    // apart by the section they are in.
    let manifest = read(&root.join("Cargo.toml"))?;
    let (members, dependencies) =
        manifest.split_once("[workspace.dependencies]").ok_or("Cargo.toml: no [workspace.dependencies] section")?;
    let members = insert_above_marker(members, &[format!("\"{krate}\",")], "Cargo.toml ([workspace] members)")?;
    let dependencies = insert_above_marker(
        dependencies,
        &[format!("{krate} = {{ path = \"{krate}\" }}")],
        "Cargo.toml ([workspace.dependencies])",
    )?;
    edits.push(Edit { file: "Cargo.toml".into(), text: format!("{members}[workspace.dependencies]{dependencies}") });
    let mut edit_file = |file: &str, lines: Vec<String>| -> Result<(), String> {
        let text = read(&root.join(file))?;
        edits.push(Edit { file: file.to_owned(), text: insert_above_marker(&text, &lines, file)? });
        Ok(())
    };
    edit_file("animcodec/Cargo.toml", vec![format!("{krate}.workspace = true")])?;
    edit_file(
        "animcodec/src/lib.rs",
        vec![
            format!("// {name}: made by cargo xtask new-codec; say what it is (method, paper)"),
            format!("Box::new(codec_{}::{}),", names.snake, names.camel),
        ],
    )?;
    edit_file(
        "fuzz/Cargo.toml",
        vec![
            "[[bin]]".into(),
            format!("name = \"{target}\""),
            format!("path = \"fuzz_targets/{target}.rs\""),
            "test = false".into(),
            "doc = false".into(),
            "bench = false".into(),
            String::new(),
        ],
    )?;
    let fuzz_target = format!("fuzz/fuzz_targets/{target}.rs");
    if root.join(&fuzz_target).exists() {
        return Err(format!("{fuzz_target} already exists; remove it or choose another name"));
    }
    edits.push(Edit { file: fuzz_target, text: fuzz_target_source(&target) });
    for e in &edits {
        write(&root.join(&e.file), &e.text)?;
    }
    Ok(edits.into_iter().map(|e| e.file).collect())
}

/// The next steps for `names`, as printed by `new-codec`.
pub fn next_steps(names: &CodecNames) -> String {
    NEXT_STEPS.replace("{name}", &names.name).replace("{snake}", &names.snake)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
    }

    fn refusal(name: &str, fourcc: Option<&str>) -> String {
        check_names(&root(), &animcodec::registry(), name, fourcc).unwrap_err()
    }

    #[test]
    fn bad_names_are_refused_with_the_rule() {
        for bad in
            ["", "a", "Wavelet", "9lives", "pca_lite", "pca--lite", "lite-", "wav elet", "ü-codec", &"x".repeat(25)]
        {
            assert!(refusal(bad, None).contains("not a valid codec name"), "{bad}: {}", refusal(bad, None));
        }
        assert!(refusal("template", None).contains("template codec's own name"));
        // The type name would clash with a type the template uses.
        assert!(refusal("packet", None).contains("`Packet`"), "{}", refusal("packet", None));
    }

    #[test]
    fn registered_names_and_fourccs_are_refused() {
        for codec in animcodec::registry().iter() {
            let e = refusal(codec.name(), None);
            assert!(e.contains("already registered") || e.contains("already exists"), "{}: {e}", codec.name());
            let e = refusal("fresh-name", Some(&codec.fourcc().to_string()));
            assert!(e.contains("already used by codec") && e.contains(codec.name()), "{e}");
        }
        assert!(refusal("fresh-name", Some("ab12")).contains("uppercase"));
        assert!(refusal("fresh-name", Some("ABCDE")).contains("exactly 4"));
        assert!(refusal("fresh-name", Some("TMPL")).contains("template"));
    }

    #[test]
    fn names_in_every_spelling() {
        let n = check_names(&root(), &animcodec::registry(), "pca-lite2", None).unwrap();
        assert_eq!((n.snake.as_str(), n.camel.as_str(), n.fourcc.as_str()), ("pca_lite2", "PcaLite2", "PCAL"));
        assert_eq!(default_fourcc("ab"), "AB00");
        let text = "codec-template codec_template Template TemplateParams \"template\" TMPL";
        assert_eq!(instantiate(text, &n), "codec-pca-lite2 codec_pca_lite2 PcaLite2 PcaLite2Params \"pca-lite2\" PCAL");
    }

    #[test]
    fn insertion_needs_exactly_one_marker() {
        let text = format!("a\n    // {MARKER}\nb\n");
        assert_eq!(insert_above_marker(&text, &["x".into()], "f").unwrap(), format!("a\nx\n// {MARKER}\nb\n"));
        let text = format!("    a, // note\n                // {MARKER}\n");
        let expected = format!("    a, // note\n    x\n    // {MARKER}\n");
        assert_eq!(insert_above_marker(&text, &["x".into()], "f").unwrap(), expected);
        assert!(insert_above_marker("a\nb\n", &["x".into()], "f").unwrap_err().contains("found 0"));
        let twice = format!("{MARKER}\n{MARKER}\n");
        assert!(insert_above_marker(&twice, &["x".into()], "f").unwrap_err().contains("found 2"));
    }

    /// Every file `new-codec` edits has its marker now, so a scaffold cannot fail half way.
    #[test]
    fn every_edited_file_has_its_marker() {
        for file in ["Cargo.toml", "animcodec/Cargo.toml", "animcodec/src/lib.rs", "fuzz/Cargo.toml"] {
            let text = read(&root().join(file)).unwrap();
            let expected = if file == "Cargo.toml" { 2 } else { 1 };
            assert_eq!(text.matches(MARKER).count(), expected, "{file}");
        }
    }
}
