//! Cross-codec conformance suite. The checks live in [`suite`] (one function per check, each
//! taking a registry and returning the [`Failures`] it found); `tests/*.rs` run them. This
//! library also holds what they share: small synthetic animations, parameter helpers (default and both ends of a codec's
//! rate ladder), error measurement against a codec's declared [`ErrorBound`], a deterministic
//! pseudo-random generator, panic capture, and tools that take a valid `.anim` stream apart
//! and corrupt it in controlled ways (byte flips with the packet or header CRC patched,
//! rebuilt streams with mutated packets or configuration).
//!
//! Synthetic data comes from `animcodec::synth`. Every test loops over
//! `animcodec::registry()`, so a codec added to the registry list is tested with no other
//! change.

/// Shared with the CLI tests: whether a message shows a Rust `Debug` value.
pub use codec_core::error::looks_like_debug;
use std::io::Cursor;
use std::panic::{catch_unwind, AssertUnwindSafe};

use codec_core::container::{self, ContainerReader, ContainerWriter, Header, IndexEntry, Section};
use codec_core::{
    Animation, AnimationCodec, CodecRegistry, Error, ErrorBound, Limits, Packet, ParamSet, ParamValue, Topology,
};

pub mod fuzz;
pub mod suite;

/// The registry under test (the one list in the `animcodec` crate).
pub fn registry() -> CodecRegistry {
    animcodec::registry()
}

/// Environment variable restricting the conformance suite to some codecs: a comma-separated
/// list of names (`ANIMCODEC_CODECS=my-codec cargo test --workspace --test conformance
/// --test corruption --test encoder_input`), for working on one codec. Unset (as in CI), every
/// codec is tested.
pub const CODECS_VAR: &str = "ANIMCODEC_CODECS";

/// The codecs the conformance suite checks (`tests/conformance.rs`, `corruption.rs`,
/// `encoder_input.rs`): [`registry`], or only the codecs named in [`CODECS_VAR`]. A restricted
/// run says so on the real standard error (past libtest's capture, like a skip), and an unknown
/// name is an error, so a typo cannot make a run that tests nothing look like a pass. Tests of
/// other things (golden streams, fuzz corpora, limits) always use the whole [`registry`].
///
/// # Panics
/// When [`CODECS_VAR`] names a codec that is not registered, or names none.
pub fn codecs_under_test() -> CodecRegistry {
    let Some(list) = std::env::var_os(CODECS_VAR) else { return registry() };
    let list = list.to_string_lossy().into_owned();
    let all = registry();
    let names: Vec<&str> = list.split(',').map(str::trim).filter(|n| !n.is_empty()).collect();
    assert!(!names.is_empty(), "{CODECS_VAR} is set but names no codec");
    let mut chosen = Vec::new();
    for name in &names {
        all.by_name(name).unwrap_or_else(|e| panic!("{CODECS_VAR}: {e}"));
        chosen.push(*name);
    }
    static SAID: std::sync::Once = std::sync::Once::new();
    SAID.call_once(|| {
        let _ = std::io::Write::write_all(
            &mut std::io::stderr(),
            format!("NOTE {CODECS_VAR}={list}: the conformance suite checks only {}\n", chosen.join(", ")).as_bytes(),
        );
    });
    all.retain(|c| chosen.contains(&c.name()))
}

// ---------------------------------------------------------------------------------------
// Synthetic animations
// ---------------------------------------------------------------------------------------

/// The shared synthetic animations (`animcodec::synth`).
pub use animcodec::synth;

/// The animations every round-trip test runs on: `(name, animation)`, every
/// `animcodec::synth` preset at `SynthSize::Small` (a few hundred vertices × 40 frames;
/// a preset added there is tested here too).
pub fn animations() -> Vec<(&'static str, Animation)> {
    synth::NAMES
        .iter()
        .map(|&name| (name, synth::by_name(name, synth::SynthSize::Small).expect("every listed name builds")))
        .collect()
}

