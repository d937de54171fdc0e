//! Streams that ask for too much memory or work are refused before it is spent:
//! `Limits::max_alloc_bytes` bounds the total a decode holds, `Limits::max_work` the
//! operations it computes. Each crafted input of `../shared/probe-round3/` has an equivalent
//! made here (so these always run); the probe files themselves are decoded too when `../shared`
//! is there. Every refusal must be a clear error within seconds and well under 1 GB.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use codec_core::container::ContainerWriter;
use codec_core::{decode_animation, Error, Limits, Packet, Topology};
use conformance_tests::{measure_peak, registry};

/// What every refusal here must stay under.
const MAX_PEAK_BYTES: u64 = 1 << 30;
const MAX_SECONDS: u64 = 10;

/// Decodes `bytes` with the default limits, checking time and peak memory; returns the error.
fn refused(label: &str, bytes: &[u8]) -> Error {
    let registry = registry();
    let start = Instant::now();
    let mut result = None;
    let peak = measure_peak(|| result = Some(decode_animation(bytes, &registry, Limits::default())));
    let elapsed = start.elapsed();
    let result = result.expect("measured");
    assert!(peak < MAX_PEAK_BYTES, "{label}: held {peak} bytes at peak");
    assert!(elapsed < Duration::from_secs(MAX_SECONDS), "{label}: took {elapsed:?}");
    let e = match result {
        Ok(a) => {
            panic!("{label}: decoded {} frames of {} vertices; expected a refusal", a.frame_count(), a.vertex_count())
        }
        Err(e) => e,
    };
    eprintln!("{label}: refused in {elapsed:?}, {peak} bytes at peak: {e}");
    e
}

/// A sac stream of one keyframe on `topology` whose config asks for `bases` vectors. The packet
/// is a placeholder: the refusals tested here come from the header, before any packet is read.
fn sac_stream(topology: &Topology, bases: u32) -> Vec<u8> {
    let registry = registry();
    let codec = registry.by_name("sac").unwrap();
    let version = codec.stream_version();
    let mut config = vec![12u8];
    config.extend_from_slice(&bases.to_le_bytes());
    config.extend_from_slice(&[0, 16]);
    if version >= 3 {
        config.extend_from_slice(&[0, 1]);
    }
    let mut w = ContainerWriter::new(Vec::new(), codec.fourcc(), version, topology, 1, 30.0, &config).unwrap();
    w.write_packet(&Packet { first_frame: 0, frame_count: 1, keyframe: true, data: vec![0, 0] }).unwrap();
    w.finish().unwrap()
}

/// `g1000.anim`'s request: 1000 harmonic bases (the most a sac config may ask for) on a
/// 160 × 160 grid, 25 600 vertices (the probe file has 99 856). Refused from the header by the
/// work budget, before the basis or the Poisson factor is allocated.
#[test]
fn a_thousand_bases_on_a_large_mesh_is_refused_by_the_work_budget() {
    let bytes = sac_stream(&animcodec::synth::flag_topology(160, 160), 1000);
    let e = refused("sac, 1000 bases on 25 600 vertices", &bytes);
    assert!(matches!(e, Error::WorkLimit { .. }) && e.to_string().contains("harmonics"), "{e}");
    // The same mesh with the default 16 bases is not refused by the limits (it fails only on
    // its placeholder packet).
    let ok = sac_stream(&animcodec::synth::flag_topology(160, 160), 16);
    let e = decode_animation(&ok, &registry(), Limits::default()).unwrap_err();
    assert!(!matches!(e, Error::WorkLimit { .. } | Error::AllocLimit { .. }), "{e}");
}

/// Random triangles, six per vertex: an expander graph, whose Cholesky factor fills in almost
/// densely whatever the ordering (`exp.anim` of the probe: 19 600 vertices).
fn expander(n: usize) -> Topology {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as u32
    };
    let mut tris = Vec::with_capacity(6 * n);
    while tris.len() < 6 * n {
        let t = [next(), next(), next()];
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            tris.push(t);
        }
    }
    Topology::new(n, tris).unwrap()
}

/// `exp.anim`'s connectivity at 12 000 vertices: the Poisson factor's work (about n³/10) is
/// over the budget, found from the symbolic factorization before any numeric one.
#[test]
fn an_expander_connectivity_is_refused_before_its_factorization() {
    let bytes = sac_stream(&expander(12_000), 16);
    let e = refused("sac on a 12 000-vertex expander", &bytes);
    assert!(matches!(e, Error::WorkLimit { .. } | Error::AllocLimit { .. }), "{e}");
    assert!(e.to_string().contains("Cholesky"), "{e}");
}

