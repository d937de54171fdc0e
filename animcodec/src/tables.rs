//! The codec table of the READMEs, made from the registry (`animcodec list --markdown`), so the
//! documentation cannot drift from the codecs that exist: `tests/tests/codec_tables.rs` fails
//! when the text between [`BEGIN`] and [`END`] in `README.md` or `python/README.md` differs from
//! [`codec_table_markdown`], and rewrites it with `ANIMCODEC_WRITE_CODEC_TABLES=1`.

use std::fmt::Write as _;

use codec_core::CodecRegistry;

/// Marker line before a generated codec table.
pub const BEGIN: &str = "<!-- codecs:begin (generated: animcodec list --markdown) -->";
/// Marker line after it.
pub const END: &str = "<!-- codecs:end -->";

/// One row per codec, in registry order: name, FourCC, stream version, the rate-ladder knob and
/// its range, and the codec's one-line summary. Parameters are left to `animcodec list` (with
/// ranges and docs): a table of every default would change with each tuning.
pub fn codec_table_markdown(registry: &CodecRegistry) -> String {
    let cell = |s: &str| s.replace('|', "\\|");
    let mut out = String::from("| codec | FourCC | stream version | rate ladder | what |\n|---|---|---|---|---|\n");
    for codec in registry.iter() {
        let ladder = codec.rate_ladder(&codec.default_params());
        let range = match (ladder.steps.first(), ladder.steps.last()) {
            (Some(a), Some(b)) if ladder.steps.len() > 1 => format!("`{}` {a} → {b}", ladder.param),
            (Some(a), _) => format!("`{}` {a}", ladder.param),
            _ => "—".to_owned(),
        };
        let _ = writeln!(
            out,
            "| `{}` | `{}` | {} | {} | {} |",
            codec.name(),
            cell(&codec.fourcc().to_string()),
            codec.stream_version(),
            cell(&range),
            cell(codec.summary())
        );
    }
    out
}

/// `document` with the text between its [`BEGIN`] and [`END`] lines replaced by `table`;
/// `None` when the markers are missing or out of order.
pub fn replace_codec_table(document: &str, table: &str) -> Option<String> {
    let start = document.find(BEGIN)? + BEGIN.len();
    let end = start + document[start..].find(END)?;
    Some(format!("{}\n{}{}", &document[..start], table, &document[end..]))
}

/// The text between the markers of `document` (what [`replace_codec_table`] replaces).
pub fn current_codec_table(document: &str) -> Option<&str> {
    let start = document.find(BEGIN)? + BEGIN.len();
    let end = start + document[start..].find(END)?;
    Some(document[start..end].strip_prefix('\n').unwrap_or(&document[start..end]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replacing_a_table_is_idempotent_and_keeps_the_rest() {
        let doc = format!("before\n{BEGIN}\nold | table\n{END}\nafter\n");
        let table = codec_table_markdown(&crate::registry());
        let once = replace_codec_table(&doc, &table).unwrap();
        assert_eq!(current_codec_table(&once), Some(table.as_str()));
        assert_eq!(replace_codec_table(&once, &table).unwrap(), once);
        assert!(once.starts_with("before\n") && once.ends_with(&format!("{END}\nafter\n")));
        assert!(replace_codec_table("no markers", &table).is_none());
        assert_eq!(table.lines().count(), 2 + crate::registry().iter().count());
    }
}
