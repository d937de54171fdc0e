use super::*;
use animcodec_synth as synth;
use codec_core::{decode_animation, decode_frame, encode_animation_fed, CodecRegistry};

fn params(p: SacParams) -> ParamSet {
    p.to_param_set().unwrap()
}

/// Encodes frame by frame straight through the encoder, returning the packets.
fn packets(anim: &Animation, p: SacParams) -> Vec<EncodedPacket> {
    let setup = EncoderSetup {
        topology: anim.topology(),
        frame_count: anim.frame_count(),
        frame_rate: 30.0,
        want_reconstruction: true,
    };
    let mut enc = Sac.new_encoder(&params(p), &setup).unwrap();
    let mut out = enc.push_frames(anim.positions()).unwrap();
    out.extend(enc.finish().unwrap());
    out
}

fn kinds(packets: &[EncodedPacket]) -> Vec<u8> {
    packets.iter().map(|p| p.packet.data[0]).collect()
}

/// RMS coordinate error relative to the bounding-box diagonal.
fn rel_rms(a: &Animation, b: &[f32]) -> f64 {
    let mse = a.positions().iter().zip(b).map(|(&x, &y)| (x as f64 - y as f64).powi(2)).sum::<f64>()
        / a.positions().len() as f64;
    mse.sqrt() / a.bounding_box_diagonal()
}

fn kg(a: &Animation, b: &[f32]) -> f64 {
    let n = a.vertex_count();
    let (mut num, mut den) = (0.0, 0.0);
    for (t, f) in a.frames().enumerate() {
        let mut c = [0.0f64; 3];
        for p in f.chunks_exact(3) {
            for k in 0..3 {
                c[k] += p[k] as f64 / n as f64;
            }
        }
        for (i, &x) in f.iter().enumerate() {
            num += (x as f64 - b[t * n * 3 + i] as f64).powi(2);
            den += (x as f64 - c[i % 3]).powi(2);
        }
    }
    100.0 * (num / den).sqrt()
}

#[test]
fn rigid_tumbling_body_is_near_lossless_even_with_one_basis() {
    // Paper §4.3/§4.4 (Vase): a rigid motion has constant gradient fields, which the first
    // (constant) harmonic carries exactly.
    let anim = synth::tumbling_body(24);
    for bases in [1u32, 4] {
        let pk = packets(&anim, SacParams { bases, ..Default::default() });
        let k = kinds(&pk);
        assert_eq!(k[0], KIND_I);
        assert!(k[1..].iter().all(|&k| k == KIND_P), "bases {bases}: some frames needed a refresh: {k:?}");
        let rec: Vec<f32> = pk.iter().flat_map(|p| p.reconstruction.clone().unwrap()).collect();
        let e = rel_rms(&anim, &rec);
        eprintln!("tumbling body, bases {bases}: relative RMS {e:.3e}, KG {:.3e}", kg(&anim, &rec));
        // Frame 0 is quantized at 20 bits over its range (≈ 1e-6 of the diagonal); the rigid
        // P-frames must not add more than a few times that.
        assert!(e < 5e-6, "bases {bases}: relative RMS error {e}");
        assert!(kg(&anim, &rec) < 1e-3, "bases {bases}: KG {}", kg(&anim, &rec));
    }
}

#[test]
fn round_trip_matches_encoder_and_does_not_depend_on_chunking() {
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let cases = [
        (synth::waving_flag(12, 9, 12), SacParams { bases: 16, ..Default::default() }),
        (synth::bending_cylinder(8, 10, 10), SacParams { bases: 30, polar: false, ..Default::default() }),
        (synth::bending_cylinder(8, 10, 10), SacParams { bases: 2, keyframe_interval: 4, ..Default::default() }),
    ];
    for (anim, p) in cases {
        let ps = params(p);
        let enc = encode_animation_fed(&Sac, &ps, &anim, true, 3).unwrap();
        let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "{p:?}");
        let once = encode_animation_fed(&Sac, &ps, &anim, false, 1000).unwrap();
        assert_eq!(once.bytes, enc.bytes, "bytes depend on how frames are fed ({p:?})");
        let bound = Sac.error_bound(&ps, &anim).unwrap().relative_rms_error.unwrap();
        let e = rel_rms(&anim, dec.positions());
        assert!(e <= bound, "{p:?}: relative RMS {e} > bound {bound}");
    }
}

