//! The C library of animcodec: open an `.anim` stream from memory or a file, query it, and
//! decode any frame — by random access through the container's packet index, in bulk, or with
//! a player that keeps the decoder's state for sequential playback. The header
//! `capi/include/animcodec.h` is generated from this file by cbindgen (`capi/cbindgen.toml`);
//! `capi/README.md` shows how to build and link it.
//!
//! Every entry point runs inside [`std::panic::catch_unwind`]: no panic crosses into C. A
//! failure returns an [`ac_status`] and leaves its text for [`ac_last_error`].
//!
//! **Random access.** A stream is a sequence of packets, each holding a run of frames, some
//! flagged as keyframes (decodable without earlier packets); the index at the end of the stream
//! gives each packet's offset. Decoding frame `t` reads and decodes the packet holding `t`
//! (and, when that packet is not a keyframe, the packets from the keyframe before it), and
//! keeps that decoded packet, so the next frame of the same packet is a copy. What one
//! packet is depends on the codec and its parameters (`capi/README.md`).

#![allow(non_camel_case_types)]

mod source;

use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Once, OnceLock, TryLockError};

use animcodec::core::container::{self, Header, IndexEntry};
use animcodec::core::error::message_with_sources;
use animcodec::core::{
    decode_frame_checked, decode_packet_checked, encode_animation, random_access_limits, Animation, AnimationCodec,
    CodecRegistry, Error, FrameDecoder, Limits, Packet, StreamDecoder, Topology,
};
use animcodec::front;
use animcodec::harness::{self, SearchRequest, Target};

use source::Source;

/// The result of every fallible call. `AC_OK` is 0; on any other value [`ac_last_error`] gives
/// the reason in words.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ac_status {
    /// Success.
    AC_OK = 0,
    /// A null pointer where a value is required, or a path that is not valid text.
    AC_ERR_INVALID_ARGUMENT = 1,
    /// The file could not be opened or read.
    AC_ERR_IO = 2,
    /// The stream is not a valid `.anim` stream: truncated, corrupt (a checksum), malformed, of
    /// an unknown codec or of a newer version than this library reads.
    AC_ERR_FORMAT = 3,
    /// Decoding would exceed the memory or work limit (`ac_limits`).
    AC_ERR_LIMIT = 4,
    /// A frame number at or past the stream's frame count.
    AC_ERR_OUT_OF_RANGE = 5,
    /// The output buffer holds fewer values than the call writes.
    AC_ERR_BUFFER_TOO_SMALL = 6,
    /// A bug in animcodec (a panic, caught at the boundary). The handle stays usable.
    AC_ERR_INTERNAL = 7,
}

use ac_status::*;

/// Decoding limits. Pass `NULL` wherever a `const ac_limits *` is taken for the defaults, or
/// start from [`ac_limits_default`]; a field left 0 takes its default too.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ac_limits {
    /// Most bytes one decode holds at once: the decoded packet, the codec's own state, the
    /// index and the triangles (default 1 GiB). The same budget as `animcodec --max-memory`.
    pub max_memory: u64,
    /// Most operations one decode may take, counted from the stream's sizes before the work
    /// starts (default 2·10¹¹). The same budget as `animcodec --max-work`.
    pub max_work: u64,
}

/// What [`ac_stream_get_info`] reports about a stream.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct ac_stream_info {
    /// Name of the codec (`"hosvd"`, `"quant-delta"`, …): a static string, never freed.
    pub codec: *const c_char,
    /// The codec's FourCC as stored in the stream, NUL-terminated.
    pub fourcc: [c_char; 5],
    /// Version of the codec's bitstream in this stream.
    pub codec_version: u32,
    /// Version of the `.anim` container.
    pub container_version: u32,
    /// Number of frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Triangles (the same for every frame).
    pub triangles: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Size of the whole stream in bytes.
    pub stream_bytes: u64,
    /// Number of packets.
    pub packets: usize,
    /// Number of keyframe packets (random-access points).
    pub keyframes: usize,
    /// Frames in the longest packet: [`ac_decode_frame`] of a frame not yet decoded costs the
    /// decode of its packet, so this is its worst case in frames.
    pub max_packet_frames: usize,
}

/// An open `.anim` stream (opaque). Made by [`ac_stream_open_memory`] or
/// [`ac_stream_open_file`], freed by [`ac_stream_free`].
///
/// Thread safety: every function taking a `const ac_stream *` may be called from several threads
/// at once on the same handle ([`ac_decode_frame`], [`ac_decode_range`], [`ac_decode_all`],
/// [`ac_copy_triangles`], [`ac_stream_get_info`], [`ac_player_new`]). The stream keeps one
/// decoded packet for [`ac_decode_frame`]; a call that finds it in use by another thread
/// decodes with a decoder of its own instead (correct, but without the kept packet). For
/// playback from one thread, use an [`ac_player`]. [`ac_stream_free`] must not run concurrently
/// with any other call on the handle.
pub struct ac_stream {
    inner: Arc<Stream>,
}

/// A player (opaque): a decoder and the last packet it decoded, for one thread's sequential
/// (or any-order) access to a stream. Made by [`ac_player_new`], freed by [`ac_player_free`]. It
/// keeps its stream alive: the stream may be freed first.
///
/// Thread safety: a player is used by one thread at a time (it may move between threads).
pub struct ac_player {
    stream: Arc<Stream>,
    head: Option<Playhead>,
}

/// Result of an entry point's body: a status and its message.
struct Failure {
    status: ac_status,
    message: String,
}

impl Failure {
    fn new(status: ac_status, message: impl Into<String>) -> Self {
        Self { status, message: message.into() }
    }

