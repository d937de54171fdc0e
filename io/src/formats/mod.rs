//! Reading and writing animation files.
//!
//! | input | how it is recognised | triangles from | frame rate |
//! |---|---|---|---|
//! | OBJ sequence | a directory (every `*.obj` inside) or a file-name pattern with `*` / `?` such as `frames/walk_*.obj`, in natural order (`f2` before `f10`) | the files (all frames must agree) | [`ReadOptions::frame_rate`], else 30 |
//! | single OBJ | `*.obj` | the file | one frame |
//! | PC2 | `*.pc2` | [`ReadOptions::topology`], else `STEM.obj` beside the cache | [`ReadOptions::frame_rate`], else 30 (PC2 stores none) |
//! | MDD | `*.mdd` | as for PC2 | [`ReadOptions::frame_rate`], else derived from the stored times when sane, else 30 |
//! | glTF / GLB | `*.gltf`, `*.glb` (the scene played back: every mesh, node animation, skins, morph targets; [`gltf`]) | the meshes' indices | sampling rate: [`ReadOptions::frame_rate`], else the file's own (animcodec's extras, the key grid), else 30 |
//! | Alembic | `*.abc` (Ogawa; every PolyMesh and SubD object, or those at/under [`ReadOptions::object`], Xform ancestors baked in; [`abc`]; HDF5 archives are refused) | `.faceCounts`/`.faceIndices`, fanned, clockwise turned counter-clockwise | [`ReadOptions::frame_rate`], else one over the sample step (seconds) |
//! | USD | `*.usda`, `*.usdc`, `*.usd`, `*.usdz` (text layer, crate file or package, told apart by the first bytes; every `Mesh` prim, time-sampled `points`; [`usd`], [`usdc`]) | `faceVertexCounts`/`faceVertexIndices`, fanned | [`ReadOptions::frame_rate`], else `timeCodesPerSecond` / the time-code step |
//!
//! Outputs: `.usda`/`.usd` (a text layer, [`usd::encode_usda`]), `.usdc` (a crate file, [`usdc::encode_usdc`]), `.abc` (Alembic, one PolyMesh, [`abc::encode_abc`]), `.pc2`, `.mdd` (each with `STEM.obj` holding frame 0 and the faces written beside
//! it, so the cache can be read back on its own) and OBJ sequences (see [`obj::write_obj_sequence`]).
//! All readers keep the file's own vertex order, check every size against the file length before
//! allocating, and name the file (and frame / vertex / line) in every error.

pub mod abc;
pub mod gltf;
mod gltf_anim;
mod gltf_buffers;
mod gltf_draco;
mod gltf_meshopt;
pub mod gltf_out;
mod gltf_out_buffer;
mod gltf_out_morphs;
mod gltf_out_rd;
mod gltf_scene;
mod gltf_scene_channels;
mod gltf_scene_mesh;
pub mod mdd;
pub mod obj;
pub mod pc2;
pub mod stream;
pub mod usd;
mod usd_assemble;
mod usd_layer;
mod usd_lexer;
mod usd_skel;
mod usd_text;
mod usd_xform;
pub mod usdc;
mod usdz;

use std::cmp::Ordering;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use codec_core::{Animation, Error, Limits, Result, Topology};

use crate::output::{commit_all, OutputPolicy, PendingFile};

/// Frame rate used when neither the file nor [`ReadOptions::frame_rate`] gives one.
pub const DEFAULT_FRAME_RATE: f32 = 30.0;

/// Input formats, for messages: what [`read_animation`] accepts.
pub const SUPPORTED_INPUTS: &str =
    "a directory of .obj files, an .obj file-name pattern with * or ?, .obj, .pc2, .mdd, .gltf, .glb, .usda, .usdc, .usd, .usdz, .abc (Alembic)";

/// Output formats, for messages: what [`write_animation`] accepts.
pub const SUPPORTED_OUTPUTS: &str =
    ".pc2, .mdd, .glb, .gltf (morph targets + weights animation), .usda / .usd (USD text layer, time-sampled points), .usdc (binary USD), .abc (Alembic, one PolyMesh), .obj (an OBJ sequence stem_0000.obj, …) or a \
     directory (frame_0000.obj, …)";

/// Options for [`read_animation`].
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// OBJ file giving the triangles of a PC2/MDD cache. Default: the OBJ with the same stem beside the cache.
    /// Its vertex count must equal the cache's; only its faces are used. Ignored for OBJ and glTF inputs.
    pub topology: Option<PathBuf>,
    /// Frame rate. When given it overrides whatever the file says; otherwise MDD times are used
    /// when they are strictly increasing and give a sane rate, glTF animations are sampled at
    /// their own rate (see [`gltf`]), and everything else gets 30 fps. A PC2 "sample rate" is
    /// the step between samples in frames (usually 1.0), not a frame rate, so PC2 is always
    /// 30 fps unless this is set.
    pub frame_rate: Option<f32>,
    /// glTF: the animation to play, by name or index (default: the first). Ignored for other
    /// inputs.
    pub animation: Option<String>,
    /// Alembic: the mesh object to read by its full path (`/root/char/body`), or an object whose
    /// meshes are read (default: every mesh, merged). Ignored for other inputs.
    pub object: Option<String>,
}