#[test]
fn more_bases_reduce_error_on_smooth_deformation() {
    let anim = synth::waving_flag(14, 10, 10);
    let mut errors = Vec::new();
    for bases in [2u32, 8, 40] {
        let pk = packets(&anim, SacParams { bases, max_error: 1.0, ..Default::default() });
        assert!(kinds(&pk)[1..].iter().all(|&k| k == KIND_P));
        let rec: Vec<f32> = pk.iter().flat_map(|p| p.reconstruction.clone().unwrap()).collect();
        errors.push(kg(&anim, &rec));
    }
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "KG by bases 2/8/40: {errors:?}");
}

/// The error guard: in stream version 3 a P-frame that misses `max_error` becomes a refresh
/// frame up to a cap (one P-frame in 8), beyond which it is repaired with a residual (still a
/// P-frame, within the bound); version 2 only had refresh frames. Either way the bound holds
/// and the encoder says so in its notes.
#[test]
fn error_guard_repairs_or_refreshes_and_says_so() {
    let anim = synth::waving_flag(12, 9, 10);
    let p = SacParams { bases: 1, max_error: 1e-4, ..Default::default() };
    let bound = Sac.error_bound(&params(p), &anim).unwrap().relative_rms_error.unwrap();
    let setup = EncoderSetup {
        topology: anim.topology(),
        frame_count: anim.frame_count(),
        frame_rate: 30.0,
        want_reconstruction: true,
    };
    let mut enc = Sac.new_encoder(&params(p), &setup).unwrap();
    let pk = enc.push_frames(anim.positions()).unwrap();
    // Refresh frames up to the cap (one P-frame in 8: frames 1 and 9), repairs otherwise.
    let k = kinds(&pk);
    assert_eq!(k[1..], [KIND_REFRESH, KIND_P, KIND_P, KIND_P, KIND_P, KIND_P, KIND_P, KIND_P, KIND_REFRESH]);
    let notes = enc.notes();
    assert!(notes.len() == 2, "{notes:?}");
    assert!(notes[0].contains("replaced 2 of 9 P-frames with refresh frames"), "{notes:?}");
    assert!(notes[1].contains("repaired 7 of 9 P-frames"), "{notes:?}");
    let rec: Vec<f32> = pk.iter().flat_map(|p| p.reconstruction.clone().unwrap()).collect();
    assert!(rel_rms(&anim, &rec) <= bound, "{} > {bound}", rel_rms(&anim, &rec));
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let enc = encode_animation_fed(&Sac, &params(p), &anim, true, 4).unwrap();
    let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
    assert_eq!(Some(&dec), enc.reconstruction.as_ref());
    // Version 2's guard: refresh frames only, reported as such.
    let settings = Settings {
        bits: p.bits,
        bases: p.bases,
        polar: p.polar,
        iframe_bits: p.iframe_bits,
        version: 2,
        basis_per_keyframe: true,
        refactor: 1,
    };
    let mut v2 = SacEncoder::new(p, Shared::new(anim.topology(), &UNLIMITED, settings).unwrap(), true);
    let pk = v2.push_frames(anim.positions()).unwrap();
    assert!(kinds(&pk)[1..].iter().all(|&k| k == KIND_REFRESH), "{:?}", kinds(&pk));
    let notes = v2.notes();
    assert!(notes.len() == 1 && notes[0].contains("replaced 9 of 9 P-frames with refresh frames"), "{notes:?}");
    let rec: Vec<f32> = pk.iter().flat_map(|p| p.reconstruction.clone().unwrap()).collect();
    assert!(rel_rms(&anim, &rec) <= bound);
}

