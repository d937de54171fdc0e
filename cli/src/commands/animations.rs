//! `animcodec list-animations` (and `info` on a glTF or Alembic file): the animations of a
//! glTF/GLB file, what `--animation` chooses from, or the mesh objects of an Alembic archive,
//! what `--object` chooses from.

use std::path::Path;

use animcodec::formats::{abc, gltf};
use serde_json::json;

use super::{emit, emit_json, CmdResult, WithContext};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `animcodec list-animations`.
#[derive(Debug, Args)]
pub struct ListAnimationsArgs {
    /// A `.gltf`, `.glb` or `.abc` file.
    #[arg(value_name = "FILE.glb")]
    pub input: PathBuf,

    /// Print JSON: {file, animations: [{index, name, channels, start, end, key_rate, properties}]}.
    #[arg(long)]
    pub json: bool,
}

/// Lists the animations of `path` (the meshes of an `.abc`), as text or JSON.
pub fn run(path: &Path, as_json: bool) -> CmdResult {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("abc")) {
        return run_abc(path, as_json);
    }
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

/// Lists the mesh objects of an Alembic archive: path, schema, points, faces, samples, times.
fn run_abc(path: &Path, as_json: bool) -> CmdResult {
    let list = abc::list_meshes(path).in_file(&path.display().to_string())?;
    if as_json {
        let rows: Vec<_> = list
            .iter()
            .map(|m| {
                json!({
                    "path": m.path,
                    "schema": m.schema,
                    "vertices": m.vertices,
                    "faces": m.faces,
                    "triangles": m.triangles,
                    "frames": m.samples,
                    "start": m.start,
                    "end": m.end,
                })
            })
            .collect();
        return emit_json(&json!({"file": path.display().to_string(), "meshes": rows}));
    }
    let mut text =
        format!("{}: {} mesh object(s) (--object PATH reads one; default: all, merged)\n", path.display(), list.len());
    for m in &list {
        text.push_str(&format!(
            "  {}  {}  {} vertices, {} faces ({} triangles), {} frames, {:.4}–{:.4} s\n",
            gltf::printable(&m.path),
            m.schema,
            m.vertices,
            m.faces,
            m.triangles,
            m.samples,
            m.start,
            m.end
        ));
    }
    emit(&text)
}
