//! Streams that ask for too much memory or work are refused before it is spent (issue 27,
//! item 2): `Limits::max_alloc_bytes` bounds the total a decode holds, `Limits::max_work` the
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
    let bytes = sac_stream(&codec_core::synth::flag_topology(160, 160), 1000);
    let e = refused("sac, 1000 bases on 25 600 vertices", &bytes);
    assert!(matches!(e, Error::WorkLimit { .. }) && e.to_string().contains("harmonics"), "{e}");
    // The same mesh with the default 16 bases is not refused by the limits (it fails only on
    // its placeholder packet).
    let ok = sac_stream(&codec_core::synth::flag_topology(160, 160), 16);
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
    let anim = codec_core::synth::waving_flag(40, 30, 20);
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
    let anim = codec_core::synth::waving_flag(12, 10, 6);
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

/// A stream of a few hundred bytes whose topology claims 2²⁴ vertices (the 700-byte
/// stream): every codec's tiny stream with its topology swapped. Coding order graphs and
/// decoded frames for that many vertices exceed the default total budget, so each is refused
/// before they are built, within seconds and under 1 GB.
#[test]
fn a_tiny_stream_claiming_16m_vertices_is_refused_early() {
    let registry = registry();
    // Few frames: the decoded frames (4 × 2^24 × 12 bytes) fit the default budget, so what
    // is refused is what each codec would build on top of them.
    let anim = codec_core::synth::waving_flag(6, 5, 4);
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
