use super::*;
use animcodec_synth as synth;
use codec_core::{decode_animation, encode_animation_fed, AnimationCodec, CodecRegistry};

fn relative_rms(a: &Animation, b: &Animation) -> f64 {
    let e: f64 = a.positions().iter().zip(b.positions()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    (e / a.positions().len() as f64).sqrt() / a.bounding_box_diagonal()
}

/// Round trip in both domains: the decoder's frames are the encoder's reconstruction, within
/// the declared bound, and a finer step gives a smaller error and a larger stream.
#[test]
fn round_trip_matches_encoder_and_improves_with_step() {
    let anim = synth::waving_flag(12, 9, 30);
    let registry = CodecRegistry::new(vec![Box::new(Laplacian)]).unwrap();
    for laplacian in [true, false] {
        let mut last: Option<(usize, f64)> = None;
        for step in [1e-2, 2e-3, 2e-4] {
            let params = LaplacianParams { step, laplacian, ..Default::default() }.to_param_set().unwrap();
            let enc = encode_animation_fed(&Laplacian, &params, &anim, true, 7).unwrap();
            let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
            assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "step {step}");
            let bound = Laplacian.error_bound(&params, &anim).unwrap().relative_rms_error.unwrap();
            let err = relative_rms(&anim, &dec);
            assert!(err <= bound, "step {step}: error {err} > bound {bound}");
            if let Some((size, e)) = last {
                assert!(
                    enc.bytes.len() > size && err < e,
                    "step {step} laplacian {laplacian}: {size} {e} -> {} {err}",
                    enc.bytes.len()
                );
            }
            last = Some((enc.bytes.len(), err));
        }
    }
}

#[test]
fn typed_validation_states_the_range() {
    let e = LaplacianParams { step: 0.9, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains(NAME) && e.contains("step") && e.contains("0.5"), "{e}");
}