    /// The failure for a library error, its text as the command line prints it: the message with
    /// its sources on one line, after the file's name unless the message already names it.
    fn from_error(e: &Error, file: Option<&str>) -> Self {
        let status = match e {
            Error::Io { .. } => AC_ERR_IO,
            Error::LimitExceeded { .. } | Error::AllocLimit { .. } | Error::WorkLimit { .. } => AC_ERR_LIMIT,
            _ => AC_ERR_FORMAT,
        };
        let text = message_with_sources(e);
        let message = match file {
            Some(f) if !text.contains(f) => format!("{f}: {text}"),
            _ => text,
        };
        Self { status, message }
    }
}

type Outcome<T = ()> = Result<T, Failure>;

thread_local! {
    /// The message of this thread's last failed call.
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Calls into this library in flight (on any thread), during which the panic hook stays quiet.
static IN_FLIGHT: AtomicUsize = AtomicUsize::new(0);

/// Installs, once, a panic hook that prints nothing while a call into this library is in flight
/// (the panic is reported through [`ac_last_error`] instead) and defers to the previous hook
/// otherwise, so a host that embeds other Rust code keeps its own panic reports.
fn quiet_panics_in_calls() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if IN_FLIGHT.load(Ordering::SeqCst) == 0 {
                previous(info);
            }
        }));
    });
}

