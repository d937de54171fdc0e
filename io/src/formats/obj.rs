//! Wavefront OBJ: single meshes and frame sequences (one file per frame).
//!
//! We parse `v` and `f` ourselves instead of using `tobj`: tobj (4.x) re-indexes every model
//! in order of first use by a face, with or without `single_index`, splits the file into
//! models per `o`/`g`, and drops vertices no face references. The animation needs the file's own
//! `v` order (it must match PC2/MDD caches and the other frames), and tobj exposes no map back to
//! the original indices.
//!
//! Parsing rules: every `v x y z [w | r g b]` line adds a vertex in file order, whatever `o`/`g`
//! block it is in (all objects and groups merge into one list); extra components are ignored.
//! `f` corners may be `i`, `i/t`, `i//n` or `i/t/n`; only the position index is used; negative
//! indices count back from the last vertex defined so far; polygons are triangulated as a fan
//! around their first corner (exact for convex polygons, which is what exporters write).
//! `l`, `p`, `vt`, `vn`, `o`, `g`, `s`, `usemtl`, `mtllib` and unknown statements are ignored;
//! line continuations (`\` at the end of a line) are not supported.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use codec_core::animation::check_finite;
use codec_core::{Animation, Error, Result, Topology};

use super::{in_file, name, read_file, write_file};
use crate::output::{commit_all, OutputPolicy, PendingFile};

/// One OBJ file: positions in file order and its triangles (0-based).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjMesh {
    /// Interleaved x y z, one triple per `v` line, in file order.
    pub positions: Vec<f32>,
    /// Triangles (polygons fan-triangulated), 0-based indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
}

impl ObjMesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len() / 3
    }
}

/// Reads one OBJ file.
pub fn read_obj(path: &Path) -> Result<ObjMesh> {
    parse_obj(&read_file(path)?, &name(path))
}

/// Parses OBJ text (bytes: comments in other encodings are fine). `file` names the source in errors,
/// which also give the line number.
pub fn parse_obj(bytes: &[u8], file: &str) -> Result<ObjMesh> {
    let limits = super::reader_limits();
    let mut positions: Vec<f32> = Vec::new();
    // Faces as raw 0-based indices; positive indices are range-checked once all `v` are known.
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut max_index_line: Option<(u32, usize)> = None;
    let mut corners: Vec<u32> = Vec::with_capacity(8);
    for (line_no, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = line_no + 1;
        let mut tokens = raw.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else { continue };
        match keyword {
            b"v" => {
                let mut xyz = [0f32; 3];
                for (axis, slot) in xyz.iter_mut().enumerate() {
                    let token = tokens.next().ok_or_else(|| {
                        Error::malformed(file.to_owned(), "v", format!("line {line_no}: a vertex needs x, y and z"))
                    })?;
                    let value =
                        std::str::from_utf8(token).ok().and_then(|s| s.parse::<f32>().ok()).ok_or_else(|| {
                            Error::malformed(
                                file.to_owned(),
                                "v",
                                format!("line {line_no}: '{}' is not a number", String::from_utf8_lossy(token)),
                            )
                        })?;
                    if !value.is_finite() {
                        return Err(Error::InvalidAnimation(format!(
                            "{file}: line {line_no}: non-finite coordinate {value} at vertex {}, axis {}",
                            positions.len() / 3,
                            ["x", "y", "z"][axis]
                        )));
                    }
                    *slot = value;
                }
                if positions.len() / 3 >= limits.max_vertices {
                    return Err(Error::LimitExceeded {
                        context: file.to_owned().into(),
                        field: "vertex_count".into(),
                        value: (positions.len() / 3 + 1) as u64,
                        limit: limits.max_vertices as u64,
                    });
                }
                positions.extend_from_slice(&xyz);
            }
            b"f" => {
                corners.clear();
                let defined = positions.len() / 3;
                for token in tokens {
                    let index_part = token.split(|&b| b == b'/').next().unwrap_or_default();
                    let index =
                        std::str::from_utf8(index_part).ok().and_then(|s| s.parse::<i64>().ok()).ok_or_else(|| {
                            Error::malformed(
                                file.to_owned(),
                                "f",
                                format!("line {line_no}: '{}' is not a vertex index", String::from_utf8_lossy(token)),
                            )
                        })?;
                    let resolved = match index {
                        i if i > 0 && i <= u32::MAX as i64 => i - 1,
                        i if i < 0 && -i <= defined as i64 => defined as i64 + i,
                        _ => {
                            return Err(Error::malformed(
                                file.to_owned(),
                                "f",
                                format!("line {line_no}: vertex index {index} is out of range ({defined} vertices defined so far)"),
                            ))
                        }
                    };
                    let resolved = resolved as u32;
                    if max_index_line.is_none_or(|(m, _)| resolved > m) {
                        max_index_line = Some((resolved, line_no));
                    }
                    corners.push(resolved);
                }
                if corners.len() < 3 {
                    return Err(Error::malformed(
                        file.to_owned(),
                        "f",
                        format!("line {line_no}: a face needs at least 3 vertices, found {}", corners.len()),
                    ));
                }
                push_fan(&corners, &mut triangles);
                if triangles.len() > limits.max_triangles {
                    return Err(Error::LimitExceeded {
                        context: file.to_owned().into(),
                        field: "triangle_count".into(),
                        value: triangles.len() as u64,
                        limit: limits.max_triangles as u64,
                    });
                }
            }
            _ => {}
        }
    }
    let vertex_count = positions.len() / 3;
    if let Some((max, line_no)) = max_index_line {
        if max as usize >= vertex_count {
            return Err(Error::malformed(
                file.to_owned(),
                "f",
                format!(
                    "line {line_no}: vertex index {} is out of range (the file has {vertex_count} vertices)",
                    max + 1
                ),
            ));
        }
    }
    if vertex_count == 0 {
        return Err(Error::malformed(file.to_owned(), "v", "the file has no vertices"));
    }
    Ok(ObjMesh { positions, triangles })
}