/// A small animation with several packets for most codecs (40 frames, 48 vertices), used by
/// the random-access and corruption tests.
pub fn small_animation() -> Animation {
    synth::waving_flag(8, 6, 40)
}

/// A tiny animation (12 frames, 20 vertices) for the exhaustive truncation test.
pub fn tiny_animation() -> Animation {
    synth::waving_flag(5, 4, 12)
}

/// Unusual but valid animations: each codec must encode them within its bound or refuse
/// them with an error, never panic.
pub fn edge_animations() -> Vec<(&'static str, Animation)> {
    let flag = synth::waving_flag(6, 5, 10);
    let v = flag.vertex_count();
    let tris = flag.triangles().to_vec();
    let first = flag.frame(0).to_vec();
    let mut out = vec![
        ("single-frame", Animation::new(flag.topology().clone(), first.clone(), 30.0).expect("valid")),
        ("static", Animation::new(flag.topology().clone(), first.repeat(8), 30.0).expect("valid")),
        (
            "one-triangle",
            Animation::from_parts(
                3,
                vec![[0, 1, 2]],
                (0..6).flat_map(|t| [0.0, 0.0, 0.0, 1.0, 0.1 * t as f32, 0.0, 0.0, 1.0, 0.0]).collect(),
                30.0,
            )
            .expect("valid"),
        ),
        ("point-cloud-no-triangles", Animation::from_parts(v, vec![], flag.positions().to_vec(), 30.0).expect("valid")),
        (
            "degenerate-triangles",
            Animation::from_parts(
                v,
                tris.iter().map(|t| [t[0], t[0], t[1]]).collect(),
                flag.positions().to_vec(),
                30.0,
            )
            .expect("valid"),
        ),
        (
            "flat-z-axis",
            Animation::new(
                flag.topology().clone(),
                flag.positions().chunks_exact(3).flat_map(|p| [p[0], p[1], 0.0]).collect(),
                30.0,
            )
            .expect("valid"),
        ),
        (
            // Far from the origin with small motion: stresses precision of ranges and bases.
            "far-from-origin",
            Animation::new(flag.topology().clone(), flag.positions().iter().map(|x| x + 1000.0).collect(), 30.0)
                .expect("valid"),
        ),
        (
            "single-vertex",
            Animation::from_parts(1, vec![], (0..5).flat_map(|t| [t as f32, 0.5, -0.5]).collect(), 30.0)
                .expect("valid"),
        ),
    ];
    // Two identical frames repeated: a motion with exact repeats (rank-deficient in time).
    let two: Vec<f32> = [flag.frame(0), flag.frame(5)].concat();
    out.push(("alternating", Animation::new(flag.topology().clone(), two.repeat(5), 30.0).expect("valid")));
    out
}

// ---------------------------------------------------------------------------------------
// Parameters
// ---------------------------------------------------------------------------------------

/// `codec`'s defaults with `name` set to `value`.
pub fn params_with(codec: &dyn AnimationCodec, name: &str, value: ParamValue) -> codec_core::Result<ParamSet> {
    codec.default_params().with(&codec.param_specs(), name, value)
}