fn set_last_error(message: &str) {
    // Interior NUL bytes (from a file name, say) cannot be in a C string: shown as U+FFFD.
    let text = CString::new(message.replace('\0', "\u{fffd}")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// Runs an entry point's body: never lets a panic through, turns a failure into its status and
/// [`ac_last_error`] text. Every `extern "C"` function of this crate goes through it.
fn guard(body: impl FnOnce() -> Outcome) -> ac_status {
    quiet_panics_in_calls();
    IN_FLIGHT.fetch_add(1, Ordering::SeqCst);
    let result = catch_unwind(AssertUnwindSafe(body));
    IN_FLIGHT.fetch_sub(1, Ordering::SeqCst);
    match result {
        Ok(Ok(())) => AC_OK,
        Ok(Err(failure)) => {
            set_last_error(&failure.message);
            failure.status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".to_owned());
            set_last_error(&format!("internal error (a bug in animcodec; please report it): {what}"));
            AC_ERR_INTERNAL
        }
    }
}

/// [`guard`] for the calls that return a value instead of a status: `fallback` when the body
/// fails or panics (the reason is then in [`ac_last_error`]).
fn guard_value<T: Copy>(fallback: T, body: impl FnOnce() -> Outcome<T>) -> T {
    let mut value = fallback;
    let status = guard(|| {
        value = body()?;
        Ok(())
    });
    if status == AC_OK {
        value
    } else {
        fallback
    }
}

fn registry() -> &'static CodecRegistry {
    static REGISTRY: OnceLock<CodecRegistry> = OnceLock::new();
    REGISTRY.get_or_init(animcodec::registry)
}

/// An open stream: its bytes, header and index, and the decoder state kept for
/// [`ac_decode_frame`].
struct Stream {
    source: Source,
    /// The path for a file (error messages name it).
    name: Option<String>,
    header: Header,
    index: Vec<IndexEntry>,
    codec: &'static dyn AnimationCodec,
    limits: Limits,
    shared: Mutex<Option<Playhead>>,
}

/// A decoder positioned in a stream and the last packet it decoded.
struct Playhead {
    decoder: Box<dyn FrameDecoder>,
    /// The index position the decoder continues at without a reset (the packet after the last
    /// one it decoded), or `None` when it must restart from a keyframe.
    next: Option<usize>,
    /// The last decoded packet: its index position and frames.
    cached: Option<(usize, Vec<f32>)>,
    /// The packet (index position and bytes) last asked one frame of, for a codec that forms a
    /// frame alone: its decoder keeps the packets it was asked frames of parsed (up to a quarter
    /// of the memory limit), so a further frame of one costs one frame.
    alone: Option<(usize, Packet)>,
    /// The last frame this playhead returned (a request for the next one is sequential playback).
    last_frame: Option<usize>,
}

impl Stream {
    fn open(source: Source, name: Option<String>, limits: Limits) -> Result<Self, Error> {
        // The checks (and so the messages) of `animcodec decode`: header, codec, stream version,
        // the work of the frames. Then the index, which random access reads from.
        let header = StreamDecoder::new_streaming(source.cursor(), registry(), limits)?.header().clone();
        let (_, index) = container::read_index(&mut source.cursor(), limits)?;
        let codec = registry().by_fourcc(header.info.fourcc)?;
        Ok(Self { source, name, header, index, codec, limits, shared: Mutex::new(None) })
    }

    fn failure(&self, e: &Error) -> Failure {
        Failure::from_error(e, self.name.as_deref())
    }

    fn frames(&self) -> usize {
        self.header.info.frame_count
    }

    fn values_per_frame(&self) -> usize {
        self.header.info.vertex_count() * 3
    }

    fn playhead(&self) -> Result<Playhead, Error> {
        let limits = random_access_limits(self.codec.name(), &self.header, &self.index, self.limits)?;
        let mut decoder = self.codec.new_decoder(&self.header.info, &self.header.config, &limits)?;
        // Random access parses each packet once: a quarter of the memory limit holds the parses
        // of the packets visited (the least recently used dropped beyond it).
        decoder.keep_parsed_packets(limits.max_alloc_bytes as u64 / 4);
        Ok(Playhead { decoder, next: None, cached: None, alone: None, last_frame: None })
    }

    /// Index position of the packet holding frame `t` (`t` < the frame count; the index covers
    /// every frame in order, which `read_index` checked).
    fn packet_of(&self, t: usize) -> usize {
        let after = self.index.partition_point(|e| e.first_frame as usize <= t);
        after.saturating_sub(1)
    }

    /// The frames of the packet at index position `target`, decoded by `head` (kept there).
    fn packet<'h>(&self, head: &'h mut Playhead, target: usize) -> Result<&'h [f32], Error> {
        if head.cached.as_ref().is_none_or(|(pos, _)| *pos != target) {
            head.cached = None;
            let start = (0..=target).rev().find(|&i| self.index[i].keyframe).unwrap_or(0);
            // Continue from where the decoder is when that is on the way to `target` (sequential
            // playback), else restart at the keyframe.
            let begin = match head.next {
                Some(next) if (start..=target).contains(&next) => next,
                _ => {
                    head.decoder.reset();
                    start
                }
            };
            head.next = None;
            let mut at = self.source.cursor();
            let name = self.codec.name();
            for pos in begin..=target {
                let packet = container::read_packet_at(&mut at, &self.index[pos], &self.header, self.limits)?;
                let positions =
                    decode_packet_checked(head.decoder.as_mut(), name, &self.header, &packet, &self.limits)?;
                head.next = Some(pos + 1);
                if pos == target {
                    head.cached = Some((pos, positions));
                }
            }
        }
        match &head.cached {
            Some((_, frames)) => Ok(frames),
            None => Err(Error::malformed(self.codec.name(), "index", "no packet holds the frame")),
        }
    }

    /// Frame `t` alone, where the codec forms one frame of a packet without the others
    /// ([`FrameDecoder::decodes_single_frames`]): the packet's parse stays in the decoder and its
    /// bytes in `head`, so the next frame of the same packet costs one frame.
    fn frame_alone(&self, head: &mut Playhead, t: usize) -> Result<Vec<f32>, Error> {
        let pos = self.packet_of(t);
        if head.alone.as_ref().is_none_or(|(p, _)| *p != pos) {
            head.alone = None;
            let packet =
                container::read_packet_at(&mut self.source.cursor(), &self.index[pos], &self.header, self.limits)?;
            head.alone = Some((pos, packet));
        }
        let Some((_, packet)) = &head.alone else {
            return Err(Error::malformed(self.codec.name(), "index", "no packet holds the frame"));
        };
        let local = t - self.index[pos].first_frame as usize;
        decode_frame_checked(head.decoder.as_mut(), self.codec.name(), &self.header, packet, local, &self.limits)
    }

    /// Writes frames `first .. first + count` into `out` (frame-major, 3 floats per vertex).
    ///
    /// One frame of a packet not kept decoded, asked out of sequence, is formed alone when the
    /// codec can ([`Stream::frame_alone`]); a frame in sequence (the one after the last returned)
    /// or a range decodes the whole packet and keeps it, so playback in order costs the bulk
    /// decode's time per frame.
    fn decode_into(&self, head: &mut Playhead, first: usize, count: usize, out: &mut [f32]) -> Outcome {
        let v3 = self.values_per_frame();
        if count == 1 && head.decoder.decodes_single_frames() {
            let pos = self.packet_of(first);
            let kept = head.cached.as_ref().is_some_and(|(p, _)| *p == pos);
            let in_sequence = head.last_frame.is_some_and(|last| last + 1 == first);
            if !kept && !in_sequence {
                let frame = self.frame_alone(head, first).map_err(|e| self.failure(&e))?;
                out[..v3].copy_from_slice(&frame);
                head.last_frame = Some(first);
                return Ok(());
            }
        }
        let mut t = first;
        let end = first + count;
        while t < end {
            let pos = self.packet_of(t);
            let entry = self.index[pos];
            let frames = self.packet(head, pos).map_err(|e| self.failure(&e))?;
            let packet_end = (entry.first_frame as usize + entry.frame_count as usize).min(end);
            let local = t - entry.first_frame as usize;
            let n = packet_end - t;
            let src = &frames[local * v3..(local + n) * v3];
            out[(t - first) * v3..(t - first + n) * v3].copy_from_slice(src);
            t = packet_end;
        }
        head.last_frame = end.checked_sub(1);
        Ok(())
    }

    /// Runs `f` with the stream's kept playhead, or with a new one when another thread holds it.
    fn with_shared<T>(&self, f: impl FnOnce(&mut Playhead) -> Outcome<T>) -> Outcome<T> {
        let mut guard = match self.shared.try_lock() {
            Ok(guard) => guard,
            Err(TryLockError::Poisoned(poisoned)) => {
                // A panic while decoding: the decoder's state is unknown, start afresh.
                let mut guard = poisoned.into_inner();
                *guard = None;
                self.shared.clear_poison();
                guard
            }
            Err(TryLockError::WouldBlock) => {
                let mut head = self.playhead().map_err(|e| self.failure(&e))?;
                return f(&mut head);
            }
        };
        if guard.is_none() {
            *guard = Some(self.playhead().map_err(|e| self.failure(&e))?);
        }
        match guard.as_mut() {
            Some(head) => f(head),
            None => Err(Failure::new(AC_ERR_INTERNAL, "no decoder")),
        }
    }

    /// Checks a request for `count` frames from `first` into a buffer of `n` floats.
    fn check_range(&self, first: usize, count: usize, n: usize) -> Outcome {
        let frames = self.frames();
        if first.checked_add(count).is_none_or(|end| end > frames) || (count == 0 && first >= frames) {
            let what = if count <= 1 {
                format!("frame {first}")
            } else {
                format!("frames {first}..{}", first.saturating_add(count))
            };
            return Err(Failure::new(
                AC_ERR_OUT_OF_RANGE,
                format!("{what} is past the end of the stream ({frames} frames)"),
            ));
        }
        let need = count.checked_mul(self.values_per_frame());
        if need.is_none_or(|need| n < need) {
            return Err(Failure::new(
                AC_ERR_BUFFER_TOO_SMALL,
                format!(
                    "the output buffer holds {n} floats; {count} frames of {} vertices need {}",
                    self.header.info.vertex_count(),
                    need.map_or("more than fit in memory".to_owned(), |v| v.to_string())
                ),
            ));
        }
        Ok(())
    }
}