impl ReadOptions {
    /// The frame rate override, checked: `None` when unset, an error outside [`FRAME_RATE_RANGE`].
    fn checked_frame_rate(&self) -> Result<Option<f32>> {
        self.frame_rate.map(check_frame_rate).transpose()
    }
}

/// Frame rates accepted wherever one enters (`--fps`, reading, glTF export and read-back): the
/// ones a stream may carry, so whatever decodes can be read back (one constant for both).
pub use codec_core::animation::FRAME_RATE_RANGE;

/// `fps` when it lies in [`FRAME_RATE_RANGE`], else an error saying so.
pub fn check_frame_rate(fps: f32) -> Result<f32> {
    if FRAME_RATE_RANGE.contains(&fps) {
        Ok(fps)
    } else {
        Err(Error::InvalidAnimation(format!(
            "frame rate {fps:e} is outside the supported range {}..={} frames per second",
            FRAME_RATE_RANGE.start(),
            FRAME_RATE_RANGE.end()
        )))
    }
}

/// Reads an animation, choosing the format from the path: a directory or glob of OBJ files,
/// `.obj`, `.pc2`, `.mdd`, `.gltf` / `.glb`, `.usda` / `.usdc` / `.usd` / `.usdz`, `.abc` (extensions
/// are case-insensitive; a USD file's content decides whether it is a text layer, a crate file
/// or a package).
pub fn read_animation(path: &Path, options: &ReadOptions) -> Result<Animation> {
    let frame_rate = options.checked_frame_rate()?;
    let fps = frame_rate.unwrap_or(DEFAULT_FRAME_RATE);
    if is_pattern(path) {
        return obj::read_obj_sequence(&expand_pattern(path)?, fps);
    }
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path.display().to_string(), e))?;
    if meta.is_dir() {
        return obj::read_obj_sequence(&list_obj_files(path)?, fps);
    }
    match extension(path).as_deref() {
        Some("obj") => obj::read_obj_sequence(&[path.to_path_buf()], fps),
        Some("pc2") => pc2::read_pc2(path, options.topology.as_deref(), frame_rate),
        Some("mdd") => mdd::read_mdd(path, options.topology.as_deref(), frame_rate),
        Some("gltf") | Some("glb") => {
            let selection = gltf::GltfSelection {
                animation: options.animation.clone(),
                frame_rate,
                memory_budget: None,
                working_copies: gltf::COMMAND_WORKING_COPIES,
            };
            gltf::read_gltf(path, &selection)
        }
        Some(ext) if usd::is_usd_extension(ext) => usd::read_usd(path, frame_rate),
        Some("abc") => abc::read_abc(path, options.object.as_deref(), frame_rate),
        _ => Err(Error::Unsupported {
            context: "formats".into(),
            detail: format!("cannot read {}: unknown format; supported inputs: {SUPPORTED_INPUTS}", path.display()),
        }),
    }
}

/// Writes an animation, choosing the format from the output path: `.pc2`, `.mdd` (each also
/// writes `STEM.obj` with frame 0 and the faces beside it), an OBJ sequence (see
/// [`obj::write_obj_sequence`]), or `.glb`/`.gltf`, a morph-target animation ([`gltf_out`],
/// default options: mean shape + principal components meeting KG 0.05 %). Existing files are
/// replaced; see [`write_animation_with`] for the checked form the command line uses.
pub fn write_animation(path: &Path, animation: &Animation) -> Result<()> {
    let options = WriteOptions { policy: OutputPolicy::new(true), topology_obj: true };
    write_animation_with(path, animation, &options).map(|_| ())
}

/// How [`write_animation_with`] writes.
#[derive(Debug, Clone, Default)]
pub struct WriteOptions {
    /// What may be replaced (existing files, inputs). Every file is written to a temporary file
    /// and renamed into place once all of them are complete.
    pub policy: OutputPolicy,
    /// For `.pc2` / `.mdd`: also write `STEM.obj` (frame 0 and the triangles) beside the cache,
    /// so it can be read back on its own.
    pub topology_obj: bool,
}

