//! Streamed reading of PC2 and MDD caches and of OBJ sequences (issue 30): a cache's header is
//! read and checked against [`super::reader_limits`] and the file's size before
//! anything else, an OBJ sequence's files are listed and its frame 0 read for the topology; then
//! frames are handed out in chunks as they are read, so an animation far larger than memory (a
//! 1 000 000-vertex, 1 000-frame PC2 is 12 GB) can be encoded by a streaming encoder.
//!
//! The frames, topology and frame rate are exactly those of [`read_animation`](super::read_animation)
//! on the same input and options (tested), and the same errors are raised (a non-finite coordinate
//! names the file, frame, vertex and axis; an OBJ file whose mesh differs from frame 0's names the
//! file and the first mismatch), only later: a bad frame 900 is found when frame 900 is read.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use codec_core::{Error, Result, Topology};

use super::{
    cache_topology, check_cache_layout, check_existing_companion, expand_pattern, extension, in_file, is_pattern,
    list_obj_files, mdd, name, obj, pc2, reader_limits, ReadOptions, WriteOptions, DEFAULT_FRAME_RATE,
};
use crate::output::{commit_all, PendingFile};

/// Byte order of the positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Endian {
    Little,
    Big,
}

/// Where a [`CacheReader`]'s frames come from.
#[derive(Debug)]
enum Frames {
    /// A PC2 or MDD file: fixed-size frames from `data_offset` on.
    Cache {
        reader: BufReader<File>,
        endian: Endian,
        /// One frame of bytes.
        bytes: Vec<u8>,
        /// Byte offset of frame 0's positions ([`CacheReader::seek_frame`]).
        data_offset: u64,
    },
    /// An OBJ sequence: one file per frame, in [`read_animation`](super::read_animation)'s
    /// order. Only the list of paths is kept, and frame 0's positions (read for the topology)
    /// until they are handed out: every other file is read when its frame is.
    Obj { paths: Vec<PathBuf>, first: Option<Vec<f32>> },
}

/// A PC2 or MDD cache, or an OBJ sequence (a directory of `.obj` files or a file-name pattern),
/// opened for reading frame by frame.
#[derive(Debug)]
pub struct CacheReader {
    file: String,
    frames: Frames,
    topology: Topology,
    frame_rate: f32,
    frame_count: usize,
    frames_read: usize,
}

/// Whether [`CacheReader::open`] reads `path` frame by frame: a `.pc2` or `.mdd` file (any case),
/// a directory (its `.obj` files) or a file-name pattern (`*`, `?`, `#`, `{}`), which
/// [`read_animation`](super::read_animation) reads as an OBJ sequence.
pub fn is_streamable(path: &Path) -> bool {
    (matches!(extension(path).as_deref(), Some("pc2" | "mdd")) && path.is_file()) || is_pattern(path) || path.is_dir()
}

fn read_exact(reader: &mut impl Read, buf: &mut [u8], file: &str, field: &str) -> Result<()> {
    reader.read_exact(buf).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            Error::Truncated { context: file.to_owned().into(), field: field.to_owned().into() }
        } else {
            Error::io(file.to_owned(), e)
        }
    })
}

