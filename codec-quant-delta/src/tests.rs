//! Round trips, the bound, the parameter declaration.

use codec_core::{decode_animation, encode_animation_fed, Animation, AnimationCodec, CodecRegistry, Limits, Topology};

use crate::{QuantDelta, QuantDeltaParams};

fn wave(frames: usize) -> Animation {
    let (nx, ny) = (6usize, 5usize);
    let mut pos = Vec::new();
    for t in 0..frames {
        for y in 0..ny {
            for x in 0..nx {
                let z = ((x as f32 * 0.7 + t as f32 * 0.3).sin()) * 0.2;
                pos.extend_from_slice(&[x as f32 * 0.1, y as f32 * 0.1, z]);
            }
        }
    }
    Animation::new(Topology::grid(nx, ny).unwrap(), pos, 30.0).unwrap()
}

#[test]
fn round_trip_within_bound_and_matches_encoder_reconstruction() {
    let anim = wave(70);
    let registry = CodecRegistry::new(vec![Box::new(QuantDelta)]).unwrap();
    for bits in [1u8, 4, 12, 24] {
        let params = QuantDeltaParams { bits, block: 16, ..Default::default() }.to_param_set().unwrap();
        let enc = encode_animation_fed(&QuantDelta, &params, &anim, true, 7).unwrap();
        let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "bits {bits}");
        let bound = QuantDelta.error_bound(&params, &anim).unwrap().max_coordinate_error.unwrap();
        let err = anim.positions().iter().zip(dec.positions()).map(|(a, b)| (a - b).abs() as f64).fold(0.0, f64::max);
        assert!(err <= bound, "bits {bits}: error {err} > bound {bound}");
        let all_at_once = encode_animation_fed(&QuantDelta, &params, &anim, false, 1000).unwrap();
        assert_eq!(all_at_once.bytes, enc.bytes, "bytes depend on how frames are fed");
    }
}

#[test]
fn parameter_declaration_agrees_with_specs_parsing_and_printing() {
    codec_core::testing::check_declared_params::<QuantDeltaParams>();
    assert_eq!(QuantDelta.param_specs(), QuantDeltaParams::specs());
}

#[test]
fn typed_validation_states_the_range() {
    let e = QuantDeltaParams { bits: 30, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("quant-delta") && e.contains("bits") && e.contains("1..=24"), "{e}");
}

/// A budget below the packets' need shortens them to the fewest equal ones that fit (the
/// parameters of `encode --memory` and of the streamed searches); below 8 frames' need it is
/// refused, naming the need.
#[test]
fn a_small_budget_shortens_the_packets() {
    let params = QuantDelta.default_params();
    let block = |p: &codec_core::ParamSet| p.get("block").map(|v| v.to_string());
    let (v, f) = (1_000_000, 1000);
    assert_eq!(QuantDelta.fit_memory(&params, v, f, 4 << 30).unwrap(), params, "32-frame packets fit 4 GiB");
    let budget = 2 << 30;
    let fitted = QuantDelta.fit_memory(&params, v, f, budget).unwrap();
    let b: usize = block(&fitted).unwrap().parse().unwrap();
    assert!((crate::MIN_MEMORY_BLOCK..32).contains(&b), "{b}");
    assert!(crate::encode_memory(v, b) <= budget, "{b} fits");
    assert!(b * f.div_ceil(b) - f < f.div_ceil(b), "{b} frames per packet leaves a short last packet");
    let e = QuantDelta.fit_memory(&params, v, f, 1 << 30).unwrap_err().to_string();
    assert!(e.contains("quant-delta") && e.contains("8 frames"), "{e}");
}
