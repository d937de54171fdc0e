//! Real data: `samba` (9971 vertices, 175 frames) through `quant-delta` at bits = 12, and
//! `horse-gallop` through `hosvd` on its real mesh.
//!
//! Without `../shared/data` (beside the repository) each test skips through
//! [`codec_core::testing::skip`]: visibly, and as a failure under `ANIMCODEC_REQUIRE_ALL=1` (CI).

use std::path::PathBuf;
use std::time::Instant;

use animcodec::formats::{read_animation, ReadOptions};
use codec_core::testing::skip;
use codec_core::{decode_animation, encode_animation_fed, Limits, ParamValue};
use conformance_tests::*;

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

#[test]
fn samba_round_trips_through_quant_delta_within_bound() {
    let path = data_dir().join("samba/samba.pc2");
    if !path.exists() {
        return skip("samba_round_trips_through_quant_delta_within_bound", &format!("{} is absent", path.display()));
    }
    let start = Instant::now();
    let anim =
        read_animation(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    assert_eq!((anim.vertex_count(), anim.frame_count()), (9971, 175), "samba's size (data/README.md)");
    assert_eq!(anim.triangles().len(), 19938);
    let read = start.elapsed();
    let registry = registry();
    let codec = registry.by_name("quant-delta").expect("quant-delta is registered");
    let params = params_with(codec, "bits", ParamValue::Int(12)).expect("bits=12 is valid");
    let enc = encode_animation_fed(codec, &params, &anim, true, 16).expect("encode");
    let encoded = start.elapsed();
    let dec = decode_animation(&enc.bytes, &registry, Limits::default()).expect("decode");
    assert_eq!(
        Some(dec.positions()),
        enc.reconstruction.as_ref().map(|r| r.positions()),
        "decoder differs from encoder"
    );
    let bound = codec.error_bound(&params, &anim).expect("bound");
    let m = measure_error(&anim, &dec).expect("same shape");
    check_bound(&bound, &m).expect("within the declared bound");
    eprintln!(
        "samba: {} bytes ({:.2} bits/coordinate), max error {:.3e} (bound {:.3e}), rel RMS {:.3e}; read {:.1?}, encode {:.1?}, decode {:.1?}",
        enc.bytes.len(),
        enc.bytes.len() as f64 * 8.0 / anim.positions().len() as f64,
        m.max_coordinate_error,
        bound.max_coordinate_error.unwrap_or(f64::NAN),
        m.relative_rms_error,
        read,
        encoded - read,
        start.elapsed() - encoded
    );
}

/// hosvd on `horse-gallop` with the mesh of the topology OBJ beside the cache: the codec's
/// default coefficient coding predicts over mesh neighbours (`codec-hosvd/src/coding.rs`), so
/// a stand-in mesh (one triangle) would not exercise it on real data.
#[test]
fn horse_gallop_round_trips_through_hosvd_on_its_real_mesh() {
    let path = data_dir().join("horse-gallop/horse-gallop.pc2");
    if !path.exists() {
        return skip(
            "horse_gallop_round_trips_through_hosvd_on_its_real_mesh",
            &format!("{} is absent", path.display()),
        );
    }
    let anim =
        read_animation(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    assert!(
        anim.triangles().len() > anim.vertex_count(),
        "the real mesh, not a stand-in: {} triangles",
        anim.triangles().len()
    );
    let registry = registry();
    let codec = registry.by_name("hosvd").expect("hosvd is registered");
    let params = params_with(codec, "ss", ParamValue::Float(0.95))
        .and_then(|p| p.with(&codec.param_specs(), "strategy", ParamValue::Choice("diagonal")))
        .expect("ss=0.95, strategy=diagonal are valid");
    let enc = encode_animation_fed(codec, &params, &anim, true, 16).expect("encode");
    let dec = decode_animation(&enc.bytes, &registry, Limits::default()).expect("decode");
    assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "decoder differs from encoder");
    let bound = codec.error_bound(&params, &anim).expect("bound");
    let m = measure_error(&anim, &dec).expect("same shape");
    check_bound(&bound, &m).expect("within the declared bound");
    // ss = 0.95 of the float model: the real stream is smaller still.
    let raw = anim.positions().len() * 4;
    assert!((enc.bytes.len() as f64) < 0.05 * raw as f64, "{} bytes of {raw} raw", enc.bytes.len());
}