fn limits_from(limits: *const ac_limits) -> Limits {
    let mut out = Limits::default();
    // SAFETY: the caller passes NULL or a pointer to a valid `ac_limits` (the header's contract).
    if let Some(l) = unsafe { limits.as_ref() } {
        if l.max_memory != 0 {
            out.max_alloc_bytes = usize::try_from(l.max_memory).unwrap_or(usize::MAX);
        }
        if l.max_work != 0 {
            out.max_work = l.max_work;
        }
    }
    out
}

fn null(what: &str) -> Failure {
    Failure::new(AC_ERR_INVALID_ARGUMENT, format!("{what} is NULL"))
}

/// The stream behind a handle.
///
/// # Safety
/// `h` is NULL or a handle from this library not yet freed.
unsafe fn stream<'a>(h: *const ac_stream) -> Outcome<&'a Arc<Stream>> {
    // SAFETY: the caller's contract.
    unsafe { h.as_ref() }.map(|s| &s.inner).ok_or_else(|| null("the stream handle"))
}

/// `n` values at `out` as a slice.
///
/// # Safety
/// `out` is NULL or points to `n` writable values.
unsafe fn out_slice<'a, T>(out: *mut T, n: usize, what: &str) -> Outcome<&'a mut [T]> {
    if out.is_null() {
        return Err(null(what));
    }
    // SAFETY: the caller's contract: `out` points to `n` writable values.
    Ok(unsafe { std::slice::from_raw_parts_mut(out, n) })
}

/// Stores `stream` in `*out`.
///
/// # Safety
/// `out` is a valid pointer to write a handle to.
unsafe fn hand_out(stream: Stream, out: *mut *mut ac_stream) {
    let handle = Box::into_raw(Box::new(ac_stream { inner: Arc::new(stream) }));
    // SAFETY: the caller's contract.
    unsafe { *out = handle };
}

/// The version of this library (`"0.1.0"`): a static string.
#[no_mangle]
pub extern "C" fn ac_version() -> *const c_char {
    static VERSION: &CStr = match CStr::from_bytes_with_nul(concat!(env!("CARGO_PKG_VERSION"), "\0").as_bytes()) {
        Ok(v) => v,
        Err(_) => c"",
    };
    guard_value(c"".as_ptr(), || Ok(VERSION.as_ptr()))
}

/// The message of the last call that failed on this thread (empty if none did), as the
/// `animcodec` command line prints it after `error: ` for the same failure. Valid until the
/// next failing call on this thread; a successful call leaves it unchanged. Thread-safe (each
/// thread has its own).
#[no_mangle]
pub extern "C" fn ac_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// A short name of a status (`"AC_ERR_FORMAT"`): a static string.
#[no_mangle]
pub extern "C" fn ac_status_name(status: ac_status) -> *const c_char {
    let name = match status {
        AC_OK => c"AC_OK",
        AC_ERR_INVALID_ARGUMENT => c"AC_ERR_INVALID_ARGUMENT",
        AC_ERR_IO => c"AC_ERR_IO",
        AC_ERR_FORMAT => c"AC_ERR_FORMAT",
        AC_ERR_LIMIT => c"AC_ERR_LIMIT",
        AC_ERR_OUT_OF_RANGE => c"AC_ERR_OUT_OF_RANGE",
        AC_ERR_BUFFER_TOO_SMALL => c"AC_ERR_BUFFER_TOO_SMALL",
        AC_ERR_INTERNAL => c"AC_ERR_INTERNAL",
    };
    name.as_ptr()
}

/// The default limits (what `NULL` stands for).
#[no_mangle]
pub extern "C" fn ac_limits_default() -> ac_limits {
    let d = Limits::default();
    ac_limits { max_memory: d.max_alloc_bytes as u64, max_work: d.max_work }
}

/// Opens a stream held in memory: `size` bytes at `data`, copied (the caller may free them on
/// return). Reads the header and the packet index and checks them; packets are read when
/// decoded. On success `*out` is a new handle, else `*out` is NULL.
///
/// # Safety
/// `data` points to `size` readable bytes; `limits` is NULL or valid; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn ac_stream_open_memory(
    data: *const u8,
    size: usize,
    limits: *const ac_limits,
    out: *mut *mut ac_stream,
) -> ac_status {
    guard(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: `out` is writable (the contract) and not NULL.
        unsafe { *out = std::ptr::null_mut() };
        if data.is_null() {
            return Err(null("data"));
        }
        // SAFETY: `data` points to `size` readable bytes (the contract).
        let bytes = unsafe { std::slice::from_raw_parts(data, size) }.to_vec();
        let stream = Stream::open(Source::Memory(bytes), None, limits_from(limits))
            .map_err(|e| Failure::from_error(&e, None))?;
        // SAFETY: checked above.
        unsafe { hand_out(stream, out) };
        Ok(())
    })
}