/// With `basis = stream` every keyframe names the first frame's position
/// block and reuses its basis (the encoder computes it once); a decoder starting at any
/// keyframe derives the identical basis from that block alone. `basis = keyframe` (the paper)
/// names none and recomputes.
#[test]
fn keyframes_reuse_the_first_frames_basis_and_random_access_still_works() {
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let anim = synth::bending_cylinder(6, 8, 11);
    let stream = SacParams { bases: 12, keyframe_interval: 4, ..Default::default() };
    let pk = packets(&anim, stream);
    for (t, p) in pk.iter().enumerate() {
        if t % 4 == 0 {
            assert_eq!(p.packet.data[0], KIND_I);
            // kind, has_bases, rest source: 1 (named) after the first keyframe.
            assert_eq!(p.packet.data[2], (t > 0) as u8, "frame {t}");
        }
    }
    let per_key = SacParams { basis: BasisSource::Keyframe, ..stream };
    let pk_key = packets(&anim, per_key);
    assert!(pk_key.iter().step_by(4).all(|p| p.packet.data[2] == 0));
    // The named rest block costs about one keyframe's positions.
    assert!(pk[4].packet.data.len() > pk_key[4].packet.data.len());
    for ps in [stream, per_key] {
        let enc = encode_animation_fed(&Sac, &params(ps), &anim, true, 3).unwrap();
        let full = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
        assert_eq!(Some(&full), enc.reconstruction.as_ref());
        for t in [0usize, 3, 4, 6, 8, 10] {
            let f = decode_frame(&mut std::io::Cursor::new(&enc.bytes), &registry, Limits::default(), t).unwrap();
            assert_eq!(f.as_slice(), full.frame(t), "frame {t}");
        }
    }
}

#[test]
fn random_access_from_keyframes() {
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let anim = synth::bending_cylinder(6, 8, 11);
    let ps = params(SacParams { bases: 12, keyframe_interval: 5, ..Default::default() });
    let enc = encode_animation_fed(&Sac, &ps, &anim, true, 4).unwrap();
    let full = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
    for t in [0usize, 4, 5, 7, 10] {
        let f = decode_frame(&mut std::io::Cursor::new(&enc.bytes), &registry, Limits::default(), t).unwrap();
        assert_eq!(f.as_slice(), full.frame(t), "frame {t}");
    }
}

#[test]
fn awkward_meshes_give_finite_output_within_the_bound() {
    // Two separate triangles strips, a vertex in no triangle, a repeated-index triangle and a
    // zero-area triangle.
    let tris: Vec<[u32; 3]> =
        vec![[0, 1, 2], [1, 3, 2], [4, 5, 6], [5, 7, 6], [0, 0, 1], [2, 3, 3], [8, 9, 10], [1, 3, 1]];
    let n = 12;
    let mut pos = Vec::new();
    for t in 0..8 {
        let s = t as f32 * 0.1;
        let base: [[f32; 3]; 12] = [
            [0., 0., 0.],
            [1., 0., s],
            [0., 1., 0.],
            [1., 1., s * 0.5],
            [3., 0., 0.],
            [4., 0., 0.],
            [3., 1., s],
            [4., 1. + s, 0.],
            [6., 0., 0.],
            [7., 0., 0.],
            [8., 0., 0.], // collinear: zero area
            [5., 5., s],  // in no triangle
        ];
        pos.extend(base.iter().flatten());
    }
    let anim = Animation::new(Topology::new(n, tris).unwrap(), pos, 30.0).unwrap();
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let ps = params(SacParams { bases: 4, ..Default::default() });
    let enc = encode_animation_fed(&Sac, &ps, &anim, true, 2).unwrap();
    let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
    assert_eq!(Some(&dec), enc.reconstruction.as_ref());
    assert!(dec.positions().iter().all(|x| x.is_finite()));
    let bound = Sac.error_bound(&ps, &anim).unwrap().relative_rms_error.unwrap();
    assert!(rel_rms(&anim, dec.positions()) <= bound);
}