impl CacheReader {
    /// Opens a `.pc2` or `.mdd` cache: reads and checks its header (counts against the reader
    /// limits, position bytes against the file's size), its topology (as [`pc2::read_pc2`]) and,
    /// for MDD, its frame times (for the frame rate). No positions are read yet.
    ///
    /// A directory or a file-name pattern is an OBJ sequence: its files are listed as
    /// [`read_animation`](super::read_animation) lists them (same order, same error when there
    /// is none) and frame 0's file is read for the topology; the others are read as their
    /// frames are. `options.topology` is ignored, as it is by the whole read.
    pub fn open(path: &Path, options: &ReadOptions) -> Result<Self> {
        let frame_rate = options.checked_frame_rate()?;
        if is_pattern(path) {
            return Self::open_obj_sequence(path, expand_pattern(path)?, frame_rate);
        }
        if path.is_dir() {
            return Self::open_obj_sequence(path, list_obj_files(path)?, frame_rate);
        }
        let file = name(path);
        let handle = File::open(path).map_err(|e| Error::io(file.clone(), e))?;
        crate::output::note_read(path, None);
        let size = handle.metadata().map_err(|e| Error::io(file.clone(), e))?.len();
        let mut reader = BufReader::with_capacity(1 << 20, handle);
        let (endian, vertices, frames, fps, data_offset) = match extension(path).as_deref() {
            Some("pc2") => {
                let mut h = [0u8; pc2::HEADER_BYTES];
                read_exact(&mut reader, &mut h, &file, "header")?;
                // The header is parsed by the in-memory parser, so both agree on every check.
                let header = pc2::parse_header(&h, &file)?;
                let (v, f) = (header.vertex_count as u64, header.frame_count as u64);
                check_cache_layout(&file, f, v, size.saturating_sub(pc2::HEADER_BYTES as u64))?;
                (
                    Endian::Little,
                    v as usize,
                    f as usize,
                    frame_rate.unwrap_or(DEFAULT_FRAME_RATE),
                    pc2::HEADER_BYTES as u64,
                )
            }
            Some("mdd") => {
                let mut h = [0u8; 8];
                read_exact(&mut reader, &mut h, &file, "header")?;
                let (frames, vertices) = mdd::parse_counts(&h, &file)?;
                let times_bytes = frames * 4;
                if times_bytes > size.saturating_sub(8) {
                    return Err(Error::malformed(
                        file.clone(),
                        "times",
                        format!(
                            "file is truncated: {frames} frame times need {times_bytes} bytes, only {} present",
                            size.saturating_sub(8)
                        ),
                    ));
                }
                check_cache_layout(&file, frames, vertices, size - 8 - times_bytes)?;
                let mut t = vec![0u8; times_bytes as usize];
                read_exact(&mut reader, &mut t, &file, "times")?;
                let times: Vec<f32> = t.chunks_exact(4).map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]])).collect();
                let fps = frame_rate.or_else(|| mdd::frame_rate_from_times(&times)).unwrap_or(DEFAULT_FRAME_RATE);
                (Endian::Big, vertices as usize, frames as usize, fps, 8 + times_bytes)
            }
            _ => {
                return Err(Error::Unsupported {
                    context: "formats".into(),
                    detail: format!(
                        "cannot stream {file}: only .pc2 and .mdd caches and OBJ sequences (a directory or a \
                         file-name pattern) are read frame by frame"
                    ),
                })
            }
        };
        let topology = cache_topology(path, options.topology.as_deref(), vertices)?;
        Ok(Self {
            file,
            frames: Frames::Cache { reader, endian, bytes: Vec::new(), data_offset },
            topology,
            frame_rate: fps,
            frame_count: frames,
            frames_read: 0,
        })
    }

    /// An OBJ sequence of `paths` (listed by the caller, never empty): reads frame 0's file for
    /// the topology, as [`obj::read_obj_sequence`] does.
    fn open_obj_sequence(path: &Path, paths: Vec<PathBuf>, frame_rate: Option<f32>) -> Result<Self> {
        let file = name(path);
        // Each file is a frame; the whole read is bounded by what it can hold, the streamed one
        // by the frame-count limit every reader checks headers against.
        let max_frames = reader_limits().max_frames;
        if paths.len() > max_frames {
            return Err(Error::LimitExceeded {
                context: file.into(),
                field: "frame_count".into(),
                value: paths.len() as u64,
                limit: max_frames as u64,
            });
        }
        let first_path = paths.first().ok_or_else(|| Error::InvalidAnimation("no OBJ file to read".into()))?;
        let mesh = obj::read_obj(first_path)?;
        let topology = obj::sequence_topology(first_path, mesh.vertex_count(), mesh.triangles)?;
        let first = mesh.positions;
        Ok(Self {
            file,
            frame_count: paths.len(),
            frames: Frames::Obj { paths, first: Some(first) },
            topology,
            frame_rate: frame_rate.unwrap_or(DEFAULT_FRAME_RATE),
            frames_read: 0,
        })
    }

    /// The triangles (from the topology OBJ, or an OBJ sequence's frame 0).
    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    /// Vertices per frame.
    pub fn vertex_count(&self) -> usize {
        self.topology.vertex_count()
    }

    /// Frames in the cache (files in an OBJ sequence).
    pub fn frame_count(&self) -> usize {
        self.frame_count
    }

    /// Frames per second (as [`read_animation`](super::read_animation) gives it).
    pub fn frame_rate(&self) -> f32 {
        self.frame_rate
    }

    /// Frames read so far.
    pub fn frames_read(&self) -> usize {
        self.frames_read
    }

    /// Moves to frame `frame` (at most the frame count: the next read then returns nothing), so
    /// that [`CacheReader::read_frames`] reads from there: a caller coding one temporal block of
    /// a cache (issue 30, the Python package's distributed encode) reads only its frames. A
    /// cache's layout was checked against the file's size when it was opened; an OBJ sequence
    /// reads file `frame` next.
    pub fn seek_frame(&mut self, frame: usize) -> Result<()> {
        if frame > self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{}: frame {frame} is past the end ({} frames)",
                self.file, self.frame_count
            )));
        }
        match &mut self.frames {
            Frames::Cache { reader, data_offset, .. } => {
                let offset = *data_offset + frame as u64 * self.topology.vertex_count() as u64 * 12;
                reader.seek(SeekFrom::Start(offset)).map_err(|e| Error::io(self.file.clone(), e))?;
            }
            // Frame 0's positions are kept only for a read from the start.
            Frames::Obj { first, .. } => {
                if frame != 0 {
                    *first = None;
                }
            }
        }
        self.frames_read = frame;
        Ok(())
    }

    /// Reads the next `frames` frames (fewer at the end) into `out` (cleared first, frame-major
    /// `n × vertices × 3`) and returns how many; 0 at the end. Every coordinate is checked finite
    /// (the error names the file, frame, vertex and axis); every file of an OBJ sequence is
    /// checked against frame 0's mesh as [`obj::read_obj_sequence`] checks it.
    pub fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> Result<usize> {
        out.clear();
        let n = frames.min(self.frame_count - self.frames_read);
        if n == 0 {
            return Ok(0);
        }
        let per_frame = self.vertex_count() * 3;
        out.reserve(n * per_frame);
        match &mut self.frames {
            Frames::Cache { reader, endian, bytes, .. } => {
                // One frame of bytes at a time: the byte buffer stays one frame, whatever `frames` is.
                bytes.resize(per_frame * 4, 0);
                for _ in 0..n {
                    read_exact(reader, bytes, &self.file, "positions")?;
                    match endian {
                        Endian::Little => {
                            out.extend(bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])))
                        }
                        Endian::Big => {
                            out.extend(bytes.chunks_exact(4).map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]])))
                        }
                    }
                }
                codec_core::animation::check_finite(out, self.topology.vertex_count(), self.frames_read)
                    .map_err(|e| in_file(&self.file, e))?;
            }
            Frames::Obj { paths, first } => {
                // One file's text and mesh at a time (the parser refuses non-finite values,
                // naming the file, line, vertex and axis).
                for t in self.frames_read..self.frames_read + n {
                    match first.take().filter(|_| t == 0) {
                        Some(positions) => out.extend_from_slice(&positions),
                        None => {
                            let mesh = obj::read_sequence_frame(&paths[t], &paths[0], &self.topology)?;
                            out.extend_from_slice(&mesh.positions);
                        }
                    }
                }
            }
        }
        self.frames_read += n;
        Ok(n)
    }
}

