use super::*;
use animcodec_synth as synth;
use codec_core::{decode_animation, encode_animation_fed, CodecRegistry};

fn registry() -> CodecRegistry {
    CodecRegistry::new(vec![Box::new(Stseg)]).unwrap()
}

fn rel_rms(a: &Animation, b: &Animation) -> f64 {
    let se: f64 = a.positions().iter().zip(b.positions()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    (se / a.positions().len() as f64).sqrt() / a.bounding_box_diagonal()
}

/// §4.5 sequential processing on a sequence whose motion changes character at known frames:
/// every true boundary has a detected (Alg. 2) boundary within `w` frames, and the segments
/// tile the animation. Extra boundaries inside the oscillating phases are allowed (see README).
#[test]
fn detected_boundaries_land_within_w_of_the_truth() {
    // Motion-sensitive Alg. 2 counts (the defaults favour long segments instead; README).
    let p = StsegParams { seg_centering: Centering::Vertex, omega_seg: 0.99, ..Default::default() };
    for frames in [200usize, 400] {
        let (anim, truth) = synth::phased_motion(frames);
        let s = segment_animation(&anim, &p).unwrap();
        let mut next = 0;
        for seg in &s.segments {
            assert_eq!(seg.first_frame, next);
            assert!(seg.frame_count >= 1 && seg.frame_count <= p.gamma_max as usize);
            assert_eq!(seg.labels.len(), anim.vertex_count());
            assert!(seg.labels.iter().all(|&l| (l as usize) < seg.group_count));
            next += seg.frame_count;
        }
        assert_eq!(next, frames);
        let detected = s.detected_boundaries();
        for &b in &truth {
            let nearest = detected.iter().map(|&d| d.abs_diff(b)).min().unwrap_or(usize::MAX);
            assert!(nearest <= p.w as usize, "F={frames}: truth {b}, detected {detected:?}");
        }
        // The spatial segmentation found more than one group somewhere (the tube's parts move
        // differently in the bending phases).
        assert!(s.segments.iter().any(|g| g.group_count > 1));
        let json = s.to_json();
        assert!(json.starts_with("{\"segments\":[") && json.contains("\"detected_boundaries\":["));
    }
}

#[test]
fn packets_are_the_segments_and_round_trip_matches_reconstruction_and_bound() {
    let (anim, _) = synth::phased_motion_sized(8, 8, 150);
    let reg = registry();
    let params = StsegParams::default();
    let ps = params.to_param_set().unwrap();
    let enc = encode_animation_fed(&Stseg, &ps, &anim, true, 7).unwrap();
    let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
    assert_eq!(Some(&dec), enc.reconstruction.as_ref());
    let all_at_once = encode_animation_fed(&Stseg, &ps, &anim, false, 1000).unwrap();
    assert_eq!(all_at_once.bytes, enc.bytes, "bytes depend on how frames are fed");
    let bound = Stseg.error_bound(&ps, &anim).unwrap().relative_rms_error.unwrap();
    let err = rel_rms(&anim, &dec);
    assert!(err <= bound, "error {err} > bound {bound}");
    // One packet per segment.
    let seg = segment_animation(&anim, &params).unwrap();
    let mut sd = codec_core::StreamDecoder::new(&enc.bytes[..], &reg, Limits::default()).unwrap();
    let mut ranges = Vec::new();
    while let Some(p) = sd.next_packet() {
        let p = p.unwrap();
        ranges.push((p.first_frame, p.frame_count));
    }
    let want: Vec<(usize, usize)> = seg.segments.iter().map(|s| (s.first_frame, s.frame_count)).collect();
    assert_eq!(ranges, want);
}

#[test]
fn higher_omega_costs_more_and_errs_less() {
    let (anim, _) = synth::phased_motion_sized(8, 8, 120);
    let reg = registry();
    let mut last: Option<(usize, f64)> = None;
    for omega in [0.9, 0.99, 0.9999] {
        let ps = StsegParams { omega, ..Default::default() }.to_param_set().unwrap();
        let enc = encode_animation_fed(&Stseg, &ps, &anim, true, 13).unwrap();
        let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref());
        let err = rel_rms(&anim, &dec);
        let bound = Stseg.error_bound(&ps, &anim).unwrap().relative_rms_error.unwrap();
        assert!(err <= bound, "omega {omega}: {err} > {bound}");
        if let Some((bytes, e)) = last {
            assert!(enc.bytes.len() > bytes, "omega {omega}: {} bytes <= {bytes}", enc.bytes.len());
            assert!(err < e, "omega {omega}: error {err} >= {e}");
        }
        last = Some((enc.bytes.len(), err));
    }
}