/// Writes an animation as [`write_animation`] does, under `options`: nothing is written unless
/// every output is allowed by the policy, and either all files are replaced or none. Returns the
/// files written.
pub fn write_animation_with(path: &Path, animation: &Animation, options: &WriteOptions) -> Result<Vec<PathBuf>> {
    if obj::is_directory_target(path) || extension(path).as_deref() == Some("obj") {
        return obj::write_obj_sequence_with(path, animation, &options.policy);
    }
    // A glTF file carries its own triangles: no companion OBJ.
    let (bytes, companion_obj) = match extension(path).as_deref() {
        Some("pc2") => (pc2::encode_pc2(animation)?, options.topology_obj),
        Some("mdd") => (mdd::encode_mdd(animation)?, options.topology_obj),
        Some(ext @ ("glb" | "gltf")) => {
            let bytes = gltf_out::encode_gltf(animation, &gltf_out::GltfOptions::default(), ext == "glb")?.0;
            check_reads_back(path, &bytes, animation)?;
            (bytes, false)
        }
        Some("usda" | "usd") => {
            let bytes = usd::encode_usda(animation)?;
            usd::check_reads_back(path, &bytes, animation)?;
            (bytes, false)
        }
        Some("abc") => {
            // Alembic has no up axis: DCCs read its caches as +Y up, so a +Z-up source is
            // turned to +Y up on the way out (and would otherwise import lying on its back).
            let turned = y_up(animation)?;
            let animation = turned.as_ref().unwrap_or(animation);
            let bytes = abc::encode_abc(animation)?;
            abc::check_reads_back(path, &bytes, animation)?;
            (bytes, false)
        }
        Some("usdc") => {
            let bytes = usdc::encode_usdc(animation)?;
            usd::check_reads_back(path, &bytes, animation)?;
            (bytes, false)
        }
        Some("usdz") => {
            return Err(Error::Unsupported {
                context: "formats".into(),
                detail: format!(
                    "cannot write {}: .usdz packages are read, not written; write .usdc (binary USD) and package it \
                     with usd-core (`UsdUtils.CreateNewUsdzPackage`) if needed",
                    path.display()
                ),
            })
        }
        _ => {
            return Err(Error::Unsupported {
                context: "formats".into(),
                detail: format!(
                    "cannot write {}: unknown format; supported outputs: {SUPPORTED_OUTPUTS}",
                    path.display()
                ),
            })
        }
    };
    let companion = path.with_extension("obj");
    options.policy.check(path)?;
    if companion_obj {
        options.policy.check(&companion)?;
        check_companion_replaced(&options.policy, path, &companion, animation.vertex_count(), animation.triangles())?;
    } else if matches!(extension(path).as_deref(), Some("pc2" | "mdd")) {
        check_existing_companion(path, &companion, animation.vertex_count(), animation.triangles())?;
    }
    let mut files = vec![PendingFile::new(path)?];
    files[0].write_all(&bytes).map_err(|e| files[0].error(e))?;
    if companion_obj {
        let comment = format!(
            "animcodec: topology of {} (frame 0 of {}, {} vertices, {} triangles)",
            path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
            animation.frame_count(),
            animation.vertex_count(),
            animation.topology().triangle_count()
        );
        let text = obj::obj_text(&companion, animation.frame(0), animation.triangles(), &comment)?;
        let mut f = PendingFile::new(&companion)?;
        f.write_all(text.as_bytes()).map_err(|e| f.error(e))?;
        files.push(f);
    }
    let written = files.iter().map(|f| f.target().to_path_buf()).collect();
    commit_all(files, &[])?;
    Ok(written)
}

/// `animation` turned from +Z up to +Y up when its metadata says it is +Z up (a rotation of
/// −90° about X, `(x, y, z) → (x, z, −y)`, exact in `f32`, triangle winding unchanged), with its
/// metadata then saying +Y; `None` when it is already +Y up or says nothing.
pub fn y_up(animation: &Animation) -> Result<Option<Animation>> {
    if animation.metadata().up_axis != Some(codec_core::UpAxis::Z) {
        return Ok(None);
    }
    let positions = animation.positions().chunks_exact(3).flat_map(|p| [p[0], p[2], -p[1]]).collect();
    let metadata = codec_core::SceneMetadata { up_axis: Some(codec_core::UpAxis::Y), ..*animation.metadata() };
    Animation::new(animation.topology().clone(), positions, animation.frame_rate())?.with_metadata(metadata).map(Some)
}

/// A glTF about to be written must read back (with our reader) as an animation of the same
/// frames and vertices: a file that does not is never written.
fn check_reads_back(path: &Path, bytes: &[u8], animation: &Animation) -> Result<()> {
    let back = gltf::parse_gltf(bytes, None, &name(path), animation.frame_rate())
        .map_err(|e| Error::InvalidAnimation(format!("the glTF written does not read back: {e}")))?;
    let (want, got) = ((animation.frame_count(), animation.vertex_count()), (back.frame_count(), back.vertex_count()));
    if want != got {
        return Err(Error::InvalidAnimation(format!(
            "{}: the glTF written reads back as {} frames × {} vertices instead of {} × {}",
            name(path),
            got.0,
            got.1,
            want.0,
            want.1
        )));
    }
    Ok(())
}