/// The settings every round-trip test uses: defaults, and both ends of the rate ladder.
/// Labels read like `default`, `bits=4 (ladder low)`.
pub fn test_settings(codec: &dyn AnimationCodec) -> Result<Vec<(String, ParamSet)>, String> {
    let mut out = vec![("default".to_string(), codec.default_params())];
    let ladder = codec.rate_ladder(&codec.default_params());
    let ends = [(ladder.steps.first(), "ladder low"), (ladder.steps.last(), "ladder high")];
    for (step, what) in ends {
        let step = step.ok_or_else(|| format!("rate ladder on '{}' has no steps", ladder.param))?;
        let p = params_with(codec, ladder.param, step.clone())
            .map_err(|e| format!("{what} {}={step} is not settable: {e}", ladder.param))?;
        out.push((format!("{}={step} ({what})", ladder.param), p));
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------
// Error measurement
// ---------------------------------------------------------------------------------------

/// Reconstruction error of `decoded` against `original`, as [`ErrorBound`] defines it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// Largest absolute coordinate difference.
    pub max_coordinate_error: f64,
    /// RMS of the per-coordinate difference divided by the bounding-box diagonal of the original.
    pub relative_rms_error: f64,
}

/// Measures the error of `decoded` against `original` (same shape required).
pub fn measure_error(original: &Animation, decoded: &Animation) -> Result<Measured, String> {
    if original.vertex_count() != decoded.vertex_count() || original.frame_count() != decoded.frame_count() {
        return Err(format!(
            "decoded shape {}×{} differs from the original {}×{}",
            decoded.frame_count(),
            decoded.vertex_count(),
            original.frame_count(),
            original.vertex_count()
        ));
    }
    let mut max = 0.0f64;
    let mut sum = 0.0f64;
    for (&a, &b) in original.positions().iter().zip(decoded.positions()) {
        let d = (a as f64 - b as f64).abs();
        max = max.max(d);
        sum += d * d;
    }
    let rms = (sum / original.positions().len() as f64).sqrt();
    let diag = original.bounding_box_diagonal();
    // A zero-extent animation has no relative scale; only an exact reconstruction is 0 then.
    let rel = if diag > 0.0 {
        rms / diag
    } else if rms == 0.0 {
        0.0
    } else {
        f64::INFINITY
    };
    Ok(Measured { max_coordinate_error: max, relative_rms_error: rel })
}

/// Checks `measured` against `bound`. At least one finite bound must be declared (an
/// infinite one is allowed beside it, e.g. a relative error on a zero-extent animation). The
/// comparison allows a relative 1e-9 for the rounding of this suite's own f64 sums (the
/// codec's promise is on exact values); nothing else is loosened.
pub fn check_bound(bound: &ErrorBound, measured: &Measured) -> Result<(), String> {
    let finite = [bound.max_coordinate_error, bound.relative_rms_error].into_iter().flatten().any(f64::is_finite);
    if !finite {
        return Err(format!("error_bound() declares no finite bound: {bound:?}"));
    }
    let slack = 1.0 + 1e-9;
    if let Some(b) = bound.max_coordinate_error {
        if b.is_nan() || b < 0.0 {
            return Err(format!("declared max_coordinate_error {b} is negative or NaN"));
        }
        if measured.max_coordinate_error > b * slack {
            return Err(format!("max coordinate error {:.6e} > bound {b:.6e}", measured.max_coordinate_error));
        }
    }
    if let Some(b) = bound.relative_rms_error {
        if b.is_nan() || b < 0.0 {
            return Err(format!("declared relative_rms_error {b} is negative or NaN"));
        }
        if measured.relative_rms_error > b * slack {
            return Err(format!("relative RMS error {:.6e} > bound {b:.6e}", measured.relative_rms_error));
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Limits, panics, failure collection, pseudo-random numbers
// ---------------------------------------------------------------------------------------

/// Tight decoding limits for a stream of `anim`: the exact vertex, frame and triangle counts
/// and `max_alloc_bytes` of 8 MiB in total (or the decoded size if that is larger — it never is
/// for the animations of this suite). `max_alloc_bytes` bounds the whole decode: a
/// sac decode of this suite's 240-vertex, 40-frame flag holds 6.2 MB at peak (its eigensolver's
/// workspaces), more than the 4 MiB this was when it bounded each allocation.
pub fn tight_limits(anim: &Animation) -> Limits {
    let decoded = anim.positions().len() * 4;
    Limits {
        max_vertices: anim.vertex_count(),
        max_frames: anim.frame_count(),
        max_triangles: anim.triangles().len(),
        max_alloc_bytes: (8usize << 20).max(decoded),
        max_work: codec_core::container::DEFAULT_MAX_WORK,
    }
}

/// Peak bytes a decode of a corrupt stream may hold live on the test thread: 16 × the
/// allocation limit. A decoder that sizes a buffer from an unchecked field of a corrupt
/// stream overshoots this by orders of magnitude.
pub fn peak_budget(limits: &Limits) -> u64 {
    16 * limits.max_alloc_bytes as u64
}

/// Runs `f`, turning a panic into `Err` with the panic message.
pub fn catch<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
        if let Some(s) = p.downcast_ref::<&str>() {
            format!("panicked: {s}")
        } else if let Some(s) = p.downcast_ref::<String>() {
            format!("panicked: {s}")
        } else {
            "panicked (non-string payload)".to_string()
        }
    })
}

/// Failures collected across codecs, so one test reports every failing codec at once.
#[derive(Debug, Default)]
pub struct Failures {
    list: Vec<String>,
    /// Most failures kept per codec (the rest are counted).
    pub per_codec_cap: usize,
    dropped: usize,
    cases: usize,
}

impl Failures {
    /// An empty collection keeping at most 20 messages per codec.
    pub fn new() -> Self {
        Self { list: Vec::new(), per_codec_cap: 20, dropped: 0, cases: 0 }
    }

    /// Records a failure of `codec`.
    pub fn push(&mut self, codec: &str, msg: impl Into<String>) {
        let prefix = format!("[{codec}] ");
        if self.list.iter().filter(|m| m.starts_with(&prefix)).count() >= self.per_codec_cap {
            self.dropped += 1;
        } else {
            self.list.push(format!("{prefix}{}", msg.into()));
        }
    }

    /// Runs one codec's checks, recording a panic escaping them as a failure.
    pub fn run(&mut self, codec: &str, f: impl FnOnce(&mut Failures)) {
        let mut local = Failures { per_codec_cap: self.per_codec_cap, ..Failures::new() };
        let r = catch(|| f(&mut local));
        self.dropped += local.dropped;
        self.cases += local.cases;
        for m in local.list {
            self.list.push(m);
        }
        if let Err(p) = r {
            self.push(codec, format!("test body {p}"));
        }
    }

    /// Counts `n` cases checked (reported by [`Failures::assert_none`], so a check that
    /// silently ran nothing shows up).
    pub fn count(&mut self, n: usize) {
        self.cases += n;
    }

    /// Cases counted so far.
    pub fn cases(&self) -> usize {
        self.cases
    }

    /// True when nothing failed.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The failure messages kept, each prefixed with `[codec] `.
    pub fn messages(&self) -> &[String] {
        &self.list
    }

    /// True when a kept message of `codec` contains `needle`.
    pub fn has(&self, codec: &str, needle: &str) -> bool {
        let prefix = format!("[{codec}] ");
        self.list.iter().any(|m| m.starts_with(&prefix) && m.contains(needle))
    }

    /// Panics with every failure, one per line, if any, and when no case was counted (a check
    /// that ran nothing must not pass); otherwise prints the case count.
    pub fn assert_none(&self, what: &str) {
        if self.list.is_empty() && self.cases == 0 {
            panic!("{what}: no case was checked");
        } else if self.list.is_empty() {
            eprintln!("{what}: {} case(s) checked, no failure", self.cases);
        } else {
            panic!(
                "{what}: {} failure(s){}:\n  {}",
                self.list.len() + self.dropped,
                if self.dropped > 0 { format!(" ({} not shown)", self.dropped) } else { String::new() },
                self.list.join("\n  ")
            );
        }
    }
}

/// SplitMix64: a tiny deterministic generator, so corruption positions are reproducible.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator seeded with `seed` (mix in the codec name for per-codec streams).
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// A generator seeded from a string and a number.
    pub fn for_codec(name: &str, salt: u64) -> Self {
        Self(name.bytes().fold(0x9E37_79B9_7F4A_7C15 ^ salt, |h, b| (h ^ b as u64).wrapping_mul(0x1000_0000_01B3)))
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// A non-zero byte (an XOR mask that always changes the byte).
    pub fn nonzero_byte(&mut self) -> u8 {
        (self.below(255) + 1) as u8
    }
}

// ---------------------------------------------------------------------------------------
// Decoding untrusted bytes
// ---------------------------------------------------------------------------------------

/// What decoding a (possibly corrupt) stream did, when it did not panic.
#[derive(Debug)]
pub struct DecodeOutcome {
    /// The decoder's result.
    pub result: codec_core::Result<Animation>,
    /// Peak bytes held live on this thread during the decode.
    pub peak_bytes: u64,
}

/// Peak bytes held live on this thread while `f` runs (`allocation_counter`), measured after
/// [`warm_up_numeric_caches`] so that only what `f` allocates counts.
pub fn measure_peak(f: impl FnOnce()) -> u64 {
    warm_up_numeric_caches();
    allocation_counter::measure(f).bytes_max
}

thread_local! {
    static NUMERIC_CACHES_WARM: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Makes faer's per-thread caches on the calling thread, once, before a peak is measured there.
///
/// On an x86-64 CPU with AVX2 or AVX-512, faer's dense products (in every decomposition, in the
/// sparse Cholesky's supernodes, in Krylov–Schur) run `private-gemm-x86`, whose first call on a
/// thread reserves a packing buffer of twice the L3 size the CPU reports (its `lib.rs`,
/// thread-local `MEM`: `2 × CACHE_INFO[2].cache_bytes`) and keeps it for the thread's life:
/// 629 145 600 bytes on a Xeon reporting 300 MiB of L3, 64 MiB on one reporting 32 MiB. The
/// buffer is reserved, not written (only the pages a product packs into are touched), and its
/// size depends on the CPU, not on the stream; counted against the first decode on a thread it
/// made the fuzz corpus replay fail on a 300 MiB-L3 machine only, and only when no earlier
/// encode had run on the thread (`docs/notes/issue-27-simd-limits.md`). The decoder
/// checks bound what a decode allocates from the stream's sizes, so they measure after it.
pub fn warm_up_numeric_caches() {
    if NUMERIC_CACHES_WARM.with(|w| w.replace(true)) {
        return;
    }
    // Above nano-gemm's size threshold, so the product takes private-gemm-x86's path (and its
    // thread-local buffer) where the CPU has one.
    let n = 64;
    let a = faer::Mat::<f64>::from_fn(n, n, |i, j| (i + j) as f64);
    let mut c = faer::Mat::<f64>::zeros(n, n);
    faer::linalg::matmul::matmul(c.as_mut(), faer::Accum::Replace, a.as_ref(), a.as_ref(), 1.0, faer::Par::Seq);
    std::hint::black_box(&c);
}

/// Decodes `bytes` with `decode_animation`, catching panics and measuring peak memory.
pub fn decode_guarded(bytes: &[u8], registry: &CodecRegistry, limits: Limits) -> Result<DecodeOutcome, String> {
    let mut result = None;
    let peak_bytes = measure_peak(|| {
        result = Some(catch(|| codec_core::decode_animation(bytes, registry, limits)));
    });
    let result = result.expect("measure runs the closure")?;
    Ok(DecodeOutcome { result, peak_bytes })
}

/// Decodes frame `t` of `bytes` with `decode_frame`, catching panics and measuring peak memory.
pub fn decode_frame_guarded(
    bytes: &[u8],
    registry: &CodecRegistry,
    limits: Limits,
    t: usize,
) -> Result<(codec_core::Result<Vec<f32>>, u64), String> {
    let mut result = None;
    let peak = measure_peak(|| {
        result = Some(catch(|| codec_core::decode_frame(&mut Cursor::new(bytes), registry, limits, t)));
    });
    Ok((result.expect("measure runs the closure")?, peak))
}

/// Checks the outcome of decoding a corrupt stream whose checksums were patched so the codec's
/// own parser sees the corruption: no panic, peak memory within [`peak_budget`], and either
/// an error or an animation of `frames × vertices` finite coordinates. Returns a failure
/// message or `None`.
pub fn judge_corrupt_decode(
    label: &str,
    bytes: &[u8],
    registry: &CodecRegistry,
    limits: Limits,
    frames: usize,
    vertices: usize,
) -> Option<String> {
    match decode_guarded(bytes, registry, limits) {
        Err(p) => Some(format!("{label}: decode {p}")),
        Ok(out) if out.peak_bytes > peak_budget(&limits) => Some(format!(
            "{label}: decode held {} bytes at peak (budget {}, max_alloc_bytes {})",
            out.peak_bytes,
            peak_budget(&limits),
            limits.max_alloc_bytes
        )),
        Ok(DecodeOutcome { result: Err(e), .. }) => {
            if e.to_string().is_empty() {
                Some(format!("{label}: empty error message"))
            } else {
                None
            }
        }
        Ok(DecodeOutcome { result: Ok(a), .. }) => {
            if a.frame_count() != frames || a.vertex_count() != vertices {
                Some(format!(
                    "{label}: decoded {}×{} instead of {frames}×{vertices}",
                    a.frame_count(),
                    a.vertex_count()
                ))
            } else if a.positions().iter().any(|x| !x.is_finite()) {
                Some(format!("{label}: decoded non-finite coordinates"))
            } else {
                None
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Taking streams apart and corrupting them
// ---------------------------------------------------------------------------------------

/// A valid stream read back into its parts, ready to be mutated and rebuilt.
#[derive(Debug, Clone)]
pub struct Parts {
    /// The header.
    pub header: Header,
    /// The packets, in order.
    pub packets: Vec<Packet>,
    /// The index (offsets of the packets in the original bytes).
    pub index: Vec<IndexEntry>,
}

/// Reads every part of a valid stream (fails on any error).
pub fn split(bytes: &[u8]) -> codec_core::Result<Parts> {
    let mut r = ContainerReader::new(bytes, Limits::default())?;
    let mut packets = Vec::new();
    while let Some(s) = r.next_section() {
        match s? {
            Section::Packet(p) => packets.push(p),
            Section::End(index) => return Ok(Parts { header: r.header().clone(), packets, index }),
        }
    }
    Err(Error::malformed("conformance", "stream", "ended without an index"))
}

/// Writes a container from parts, with every checksum, length and index entry consistent.
/// `topology` and `frame_count` default to the header's.
pub fn rebuild(
    header: &Header,
    config: &[u8],
    codec_version: u16,
    topology: Option<&Topology>,
    frame_count: Option<usize>,
    packets: &[Packet],
) -> codec_core::Result<Vec<u8>> {
    let info = &header.info;
    let mut w = ContainerWriter::new(
        Vec::new(),
        info.fourcc,
        codec_version,
        topology.unwrap_or(&info.topology),
        frame_count.unwrap_or(info.frame_count),
        info.frame_rate,
        config,
    )?;
    for p in packets {
        w.write_packet(p)?;
    }
    w.finish()
}

/// Offset of the packet header fields (after the tag) and payload bounds of index entry `e`.
fn packet_span(e: &IndexEntry) -> (usize, usize, usize) {
    let fields = e.offset as usize + 4;
    let payload = fields + 13;
    (fields, payload, payload + e.payload_bytes as usize)
}

/// Recomputes the CRC-32 of the packet whose tag starts at `e.offset` (FORMAT.md: CRC over
/// the 13 header bytes after the "APKT" tag plus the payload, stored little-endian after the
/// payload), so a corrupted payload reaches the codec's parser.
pub fn patch_packet_crc(bytes: &mut [u8], e: &IndexEntry) {
    let (fields, _, end) = packet_span(e);
    let crc = crc32fast::hash(&bytes[fields..end]);
    bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
}

/// Payload byte range of index entry `e` in the stream.
pub fn payload_range(e: &IndexEntry) -> std::ops::Range<usize> {
    let (_, start, end) = packet_span(e);
    start..end
}

/// Byte range of the codec configuration inside the header.
pub fn config_range(header: &Header) -> std::ops::Range<usize> {
    let start = container::FIXED_HEADER_BYTES + 4;
    start..start + header.config.len()
}

/// Recomputes the header CRC-32 (over every header byte before it).
pub fn patch_header_crc(bytes: &mut [u8], header: &Header) {
    let end = header.header_bytes - 4;
    let crc = crc32fast::hash(&bytes[..end]);
    bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_animations_are_small_and_valid() {
        for (name, a) in animations().into_iter().chain(edge_animations()) {
            assert!(a.vertex_count() <= 400 && a.frame_count() <= 40, "{name} too large");
        }
        assert!(animations().len() >= 4);
    }

    #[test]
    fn error_measure_and_bound_check() {
        let a = synth::waving_flag(4, 3, 2);
        let mut p = a.positions().to_vec();
        p[5] += 0.25;
        let b = Animation::new(a.topology().clone(), p, 30.0).unwrap();
        let m = measure_error(&a, &b).unwrap();
        assert!((m.max_coordinate_error - 0.25).abs() < 1e-6);
        let expect_rms = (0.25f64 * 0.25 / a.positions().len() as f64).sqrt() / a.bounding_box_diagonal();
        assert!((m.relative_rms_error - expect_rms).abs() < 1e-6 * expect_rms);
        let ok = ErrorBound { max_coordinate_error: Some(0.3), relative_rms_error: None };
        assert!(check_bound(&ok, &m).is_ok());
        let bad = ErrorBound { max_coordinate_error: Some(0.2), relative_rms_error: None };
        assert!(check_bound(&bad, &m).is_err());
        assert!(check_bound(&ErrorBound::default(), &m).is_err());
        let only_inf = ErrorBound { max_coordinate_error: Some(f64::INFINITY), relative_rms_error: None };
        assert!(check_bound(&only_inf, &m).is_err());
        let nan = ErrorBound { max_coordinate_error: Some(0.3), relative_rms_error: Some(f64::NAN) };
        assert!(check_bound(&nan, &m).is_err());
        let rms_bad = ErrorBound { max_coordinate_error: None, relative_rms_error: Some(expect_rms * 0.5) };
        assert!(check_bound(&rms_bad, &m).is_err());
    }

    #[test]
    fn crc_patch_makes_a_flipped_payload_pass_the_container() {
        let codec = codec_quant_delta::QuantDelta;
        let anim = small_animation();
        let bytes = codec_core::encode_animation(&codec, &codec.default_params(), &anim).unwrap();
        let parts = split(&bytes).unwrap();
        let e = parts.index[0];
        let mut b = bytes.clone();
        b[payload_range(&e).start + 2] ^= 0x40;
        assert!(matches!(split(&b), Err(Error::Checksum { .. })));
        patch_packet_crc(&mut b, &e);
        let reread = split(&b).unwrap();
        assert_ne!(reread.packets[0].data, parts.packets[0].data);
        // Same for the header and its configuration bytes.
        let mut h = bytes.clone();
        h[config_range(&parts.header).start] ^= 1;
        assert!(matches!(split(&h), Err(Error::Checksum { .. })));
        patch_header_crc(&mut h, &parts.header);
        assert_eq!(split(&h).unwrap().header.config[0], parts.header.config[0] ^ 1);
        // Rebuilding unchanged parts gives the original bytes.
        let same =
            rebuild(&parts.header, &parts.header.config, parts.header.info.codec_version, None, None, &parts.packets)
                .unwrap();
        assert_eq!(same, bytes);
    }

    #[test]
    fn rng_is_deterministic_and_spread() {
        let mut a = Rng::for_codec("x", 1);
        let mut b = Rng::for_codec("x", 1);
        let va: Vec<u64> = (0..8).map(|_| a.next_u64()).collect();
        let vb: Vec<u64> = (0..8).map(|_| b.next_u64()).collect();
        assert_eq!(va, vb);
        let mut c = Rng::new(7);
        let mut hits = [0usize; 4];
        for _ in 0..4000 {
            hits[c.below(4)] += 1;
        }
        assert!(hits.iter().all(|&h| h > 800), "{hits:?}");
        assert!((0..1000).all(|_| c.nonzero_byte() != 0));
    }
}
