//! Reading and writing animation files (placeholder signatures; filled in by the formats work item).

use std::path::{Path, PathBuf};

use codec_core::{Animation, Error, Result};

/// Options for [`read_animation`].
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// OBJ file giving the triangles of a PC2/MDD cache. Default: the OBJ with the same stem beside the cache.
    pub topology: Option<PathBuf>,
    /// Frame rate to use when the file stores none (PC2 sample rate and MDD times are used when sane). Default 30.
    pub frame_rate: Option<f32>,
}

/// Reads an animation, choosing the format from the path: a directory or glob of OBJ files,
/// `.pc2`, `.mdd`, `.gltf` / `.glb`.
pub fn read_animation(path: &Path, options: &ReadOptions) -> Result<Animation> {
    let _ = options;
    Err(Error::Unsupported { context: "formats".into(), detail: format!("reading {} is not implemented yet", path.display()) })
}

/// Writes an animation, choosing the format from the output path: `.pc2`, `.mdd`, or an OBJ
/// sequence (a path ending in `.obj` containing `{}` or `#` for the frame number, or a directory).
pub fn write_animation(path: &Path, animation: &Animation) -> Result<()> {
    let _ = animation;
    Err(Error::Unsupported { context: "formats".into(), detail: format!("writing {} is not implemented yet", path.display()) })
}