/// A cache written without its topology OBJ is read back with the `STEM.obj` beside it: when
/// one is there, it must hold this animation's mesh, or a later read would silently pair
/// another mesh's triangles (same vertex count) with these positions.
fn check_existing_companion(cache: &Path, companion: &Path, vertex_count: usize, triangles: &[[u32; 3]]) -> Result<()> {
    if std::fs::symlink_metadata(companion).is_err() {
        return Ok(());
    }
    let why = match cache_topology(cache, Some(companion), vertex_count) {
        Ok(topology) if topology.triangles() == triangles => return Ok(()),
        Ok(_) => "holds other triangles".to_owned(),
        Err(e) => format!("is not this animation's mesh ({e})"),
    };
    Err(crate::output::refused(
        cache,
        format!(
            "{} beside it {why}, and a later read of the cache would pair it with these positions; \
             write it with --topology-obj (with --force to replace it), or choose another name",
            companion.display()
        ),
    ))
}

/// The first line of the topology OBJ written beside `cache` ([`write_animation_with`],
/// [`stream::CacheWriter`]) starts with this, which tells an OBJ animcodec wrote for that cache.
fn companion_comment_prefix(cache: &Path) -> String {
    let file = cache.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    format!("# animcodec: topology of {file} (")
}

/// `-f` names one output, the cache: unless the policy says the companion was asked for by name
/// ([`OutputPolicy::replace_companions`]), the `STEM.obj` written beside it may replace an
/// existing file only when that file is this cache's own companion (animcodec wrote it for this
/// very cache name) or holds the same mesh (same vertex count and triangles: a reader of any other
/// cache beside it, which uses only its faces, still reads the same). Any other OBJ there may
/// be the topology of another cache of the same stem (`a.pc2` beside `a.mdd`) or a
/// user's model, and is refused by name. The caller has already checked the companion against
/// the output policy (without `--force` an existing one is refused there).
fn check_companion_replaced(
    policy: &OutputPolicy,
    cache: &Path,
    companion: &Path,
    vertex_count: usize,
    triangles: &[[u32; 3]],
) -> Result<()> {
    if policy.replace_companions {
        return Ok(());
    }
    let Ok(meta) = std::fs::metadata(companion) else { return Ok(()) };
    if !meta.is_file() {
        return Ok(()); // a device is written in place; a directory is refused by the policy
    }
    // Read without noting it as an input (it is an output here); a file that cannot be read
    // as an OBJ is not this mesh.
    let same_mesh = match std::fs::read(companion) {
        Ok(bytes) => {
            let first_line = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
            if first_line.starts_with(companion_comment_prefix(cache).as_bytes()) {
                return Ok(());
            }
            obj::parse_obj(&bytes, &name(companion))
                .is_ok_and(|mesh| mesh.vertex_count() == vertex_count && mesh.triangles == triangles)
        }
        Err(_) => false,
    };
    if same_mesh {
        return Ok(());
    }
    Err(crate::output::refused(
        companion,
        format!(
            "it is the topology OBJ that would be written beside {}, but the OBJ already there holds \
             another mesh and was not written for this file (it may be the topology of another cache \
             with the same stem); --force replaces {} only: remove {} or choose another output name",
            cache.display(),
            cache.display(),
            companion.display()
        ),
    ))
}

/// Lower-case extension of a path, if any.
fn extension(path: &Path) -> Option<String> {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase())
}

/// Display form of a path for error contexts.
fn name(path: &Path) -> String {
    path.display().to_string()
}

/// Reads a whole file; the error names the path.
/// The file is noted as read ([`crate::output::note_read`]): no output of the command may
/// replace it.
fn read_file(path: &Path) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(name(path), e))?;
    crate::output::note_read(path, None);
    Ok(bytes)
}

/// Writes a whole file (replacing it) through a temporary file; the error names the path.
fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    OutputPolicy::new(true).write(path, bytes)
}

/// Prefixes the file name to an [`Error::InvalidAnimation`] message (which already names frame,
/// vertex and axis); other errors already carry their context.
fn in_file(file: &str, error: Error) -> Error {
    match error {
        Error::InvalidAnimation(msg) => Error::InvalidAnimation(format!("{file}: {msg}")),
        other => other,
    }
}