/// Triangulates a polygon (at least 3 corners) as a fan around its first corner, keeping its
/// winding: `[c0, ck, ck+1]` for each k. Every reader of polygons fans them this way.
pub(crate) fn push_fan(corners: &[u32], triangles: &mut Vec<[u32; 3]>) {
    for k in 1..corners.len().saturating_sub(1) {
        triangles.push([corners[0], corners[k], corners[k + 1]]);
    }
}

/// Reads OBJ files as the frames of one animation, in the order given. Every file must have the
/// vertex count and the triangle list of the first; errors name the file and the first mismatch.
pub fn read_obj_sequence(paths: &[PathBuf], frame_rate: f32) -> Result<Animation> {
    let first_path = paths.first().ok_or_else(|| Error::InvalidAnimation("no OBJ file to read".into()))?;
    let first = read_obj(first_path)?;
    let vertex_count = first.vertex_count();
    let floats = vertex_count * 3;
    let total = floats.checked_mul(paths.len()).filter(|&n| n <= super::reader_limits().max_alloc_bytes / 4);
    let total = total.ok_or_else(|| {
        Error::InvalidAnimation(format!("{} frames of {vertex_count} vertices are too many to hold", paths.len()))
    })?;
    let mut positions = Vec::with_capacity(total);
    positions.extend_from_slice(&first.positions);
    let topology = sequence_topology(first_path, vertex_count, first.triangles)?;
    for path in &paths[1..] {
        positions.extend_from_slice(&read_sequence_frame(path, first_path, &topology)?.positions);
    }
    let file = if paths.len() == 1 { name(first_path) } else { format!("{}…", name(first_path)) };
    Animation::new(topology, positions, frame_rate).map_err(|e| in_file(&file, e))
}

/// The topology of a sequence whose frame 0, read from `first_path` (named in errors), has
/// `vertex_count` vertices and `triangles`.
pub(crate) fn sequence_topology(first_path: &Path, vertex_count: usize, triangles: Vec<[u32; 3]>) -> Result<Topology> {
    Topology::new(vertex_count, triangles).map_err(|e| in_file(&name(first_path), e))
}