#[test]
fn rigid_and_still_inputs_code_exactly_enough() {
    // A still mesh: every block is case I, no components, only the mean.
    let flag = synth::waving_flag(5, 4, 1);
    let still: Vec<f32> = flag.positions().iter().cycle().take(flag.positions().len() * 30).copied().collect();
    let anim = Animation::new(flag.topology().clone(), still, 30.0).unwrap();
    let reg = registry();
    let ps = StsegParams::default().to_param_set().unwrap();
    let enc = encode_animation_fed(&Stseg, &ps, &anim, true, 4).unwrap();
    let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
    assert!(rel_rms(&anim, &dec) <= 1.0 / 4095.0, "{}", rel_rms(&anim, &dec));
    // Fewer frames than the initial-cut range and a single frame still code.
    for frames in [1usize, 3, 9] {
        let a = synth::waving_flag(5, 4, frames);
        let enc = encode_animation_fed(&Stseg, &ps, &a, true, 2).unwrap();
        let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref());
        assert_eq!(dec.frame_count(), frames);
    }
}

#[test]
fn corrupt_and_truncated_streams_error_without_panicking() {
    let (anim, _) = synth::phased_motion_sized(4, 5, 60);
    let reg = registry();
    let ps = StsegParams::default().to_param_set().unwrap();
    let bytes = encode_animation_fed(&Stseg, &ps, &anim, false, 60).unwrap().bytes;
    for cut in (0..bytes.len()).step_by(7) {
        assert!(decode_animation(&bytes[..cut], &reg, Limits::default()).is_err(), "cut {cut}");
    }
    // Flip bytes everywhere: decoding may fail (checksums, structure) but never panics.
    for i in (0..bytes.len()).step_by(3) {
        let mut b = bytes.clone();
        b[i] ^= 0xA5;
        let _ = decode_animation(&b, &reg, Limits::default());
    }
    // The decoder itself, without the container's checksum, on garbage payloads.
    for coding in [Coding::Paper, Coding::Toolkit] {
        let params = StsegParams { centering: Centering::Frame, coding, ..Default::default() };
        let mut dec = StsegDecoder::for_params(&params, anim.topology());
        for payload in [
            vec![],
            vec![2u8],
            vec![2, 200, 1],
            vec![9, 1, 0],
            vec![1, 1, 0xff, 0xff, 0xff, 0xff, 0x0f],
            vec![1, 2, 1, 1, 3, 0, 0, 0],
            vec![1, 1, 2, 0xff, 0xff, 0xff, 0xff, 0xff],
        ] {
            let p = Packet { first_frame: 0, frame_count: 10, keyframe: true, data: payload };
            assert!(dec.decode_packet(&p).is_err());
        }
    }
}

#[test]
fn typed_validation_states_ranges_and_cross_constraints() {
    let e = StsegParams { omega: 1.5, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("stseg") && e.contains("omega"), "{e}");
    let e = StsegParams { gamma_max: 10, gamma_init: 20, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("gamma_max") && e.contains("at least"), "{e}");
    let e = StsegParams { w: 20, gamma_init: 20, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("gamma_init"), "{e}");
    let ps = StsegParams::default().to_param_set().unwrap();
    assert_eq!(StsegParams::from_param_set(&ps).unwrap(), StsegParams::default());
    assert_eq!(Stseg.default_params(), ps);
    let ladder = Stseg.rate_ladder(&Stseg.default_params());
    for step in &ladder.steps {
        let mut p = ps.clone();
        p.set(&Stseg.param_specs(), ladder.param, step.clone()).unwrap();
        Stseg.validate(&p).unwrap();
    }
}