#[test]
fn corrupt_streams_fail_cleanly() {
    let anim = synth::waving_flag(6, 5, 5);
    // Without and with the residual layer (its packets carry a second, coded residual).
    for residual in [0.0, 0.001] {
        let ps = params(SacParams { bases: 8, residual, ..Default::default() });
        let setup = EncoderSetup {
            topology: anim.topology(),
            frame_count: anim.frame_count(),
            frame_rate: 30.0,
            want_reconstruction: false,
        };
        let mut enc = Sac.new_encoder(&ps, &setup).unwrap();
        let pk = enc.push_frames(anim.positions()).unwrap();
        let info = StreamInfo {
            fourcc: Sac.fourcc(),
            codec_version: STREAM_VERSION,
            topology: anim.topology().clone(),
            frame_count: anim.frame_count(),
            frame_rate: 30.0,
        };
        let config = enc.config();
        for cut in 0..config.len() {
            assert!(Sac.new_decoder(&info, &config[..cut], &Limits::default()).is_err());
        }
        let mut state = 7u64;
        for trial in 0..300 {
            let mut dec = Sac.new_decoder(&info, &config, &Limits::default()).unwrap();
            for (i, p) in pk.iter().enumerate() {
                let mut p = p.packet.clone();
                if i == trial % pk.len() {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    if trial % 3 == 0 {
                        p.data.truncate((state >> 33) as usize % p.data.len());
                    } else {
                        let at = (state >> 33) as usize % p.data.len();
                        p.data[at] ^= (state >> 20) as u8 | 1;
                    }
                }
                match dec.decode_packet(&p) {
                    Ok(f) => assert!(f.len() == anim.vertex_count() * 3 && f.iter().all(|x| x.is_finite())),
                    Err(_) => break,
                }
            }
        }
        // A P-frame first is an error, not a panic.
        let mut dec = Sac.new_decoder(&info, &config, &Limits::default()).unwrap();
        assert!(dec.decode_packet(&pk[1].packet).is_err());
    }
}

#[test]
fn parameters_are_validated_with_ranges() {
    let e = SacParams { bases: 0, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("sac") && e.contains("bases") && e.contains("1..=1000"), "{e}");
    let e = SacParams { bits: 31, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("bits") && e.contains("4..=30"), "{e}");
    assert_eq!(SacParams::from_param_set(&Sac.default_params()).unwrap(), SacParams::default());
    for step in Sac.rate_ladder(&Sac.default_params()).steps {
        let mut p = Sac.default_params();
        p.set(&Sac.param_specs(), "rate", step).unwrap();
        Sac.validate(&p).unwrap();
    }
    // The residual step is 0 (off) or at least 1e-6.
    let e = SacParams { residual: 1e-7, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("residual") && e.contains("1e-6"), "{e}");
    // A preset sets bases and residual.
    let mut p = Sac.default_params();
    p.set(&Sac.param_specs(), "rate", ParamValue::Int(RATE_PRESETS.len() as i64)).unwrap();
    let typed = SacParams::from_param_set(&p).unwrap();
    assert_eq!((typed.bases, typed.residual), RATE_PRESETS[RATE_PRESETS.len() - 1]);
}

#[test]
fn bytes_do_not_depend_on_the_thread_count() {
    let anim = synth::bending_cylinder(10, 12, 6);
    let ps = params(SacParams { bases: 40, ..Default::default() });
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| encode_animation_fed(&Sac, &ps, &anim, false, 2).unwrap().bytes)
    };
    assert_eq!(run(1), run(3));
}