/// Opens the stream in the file at `path` (a NUL-terminated path; UTF-8 on Windows). The file
/// stays open and is read at offsets as frames are decoded. Messages name the file as given.
/// On success `*out` is a new handle, else `*out` is NULL.
///
/// # Safety
/// `path` is a NUL-terminated string; `limits` is NULL or valid; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn ac_stream_open_file(
    path: *const c_char,
    limits: *const ac_limits,
    out: *mut *mut ac_stream,
) -> ac_status {
    guard(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: `out` is writable (the contract) and not NULL.
        unsafe { *out = std::ptr::null_mut() };
        if path.is_null() {
            return Err(null("path"));
        }
        // SAFETY: `path` is NUL-terminated (the contract).
        let raw = unsafe { CStr::from_ptr(path) };
        let path = path_from(raw)?;
        let name = path.display().to_string();
        // The command line's own wording for these two failures (`animcodec decode`).
        let file = std::fs::File::open(&path)
            .map_err(|e| Failure::from_error(&Error::io(format!("cannot open {name}"), e), None))?;
        let meta =
            file.metadata().map_err(|e| Failure::from_error(&Error::io(format!("cannot read {name}"), e), None))?;
        if meta.is_dir() {
            return Err(Failure::new(AC_ERR_IO, format!("cannot read {name}: it is a directory")));
        }
        let source = Source::File { file, len: meta.len() };
        let stream = Stream::open(source, Some(name.clone()), limits_from(limits))
            .map_err(|e| Failure::from_error(&e, Some(&name)))?;
        // SAFETY: checked above.
        unsafe { hand_out(stream, out) };
        Ok(())
    })
}

#[cfg(unix)]
fn path_from(raw: &CStr) -> Outcome<std::path::PathBuf> {
    use std::os::unix::ffi::OsStrExt;
    Ok(std::path::PathBuf::from(std::ffi::OsStr::from_bytes(raw.to_bytes())))
}

#[cfg(not(unix))]
fn path_from(raw: &CStr) -> Outcome<std::path::PathBuf> {
    raw.to_str()
        .map(std::path::PathBuf::from)
        .map_err(|_| Failure::new(AC_ERR_INVALID_ARGUMENT, "the path is not UTF-8"))
}

/// Frees a stream (NULL is accepted). Players made from it stay valid.
///
/// # Safety
/// `h` is NULL or a handle from this library, not used again.
#[no_mangle]
pub unsafe extern "C" fn ac_stream_free(h: *mut ac_stream) {
    guard(|| {
        if !h.is_null() {
            // SAFETY: made by `Box::into_raw` in `hand_out`, freed once (the contract).
            drop(unsafe { Box::from_raw(h) });
        }
        Ok(())
    });
}

/// Fills `*out` with what the header and index say about the stream. Thread-safe.
///
/// # Safety
/// `h` is a live handle; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn ac_stream_get_info(h: *const ac_stream, out: *mut ac_stream_info) -> ac_status {
    guard(|| {
        // SAFETY: the contract.
        let s = unsafe { stream(h) }?;
        // SAFETY: the contract.
        let out = unsafe { out.as_mut() }.ok_or_else(|| null("out"))?;
        let info = &s.header.info;
        let mut fourcc = [0 as c_char; 5];
        for (d, &b) in fourcc.iter_mut().zip(&info.fourcc.0) {
            *d = b as c_char;
        }
        *out = ac_stream_info {
            codec: codec_name_ptr(s.codec.name()),
            fourcc,
            codec_version: info.codec_version as u32,
            container_version: s.header.container_version as u32,
            frames: info.frame_count,
            vertices: info.vertex_count(),
            triangles: info.topology.triangle_count(),
            frame_rate: info.frame_rate,
            stream_bytes: s.source.len(),
            packets: s.index.len(),
            keyframes: s.index.iter().filter(|e| e.keyframe).count(),
            max_packet_frames: s.index.iter().map(|e| e.frame_count as usize).max().unwrap_or(0),
        };
        Ok(())
    })
}