/// Checks that every coordinate is finite; the error (from
/// [`check_finite`](codec_core::animation::check_finite)) names the file, frame, vertex and axis.
/// The scan tests exponent bits in branch-free blocks, which vectorizes (several times faster than
/// a short-circuiting `is_finite` search on multi-megabyte caches); the slow path only runs to
/// build the message.
fn check_finite_in(file: &str, positions: &[f32], vertex_count: usize) -> Result<()> {
    codec_core::animation::check_finite(positions, vertex_count, 0).map_err(|e| in_file(file, e))
}

/// Memory a file reader may allocate at once: 4 GiB (the whole address space on 32-bit
/// targets). Readers load a user's own file whole (a 100 000-vertex, 1 000-frame PC2 is 1.2 GB),
/// so they keep the per-allocation bound they had before decodes got their 1 GiB total
/// ([`codec_core::container::DEFAULT_MAX_MEMORY`]); the glTF reader also holds a total budget
/// (`gltf::set_default_memory_budget`, `--max-memory`).
pub const READER_MAX_ALLOC: usize = if usize::MAX as u64 >= 4 << 30 { (4u64 << 30) as usize } else { usize::MAX };

/// The [`Limits`] file readers check header counts and allocations against: the decoders'
/// count limits, [`READER_MAX_ALLOC`] per allocation.
pub fn reader_limits() -> Limits {
    Limits { max_alloc_bytes: READER_MAX_ALLOC, ..Limits::default() }
}

/// Checks a frame count and vertex count read from a file header against [`reader_limits`]
/// and against the number of position bytes the file can hold, before anything is allocated.
/// Returns the number of position floats.
fn check_cache_sizes(file: &str, frames: u64, vertices: u64, position_bytes_available: u64) -> Result<usize> {
    let needed = check_cache_layout(file, frames, vertices, position_bytes_available)?;
    reader_limits().check_alloc("formats", "positions", needed)?;
    Ok((frames * vertices * 3) as usize)
}

/// [`check_cache_sizes`] without the allocation of the whole: the counts against
/// [`reader_limits`] and the file's size; returns the bytes of positions. A streamed read
/// ([`stream::CacheReader`]) holds a chunk at a time.
fn check_cache_layout(file: &str, frames: u64, vertices: u64, position_bytes_available: u64) -> Result<u64> {
    let limits = reader_limits();
    if vertices == 0 {
        return Err(Error::malformed(file.to_owned(), "vertex_count", "is 0: the cache has no vertices"));
    }
    if frames == 0 {
        return Err(Error::malformed(file.to_owned(), "frame_count", "is 0: the cache has no frames"));
    }
    if vertices > limits.max_vertices as u64 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "vertex_count".into(),
            value: vertices,
            limit: limits.max_vertices as u64,
        });
    }
    if frames > limits.max_frames as u64 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "frame_count".into(),
            value: frames,
            limit: limits.max_frames as u64,
        });
    }
    // Both factors are below 2^24, so the product fits easily in u64.
    let needed = frames * vertices * 12;
    if needed > position_bytes_available {
        return Err(Error::malformed(
            file.to_owned(),
            "positions",
            format!(
                "file is truncated: {frames} frames × {vertices} vertices need {needed} bytes of positions, \
                 only {position_bytes_available} present"
            ),
        ));
    }
    if needed < position_bytes_available {
        return Err(Error::malformed(
            file.to_owned(),
            "positions",
            format!(
                "{frames} frames × {vertices} vertices need {needed} bytes of positions but the file holds \
                 {position_bytes_available}: the header does not match the file"
            ),
        ));
    }
    Ok(needed)
}

/// Loads the triangles of a PC2/MDD cache: from `topology` when given, else from the OBJ with the
/// cache's stem beside it. The OBJ must have `vertex_count` vertices.
fn cache_topology(cache: &Path, topology: Option<&Path>, vertex_count: usize) -> Result<Topology> {
    let obj_path = match topology {
        Some(p) => p.to_path_buf(),
        None => {
            let beside = cache.with_extension("obj");
            if !beside.is_file() {
                return Err(Error::io(
                    format!(
                        "{}: no triangles for this cache: {} does not exist; give the topology OBJ with \
                         --topology FILE.obj (ReadOptions::topology)",
                        name(cache),
                        name(&beside)
                    ),
                    std::io::Error::new(std::io::ErrorKind::NotFound, "topology OBJ not found"),
                ));
            }
            beside
        }
    };
    crate::output::note_read(&obj_path, Some(format!("the topology OBJ {} of {}", name(&obj_path), name(cache))));
    let mesh = obj::read_obj(&obj_path)?;
    if mesh.vertex_count() != vertex_count {
        return Err(Error::malformed(
            name(&obj_path),
            "vertex_count",
            format!(
                "the topology OBJ has {} vertices but the cache {} has {vertex_count}",
                mesh.vertex_count(),
                name(cache)
            ),
        ));
    }
    Topology::new(vertex_count, mesh.triangles).map_err(|e| in_file(&name(&obj_path), e))
}