/// A PC2 or MDD cache written frame by frame (issue 30: `decode` writes frames as each packet
/// decodes), through the pending-file mechanism ([`crate::output`]): the cache (and its
/// `STEM.obj` companion when asked for) is written under a temporary name and renamed into
/// place by [`CacheWriter::finish`] only when every frame is there, so a failure or an
/// interruption loses nothing. The bytes equal [`write_animation_with`](super::write_animation_with)'s
/// on the same animation and options (tested).
#[derive(Debug)]
pub struct CacheWriter {
    file: PendingFile,
    endian: Endian,
    vertex_count: usize,
    frame_count: usize,
    frames_written: usize,
    /// The companion OBJ to write (its path and the triangles), when asked for.
    companion: Option<(std::path::PathBuf, Vec<[u32; 3]>, String)>,
    companion_file: Option<PendingFile>,
    bytes: Vec<u8>,
}

/// Whether `path` names an output [`CacheWriter::create`] writes (`.pc2`, `.mdd`, any case).
pub fn is_streamable_output(path: &Path) -> bool {
    matches!(extension(path).as_deref(), Some("pc2" | "mdd"))
}

impl CacheWriter {
    /// Checks the outputs against `options.policy` (and an existing companion OBJ against
    /// `topology`, as [`write_animation_with`](super::write_animation_with) does), creates the
    /// pending file and writes the header.
    pub fn create(
        path: &Path,
        topology: &Topology,
        frame_count: usize,
        frame_rate: f32,
        options: &WriteOptions,
    ) -> Result<Self> {
        let endian = match extension(path).as_deref() {
            Some("pc2") => Endian::Little,
            Some("mdd") => Endian::Big,
            _ => {
                return Err(Error::Unsupported {
                    context: "formats".into(),
                    detail: format!("cannot stream to {}: only .pc2 and .mdd are written frame by frame", name(path)),
                })
            }
        };
        let context = if endian == Endian::Little { "pc2" } else { "mdd" };
        let too_many =
            |what: &str| Error::Unsupported { context: context.into(), detail: format!("more than 2^31-1 {what}") };
        let vertices = i32::try_from(topology.vertex_count()).map_err(|_| too_many("vertices"))?;
        let frames = i32::try_from(frame_count).map_err(|_| too_many("frames"))?;
        let companion = path.with_extension("obj");
        options.policy.check(path)?;
        if options.topology_obj {
            options.policy.check(&companion)?;
            super::check_companion_replaced(
                &options.policy,
                path,
                &companion,
                topology.vertex_count(),
                topology.triangles(),
            )?;
        } else {
            check_existing_companion(path, &companion, topology.vertex_count(), topology.triangles())?;
        }
        let mut header = Vec::new();
        match endian {
            Endian::Little => {
                header.extend_from_slice(pc2::MAGIC);
                header.extend_from_slice(&1i32.to_le_bytes());
                header.extend_from_slice(&vertices.to_le_bytes());
                header.extend_from_slice(&0f32.to_le_bytes());
                header.extend_from_slice(&1f32.to_le_bytes());
                header.extend_from_slice(&frames.to_le_bytes());
            }
            Endian::Big => {
                header.extend_from_slice(&frames.to_be_bytes());
                header.extend_from_slice(&vertices.to_be_bytes());
                let fps = frame_rate as f64;
                for t in 0..frame_count {
                    header.extend_from_slice(&((t as f64 / fps) as f32).to_be_bytes());
                }
            }
        }
        let mut file = PendingFile::new(path)?;
        file.write_all(&header).map_err(|e| file.error(e))?;
        let companion = options.topology_obj.then(|| {
            let comment = format!(
                "animcodec: topology of {} (frame 0 of {frame_count}, {} vertices, {} triangles)",
                path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default(),
                topology.vertex_count(),
                topology.triangle_count()
            );
            (companion, topology.triangles().to_vec(), comment)
        });
        Ok(Self {
            file,
            endian,
            vertex_count: topology.vertex_count(),
            frame_count,
            frames_written: 0,
            companion,
            companion_file: None,
            bytes: Vec::new(),
        })
    }