/// A codec's name as a static C string (one per registered codec, made once).
fn codec_name_ptr(name: &'static str) -> *const c_char {
    static NAMES: OnceLock<Vec<(&'static str, CString)>> = OnceLock::new();
    let names = NAMES
        .get_or_init(|| registry().iter().map(|c| (c.name(), CString::new(c.name()).unwrap_or_default())).collect());
    names.iter().find(|(n, _)| *n == name).map_or(c"".as_ptr(), |(_, c)| c.as_ptr())
}

/// Copies the triangles (3 vertex indices each, counter-clockwise as stored) into `out`, which
/// holds `n` values: at least 3 × the triangle count. Thread-safe.
///
/// # Safety
/// `h` is a live handle; `out` points to `n` writable values.
#[no_mangle]
pub unsafe extern "C" fn ac_copy_triangles(h: *const ac_stream, out: *mut u32, n: usize) -> ac_status {
    guard(|| {
        // SAFETY: the contract.
        let s = unsafe { stream(h) }?;
        let triangles = s.header.info.topology.triangles();
        let need = triangles.len() * 3;
        if n < need {
            return Err(Failure::new(
                AC_ERR_BUFFER_TOO_SMALL,
                format!("the output buffer holds {n} indices; {} triangles need {need}", triangles.len()),
            ));
        }
        // SAFETY: the contract.
        let out = unsafe { out_slice(out, n, "out") }?;
        for (d, t) in out.chunks_exact_mut(3).zip(triangles) {
            d.copy_from_slice(t);
        }
        Ok(())
    })
}

/// Decodes frame `frame` into `out_xyz` (`n` floats, at least 3 × vertices: x, y, z per vertex).
/// Random access: pca-aoi, hosvd and laplacian form that frame alone from the packet's parse,
/// which the stream keeps (for the packets visited, within a quarter of the memory limit), so a
/// frame costs about one frame once its packet was parsed; the other codecs decode the packet
/// holding the frame (from its keyframe when it is not one) and keep it, so the other frames of
/// that packet then cost a copy. Thread-safe on a shared handle.
///
/// # Safety
/// `h` is a live handle; `out_xyz` points to `n` writable floats.
#[no_mangle]
pub unsafe extern "C" fn ac_decode_frame(h: *const ac_stream, frame: usize, out_xyz: *mut f32, n: usize) -> ac_status {
    // SAFETY: the contract.
    unsafe { ac_decode_range(h, frame, 1, out_xyz, n) }
}

/// Decodes `count` frames from `first` into `out_xyz` (`n` floats, at least count × 3 ×
/// vertices), frame after frame. Each packet is decoded once. Thread-safe on a shared handle.
///
/// # Safety
/// `h` is a live handle; `out_xyz` points to `n` writable floats.
#[no_mangle]
pub unsafe extern "C" fn ac_decode_range(
    h: *const ac_stream,
    first: usize,
    count: usize,
    out_xyz: *mut f32,
    n: usize,
) -> ac_status {
    guard(|| {
        // SAFETY: the contract.
        let s = unsafe { stream(h) }?;
        s.check_range(first, count, n)?;
        // SAFETY: the contract.
        let out = unsafe { out_slice(out_xyz, n, "out_xyz") }?;
        s.with_shared(|head| s.decode_into(head, first, count, out))
    })
}

/// Decodes every frame into `out_xyz` (`n` floats, at least frames × 3 × vertices). Thread-safe
/// on a shared handle.
///
/// # Safety
/// `h` is a live handle; `out_xyz` points to `n` writable floats.
#[no_mangle]
pub unsafe extern "C" fn ac_decode_all(h: *const ac_stream, out_xyz: *mut f32, n: usize) -> ac_status {
    guard(|| {
        // SAFETY: the contract.
        let s = unsafe { stream(h) }?;
        let frames = s.frames();
        s.check_range(0, frames, n)?;
        // SAFETY: the contract.
        let out = unsafe { out_slice(out_xyz, n, "out_xyz") }?;
        s.with_shared(|head| s.decode_into(head, 0, frames, out))
    })
}

/// Makes a player on `h` in `*out` (NULL on failure). The player holds its own decoder, so
/// playing never waits for other threads; it keeps the stream alive. Thread-safe.
///
/// # Safety
/// `h` is a live handle; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn ac_player_new(h: *const ac_stream, out: *mut *mut ac_player) -> ac_status {
    guard(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: `out` is writable (the contract) and not NULL.
        unsafe { *out = std::ptr::null_mut() };
        // SAFETY: the contract.
        let s = unsafe { stream(h) }?;
        let player = Box::new(ac_player { stream: Arc::clone(s), head: None });
        // SAFETY: checked above.
        unsafe { *out = Box::into_raw(player) };
        Ok(())
    })
}

/// Decodes frame `frame` with the player into `out_xyz` (`n` floats, at least 3 × vertices).
/// Frames in order cost the bulk decode's time per frame (each packet decoded once, the
/// decoder carried from packet to packet); any other order costs what [`ac_decode_frame`] does.
///
/// # Safety
/// `p` is a live player used by no other thread meanwhile; `out_xyz` points to `n` writable
/// floats.
#[no_mangle]
pub unsafe extern "C" fn ac_player_decode_frame(
    p: *mut ac_player,
    frame: usize,
    out_xyz: *mut f32,
    n: usize,
) -> ac_status {
    guard(|| {
        // SAFETY: the contract.
        let player = unsafe { p.as_mut() }.ok_or_else(|| null("the player"))?;
        let s = Arc::clone(&player.stream);
        s.check_range(frame, 1, n)?;
        // SAFETY: the contract.
        let out = unsafe { out_slice(out_xyz, n, "out_xyz") }?;
        if player.head.is_none() {
            player.head = Some(s.playhead().map_err(|e| s.failure(&e))?);
        }
        let Some(head) = player.head.as_mut() else { return Err(Failure::new(AC_ERR_INTERNAL, "no decoder")) };
        let result = s.decode_into(head, frame, 1, out);
        if result.is_err() {
            // The decoder's state after a failed packet is unknown: the next call starts afresh.
            player.head = None;
        }
        result
    })
}

/// Decodes frame `frame` with the player and sets `*out_xyz` to its 3 × vertices floats inside
/// the packet the player keeps: no copy (for an engine that uploads straight from it). The
/// pointer is valid until the next call on this player or its free; `*out_xyz` is NULL on failure.
/// Costs as [`ac_player_decode_frame`], less the copy.
///
/// # Safety
/// `p` is a live player used by no other thread meanwhile; `out_xyz` is writable.
#[no_mangle]
pub unsafe extern "C" fn ac_player_frame_view(p: *mut ac_player, frame: usize, out_xyz: *mut *const f32) -> ac_status {
    guard(|| {
        if out_xyz.is_null() {
            return Err(null("out_xyz"));
        }
        // SAFETY: `out_xyz` is writable (the contract) and not NULL.
        unsafe { *out_xyz = std::ptr::null() };
        // SAFETY: the contract.
        let player = unsafe { p.as_mut() }.ok_or_else(|| null("the player"))?;
        let s = Arc::clone(&player.stream);
        s.check_range(frame, 1, usize::MAX)?;
        if player.head.is_none() {
            player.head = Some(s.playhead().map_err(|e| s.failure(&e))?);
        }
        let Some(head) = player.head.as_mut() else { return Err(Failure::new(AC_ERR_INTERNAL, "no decoder")) };
        let pos = s.packet_of(frame);
        let local = frame - s.index[pos].first_frame as usize;
        let v3 = s.values_per_frame();
        match s.packet(head, pos) {
            Ok(frames) => {
                let view = frames[local * v3..(local + 1) * v3].as_ptr();
                // SAFETY: as above.
                unsafe { *out_xyz = view };
                Ok(())
            }
            Err(e) => {
                // The decoder's state after a failed packet is unknown: the next call starts afresh.
                player.head = None;
                Err(s.failure(&e))
            }
        }
    })
}