/// Reads the frame file `path` of a sequence whose frame 0 (`first_path`) has `topology`, and
/// checks that it has the same vertex count and triangles; the error names the file and the
/// first mismatch. Shared by the whole read ([`read_obj_sequence`]) and the streamed one
/// ([`super::stream::CacheReader`]), so both say the same thing.
pub(crate) fn read_sequence_frame(path: &Path, first_path: &Path, topology: &Topology) -> Result<ObjMesh> {
    let mesh = read_obj(path)?;
    let vertex_count = topology.vertex_count();
    if mesh.vertex_count() != vertex_count {
        return Err(Error::malformed(
            name(path),
            "vertex_count",
            format!("{} vertices, but {} (frame 0) has {vertex_count}", mesh.vertex_count(), name(first_path)),
        ));
    }
    if mesh.triangles != topology.triangles() {
        let detail = match mesh.triangles.iter().zip(topology.triangles()).position(|(a, b)| a != b) {
            Some(t) => format!(
                "triangle {t} is {:?} but in {} (frame 0) it is {:?} (0-based indices)",
                mesh.triangles[t],
                name(first_path),
                topology.triangles()[t]
            ),
            None => format!(
                "{} triangles, but {} (frame 0) has {}",
                mesh.triangles.len(),
                name(first_path),
                topology.triangle_count()
            ),
        };
        return Err(Error::malformed(name(path), "faces", detail));
    }
    Ok(mesh)
}

/// Writes one OBJ file: a comment line, the vertices (`{}` Display of `f32`, which reads back to
/// the identical value) and the triangles as 1-based `f` lines.
pub fn write_obj(path: &Path, positions: &[f32], triangles: &[[u32; 3]], comment: &str) -> Result<()> {
    write_file(path, obj_text(path, positions, triangles, comment)?.as_bytes())
}

/// The text [`write_obj`] writes; `path` names the file in errors.
pub fn obj_text(path: &Path, positions: &[f32], triangles: &[[u32; 3]], comment: &str) -> Result<String> {
    // Finite positions are the caller's contract ([`Animation`] guarantees it); check anyway so
    // a bad slice is an error, not a file that fails later.
    check_finite(positions, (positions.len() / 3).max(1), 0).map_err(|e| in_file(&name(path), e))?;
    let mut text = String::with_capacity(positions.len() * 12 + triangles.len() * 24 + 64);
    for line in comment.lines() {
        let _ = writeln!(text, "# {line}");
    }
    for p in positions.chunks_exact(3) {
        let _ = writeln!(text, "v {} {} {}", p[0], p[1], p[2]);
    }
    for t in triangles {
        let _ = writeln!(text, "f {} {} {}", t[0] as u64 + 1, t[1] as u64 + 1, t[2] as u64 + 1);
    }
    Ok(text)
}

/// True when an output path names a directory: an existing one, or a path ending in `/`.
pub fn is_directory_target(path: &Path) -> bool {
    let s = path.as_os_str().to_string_lossy();
    path.is_dir() || s.ends_with('/') || s.ends_with(std::path::MAIN_SEPARATOR)
}

/// How the frames of a sequence are named.
enum Naming {
    /// `DIR/frame_0000.obj`, …. Reading `DIR` back reads every `*.obj` in it, so other `.obj`
    /// files there are refused (never removed).
    Directory(PathBuf),
    /// A file name with `prefix`, the frame number (`width` digits, more when needed) and
    /// `suffix`; `min_width` is the fewest digits a frame of this name pattern has.
    Template { dir: PathBuf, prefix: String, width: usize, min_width: usize, suffix: String },
}

/// Digits of a directory target's frame numbers (`frame_0000.obj`), and of `{}` and plain names.
const MIN_FRAME_DIGITS: usize = 4;