/// The decoder derives the basis from the stream alone, so it must be bit-for-bit the same
/// whatever the thread count: the harmonics of a disconnected mesh (one
/// Krylov component, several dense ones) and a whole decode, in pools of 1 and 3 threads.
#[test]
fn basis_and_decode_do_not_depend_on_the_thread_count() {
    let anim = two_flags(5);
    let tris: Vec<[usize; 3]> =
        anim.triangles().iter().map(|t| [t[0] as usize, t[1] as usize, t[2] as usize]).collect();
    let pos = to_v3(anim.frame(0));
    let (one, _) = crate::geometry::tests::blob(4);
    let blob_tris = crate::geometry::tests::blob(4).1;
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let bytes = encode_animation_fed(&Sac, &params(SacParams { bases: 12, ..Default::default() }), &anim, false, 5)
        .unwrap()
        .bytes;
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            (
                harmonics::harmonics_by_component(&pos, &tris, 12).unwrap().basis,
                harmonics::harmonics(&one, &blob_tris, 30).unwrap().basis,
                decode_animation(&bytes, &registry, Limits::default()).unwrap(),
            )
        })
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.0, b.0);
    assert_eq!(a.1, b.1);
    assert_eq!(a.2, b.2);
}

#[test]
fn rate_ladder_streams_grow_on_synthetic_data() {
    for name in ["flag", "cylinder"] {
        let anim = synth::by_name(name, synth::SynthSize::Small).unwrap();
        let frames = anim.frame_count().min(12);
        let n3 = anim.vertex_count() * 3;
        let anim = Animation::new(anim.topology().clone(), anim.positions()[..frames * n3].to_vec(), 30.0).unwrap();
        let mut last = 0usize;
        for step in Sac.rate_ladder(&Sac.default_params()).steps {
            let mut p = Sac.default_params();
            p.set(&Sac.param_specs(), "rate", step.clone()).unwrap();
            let size = encode_animation_fed(&Sac, &p, &anim, false, frames).unwrap().bytes.len();
            assert!(size >= last, "{name}: rate {step} gives {size} bytes, fewer than the previous step's {last}");
            last = size;
        }
    }
}

/// Two flags side by side (two connected components), the second one moving differently.
fn two_flags(frames: usize) -> Animation {
    let (cols, rows) = (12, 10);
    let a = synth::waving_flag(cols, rows, frames);
    let n1 = a.vertex_count();
    let mut tris: Vec<[u32; 3]> = a.topology().triangles().to_vec();
    tris.extend(a.topology().triangles().iter().map(|t| t.map(|i| i + n1 as u32)));
    let mut pos = Vec::new();
    for t in 0..frames {
        pos.extend_from_slice(a.frame(t));
        // The second flag plays the first one's motion backwards, mirrored and shifted.
        pos.extend(a.frame(frames - 1 - t).chunks_exact(3).flat_map(|p| [p[0] + 3.0, -p[1], p[2]]));
    }
    Animation::new(Topology::new(2 * n1, tris).unwrap(), pos, 30.0).unwrap()
}

/// An encoder writing stream version `version` (the current code's old-version path).
fn packets_version(anim: &Animation, p: SacParams, version: u16) -> (Vec<u8>, Vec<EncodedPacket>) {
    let settings = Settings {
        bits: p.bits,
        bases: p.bases,
        polar: p.polar,
        iframe_bits: p.iframe_bits,
        version,
        basis_per_keyframe: version < 3 || p.basis == BasisSource::Keyframe,
        refactor: p.refactor,
    };
    let shared = Shared::new(anim.topology(), &UNLIMITED, settings).unwrap();
    let mut enc = SacEncoder::new(p, shared, true);
    let config = enc.config();
    (config, enc.push_frames(anim.positions()).unwrap())
}