/// Frees a player (NULL is accepted).
///
/// # Safety
/// `p` is NULL or a player from this library, not used again.
#[no_mangle]
pub unsafe extern "C" fn ac_player_free(p: *mut ac_player) {
    guard(|| {
        if !p.is_null() {
            // SAFETY: made by `Box::into_raw` in `ac_player_new`, freed once (the contract).
            drop(unsafe { Box::from_raw(p) });
        }
        Ok(())
    });
}

/// Bytes the library allocated (the stream [`ac_encode`] wrote): `size` bytes at `data`. Free
/// them with [`ac_buffer_free`]; `data` is NULL when `size` is 0.
#[repr(C)]
pub struct ac_buffer {
    /// The bytes.
    pub data: *mut u8,
    /// Their number.
    pub size: usize,
}

/// `key=value` pairs separated by spaces, tabs, newlines or commas (the values of every codec
/// parameter are numbers or names without either).
fn param_pairs(text: &str) -> Vec<String> {
    text.split(|c: char| c == ',' || c.is_whitespace()).filter(|p| !p.is_empty()).map(str::to_owned).collect()
}

/// An error of the encoder or the searches, with its sources on one line as the CLI prints it.
fn encode_failure(e: &(dyn std::error::Error + 'static)) -> Failure {
    let status = match e.downcast_ref::<Error>() {
        Some(e) => return Failure::from_error(e, None),
        None => AC_ERR_FORMAT,
    };
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let more = s.to_string();
        if !text.contains(&more) {
            text = format!("{text}: {more}");
        }
        source = s.source();
    }
    Failure::new(status, text)
}

/// A C string argument: `None` for NULL or "", else its UTF-8 text.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string.
unsafe fn text_arg<'a>(p: *const c_char, what: &str) -> Outcome<Option<&'a str>> {
    if p.is_null() {
        return Ok(None);
    }
    // SAFETY: NUL-terminated (the contract).
    let s = unsafe { CStr::from_ptr(p) };
    let s = s.to_str().map_err(|_| Failure::new(AC_ERR_INVALID_ARGUMENT, format!("{what} is not UTF-8")))?;
    Ok(Some(s).filter(|s| !s.trim().is_empty()))
}

/// Encodes an animation into `.anim` stream bytes in `*out` (a buffer the library owns: free it
/// with [`ac_buffer_free`]; `{NULL, 0}` on failure), as `animcodec encode` does:
///
/// - `positions`: `frames × vertices × 3` floats (x, y, z per vertex, frame after frame), finite;
/// - `triangles`: `triangle_count × 3` vertex indices (NULL when `triangle_count` is 0);
/// - `frame_rate`: frames per second (> 0);
/// - `codec`: a codec name (`"quant-delta"`, `"pca-aoi"`, `"hosvd"`, `"sac"`, `"stseg"`,
///   `"laplacian"`) or `"auto"` (the smallest stream over every codec; not with `params`);
/// - `params`: NULL, or the codec's parameters as `key=value` pairs separated by spaces or
///   commas (`"bits=12 block=8"`), as `-p` takes them;
/// - `target`: NULL, or an error to meet as `--target` takes it (`"kg=0.5"`,
///   `"kg=0.5,sted=0.05"`): the codec's parameter space is searched for the smallest stream
///   meeting it, the `params` staying fixed.
///
/// With `params` and no `target`: exactly those parameters (the rest at their defaults). With
/// neither: the smallest stream meeting the default quality (`kg=0.5,sted=0.05`). A search
/// encodes and measures many candidates: seconds to minutes on large animations. Errors carry
/// the CLI's messages. Thread-safe.
///
/// # Safety
/// `positions` points to `frames × vertices × 3` readable floats; `triangles` to
/// `triangle_count × 3` readable indices (or is NULL when that count is 0); `codec`, `params`
/// and `target` are NULL or NUL-terminated strings; `out` is writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn ac_encode(
    positions: *const f32,
    frames: usize,
    vertices: usize,
    triangles: *const u32,
    triangle_count: usize,
    frame_rate: f32,
    codec: *const c_char,
    params: *const c_char,
    target: *const c_char,
    out: *mut ac_buffer,
) -> ac_status {
    guard(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: `out` is writable (the contract) and not NULL.
        unsafe { *out = ac_buffer { data: std::ptr::null_mut(), size: 0 } };
        // SAFETY: the contract.
        let codec_name = unsafe { text_arg(codec, "codec") }?.ok_or_else(|| null("codec"))?;
        // SAFETY: the contract.
        let params = unsafe { text_arg(params, "params") }?.map(param_pairs).unwrap_or_default();
        // SAFETY: the contract.
        let target = unsafe { text_arg(target, "target") }?;
        let too_many = || Failure::new(AC_ERR_INVALID_ARGUMENT, "the animation's size overflows the address space");
        let coords = frames.checked_mul(vertices).and_then(|n| n.checked_mul(3)).ok_or_else(too_many)?;
        let indices = triangle_count.checked_mul(3).ok_or_else(too_many)?;
        if positions.is_null() && coords > 0 {
            return Err(null("positions"));
        }
        if triangles.is_null() && indices > 0 {
            return Err(null("triangles"));
        }
        let coords: Vec<f32> = if coords == 0 {
            Vec::new()
        } else {
            // SAFETY: `coords` readable floats (the contract), not NULL.
            unsafe { std::slice::from_raw_parts(positions, coords) }.to_vec()
        };
        let tris: Vec<[u32; 3]> = if indices == 0 {
            Vec::new()
        } else {
            // SAFETY: `indices` readable values (the contract), not NULL.
            unsafe { std::slice::from_raw_parts(triangles, indices) }
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        };
        let invalid = |e: Error| Failure::new(AC_ERR_INVALID_ARGUMENT, message_with_sources(&e));
        let topology = Topology::new(vertices, tris).map_err(invalid)?;
        let animation = Animation::new(topology, coords, frame_rate).map_err(invalid)?;
        let bytes = encode_with(&animation, codec_name, &params, target)?;
        let boxed = bytes.into_boxed_slice();
        let size = boxed.len();
        let data = Box::into_raw(boxed).cast::<u8>();
        // SAFETY: checked above.
        unsafe { *out = ac_buffer { data, size } };
        Ok(())
    })
}