#[test]
fn encode_with_segmentation_reproduces_the_codec_and_runs_fixed_blocks() {
    let (anim, _) = synth::phased_motion_sized(6, 6, 90);
    let p = StsegParams::default();
    let ps = p.to_param_set().unwrap();
    let reg = registry();
    let enc = encode_animation_fed(&Stseg, &ps, &anim, false, 90).unwrap();
    let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
    let seg = segment_animation(&anim, &p).unwrap();
    let (_, rec) = encode_with_segmentation(&anim, &p, &seg).unwrap();
    assert_eq!(rec, dec.positions());
    let fixed = fixed_block_segmentation(anim.vertex_count(), anim.frame_count(), 16);
    assert_eq!(fixed.segments.len(), 6);
    let (packets, rec) = encode_with_segmentation(&anim, &p, &fixed).unwrap();
    assert_eq!(packets.len(), 6);
    assert!(rel_rms(&anim, &Animation::new(anim.topology().clone(), rec, 30.0).unwrap()) < 0.01);
    let mut bad = fixed.clone();
    bad.segments[1].first_frame += 1;
    assert!(encode_with_segmentation(&anim, &p, &bad).is_err());
}

/// What the conformance suite will check, on every small synthetic animation: the ladder's
/// streams grow from rung to rung and both ends stay within the declared bound.
#[test]
fn ladder_is_monotone_and_within_bound_on_small_synthetic_animations() {
    let reg = registry();
    let ladder = Stseg.rate_ladder(&Stseg.default_params());
    for name in synth::NAMES {
        let anim = synth::by_name(name, synth::SynthSize::Small).unwrap();
        let mut last = 0usize;
        for (i, step) in ladder.steps.iter().enumerate() {
            let mut ps = Stseg.default_params();
            ps.set(&Stseg.param_specs(), ladder.param, step.clone()).unwrap();
            let enc = encode_animation_fed(&Stseg, &ps, &anim, true, 5).unwrap();
            assert!(enc.bytes.len() >= last, "{name} rung {i}: {} < {last}", enc.bytes.len());
            last = enc.bytes.len();
            if i == 0 || i + 1 == ladder.steps.len() {
                let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
                assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "{name}");
                let bound = Stseg.error_bound(&ps, &anim).unwrap().relative_rms_error.unwrap();
                let err = rel_rms(&anim, &dec);
                assert!(err <= bound, "{name} rung {i}: {err} > {bound}");
            }
        }
    }
}

#[test]
fn bytes_do_not_depend_on_the_thread_count() {
    let (anim, _) = synth::phased_motion_sized(6, 8, 100);
    let ps = StsegParams::default().to_param_set().unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| encode_animation_fed(&Stseg, &ps, &anim, false, 17).unwrap().bytes)
    };
    assert_eq!(run(1), run(4));
}

/// Every centering (§4.4 readings) round-trips: decoder output = encoder reconstruction, error
/// within the declared bound, a config with an unknown centering code is rejected.
#[test]
fn every_centering_round_trips_within_bound() {
    let (anim, _) = synth::phased_motion_sized(6, 6, 70);
    let reg = registry();
    for (name, coding) in Centering::NAMES.iter().flat_map(|n| [(n, Coding::Paper), (n, Coding::Toolkit)]) {
        let c = Centering::from_name(name).unwrap();
        assert_eq!(Centering::from_code(c.code()), Some(c));
        let p = StsegParams { centering: c, coding, ..Default::default() };
        let ps = p.to_param_set().unwrap();
        let enc = encode_animation_fed(&Stseg, &ps, &anim, true, 9).unwrap();
        let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "{name}");
        let bound = Stseg.error_bound(&ps, &anim).unwrap().relative_rms_error.unwrap();
        let err = rel_rms(&anim, &dec);
        assert!(err <= bound, "{name}: error {err} > bound {bound}");
    }
    let info = codec_core::StreamInfo {
        fourcc: Stseg.fourcc(),
        codec_version: Stseg.stream_version(),
        topology: anim.topology().clone(),
        frame_count: 70,
        frame_rate: 30.0,
    };
    assert!(Stseg.new_decoder(&info, &[12, 12, 4], &Limits::default()).is_err());
    // Version 3: coding and predictor codes are checked; version 2's 3-byte config still opens.
    assert!(Stseg.new_decoder(&info, &[12, 12, 3, 1, 2, 1], &Limits::default()).is_ok());
    assert!(Stseg.new_decoder(&info, &[12, 12, 3, 2, 2, 1], &Limits::default()).is_err());
    assert!(Stseg.new_decoder(&info, &[12, 12, 3, 1, 4, 1], &Limits::default()).is_err());
    let v2 = codec_core::StreamInfo { codec_version: 2, ..info.clone() };
    assert!(Stseg.new_decoder(&v2, &[12, 12, 3], &Limits::default()).is_ok());
    let v1 = codec_core::StreamInfo { codec_version: 1, ..info.clone() };
    assert!(Stseg.new_decoder(&v1, &[12, 12, 3], &Limits::default()).is_err());
    assert!(Stseg.new_decoder(&info, &[12, 12], &Limits::default()).is_err());
}