/// True when the last path component contains a wildcard (`*` or `?`) or a frame-number
/// placeholder (`{}` or `#`, as written by [`obj::write_obj_sequence`]).
fn is_pattern(path: &Path) -> bool {
    path.file_name()
        .map(|f| {
            let f = f.to_string_lossy();
            f.contains(['*', '?', '#']) || f.contains("{}")
        })
        .unwrap_or(false)
}

/// Expands a file-name pattern (wildcards only in the last component: `*` any run, `?` one
/// character), in natural order. No match is an error naming the pattern.
fn expand_pattern(pattern: &Path) -> Result<Vec<PathBuf>> {
    // Placeholders: `{}` is any frame number, each `#` one character (one digit of the number).
    let file_pattern =
        pattern.file_name().map(|f| f.to_string_lossy().replace("{}", "*").replace('#', "?")).unwrap_or_default();
    let dir = match pattern.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if dir.to_string_lossy().contains(['*', '?']) {
        return Err(Error::Unsupported {
            context: "formats".into(),
            detail: format!("{}: wildcards are only supported in the file name", pattern.display()),
        });
    }
    let mut files = Vec::new();
    for entry in std::fs::read_dir(&dir).map_err(|e| Error::io(name(&dir), e))? {
        let entry = entry.map_err(|e| Error::io(name(&dir), e))?;
        let file_name = entry.file_name().to_string_lossy().into_owned();
        if wildcard_match(&file_pattern, &file_name) && entry.path().is_file() {
            files.push(entry.path());
        }
    }
    if files.is_empty() {
        return Err(Error::io(
            format!("{}: no file matches this pattern", pattern.display()),
            std::io::Error::new(std::io::ErrorKind::NotFound, "no match"),
        ));
    }
    sort_natural(&mut files);
    Ok(files)
}

/// Every `*.obj` file (extension case-insensitive, not recursive) in a directory, in natural order.
fn list_obj_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(name(dir), e))? {
        let path = entry.map_err(|e| Error::io(name(dir), e))?.path();
        if extension(&path).as_deref() == Some("obj") && path.is_file() {
            files.push(path);
        }
    }
    if files.is_empty() {
        return Err(Error::io(
            format!("{}: the directory contains no .obj file", name(dir)),
            std::io::Error::new(std::io::ErrorKind::NotFound, "no .obj file"),
        ));
    }
    sort_natural(&mut files);
    Ok(files)
}

/// Sorts paths by file name in natural order.
fn sort_natural(paths: &mut [PathBuf]) {
    paths.sort_by(|a, b| {
        let fa = a.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        let fb = b.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        natural_cmp(&fa, &fb).then_with(|| a.cmp(b))
    });
}

/// Natural string order: runs of ASCII digits compare by numeric value (`frame2` < `frame10`),
/// everything else character by character. Equal values with different zero padding order the
/// shorter run first, and the plain string order breaks any remaining tie, so the order is total.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (ab, bb) = (a.as_bytes(), b.as_bytes());
    let (mut i, mut j) = (0, 0);
    while i < ab.len() && j < bb.len() {
        if ab[i].is_ascii_digit() && bb[j].is_ascii_digit() {
            let si = i;
            while i < ab.len() && ab[i].is_ascii_digit() {
                i += 1;
            }
            let sj = j;
            while j < bb.len() && bb[j].is_ascii_digit() {
                j += 1;
            }
            let (ra, rb) = (&a[si..i], &b[sj..j]);
            let (ta, tb) = (ra.trim_start_matches('0'), rb.trim_start_matches('0'));
            // Without leading zeros, a longer digit run is a larger number; equal lengths compare
            // digit by digit. This never overflows, whatever the run length.
            let ord = ta.len().cmp(&tb.len()).then_with(|| ta.cmp(tb)).then_with(|| ra.len().cmp(&rb.len()));
            if ord != Ordering::Equal {
                return ord;
            }
        } else {
            // Compare one (possibly multi-byte) character.
            let ca = a[i..].chars().next().unwrap_or_default();
            let cb = b[j..].chars().next().unwrap_or_default();
            if ca != cb {
                return ca.cmp(&cb);
            }
            i += ca.len_utf8();
            j += cb.len_utf8();
        }
    }
    (ab.len() - i).cmp(&(bb.len() - j)).then_with(|| a.cmp(b))
}