/// Stream version 2 computes the harmonics per connected component. A version-1 stream of a
/// disconnected mesh must still decode to exactly what its encoder reconstructed, which needs
/// version 1's basis: decoding the same packets as version 2 gives different frames.
#[test]
fn version_1_streams_still_decode_with_the_version_1_basis() {
    let anim = two_flags(6);
    let p = SacParams { bases: 8, ..Default::default() };
    let (config, pk) = packets_version(&anim, p, 1);
    assert!(kinds(&pk)[1..].iter().all(|&k| k == KIND_P), "{:?}", kinds(&pk));
    let decode = |version: u16| -> Result<Vec<Vec<f32>>> {
        let info = StreamInfo {
            fourcc: Sac.fourcc(),
            codec_version: version,
            topology: anim.topology().clone(),
            frame_count: anim.frame_count(),
            frame_rate: 30.0,
        };
        let mut dec = Sac.new_decoder(&info, &config, &Limits::default()).unwrap();
        pk.iter().map(|p| dec.decode_packet(&p.packet)).collect()
    };
    let v1 = decode(1).unwrap();
    for (t, p) in pk.iter().enumerate() {
        assert_eq!(Some(&v1[t]), p.reconstruction.as_ref(), "frame {t}");
    }
    // Read as version 2 the packets are malformed (no residual field) or decode differently.
    assert!(decode(2).map_or(true, |v2| v2 != v1), "the version gate must matter");
    // Unknown versions are rejected.
    let info = StreamInfo {
        fourcc: Sac.fourcc(),
        codec_version: STREAM_VERSION + 1,
        topology: anim.topology().clone(),
        frame_count: anim.frame_count(),
        frame_rate: 30.0,
    };
    assert!(Sac.new_decoder(&info, &config, &Limits::default()).is_err());
    // The current encoder writes version 3 and round-trips the same animation.
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let enc = encode_animation_fed(&Sac, &params(p), &anim, true, 3).unwrap();
    let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
    assert_eq!(Some(&dec), enc.reconstruction.as_ref());
}

/// The residual layer removes the error floor of the paper's method. On a bending
/// cylinder, finer residual steps lower KG step by step below the paper's method at the same
/// 4 bases, the decoder reproduces the encoder's closed loop exactly, and every frame but
/// the first is still a P-frame.
#[test]
fn residual_layer_lowers_the_error_below_the_paper_floor() {
    let anim = synth::bending_cylinder(16, 20, 16);
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let run = |p: SacParams| {
        let enc = encode_animation_fed(&Sac, &params(p), &anim, true, 5).unwrap();
        let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "decoder differs from the encoder");
        (kg(&anim, dec.positions()), enc.bytes.len())
    };
    let (paper_kg, paper_bytes) = run(SacParams { bases: 4, ..Default::default() });
    let mut last = (paper_kg, paper_bytes);
    for residual in [0.003, 0.001, 0.0003, 0.0001] {
        let (k, b) = run(SacParams { bases: 4, residual, ..Default::default() });
        assert!(k < last.0, "residual {residual}: KG {k} not below {}", last.0);
        assert!(b > last.1, "residual {residual}: {b} bytes not above {}", last.1);
        last = (k, b);
    }
    assert!(last.0 < 0.1 * paper_kg, "finest residual KG {} vs the paper's {paper_kg}", last.0);
    let pk = packets(&anim, SacParams { bases: 4, residual: 0.0003, ..Default::default() });
    assert!(kinds(&pk)[1..].iter().all(|&k| k == KIND_P), "{:?}", kinds(&pk));
}

/// A closed mesh under large elastic deformation (stretch to 1.8× with
/// volume-preserving squash, plus a twist of up to ±1.2 rad along the axis). Walking the rate
/// ladder, the stream grows and KG falls at every step, down to the residual presets.
#[test]
fn ladder_is_monotone_under_large_elastic_deformation() {
    let (rest, tris) = crate::geometry::tests::blob(3);
    let frames = 12;
    let mut pos = Vec::new();
    for t in 0..frames {
        let phase = (t as f64 / (frames - 1) as f64 * std::f64::consts::PI * 2.0).sin();
        let s = 1.0 + 0.8 * phase.abs();
        for p in &rest {
            let (x, y, z) = (p[0] * s, p[1] / s.sqrt(), p[2] / s.sqrt());
            let a = 1.2 * phase * p[0];
            let (c, si) = (a.cos(), a.sin());
            pos.extend([x as f32, (c * y - si * z) as f32, (si * y + c * z) as f32]);
        }
    }
    let tris: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|i| i as u32)).collect();
    let anim = Animation::new(Topology::new(rest.len(), tris).unwrap(), pos, 30.0).unwrap();
    let registry = CodecRegistry::new(vec![Box::new(Sac)]).unwrap();
    let mut last: Option<(f64, usize)> = None;
    for step in Sac.rate_ladder(&Sac.default_params()).steps {
        let mut p = Sac.default_params();
        p.set(&Sac.param_specs(), "rate", step.clone()).unwrap();
        let enc = encode_animation_fed(&Sac, &p, &anim, false, frames).unwrap();
        let dec = decode_animation(&enc.bytes, &registry, Limits::default()).unwrap();
        let (k, b) = (kg(&anim, dec.positions()), enc.bytes.len());
        if let Some((lk, lb)) = last {
            assert!(b >= lb, "rate {step}: {b} bytes, fewer than the previous step's {lb}");
            assert!(k <= lk, "rate {step}: KG {k} above the previous step's {lk}");
        }
        last = Some((k, b));
    }
    let (k, _) = last.unwrap();
    assert!(k < 0.2, "the last ladder step reaches only KG {k}");
}