/// [`ac_encode`]'s work on a checked animation: fixed parameters, a target search or the
/// default-quality search, through the facade's front door (parameters from text) and searches.
fn encode_with(animation: &Animation, codec: &str, params: &[String], target: Option<&str>) -> Outcome<Vec<u8>> {
    let registry = registry();
    let invalid = |text: String| Failure::new(AC_ERR_INVALID_ARGUMENT, text);
    let chosen = if codec == "auto" {
        if !params.is_empty() {
            return Err(invalid(
                "parameters cannot be combined with codec \"auto\": parameters belong to one codec".into(),
            ));
        }
        None
    } else {
        let c = registry.by_name(codec).map_err(|e| invalid(message_with_sources(&e)))?;
        let base = front::params_from_text(c, params).map_err(|e| invalid(encode_failure(e.as_ref()).message))?;
        Some((c, base))
    };
    let progress = |_: &harness::Point| {};
    let all: Vec<&dyn AnimationCodec> = registry.iter().collect();
    let fixed: Vec<&str> = params.iter().filter_map(|p| p.split('=').next()).collect();
    let hit = match (target, chosen) {
        (None, Some((c, base))) if !params.is_empty() => {
            return encode_animation(c, &base, animation).map_err(|e| encode_failure(&e));
        }
        (None, chosen) => {
            let request =
                SearchRequest { refine: 4, progress: &progress, ..SearchRequest::default_quality(registry, animation) };
            match chosen {
                Some((c, _)) => harness::search_default_quality(&request, c).map_err(|e| encode_failure(&e))?,
                None => harness::search_space_target_auto(&request, &all).map_err(|e| encode_failure(&e))?.0,
            }
        }
        (Some(text), chosen) => {
            let target: Target = text.parse().map_err(invalid)?;
            let request =
                SearchRequest { refine: 4, progress: &progress, ..SearchRequest::new(registry, animation, target) };
            match chosen {
                Some((c, base)) => {
                    let walked = c.rate_ladder(&base).param;
                    if fixed.contains(&walked) {
                        return Err(invalid(format!(
                            "{}: '{walked}' is the rate ladder's parameter, which the target {target} chooses; leave it out",
                            c.name()
                        )));
                    }
                    harness::search_space_target(&request, c, &base, &fixed).map_err(|e| encode_failure(&e))?
                }
                None => harness::search_space_target_auto(&request, &all).map_err(|e| encode_failure(&e))?.0,
            }
        }
    };
    Ok(hit.stream)
}

/// Frees a buffer made by [`ac_encode`] and sets it to `{NULL, 0}` (NULL, and a buffer already
/// freed, are accepted).
///
/// # Safety
/// `b` is NULL or points to a buffer from [`ac_encode`] (or `{NULL, 0}`).
#[no_mangle]
pub unsafe extern "C" fn ac_buffer_free(b: *mut ac_buffer) {
    guard(|| {
        // SAFETY: NULL or a valid buffer (the contract).
        if let Some(b) = unsafe { b.as_mut() } {
            if !b.data.is_null() {
                let slice = std::ptr::slice_from_raw_parts_mut(b.data, b.size);
                // SAFETY: made by `Box::into_raw` of a boxed slice of `size` bytes in `ac_encode`,
                // freed once (the pointer is cleared below).
                drop(unsafe { Box::from_raw(slice) });
            }
            *b = ac_buffer { data: std::ptr::null_mut(), size: 0 };
        }
        Ok(())
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_in_an_entry_point_is_reported_as_an_internal_error() {
        let status = guard(|| panic!("decoder exploded"));
        assert_eq!(status, AC_ERR_INTERNAL);
        // SAFETY: a C string this thread owns until its next failing call.
        let text = unsafe { CStr::from_ptr(ac_last_error()) }.to_str().unwrap().to_owned();
        assert!(text.contains("internal error") && text.contains("decoder exploded"), "{text}");
        // Also a panic with a formatted message, and one on another thread joined inside.
        let status = guard(|| {
            let n = 3;
            std::thread::scope(|scope| scope.spawn(move || panic!("worker {n}")).join())
                .map_err(|_| Failure::new(AC_ERR_INTERNAL, "worker panicked"))
        });
        assert_eq!(status, AC_ERR_INTERNAL);
        assert_eq!(guard(|| Ok(())), AC_OK);
    }

    #[test]
    fn every_entry_point_runs_inside_the_guard() {
        let source = include_str!("lib.rs");
        let mut checked = 0;
        for item in source.split("#[no_mangle]").skip(1) {
            let body = &item[..item.find("\n}\n").expect("function end")];
            let name = body.split("fn ").nth(1).and_then(|s| s.split('(').next()).unwrap();
            // ac_last_error and ac_status_name only read a thread-local or a static table;
            // ac_limits_default only reads constants; ac_decode_frame forwards to a guarded call.
            let exempt = ["ac_last_error", "ac_status_name", "ac_limits_default", "ac_decode_frame"];
            assert!(body.contains("guard(") || body.contains("guard_value(") || exempt.contains(&name), "{name}");
            checked += 1;
        }
        assert!(checked >= 13, "{checked}");
    }
}