/// With the shape left in the PCA (per-frame centring, the paper's Eq. 5/8
/// reading) ω is a share of a much larger energy, so fewer components are kept than with the
/// mean shape removed; and Eq. 8's Q is exactly 32·Σ(3|V_j|k + k|τ| + mean size).
#[test]
fn frame_centring_keeps_fewer_components_and_eq8_counts_them() {
    let (anim, _) = synth::phased_motion_sized(8, 8, 90);
    let vertex = StsegParams { centering: Centering::Vertex, ..Default::default() };
    let seg = segment_animation(&anim, &vertex).unwrap();
    let total = |c: Centering| -> usize {
        let p = StsegParams { centering: c, ..vertex };
        seg.segments.iter().map(|s| segment_components(&anim, &p, s).unwrap().iter().sum::<usize>()).sum()
    };
    let (kv, kf, ka) = (total(Centering::Vertex), total(Centering::Frame), total(Centering::FrameAxis));
    assert!(kf < kv && ka < kv, "components: frame {kf}, frame-axis {ka}, vertex {kv}");
    for c in [Centering::Frame, Centering::FrameAxis, Centering::Vertex, Centering::None] {
        let p = StsegParams { centering: c, ..vertex };
        let est = paper_rate_estimate(&anim, &p, &seg).unwrap();
        let mut q = 0.0;
        for s in &seg.segments {
            let ks = segment_components(&anim, &p, s).unwrap();
            for (g, &k) in ks.iter().enumerate() {
                let n = s.labels.iter().filter(|&&l| l as usize == g).count();
                let mean = mean_layout(c, n, s.frame_count).1;
                q += 32.0 * (3 * n * k + k * s.frame_count + mean) as f64;
            }
        }
        assert_eq!(est.q_bits, q, "{c:?}");
        let vf = (anim.vertex_count() * anim.frame_count()) as f64;
        assert!((est.bpvf_uncompressed - q / vf).abs() < 1e-9);
        assert!(est.compressed_bytes > 0 && est.bpvf > 0.0 && est.bpvf < est.bpvf_uncompressed * 1.1);
    }
}

/// With the scanning detector (`detector = scan`, beyond the paper), every
/// change of `synth:phases` has a detected boundary within `w` frames at every size, and no
/// segment but the last is shorter than `w`.
#[test]
fn scanning_detector_finds_every_phase_change_at_every_size() {
    use animcodec_synth::SynthSize;
    let p = StsegParams { detector: Detector::Scan, ..Default::default() };
    let w = p.w as usize;
    for size in [SynthSize::Small, SynthSize::Medium, SynthSize::Large] {
        let anim = synth::by_name("phases", size).unwrap();
        let truth = synth::phase_boundaries(anim.frame_count());
        let s = segment_animation(&anim, &p).unwrap();
        let detected = s.detected_boundaries();
        for &b in &truth {
            let nearest = detected.iter().map(|&d| d.abs_diff(b)).min();
            assert!(nearest.is_some_and(|d| d <= w), "{size:?}: truth {b}, detected {detected:?}");
        }
        let n = s.segments.len();
        for seg in &s.segments[..n - 1] {
            assert!(seg.frame_count >= w, "{size:?}: segment {seg:?} shorter than w");
        }
        assert_eq!(s.segments.iter().map(|x| x.frame_count).sum::<usize>(), anim.frame_count());
    }
}

