//! `animcodec list-animations` (and `info` on a glTF file): the animations of a glTF/GLB file,
//! what `--animation` chooses from.

use std::path::Path;

use animcodec::formats::gltf;
use serde_json::json;

use super::{emit, emit_json, CmdResult, WithContext};

/// Lists the animations of `path`, as text or JSON.
pub fn run(path: &Path, as_json: bool) -> CmdResult {
    let list = gltf::list_animations(path).in_file(&path.display().to_string())?;
    if as_json {
        let rows: Vec<_> = list
            .iter()
            .map(|a| {
                json!({
                    "index": a.index,
                    "name": a.name,
                    "channels": a.channels,
                    "start": a.start,
                    "end": a.end,
                    "duration": a.end - a.start,
                    "key_rate": a.key_rate,
                    "properties": a.properties,
                })
            })
            .collect();
        return emit_json(&json!({"file": path.display().to_string(), "animations": rows}));
    }
    let mut text = format!("{}: {} animation(s)\n", path.display(), list.len());
    for a in &list {
        let rate =
            a.key_rate.map_or_else(|| "irregular keys (30 fps default)".to_string(), |r| format!("keys at {r} fps"));
        text.push_str(&format!(
            "{:>3}  {:<16} {:>3} channels  {:.4}–{:.4} s ({:.4} s)  {}  [{}]\n",
            a.index,
            a.name.as_deref().map_or_else(|| "(unnamed)".to_string(), gltf::printable),
            a.channels,
            a.start,
            a.end,
            a.end - a.start,
            rate,
            a.properties.join(", ")
        ));
    }
    emit(&text)
}
