//! The codec tables of `README.md` and `python/README.md` are the registry's
//! (`animcodec::tables::codec_table_markdown`, what `animcodec list --markdown` prints): a codec
//! added, removed or changed (summary, parameters, ladder, version) shows up here until the
//! tables are rewritten with
//! `ANIMCODEC_WRITE_CODEC_TABLES=1 cargo test --workspace --test codec_tables`.

use std::path::Path;

use animcodec::tables::{codec_table_markdown, current_codec_table, replace_codec_table, BEGIN, END};

#[test]
fn readme_codec_tables_match_the_registry() {
    let table = codec_table_markdown(&animcodec::registry());
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let write = std::env::var_os("ANIMCODEC_WRITE_CODEC_TABLES").is_some();
    let mut stale = Vec::new();
    for file in ["README.md", "python/README.md"] {
        let path = root.join(file);
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{file}: {e}"));
        let current = current_codec_table(&text)
            .unwrap_or_else(|| panic!("{file}: no codec table between the lines\n{BEGIN}\n{END}"));
        if current == table {
            continue;
        }
        if write {
            std::fs::write(&path, replace_codec_table(&text, &table).expect("markers found above")).unwrap();
            eprintln!("rewrote the codec table of {file}");
        } else {
            stale.push(file);
        }
    }
    assert!(
        stale.is_empty(),
        "the codec table of {} differs from the registry's:\n{table}\nrewrite it with \
         ANIMCODEC_WRITE_CODEC_TABLES=1 cargo test --workspace --test codec_tables",
        stale.join(" and ")
    );
}