/// An unknown stream version is named as such, whatever its config looks like (the config
/// layout depends on the version, so it is not parsed first).
#[test]
fn unknown_stream_version_is_refused_before_the_config_is_read() {
    let anim = two_flags(3);
    for (version, config) in [(0u16, vec![12u8, 8, 0, 0, 0]), (4, vec![]), (99, vec![1, 2, 3, 4, 5, 6, 7, 8, 9])] {
        let info = StreamInfo {
            fourcc: Sac.fourcc(),
            codec_version: version,
            topology: anim.topology().clone(),
            frame_count: anim.frame_count(),
            frame_rate: 30.0,
        };
        let e = Sac.new_decoder(&info, &config, &Limits::default()).err().expect("unknown version accepted");
        let msg = e.to_string();
        assert!(matches!(e, Error::Unsupported { .. }), "{msg}");
        assert!(msg.contains("sac") && msg.contains(&format!("stream version {version}")), "{msg}");
    }
}

/// A crafted topology whose vertex adjacency is an expander: every vertex in triangles with
/// pseudo-random partners. Few vertices, but any elimination order fills its Cholesky factor
/// in almost densely (a real surface mesh fills in like `n log n`).
pub(crate) fn expander_topology(n: usize) -> Vec<[usize; 3]> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as usize % n
    };
    let mut tris = Vec::with_capacity(2 * n);
    for i in 0..2 * n {
        let a = i % n;
        let (mut b, mut c) = (next(), next());
        while b == a {
            b = next();
        }
        while c == a || c == b {
            c = next();
        }
        tris.push([a, b, c]);
    }
    tris
}

fn grid_topology(cols: usize, rows: usize) -> Vec<[usize; 3]> {
    let mut tris = Vec::new();
    for r in 0..rows - 1 {
        for c in 0..cols - 1 {
            let v = r * cols + c;
            tris.push([v, v + 1, v + cols]);
            tris.push([v + 1, v + cols + 1, v + cols]);
        }
    }
    tris
}