/// Memory is a budget for the whole decode: parts that each fit but together do not are
/// refused (the decoded animation is reserved first, the decoder gets what is left).
#[test]
fn the_memory_limit_bounds_the_total_not_each_allocation() {
    let registry = registry();
    let codec = registry.by_name("quant-delta").unwrap();
    let anim = animcodec::synth::waving_flag(40, 30, 20);
    let bytes = codec_core::encode_animation(codec, &codec.default_params(), &anim).unwrap();
    let decoded = anim.positions().len() as u64 * 4;
    // Room for the decoded animation alone, not for it and one decoded packet besides.
    let limits = Limits { max_alloc_bytes: decoded as usize + 1024, ..Limits::default() };
    let e = decode_animation(&bytes, &registry, limits).unwrap_err();
    assert!(matches!(e, Error::AllocLimit { .. }), "{e}");
    let roomy = Limits { max_alloc_bytes: 4 * decoded as usize + (1 << 20), ..Limits::default() };
    assert_eq!(
        decode_animation(&bytes, &registry, roomy).unwrap().positions(),
        decode_animation(&bytes, &registry, Limits::default()).unwrap().positions()
    );
}

/// The work budget is deterministic and checked: a small one refuses a stream a large one
/// decodes.
#[test]
fn the_work_limit_refuses_what_exceeds_it() {
    let registry = registry();
    let codec = registry.by_name("sac").unwrap();
    let anim = animcodec::synth::waving_flag(12, 10, 6);
    let bytes = codec_core::encode_animation(codec, &codec.default_params(), &anim).unwrap();
    assert!(decode_animation(&bytes, &registry, Limits::default()).is_ok());
    let e = decode_animation(&bytes, &registry, Limits { max_work: 1000, ..Limits::default() }).unwrap_err();
    assert!(matches!(e, Error::WorkLimit { .. }), "{e}");
    assert!(e.to_string().contains("--max-work"), "{e}");
}

/// `Limits::default` is representable on every target (1 GiB), never 0.
#[test]
fn default_limits_are_never_zero() {
    let l = Limits::default();
    assert!(l.max_alloc_bytes > 0 && l.max_work > 0);
    assert_eq!(l.max_alloc_bytes as u64, 1u64 << 30);
}

fn probe_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("..").join("shared").join("probe-round3")
}

/// The probe files themselves (when `../shared` is there).
#[test]
fn probe_round3_streams_are_refused() {
    let dir = probe_dir();
    if !dir.is_dir() {
        codec_core::testing::skip(
            "probe_round3_streams_are_refused",
            &format!("{} is missing (the equivalents above ran)", dir.display()),
        );
        return;
    }
    for name in ["g1000.anim", "exp.anim"] {
        let bytes = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        refused(name, &bytes);
    }
}

/// A stream of a few hundred bytes whose topology claims 2²⁴ vertices (as a 700-byte
/// probe stream did): every codec's tiny stream with its topology swapped. Coding order graphs and
/// decoded frames for that many vertices exceed the default total budget, so each is refused
/// before they are built, within seconds and under 1 GB.
#[test]
fn a_tiny_stream_claiming_16m_vertices_is_refused_early() {
    let registry = registry();
    // Few frames: the decoded frames (4 × 2^24 × 12 bytes) fit the default budget, so what
    // is refused is what each codec would build on top of them.
    let anim = animcodec::synth::waving_flag(6, 5, 4);
    let huge = Topology::new(1 << 24, anim.topology().triangles().to_vec()).unwrap();
    for codec in registry.iter() {
        // hosvd's default size model cannot reduce 4 frames; the smallest rate point can.
        let params = match codec.name() {
            "hosvd" => conformance_tests::params_with(codec, "ss", codec_core::ParamValue::Float(0.3)).unwrap(),
            _ => codec.default_params(),
        };
        let bytes = codec_core::encode_animation(codec, &params, &anim).unwrap();
        let parts = conformance_tests::split(&bytes).unwrap();
        let crafted = conformance_tests::rebuild(
            &parts.header,
            &parts.header.config,
            parts.header.info.codec_version,
            Some(&huge),
            None,
            &parts.packets,
        )
        .unwrap();
        assert!(crafted.len() < 4096, "{}: {} bytes", codec.name(), crafted.len());
        refused(&format!("{} claiming 2^24 vertices ({} bytes)", codec.name(), crafted.len()), &crafted);
    }
}