/// Matches a file name against a pattern with `*` (any run, possibly empty) and `?` (one character).
fn wildcard_match(pattern: &str, text: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let t: Vec<char> = text.chars().collect();
    let (mut pi, mut ti) = (0, 0);
    // Classic greedy matcher with one backtrack point: linear in practice, never exponential.
    let mut star: Option<(usize, usize)> = None;
    while ti < t.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, ti));
            pi += 1;
        } else if let Some((sp, st)) = star {
            pi = sp + 1;
            ti = st + 1;
            star = Some((sp, st + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// A unique scratch directory under the system temp dir for tests; removed on drop.
#[cfg(test)]
pub(crate) struct TempDir(pub PathBuf);

#[cfg(test)]
impl TempDir {
    pub(crate) fn new(tag: &str) -> Self {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("animcodec-formats-{tag}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    pub(crate) fn path(&self, file: &str) -> PathBuf {
        self.0.join(file)
    }
}

#[cfg(test)]
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Small animations for the format tests.
#[cfg(test)]
pub(crate) fn test_animation(vertices: usize, frames: usize, fps: f32) -> Animation {
    // A strip of triangles (v, v+1, v+2) and positions with awkward binary expansions, negative
    // values and negative zero, so round trips are tested on more than round numbers.
    let triangles: Vec<[u32; 3]> = (0..vertices.saturating_sub(2) as u32).map(|v| [v, v + 1, v + 2]).collect();
    let positions: Vec<f32> = (0..vertices * frames * 3)
        .map(|i| match i % 7 {
            0 => -0.0,
            1 => (i as f32 * 0.1).sin() * 1e-3,
            2 => 1.0 / 3.0 + i as f32,
            3 => -(i as f32).sqrt() * 12345.678,
            4 => f32::MIN_POSITIVE * i as f32,
            5 => 1e30 / (i as f32 + 1.0),
            _ => i as f32 * 0.7,
        })
        .collect();
    Animation::from_parts(vertices, triangles, positions, fps).unwrap()
}

/// Bit-exact comparison of positions (so -0.0 ≠ 0.0) and equality of the triangles.
#[cfg(test)]
pub(crate) fn assert_same_geometry(a: &Animation, b: &Animation) {
    assert_eq!(a.vertex_count(), b.vertex_count());
    assert_eq!(a.frame_count(), b.frame_count());
    assert_eq!(a.triangles(), b.triangles());
    for (i, (x, y)) in a.positions().iter().zip(b.positions()).enumerate() {
        assert_eq!(x.to_bits(), y.to_bits(), "coordinate {i}: {x} vs {y}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_puts_frame2_before_frame10() {
        let mut names = vec!["f10.obj", "f2.obj", "f1.obj", "f02.obj", "g.obj", "f.obj", "F3.obj", "f100.obj"];
        names.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(names, vec!["F3.obj", "f.obj", "f1.obj", "f2.obj", "f02.obj", "f10.obj", "f100.obj", "g.obj"]);
        // Long digit runs compare without overflow.
        assert_eq!(natural_cmp("a99999999999999999999999", "a100000000000000000000000"), Ordering::Less);
        assert_eq!(natural_cmp("a1b2", "a1b10"), Ordering::Less);
        assert_eq!(natural_cmp("x", "x"), Ordering::Equal);
    }

    #[test]
    fn wildcards_match_file_names() {
        assert!(wildcard_match("walk_*.obj", "walk_0001.obj"));
        assert!(wildcard_match("walk_*.obj", "walk_.obj"));
        assert!(!wildcard_match("walk_*.obj", "run_0001.obj"));
        assert!(!wildcard_match("walk_*.obj", "walk_0001.obj.bak"));
        assert!(wildcard_match("f?.obj", "f1.obj"));
        assert!(!wildcard_match("f?.obj", "f10.obj"));
        assert!(wildcard_match("*a*b*", "xxaxxbxx"));
        assert!(!wildcard_match("*a*b", "xxaxxbxx"));
    }

    #[test]
    fn directory_and_pattern_inputs_read_in_natural_order() {
        let dir = TempDir::new("natural");
        let anim = test_animation(4, 12, 30.0);
        // Frame t goes to f{t}.obj: lexical order would put f10, f11 before f2.
        for t in 0..anim.frame_count() {
            obj::write_obj(&dir.path(&format!("f{t}.obj")), anim.frame(t), anim.triangles(), "test").unwrap();
        }
        std::fs::write(dir.path("notes.txt"), "not an obj").unwrap();
        let from_dir = read_animation(&dir.0, &ReadOptions::default()).unwrap();
        assert_same_geometry(&anim, &from_dir);
        assert_eq!(from_dir.frame_rate(), DEFAULT_FRAME_RATE);
        let opts = ReadOptions { frame_rate: Some(24.0), ..Default::default() };
        let from_glob = read_animation(&dir.path("f*.obj"), &opts).unwrap();
        assert_same_geometry(&anim, &from_glob);
        assert_eq!(from_glob.frame_rate(), 24.0);
        let e = read_animation(&dir.path("nothing_*.obj"), &opts).unwrap_err().to_string();
        assert!(e.contains("nothing_*.obj") && e.contains("no file matches"), "{e}");
    }

    #[test]
    fn unknown_formats_and_missing_files_are_named() {
        let dir = TempDir::new("unknown");
        let p = dir.path("anim.xyz");
        std::fs::write(&p, "x").unwrap();
        let e = read_animation(&p, &ReadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("anim.xyz") && e.contains(".pc2") && e.contains(".glb"), "{e}");
        let e = write_animation(&dir.path("out.xyz"), &test_animation(3, 1, 30.0)).unwrap_err().to_string();
        assert!(e.contains("out.xyz") && e.contains(".mdd"), "{e}");
        let missing = dir.path("missing.pc2");
        let e = read_animation(&missing, &ReadOptions::default()).unwrap_err();
        assert!(matches!(e, Error::Io { .. }) && e.to_string().contains("missing.pc2"), "{e}");
        let empty = TempDir::new("empty");
        let e = read_animation(&empty.0, &ReadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("no .obj file"), "{e}");
        let bad = ReadOptions { frame_rate: Some(f32::NAN), ..Default::default() };
        assert!(read_animation(&p, &bad).is_err());
    }

    /// `-f` names the cache (probe misc); the topology OBJ written beside it replaces an
    /// existing `STEM.obj` only when it is the cache's own (written for this name) or the same
    /// mesh, or when the companion was asked for by name ([`OutputPolicy::replacing_companions`]).
    #[test]
    fn a_companion_obj_replaces_only_its_own_or_the_same_mesh() {
        let dir = TempDir::new("companion");
        let anim = test_animation(7, 3, 30.0);
        let other = test_animation(5, 2, 30.0);
        let force = WriteOptions { policy: OutputPolicy::new(true), topology_obj: true };
        // a.pc2 + a.obj: another cache of the same stem.
        write_animation_with(&dir.path("a.pc2"), &other, &force).unwrap();
        let a_obj = std::fs::read(dir.path("a.obj")).unwrap();
        let e = write_animation_with(&dir.path("a.mdd"), &anim, &force).unwrap_err().to_string();
        assert!(e.contains("a.obj") && e.contains("a.mdd") && e.contains("another mesh"), "{e}");
        assert_eq!(std::fs::read(dir.path("a.obj")).unwrap(), a_obj);
        assert!(!dir.path("a.mdd").exists());
        // The streamed writer refuses it the same way.
        let e = stream::CacheWriter::create(&dir.path("a.mdd"), anim.topology(), 3, 30.0, &force)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("a.obj") && e.contains("another mesh"), "{e}");
        // Its own companion: replaced (a.pc2 rewritten with another mesh).
        write_animation_with(&dir.path("a.pc2"), &anim, &force).unwrap();
        let opts = ReadOptions { frame_rate: Some(30.0), ..Default::default() };
        assert_same_geometry(&anim, &read_animation(&dir.path("a.pc2"), &opts).unwrap());
        // The same mesh (now a.obj holds anim's triangles): a.mdd may replace it.
        write_animation_with(&dir.path("a.mdd"), &anim, &force).unwrap();
        // Asked for by name: replaced whatever it holds.
        std::fs::write(dir.path("b.obj"), "v 0 0 0\n").unwrap();
        let named = WriteOptions { policy: OutputPolicy::new(true).replacing_companions(true), topology_obj: true };
        assert!(write_animation_with(&dir.path("b.pc2"), &anim, &force).is_err());
        write_animation_with(&dir.path("b.pc2"), &anim, &named).unwrap();
    }

    #[test]
    fn every_writer_reads_back_bit_exact() {
        let dir = TempDir::new("roundtrip");
        let anim = test_animation(7, 5, 25.0);
        let opts = ReadOptions { frame_rate: Some(25.0), ..Default::default() };
        for out in ["a.pc2", "b.MDD", "seq.obj", "dir/"] {
            let path = dir.path(out);
            write_animation(&path, &anim).unwrap();
            let back = match out {
                "seq.obj" => read_animation(&dir.path("seq_*.obj"), &opts),
                _ => read_animation(&path, &opts),
            }
            .unwrap_or_else(|e| panic!("{out}: {e}"));
            assert_same_geometry(&anim, &back);
            assert_eq!(back.frame_rate(), 25.0, "{out}");
        }
        // MDD stores times: read back without an override, the rate comes from them.
        let back = read_animation(&dir.path("b.MDD"), &ReadOptions::default()).unwrap();
        assert_eq!(back.frame_rate(), 25.0);
    }
}