/// The decoder checks the Poisson system's sparse Cholesky fill
/// against its `Limits` right after the symbolic factorization, before any numeric factor or
/// scratch is allocated. A crafted expander-like topology of 3000 vertices (≈ 24 MB of factor and scratch)
/// is refused with an error naming the Poisson factor under an 8 MiB limit, in every stream
/// version, while a surface-like grid of the same size is accepted under the same limit.
#[test]
fn crafted_high_fill_topology_is_refused_by_the_decoder_limits() {
    let limits = Limits { max_alloc_bytes: 8 << 20, ..Limits::default() };
    let n = 3000;
    let topology = |n: usize, tris: &[[usize; 3]]| {
        Topology::new(n, tris.iter().map(|t| [t[0] as u32, t[1] as u32, t[2] as u32]).collect()).unwrap()
    };
    let info = |topology: Topology, version: u16| StreamInfo {
        fourcc: Sac.fourcc(),
        codec_version: version,
        topology,
        frame_count: 2,
        frame_rate: 30.0,
    };
    // Versions 1–2: bits, bases, polar, iframe_bits; version 3 adds basis and refactor.
    let config = |version: u16| {
        let mut c = vec![18u8, 16, 0, 0, 0, 1, 20];
        if version >= 3 {
            c.extend([0, 4]);
        }
        c
    };
    let expander = topology(n, &expander_topology(n));
    let grid = topology(60 * 50, &grid_topology(60, 50));
    for version in 1..=STREAM_VERSION {
        assert!(
            Sac.new_decoder(&info(grid.clone(), version), &config(version), &limits).is_ok(),
            "version {version}: a 3000-vertex grid must fit in 8 MiB"
        );
        let e = Sac
            .new_decoder(&info(expander.clone(), version), &config(version), &limits)
            .err()
            .expect("a high-fill topology was accepted");
        let msg = e.to_string();
        assert!(matches!(e, Error::AllocLimit { .. }), "version {version}: {msg}");
        assert!(msg.contains("sac") && msg.contains("poisson factor"), "version {version}: {msg}");
        // With the default limits (1 GiB) the same topology (≈ 24 MB) is accepted.
        assert!(Sac.new_decoder(&info(expander.clone(), version), &config(version), &Limits::default()).is_ok());
    }
}

/// The eigensolver checks its allocations against the limits before making them: the
/// Laplacian factor's fill (after its symbolic factorization), the Krylov workspace
/// (`max_dim` vectors plus the returned block and the Rayleigh–Ritz step) and the dense
/// fallback's n × n matrices. Each is refused with an error naming it.
#[test]
fn eigensolver_allocations_are_checked_against_the_limits() {
    let sphere = |n: usize| -> Vec<V3> {
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let a = i as f64 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                [r * a.cos(), r * a.sin(), z]
            })
            .collect()
    };
    let flat = |cols: usize, rows: usize| -> Vec<V3> {
        (0..cols * rows).map(|v| [(v % cols) as f64, (v / cols) as f64, 0.01 * ((v * 7) % 5) as f64]).collect()
    };
    let expect = |r: Result<harmonics::Harmonics>, what: &str| {
        let e = r.err().unwrap_or_else(|| panic!("{what}: accepted"));
        let msg = e.to_string();
        assert!(matches!(e, Error::AllocLimit { .. }) && msg.contains(what), "{msg}");
    };
    let tight = |bytes: usize| Limits { max_alloc_bytes: bytes, ..Limits::default() };
    // The expander's Laplacian factor (≈ 22 MB) against 8 MiB.
    let n = 3000;
    expect(harmonics::harmonics_within(&sphere(n), &expander_topology(n), 16, &tight(8 << 20)), "laplacian factor");
    // A 3000-vertex grid: its factor fits in 2 MiB, 100 bases' Krylov workspace (≈ 28 MB) does not.
    let (pos, tris) = (flat(60, 50), grid_topology(60, 50));
    expect(harmonics::harmonics_within(&pos, &tris, 100, &tight(2 << 20)), "eigensolver workspace");
    assert!(harmonics::harmonics_within(&pos, &tris, 100, &tight(64 << 20)).is_ok());
    // A 225-vertex grid at 120 bases takes the dense path: two 225 × 225 matrices and the
    // decomposition's scratch (≈ 2 MB).
    let (pos, tris) = (flat(15, 15), grid_topology(15, 15));
    expect(harmonics::harmonics_within(&pos, &tris, 120, &tight(256 << 10)), "dense eigensolver");
    expect(harmonics::harmonics_by_component_within(&pos, &tris, 120, &tight(256 << 10)), "dense eigensolver");
    assert!(harmonics::harmonics_within(&pos, &tris, 120, &tight(8 << 20)).is_ok());
}

/// Specs, parsing and printing of every parameter agree (one declaration each), so a
/// parameter cannot be documented with one range and parsed with another.
#[test]
fn parameter_declaration_agrees_with_specs_parsing_and_printing() {
    codec_core::testing::check_declared_params::<SacParams>();
    assert_eq!(Sac.param_specs(), SacParams::specs());
}