/// A sac stream coded with 32 bases whose config byte says 544 (header CRC valid). Computing
/// the 544-vector basis first would cost a dense 900 × 900 eigenproblem here (13 MB; 27 s and
/// 560 MB on horse-gallop) before the P-frames' descriptors show the stream malformed, so the
/// basis waits for the interval's first P-frame, whose descriptors are decoded at the basis's
/// size first: the refusal holds a fraction of that.
#[test]
fn a_sac_config_asking_for_more_bases_is_refused_before_the_basis() {
    let registry = registry();
    let codec = registry.by_name("sac").unwrap();
    let anim = animcodec::synth::waving_flag(30, 30, 8);
    let params = conformance_tests::params_with(codec, "bases", codec_core::ParamValue::Int(32)).unwrap();
    let bytes = codec_core::encode_animation(codec, &params, &anim).unwrap();
    let parts = conformance_tests::split(&bytes).unwrap();
    let mut config = parts.header.config.clone();
    assert_eq!(u32::from_le_bytes(config[1..5].try_into().unwrap()), 32);
    config[2] = 2; // 32 → 544
    let forged =
        conformance_tests::rebuild(&parts.header, &config, parts.header.info.codec_version, None, None, &parts.packets)
            .unwrap();
    let mut result = None;
    let peak = measure_peak(|| result = Some(decode_animation(&forged, &registry, Limits::default())));
    let e = result.unwrap().expect_err("544 bases accepted for a stream coded with 32");
    assert!(e.to_string().contains("descriptors"), "{e}");
    // The two 900 × 900 f64 matrices of the dense eigensolver alone are 13 MB.
    assert!(peak < 6 << 20, "held {peak} bytes at peak: the basis was computed");
    // The stream as coded decodes.
    assert!(decode_animation(&bytes, &registry, Limits::default()).is_ok());
}

/// `craft_hosvd.py` of `../shared/probe-round4/hosvd-work`: a hosvd stream of one toolkit
/// packet (no triangles, `u2 = 0`, steps 1, `codes` of `zero_bytes` zeros) whose decode
/// declares `K · V_RANK · 3F` multiply-adds.
fn hosvd_bomb(k: usize, frames: usize, v_rank: u64, f_rank: u64, zero_bytes: usize) -> Vec<u8> {
    let mut w = codec_core::bytes::ByteWriter::new();
    let mut side = vec![0u8; 36];
    for _ in 0..2 * v_rank + f_rank {
        side.extend_from_slice(&1.0f32.to_le_bytes());
    }
    let side = codec_core::entropy::compress(&side, 19);
    w.u8(2);
    w.varint(v_rank);
    w.varint(f_rank);
    w.u8(2);
    w.u8(1);
    w.varint(side.len() as u64);
    w.bytes(&side);
    w.varint(zero_bytes as u64);
    w.bytes(&vec![0u8; zero_bytes]);
    let topology = Topology::new(k, Vec::new()).unwrap();
    let config = (frames as u32).to_le_bytes();
    let mut c = ContainerWriter::new(Vec::new(), codec_core::FourCc::new(b"HOSV"), 5, &topology, frames, 30.0, &config)
        .unwrap();
    c.write_packet(&Packet { first_frame: 0, frame_count: frames as u32, keyframe: true, data: w.into_vec() }).unwrap();
    c.finish().unwrap()
}

/// The `hosvd-work` probe's 171-byte streams (40 s and 1 GB each without the work budget).
/// The larger declares 2.7·10^11 operations, over the default budget: refused from its sizes.
/// The smaller (10^11) is within it but is refused by a budget of 10^10 the same way; under
/// the default budget its 8 bytes of codes run out long before its 8 million values.
#[test]
fn the_probe_hosvd_streams_are_refused_by_the_work_budget() {
    let bomb2 = hosvd_bomb(6000, 6000, 2500, 1, 8);
    assert!(bomb2.len() < 256, "{} bytes", bomb2.len());
    let e = refused("hosvd declaring 2.7e11 operations", &bomb2);
    assert!(matches!(e, Error::WorkLimit { .. }), "{e}");
    let bomb = hosvd_bomb(4000, 4000, 2000, 1, 8);
    let e = decode_animation(&bomb, &registry(), Limits { max_work: 10_000_000_000, ..Limits::default() }).unwrap_err();
    assert!(matches!(e, Error::WorkLimit { .. }), "{e}");
    let e = refused("hosvd declaring 1e11 operations, 8 bytes of codes", &bomb);
    assert!(e.to_string().contains("ends before its symbols do"), "{e}");
}