    /// Appends whole frames (frame-major `n × vertices × 3`, finite).
    pub fn write_frames(&mut self, positions: &[f32]) -> Result<()> {
        let n = codec_core::animation::whole_frames(positions.len(), self.vertex_count)?;
        if self.frames_written + n > self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{} frames written to {}, which was declared with {}",
                self.frames_written + n,
                self.file.target().display(),
                self.frame_count
            )));
        }
        if self.frames_written == 0 && n > 0 {
            if let Some((path, triangles, comment)) = &self.companion {
                let text = obj::obj_text(path, &positions[..self.vertex_count * 3], triangles, comment)?;
                let mut f = PendingFile::new(path)?;
                f.write_all(text.as_bytes()).map_err(|e| f.error(e))?;
                self.companion_file = Some(f);
            }
        }
        // One frame of bytes at a time (issue 30: a whole decoded packet converted at once was
        // another copy of it — 480 MB for a 40-frame packet of 1M vertices).
        for frame in positions.chunks(self.vertex_count.max(1) * 3) {
            self.bytes.clear();
            self.bytes.reserve(frame.len() * 4);
            match self.endian {
                Endian::Little => frame.iter().for_each(|x| self.bytes.extend_from_slice(&x.to_le_bytes())),
                Endian::Big => frame.iter().for_each(|x| self.bytes.extend_from_slice(&x.to_be_bytes())),
            }
            self.file.write_all(&self.bytes).map_err(|e| self.file.error(e))?;
        }
        self.frames_written += n;
        Ok(())
    }

    /// Checks that every declared frame was written and renames the file(s) into place;
    /// returns the files written.
    pub fn finish(self) -> Result<Vec<std::path::PathBuf>> {
        if self.frames_written != self.frame_count {
            return Err(Error::InvalidAnimation(format!(
                "{} of {} frames written to {}",
                self.frames_written,
                self.frame_count,
                self.file.target().display()
            )));
        }
        let mut files = vec![self.file];
        files.extend(self.companion_file);
        let written = files.iter().map(|f| f.target().to_path_buf()).collect();
        commit_all(files, &[])?;
        Ok(written)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{read_animation, test_animation, write_animation, write_animation_with, TempDir};
    use super::*;
    use crate::output::OutputPolicy;

    fn streamed(path: &Path, options: &ReadOptions, chunk: usize) -> Result<(Vec<f32>, CacheReader)> {
        let mut r = CacheReader::open(path, options)?;
        let (mut all, mut buf) = (Vec::new(), Vec::new());
        while r.read_frames(chunk, &mut buf)? > 0 {
            all.extend_from_slice(&buf);
        }
        Ok((all, r))
    }

    #[test]
    fn streamed_frames_equal_the_whole_read_for_pc2_and_mdd() {
        let dir = TempDir::new("stream-read");
        let anim = test_animation(7, 11, 24.0);
        for ext in ["pc2", "mdd"] {
            let path = dir.path(&format!("a.{ext}"));
            write_animation(&path, &anim).unwrap();
            let options = ReadOptions::default();
            let whole = read_animation(&path, &options).unwrap();
            for chunk in [1, 3, 11, 100] {
                let (all, r) = streamed(&path, &options, chunk).unwrap();
                assert_eq!(all, whole.positions(), "{ext}, chunks of {chunk}");
                assert_eq!(r.frame_count(), whole.frame_count());
                assert_eq!(r.frame_rate(), whole.frame_rate(), "{ext}");
                assert_eq!(r.topology().triangles(), whole.triangles());
            }
        }
    }

    /// Issue 30: a block of frames read after a seek equals those frames of the whole read.
    #[test]
    fn a_seek_reads_from_that_frame() {
        let dir = TempDir::new("stream-seek");
        let anim = test_animation(7, 11, 24.0);
        let per_frame = 7 * 3;
        for ext in ["pc2", "mdd"] {
            let path = dir.path(&format!("a.{ext}"));
            write_animation(&path, &anim).unwrap();
            let mut r = CacheReader::open(&path, &ReadOptions::default()).unwrap();
            let mut buf = Vec::new();
            for (first, n) in [(5, 4), (0, 2), (9, 5), (11, 1)] {
                r.seek_frame(first).unwrap();
                let got = r.read_frames(n, &mut buf).unwrap();
                assert_eq!(got, n.min(11 - first), "{ext}");
                assert_eq!(buf, anim.positions()[first * per_frame..(first + got) * per_frame], "{ext} from {first}");
            }
            assert!(r.seek_frame(12).is_err());
        }
    }

    #[test]
    fn a_header_that_does_not_match_the_file_is_refused_before_reading() {
        let dir = TempDir::new("stream-bad");
        let anim = test_animation(4, 3, 30.0);
        let path = dir.path("a.pc2");
        write_animation(&path, &anim).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        // Claim 2^20 frames: the file holds 3.
        bytes[28..32].copy_from_slice(&(1i32 << 20).to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let e = CacheReader::open(&path, &ReadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");
        // MDD claiming more frame times than the file holds.
        let path = dir.path("b.mdd");
        write_animation(&path, &anim).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[0..4].copy_from_slice(&(1i32 << 30).to_be_bytes());
        std::fs::write(&path, &bytes).unwrap();
        assert!(CacheReader::open(&path, &ReadOptions::default()).is_err());
    }

    #[test]
    fn a_non_finite_coordinate_names_its_frame() {
        let dir = TempDir::new("stream-nan");
        let anim = test_animation(4, 3, 30.0);
        let path = dir.path("a.pc2");
        write_animation(&path, &anim).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        // Frame 2, vertex 1, axis y.
        let at = pc2::HEADER_BYTES + (2 * 4 * 3 + 3 + 1) * 4;
        bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let whole = read_animation(&path, &ReadOptions::default()).unwrap_err().to_string();
        let e = streamed(&path, &ReadOptions::default(), 1).unwrap_err().to_string();
        assert_eq!(e, whole);
        assert!(e.contains("frame 2"), "{e}");
    }

    /// An OBJ sequence of `anim` in `dir`: frame t in `f{t}.obj` (natural order differs from
    /// the lexical one from frame 10 on), with a file that is not a frame beside them.
    fn obj_sequence(dir: &TempDir, anim: &codec_core::Animation) {
        for t in 0..anim.frame_count() {
            obj::write_obj(&dir.path(&format!("f{t}.obj")), anim.frame(t), anim.triangles(), "test").unwrap();
        }
        std::fs::write(dir.path("notes.txt"), "not a frame").unwrap();
    }

    #[test]
    fn streamed_obj_sequences_equal_the_whole_read() {
        let dir = TempDir::new("stream-obj");
        let anim = test_animation(7, 12, 24.0);
        obj_sequence(&dir, &anim);
        for (input, fps) in [(dir.0.clone(), None), (dir.path("f*.obj"), Some(24.0)), (dir.path("f{}.obj"), None)] {
            assert!(is_streamable(&input), "{}", input.display());
            let options = ReadOptions { frame_rate: fps, ..Default::default() };
            let whole = read_animation(&input, &options).unwrap();
            assert_eq!(whole.frame_count(), 12);
            for chunk in [1, 3, 12, 100] {
                let (all, r) = streamed(&input, &options, chunk).unwrap();
                let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&all), bits(whole.positions()), "{}, chunks of {chunk}", input.display());
                assert_eq!(r.frame_count(), whole.frame_count());
                assert_eq!(r.frames_read(), whole.frame_count());
                assert_eq!(r.frame_rate(), whole.frame_rate());
                assert_eq!(r.topology().triangles(), whole.triangles());
                assert_eq!(r.vertex_count(), whole.vertex_count());
            }
        }
        // A single .obj stays a whole read (one frame); so does a missing path.
        assert!(!is_streamable(&dir.path("f0.obj")));
        assert!(!is_streamable(&dir.path("missing")));
    }

    #[test]
    fn a_seek_in_an_obj_sequence_reads_from_that_file() {
        let dir = TempDir::new("stream-obj-seek");
        let anim = test_animation(5, 11, 30.0);
        obj_sequence(&dir, &anim);
        let per_frame = 5 * 3;
        let mut r = CacheReader::open(&dir.0, &ReadOptions::default()).unwrap();
        let mut buf = Vec::new();
        for (first, n) in [(5, 4), (0, 2), (0, 1), (9, 5), (11, 1), (1, 3)] {
            r.seek_frame(first).unwrap();
            let got = r.read_frames(n, &mut buf).unwrap();
            assert_eq!(got, n.min(11 - first));
            assert_eq!(buf, anim.positions()[first * per_frame..(first + got) * per_frame], "from {first}");
            assert_eq!(r.frames_read(), first + got);
        }
        assert!(r.seek_frame(12).is_err());
    }

    /// A later file whose mesh differs from frame 0's fails when its frame is read, with the
    /// whole read's message; the frames before it are handed out.
    #[test]
    fn a_mismatching_later_file_fails_at_its_frame_with_the_whole_read_s_message() {
        let dir = TempDir::new("stream-obj-bad");
        let anim = test_animation(6, 8, 30.0);
        obj_sequence(&dir, &anim);
        let bad = dir.path("f5.obj");
        let mut tris = anim.triangles().to_vec();
        tris[2] = [0, 1, 5];
        // (positions, triangles, a word of the message); an empty word: a file that does not parse.
        type Case<'a> = (&'a [f32], &'a [[u32; 3]], &'a str);
        let cases: [Case; 4] = [
            (&anim.frame(5)[..15], &anim.triangles()[..3], "5 vertices"),
            (anim.frame(5), &tris, "triangle 2 is [0, 1, 5]"),
            (anim.frame(5), &anim.triangles()[..3], "3 triangles"),
            (anim.frame(5), anim.triangles(), ""),
        ];
        for (positions, triangles, needle) in cases {
            obj::write_obj(&bad, positions, triangles, "").unwrap();
            if needle.is_empty() {
                // A file that does not parse: the parser's error, naming the file and line.
                std::fs::write(&bad, "v 0 0 0\nv 1 nan 0\n").unwrap();
            }
            let whole = read_animation(&dir.0, &ReadOptions::default()).unwrap_err().to_string();
            assert!(whole.contains("f5.obj") && whole.contains(needle), "{whole}");
            let mut r = CacheReader::open(&dir.0, &ReadOptions::default()).unwrap();
            let mut buf = Vec::new();
            assert_eq!(r.read_frames(3, &mut buf).unwrap(), 3);
            assert_eq!(r.read_frames(2, &mut buf).unwrap(), 2);
            let e = r.read_frames(1, &mut buf).unwrap_err().to_string();
            assert_eq!(e, whole);
            // In one chunk spanning it, too.
            let e = streamed(&dir.0, &ReadOptions::default(), 8).unwrap_err().to_string();
            assert_eq!(e, whole);
        }
    }

    #[test]
    fn an_empty_or_unmatched_obj_sequence_errors_as_the_whole_read() {
        let dir = TempDir::new("stream-obj-empty");
        std::fs::write(dir.path("notes.txt"), "not a frame").unwrap();
        for input in [dir.0.clone(), dir.path("f*.obj")] {
            assert!(is_streamable(&input));
            let whole = read_animation(&input, &ReadOptions::default()).unwrap_err().to_string();
            let e = CacheReader::open(&input, &ReadOptions::default()).unwrap_err().to_string();
            assert_eq!(e, whole);
            assert!(e.contains("no .obj file") || e.contains("no file matches"), "{e}");
        }
        // A bad frame 0 (the topology) fails at open, as the whole read fails.
        std::fs::write(dir.path("f0.obj"), "# nothing\n").unwrap();
        let whole = read_animation(&dir.0, &ReadOptions::default()).unwrap_err().to_string();
        let e = CacheReader::open(&dir.0, &ReadOptions::default()).unwrap_err().to_string();
        assert_eq!(e, whole);
        assert!(e.contains("f0.obj") && e.contains("no vertices"), "{e}");
        // A bad frame rate, as the whole read.
        let bad = ReadOptions { frame_rate: Some(0.0), ..Default::default() };
        assert!(CacheReader::open(&dir.0, &bad).is_err());
    }

    #[test]
    fn streamed_writes_equal_the_whole_write_and_leave_nothing_on_failure() {
        let dir = TempDir::new("stream-write");
        let anim = test_animation(6, 9, 24.0);
        for ext in ["pc2", "mdd"] {
            for topology_obj in [false, true] {
                let whole = dir.path(&format!("whole-{topology_obj}-{ext}.{ext}"));
                let options = WriteOptions { policy: OutputPolicy::new(false), topology_obj };
                write_animation_with(&whole, &anim, &options).unwrap();
                let streamed = dir.path(&format!("streamed-{topology_obj}-{ext}.{ext}"));
                let mut w = CacheWriter::create(&streamed, anim.topology(), 9, 24.0, &options).unwrap();
                for chunk in anim.positions().chunks(4 * 6 * 3) {
                    w.write_frames(chunk).unwrap();
                }
                let files = w.finish().unwrap();
                assert_eq!(files.len(), 1 + topology_obj as usize);
                assert_eq!(std::fs::read(&whole).unwrap(), std::fs::read(&streamed).unwrap(), "{ext}");
                if topology_obj {
                    let (a, b) = (
                        std::fs::read_to_string(whole.with_extension("obj")).unwrap(),
                        std::fs::read_to_string(streamed.with_extension("obj")).unwrap(),
                    );
                    // The comment names the file; the rest is the same.
                    assert_eq!(a.lines().skip(1).collect::<Vec<_>>(), b.lines().skip(1).collect::<Vec<_>>());
                }
            }
            // A writer dropped before its last frame leaves no file.
            let partial = dir.path(&format!("partial-{ext}.{ext}"));
            let options = WriteOptions { policy: OutputPolicy::new(false), topology_obj: true };
            let mut w = CacheWriter::create(&partial, anim.topology(), 9, 24.0, &options).unwrap();
            w.write_frames(&anim.positions()[..6 * 3]).unwrap();
            assert!(w.finish().is_err());
            assert!(!partial.exists() && !partial.with_extension("obj").exists());
        }
        let leftovers: Vec<_> = std::fs::read_dir(&dir.0)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}