/// At equal segmentation and ω the toolkit coding (prediction along the group's
/// mesh and in time, RD steps, adaptive arithmetic coding) needs fewer bytes than the paper
/// coding for no more than 10% more error, and the paper coding stays reachable by parameter.
#[test]
fn toolkit_coding_is_smaller_than_the_paper_coding_at_similar_error() {
    let anim = synth::waving_flag(24, 16, 60);
    let reg = registry();
    let mut results = Vec::new();
    for coding in [Coding::Paper, Coding::Toolkit] {
        let ps = StsegParams { coding, omega: 0.999, ..Default::default() }.to_param_set().unwrap();
        let enc = encode_animation_fed(&Stseg, &ps, &anim, true, 60).unwrap();
        let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref());
        results.push((enc.bytes.len(), rel_rms(&anim, &dec)));
    }
    let ((paper_bytes, paper_err), (tk_bytes, tk_err)) = (results[0], results[1]);
    assert!(tk_bytes < paper_bytes, "toolkit {tk_bytes} bytes >= paper {paper_bytes}");
    assert!(tk_err <= 1.1 * paper_err, "toolkit error {tk_err} > 1.1 × paper {paper_err}");
}

/// `coding=paper` keeps version 2's packets: on the golden input its decoded frames hash to
/// `tests/golden/stseg-v2.anim`'s entry in `hashes.txt` (FNV-1a 64, as `tests/tests/golden.rs`).
#[test]
fn paper_coding_reproduces_the_version_2_golden_output() {
    let a = synth::waving_flag(8, 6, 16);
    let ps = StsegParams { coding: Coding::Paper, ..Default::default() }.to_param_set().unwrap();
    let enc = encode_animation_fed(&Stseg, &ps, &a, false, 16).unwrap();
    let dec = decode_animation(&enc.bytes, &registry(), Limits::default()).unwrap();
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&(dec.frame_count() as u64).to_le_bytes());
    eat(&(dec.vertex_count() as u64).to_le_bytes());
    for t in dec.triangles() {
        for i in t {
            eat(&i.to_le_bytes());
        }
    }
    for x in dec.positions() {
        eat(&x.to_bits().to_le_bytes());
    }
    assert_eq!(format!("{h:016x}"), "5d097985a4c57b14");
}

/// Zero-step components cost a toolkit packet almost nothing, so
/// the decoder refuses packets longer than any segment the encoder writes (bounding k and the
/// reconstruction work per value), and real packets damaged past the container's checksum
/// error or decode to finite values, never panic.
#[test]
fn toolkit_decoder_refuses_overlong_packets_and_survives_damaged_payloads() {
    let (anim, _) = synth::phased_motion_sized(4, 5, 60);
    let params = StsegParams { coding: Coding::Toolkit, ..Default::default() };
    let mut dec = StsegDecoder::for_params(&params, anim.topology());
    let long = Packet { first_frame: 0, frame_count: MAX_SEGMENT_FRAMES as u32 + 1, keyframe: true, data: vec![1, 1] };
    let e = dec.decode_packet(&long).unwrap_err().to_string();
    assert!(e.contains("stseg") && e.contains("packet frames") && e.contains("1024"), "{e}");

    let ps = params.to_param_set().unwrap();
    let enc = encode_animation_fed(&Stseg, &ps, &anim, false, 60).unwrap();
    let mut reader = codec_core::container::ContainerReader::new(&enc.bytes[..], Limits::default()).unwrap();
    let mut packets = Vec::new();
    while let Some(section) = reader.next_section() {
        if let codec_core::container::Section::Packet(p) = section.unwrap() {
            packets.push(p);
        }
    }
    assert!(!packets.is_empty());
    for p in &packets {
        assert!(dec.decode_packet(p).is_ok());
        for cut in (0..p.data.len()).step_by(5) {
            let q = Packet { data: p.data[..cut].to_vec(), ..p.clone() };
            if let Ok(v) = dec.decode_packet(&q) {
                assert!(v.iter().all(|x| x.is_finite()));
            }
        }
        for i in (0..p.data.len()).step_by(3) {
            let mut q = p.clone();
            q.data[i] ^= 0x5A;
            if let Ok(v) = dec.decode_packet(&q) {
                assert!(v.iter().all(|x| x.is_finite()));
            }
        }
    }
}

/// Specs, parsing and printing of every parameter agree (one declaration each), so a
/// parameter cannot be documented with one range and parsed with another.
#[test]
fn parameter_declaration_agrees_with_specs_parsing_and_printing() {
    codec_core::testing::check_declared_params::<StsegParams>();
    assert_eq!(Stseg.param_specs(), StsegParams::specs());
}