impl Naming {
    fn of(path: &Path, frames: usize) -> Naming {
        let digits = frames.saturating_sub(1).to_string().len().max(MIN_FRAME_DIGITS);
        if is_directory_target(path) {
            return Naming::Directory(path.to_path_buf());
        }
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let file = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        if let Some(at) = file.find("{}") {
            return Naming::Template {
                dir,
                prefix: file[..at].into(),
                width: digits,
                min_width: MIN_FRAME_DIGITS,
                suffix: file[at + 2..].into(),
            };
        }
        if let Some(at) = file.find('#') {
            let run = file[at..].chars().take_while(|&c| c == '#').count();
            return Naming::Template {
                dir,
                prefix: file[..at].into(),
                width: run.max(frames.saturating_sub(1).to_string().len()),
                min_width: run,
                suffix: file[at + run..].into(),
            };
        }
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "frame".into());
        let ext = path.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_else(|| ".obj".into());
        Naming::Template { dir, prefix: format!("{stem}_"), width: digits, min_width: MIN_FRAME_DIGITS, suffix: ext }
    }

    fn dir(&self) -> &Path {
        match self {
            Naming::Directory(d) | Naming::Template { dir: d, .. } => d,
        }
    }

    fn file(&self, t: usize, frames: usize) -> PathBuf {
        match self {
            Naming::Directory(d) => {
                let digits = frames.saturating_sub(1).to_string().len().max(MIN_FRAME_DIGITS);
                d.join(format!("frame_{t:0digits$}.obj"))
            }
            Naming::Template { dir, prefix, width, suffix, .. } => dir.join(format!("{prefix}{t:0width$}{suffix}")),
        }
    }

    /// True when an existing file name is of this sequence's name pattern: the prefix (`frame_`
    /// for a directory), a frame number of at least the pattern's digits and the suffix
    /// (`.obj`), matched exactly (case included). Only such files are replaced or removed.
    fn is_frame(&self, file_name: &str) -> bool {
        let (prefix, min_width, suffix) = match self {
            Naming::Directory(_) => ("frame_", MIN_FRAME_DIGITS, ".obj"),
            Naming::Template { prefix, min_width, suffix, .. } => (prefix.as_str(), *min_width, suffix.as_str()),
        };
        file_name
            .strip_prefix(prefix)
            .and_then(|rest| rest.strip_suffix(suffix))
            .is_some_and(|digits| digits.len() >= min_width && digits.bytes().all(|b| b.is_ascii_digit()))
    }

    /// True when reading the sequence back would also read `file_name`, though it is not of the
    /// sequence's name pattern: any other `.obj` (any case) in a directory target.
    fn would_be_read_with(&self, file_name: &str) -> bool {
        matches!(self, Naming::Directory(_))
            && file_name.to_ascii_lowercase().ends_with(".obj")
            && !self.is_frame(file_name)
    }
}

/// Writes every frame as an OBJ file (with the faces) and returns the files written, in order.
/// Existing files are replaced and stale frames of an older sequence removed
/// (see [`write_obj_sequence_with`]).
pub fn write_obj_sequence(path: &Path, animation: &Animation) -> Result<Vec<PathBuf>> {
    write_obj_sequence_with(path, animation, &OutputPolicy::new(true))
}

