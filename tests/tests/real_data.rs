//! Real data: `samba` (9971 vertices, 175 frames) through `quant-delta` at bits = 12.
//!
//! Skips with a message when `../shared/data` (beside the repository) is absent or the
//! file reader is not implemented yet.

use std::path::PathBuf;
use std::time::Instant;

use animcodec::formats::{read_animation, ReadOptions};
use codec_core::{decode_animation, encode_animation_fed, Error, Limits, ParamValue};
use conformance_tests::*;

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

#[test]
fn samba_round_trips_through_quant_delta_within_bound() {
    let path = data_dir().join("samba/samba.pc2");
    if !path.exists() {
        eprintln!("SKIPPED: {} is absent", path.display());
        return;
    }
    let start = Instant::now();
    let anim = match read_animation(&path, &ReadOptions::default()) {
        Ok(a) => a,
        Err(Error::Unsupported { detail, .. }) if detail.contains("not implemented") => {
            eprintln!("SKIPPED: animcodec::formats::read_animation: {detail}");
            return;
        }
        Err(e) => panic!("reading {}: {e}", path.display()),
    };
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