/// Writes every frame as an OBJ file (with the faces) and returns the files written, in order.
///
/// Names: a directory target (existing, or ending in `/`; created if missing) receives
/// `frame_0000.obj`, `frame_0001.obj`, …; a file name with `{}` gets the frame number there
/// (`seq/f_{}.obj` → `seq/f_0000.obj`, …), one with a run of `#` the frame number padded to the
/// run's length (`f_###.obj` → `f_000.obj`, …); a plain `DIR/stem.obj` receives
/// `DIR/stem_0000.obj`, …, except that a one-frame animation is written to exactly
/// `DIR/stem.obj`. Frame numbers have at least 4 digits (`{}` and plain names), more when
/// needed so that plain and natural order agree.
///
/// Safety: a sequence owns only the files of its name pattern: the prefix (`frame_` in a
/// directory target, the text before `{}`/`#` in a template, `stem_` for a plain name), a frame
/// number of at least as many digits as the pattern gives (4 for a directory, `{}` and plain
/// names; the run's length for `#`), and the suffix (`.obj`, or what follows the placeholder),
/// matched exactly, case included. Files of that pattern not written now (an older, longer
/// sequence) are stale. Unless the policy allows overwriting, existing or stale frames make this
/// an error and nothing is written; with overwriting, stale frames are removed. No other file
/// is ever replaced or removed: a directory target holding any other `.obj` (which reading the
/// folder back would take as a frame) is refused even with overwriting. All frames are written
/// to temporary files first and renamed into place together.
pub fn write_obj_sequence_with(path: &Path, animation: &Animation, policy: &OutputPolicy) -> Result<Vec<PathBuf>> {
    let frames = animation.frame_count();
    let naming = Naming::of(path, frames);
    let has_placeholder = matches!(&naming, Naming::Template { .. })
        && path.file_name().is_some_and(|f| f.to_string_lossy().contains(['#', '{']));
    let files: Vec<PathBuf> = if frames == 1 && !has_placeholder && !matches!(naming, Naming::Directory(_)) {
        vec![path.to_path_buf()]
    } else {
        (0..frames).map(|t| naming.file(t, frames)).collect()
    };
    let dir = naming.dir().to_path_buf();
    // Existing frame files (ours or stale), found before anything is created.
    let mut existing = Vec::new();
    let mut foreign = Vec::new();
    if let Ok(entries) = std::fs::read_dir(&dir) {
        for entry in entries.flatten() {
            let file_name = entry.file_name().to_string_lossy().into_owned();
            let p = entry.path();
            if p.is_file() && naming.would_be_read_with(&file_name) {
                foreign.push(p);
            } else if p.is_file()
                && (naming.is_frame(&file_name) || files.iter().any(|f| f.file_name() == p.file_name()))
            {
                existing.push(p);
            }
        }
    }
    if !foreign.is_empty() {
        // Never removed, and never silently mixed into the sequence when it is read back.
        super::sort_natural(&mut foreign);
        let names: Vec<String> =
            foreign.iter().take(3).map(|p| p.file_name().unwrap_or_default().to_string_lossy().into_owned()).collect();
        return Err(crate::output::refused(
            path,
            format!(
                "{} holds {} other .obj file{} ({}{}) that reading the folder back would take as frames; they \
                 are never removed (even with --force): write to an empty folder, or name the frames with a \
                 pattern such as {}",
                dir.display(),
                foreign.len(),
                if foreign.len() == 1 { "" } else { "s" },
                names.join(", "),
                if foreign.len() > 3 { ", …" } else { "" },
                dir.join("frame_{}.obj").display()
            ),
        ));
    }
    super::sort_natural(&mut existing);
    let stale: Vec<PathBuf> =
        existing.iter().filter(|p| !files.iter().any(|f| f.file_name() == p.file_name())).cloned().collect();
    if !policy.overwrite && !existing.is_empty() {
        return Err(crate::output::refused(
            path,
            format!(
                "{} already holds {} frame file{} of this sequence ({}{}) that would be read with the new frames; \
                 use -f/--force to replace them (older frames beyond the new ones are then removed)",
                dir.display(),
                existing.len(),
                if existing.len() == 1 { "" } else { "s" },
                existing[0].file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
                if existing.len() > 1 { ", …" } else { "" }
            ),
        ));
    }
    let checks = OutputPolicy { overwrite: true, inputs: policy.inputs.clone(), replace_companions: false };
    for f in files.iter().chain(&stale) {
        checks.check(f)?;
    }
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(name(&dir), e))?;
    let mut pending = Vec::with_capacity(files.len());
    for (t, file) in files.iter().enumerate() {
        let comment = format!("animcodec: frame {t} of {frames}, {} vertices", animation.vertex_count());
        let text = obj_text(file, animation.frame(t), animation.triangles(), &comment)?;
        let mut out = PendingFile::new(file)?;
        out.write_all(text.as_bytes()).map_err(|e| out.error(e))?;
        pending.push(out);
    }
    commit_all(pending, &stale)?;
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::super::{assert_same_geometry, read_animation, test_animation, write_animation, ReadOptions, TempDir};
    use super::*;

    #[test]
    fn parses_groups_polygons_negative_indices_and_slashes() {
        let text = b"# comment \xff latin1\r\n\
            mtllib x.mtl\r\n\
            o first\n\
            v 0 0 0\n\
            v 1 0 0 1.0\n\
            vt 0 0\n\
            vn 0 0 1\n\
            v 1 1 0 0.5 0.5 0.5\n\
            g second\n\
            v 0 1 0\n\
            usemtl m\n\
            s off\n\
            f 1/1/1 2/1/1 3/1/1 4/1/1\n\
            f -4//1 -2//1 -1//1\n\
            l 1 2\n\
            \n";
        let mesh = parse_obj(text, "t.obj").unwrap();
        assert_eq!(mesh.positions, vec![0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.]);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    }

    #[test]
    fn keeps_unreferenced_vertices_in_file_order() {
        // tobj would drop vertex 1 and renumber: we must not.
        let mesh = parse_obj(b"v 5 5 5\nv 9 9 9\nv 1 1 1\nv 2 2 2\nf 4 3 1\n", "t.obj").unwrap();
        assert_eq!(mesh.vertex_count(), 4);
        assert_eq!(mesh.positions[3..6], [9., 9., 9.]);
        assert_eq!(mesh.triangles, vec![[3, 2, 0]]);
    }

    #[test]
    fn malformed_lines_are_errors_naming_file_and_line() {
        let cases: [(&[u8], &str); 8] = [
            (b"v 1 2\n", "line 1"),
            (b"v 1 2 x\n", "'x' is not a number"),
            (b"v 0 0 0\nv 1 nan 0\n", "non-finite"),
            (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "vertex index 4"),
            (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "line 4"),
            (b"v 0 0 0\nf -2 1 1\n", "out of range"),
            (b"v 0 0 0\nv 1 0 0\nf 1 2\n", "at least 3"),
            (b"# only a comment\n", "no vertices"),
        ];
        for (text, expected) in cases {
            let e = parse_obj(text, "bad.obj").unwrap_err().to_string();
            assert!(e.contains("bad.obj") && e.contains(expected), "{e} (expected '{expected}')");
        }
        let e = parse_obj(b"v 0 inf 0\n", "bad.obj").unwrap_err().to_string();
        assert!(e.contains("vertex 0, axis y") && e.contains("line 1"), "{e}");
    }

    #[test]
    fn single_obj_is_one_frame_and_writes_back_exactly() {
        let dir = TempDir::new("single-obj");
        let anim = test_animation(6, 1, 30.0);
        let path = dir.path("one.obj");
        write_animation(&path, &anim).unwrap();
        assert!(path.is_file(), "a one-frame animation writes exactly the named file");
        let back = read_animation(&path, &ReadOptions::default()).unwrap();
        assert_same_geometry(&anim, &back);
        assert_eq!(back.frame_count(), 1);
    }

    #[test]
    fn sequence_file_names_follow_the_target() {
        let dir = TempDir::new("seq-names");
        let anim = test_animation(3, 3, 30.0);
        let files = write_obj_sequence(&dir.path("walk.obj"), &anim).unwrap();
        let names: Vec<_> = files.iter().map(|f| f.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["walk_0000.obj", "walk_0001.obj", "walk_0002.obj"]);
        let out = dir.path("frames/");
        let files = write_obj_sequence(&out, &anim).unwrap();
        assert_eq!(files[2], dir.path("frames").join("frame_0002.obj"));
        assert!(files.iter().all(|f| f.is_file()));
        let text = std::fs::read_to_string(&files[0]).unwrap();
        assert!(text.contains("\nf 1 2 3\n"), "faces are written 1-based: {text}");
    }

    #[test]
    fn mismatched_frames_are_errors_naming_the_file() {
        let dir = TempDir::new("mismatch");
        let anim = test_animation(5, 2, 30.0);
        let f0 = dir.path("a0.obj");
        write_obj(&f0, anim.frame(0), anim.triangles(), "").unwrap();
        // Fewer vertices.
        let f1 = dir.path("a1.obj");
        write_obj(&f1, &anim.frame(1)[..12], &anim.triangles()[..2], "").unwrap();
        let e = read_obj_sequence(&[f0.clone(), f1.clone()], 30.0).unwrap_err().to_string();
        assert!(e.contains("a1.obj") && e.contains("4 vertices") && e.contains("has 5"), "{e}");
        // Same count, different connectivity at triangle 1.
        let mut tris = anim.triangles().to_vec();
        tris[1] = [0, 1, 4];
        write_obj(&f1, anim.frame(1), &tris, "").unwrap();
        let e = read_obj_sequence(&[f0.clone(), f1.clone()], 30.0).unwrap_err().to_string();
        assert!(e.contains("a1.obj") && e.contains("triangle 1 is [0, 1, 4]"), "{e}");
        // Same count, one triangle fewer.
        write_obj(&f1, anim.frame(1), &anim.triangles()[..2], "").unwrap();
        let e = read_obj_sequence(&[f0.clone(), f1.clone()], 30.0).unwrap_err().to_string();
        assert!(e.contains("a1.obj") && e.contains("2 triangles"), "{e}");
        // A missing frame names its path.
        let e = read_obj_sequence(&[f0, dir.path("gone.obj")], 30.0).unwrap_err().to_string();
        assert!(e.contains("gone.obj"), "{e}");
    }
}
