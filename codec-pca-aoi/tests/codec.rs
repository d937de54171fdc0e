//! End-to-end tests of `pca-aoi` through the container.

use std::io::Cursor;

use codec_core::{
    decode_animation, decode_frame, encode_animation_fed, Animation, AnimationCodec, CodecRegistry, EncoderSetup,
    FrameEncoder, Limits, Packet, StreamInfo, Topology,
};
use codec_pca_aoi::{
    qaoi_rate_ladder, toolkit_rate_ladder, Coding, Domain, Method, Mode, PcaAoi, PcaAoiEncoder, PcaAoiParams,
};

/// A waving, drifting grid: smooth low-rank-ish motion plus a translation per frame.
fn flag(cols: usize, rows: usize, frames: usize) -> Animation {
    let mut tris = Vec::new();
    for y in 0..rows - 1 {
        for x in 0..cols - 1 {
            let i = (y * cols + x) as u32;
            tris.push([i, i + 1, i + cols as u32]);
            tris.push([i + 1, i + cols as u32 + 1, i + cols as u32]);
        }
    }
    let mut pos = Vec::with_capacity(frames * rows * cols * 3);
    for t in 0..frames {
        let tt = t as f32 * 0.15;
        for y in 0..rows {
            for x in 0..cols {
                let (u, v) = (x as f32 / cols as f32, y as f32 / rows as f32);
                let z = 0.2 * u * (6.0 * u - 2.0 * tt).sin() + 0.05 * (4.0 * v + tt * 1.3).cos() * u;
                pos.extend_from_slice(&[u + 0.01 * tt, v + 0.02 * (tt).sin() * u, z]);
            }
        }
    }
    Animation::new(Topology::new(rows * cols, tris).unwrap(), pos, 30.0).unwrap()
}

fn registry() -> CodecRegistry {
    CodecRegistry::new(vec![Box::new(PcaAoi)]).unwrap()
}

/// Relative RMS error against the bounding-box diagonal, as `ErrorBound` defines it.
fn relative_rms(a: &Animation, b: &Animation) -> f64 {
    let se: f64 = a.positions().iter().zip(b.positions()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    (se / a.positions().len() as f64).sqrt() / a.bounding_box_diagonal()
}

/// KG error (Karni & Gotsman): 100·‖A−Â‖_F / ‖A−E(A)‖_F, E(A) the per-frame centroid.
fn kg(a: &Animation, b: &Animation) -> f64 {
    let v = a.vertex_count();
    let (mut num, mut den) = (0.0, 0.0);
    for (fa, fb) in a.frames().zip(b.frames()) {
        let mut c = [0.0f64; 3];
        for p in fa.chunks_exact(3) {
            for k in 0..3 {
                c[k] += p[k] as f64 / v as f64;
            }
        }
        for (i, (x, y)) in fa.iter().zip(fb).enumerate() {
            num += (*x as f64 - *y as f64).powi(2);
            den += (*x as f64 - c[i % 3]).powi(2);
        }
    }
    100.0 * (num / den).sqrt()
}

fn cases() -> Vec<PcaAoiParams> {
    let d = PcaAoiParams { block: 8, k: 4, ..Default::default() };
    vec![
        PcaAoiParams { mode: Mode::Svd, ..d },
        d,
        PcaAoiParams { tmax: 2, z: 2, ..d },
        PcaAoiParams { mode: Mode::Qaoi, eps_low: 0.001, eps_high: 0.01, ..d },
        PcaAoiParams { domain: Domain::Spatial, ..d },
        PcaAoiParams { domain: Domain::Temporal, clusters: 3, ..d },
        PcaAoiParams { clusters: 4, mode: Mode::Qaoi, ..d },
        PcaAoiParams { block: 1, k: 2, ..d },
        PcaAoiParams { dict_bits: 4, feat_bits: 4, ..d },
    ]
}

#[test]
fn round_trip_matches_reconstruction_bound_and_chunking() {
    let anim = flag(9, 7, 37); // 37 = 4 full blocks of 8 and a short one
    let reg = registry();
    for p in cases() {
        let params = p.to_param_set().unwrap();
        let enc = encode_animation_fed(&PcaAoi, &params, &anim, true, 5).unwrap();
        let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
        assert_eq!(Some(&dec), enc.reconstruction.as_ref(), "{p:?}: decoder differs from encoder reconstruction");
        for feed in [1, 8, 1000] {
            let other = encode_animation_fed(&PcaAoi, &params, &anim, false, feed).unwrap();
            assert!(other.bytes == enc.bytes, "{p:?}: bytes depend on feeding {feed} frames at a time");
        }
        let bound = PcaAoi.error_bound(&params, &anim).unwrap().relative_rms_error.unwrap();
        let err = relative_rms(&anim, &dec);
        assert!(err <= bound, "{p:?}: relative rms {err} > bound {bound}");
        // The bound is loose by design; the actual error must be far better than "no coding".
        assert!(kg(&anim, &dec) < 20.0, "{p:?}: KG {}", kg(&anim, &dec));
    }
}

#[test]
fn more_components_and_bits_reduce_error() {
    let anim = flag(10, 8, 48);
    let reg = registry();
    let err = |p: PcaAoiParams| {
        let bytes = encode_animation_fed(&PcaAoi, &p.to_param_set().unwrap(), &anim, false, 48).unwrap().bytes;
        (kg(&anim, &decode_animation(&bytes, &reg, Limits::default()).unwrap()), bytes.len())
    };
    let base = PcaAoiParams {
        block: 12,
        mode: Mode::Svd,
        dict_bits: 16,
        feat_bits: 16,
        coding: Coding::Paper,
        ..Default::default()
    };
    let mut prev = (f64::INFINITY, 0);
    for k in [1, 2, 4, 8] {
        let (e, n) = err(PcaAoiParams { k, ..base });
        assert!(e < prev.0 && n > prev.1, "k {k}: KG {e} bytes {n} vs {prev:?}");
        prev = (e, n);
    }
    // Full rank (k = 3·block) leaves only quantization error.
    let (full, _) = err(PcaAoiParams { k: 36, ..base });
    assert!(full < 0.05, "full-rank KG {full}");
    // Toolkit coding: every block meets its KG target (within the estimate's slack), and a
    // smaller target costs more bytes.
    let mut prev = (f64::INFINITY, 0);
    for target in [8.0, 4.0, 2.0, 1.0, 0.5, 0.25, 0.1] {
        let (e, n) = err(PcaAoiParams { kg: target, block: 12, ..Default::default() });
        assert!(e <= 1.05 * target, "kg target {target}: KG {e}");
        assert!(e < prev.0 && n > prev.1, "kg target {target}: KG {e} bytes {n} vs {prev:?}");
        prev = (e, n);
    }
}

#[test]
fn every_packet_decodes_alone_and_frames_seek() {
    let anim = flag(8, 6, 30);
    let params = PcaAoiParams { block: 7, ..Default::default() }.to_param_set().unwrap();
    let enc = encode_animation_fed(&PcaAoi, &params, &anim, true, 30).unwrap();
    let rec = enc.reconstruction.unwrap();
    let reg = registry();
    for t in [0, 6, 7, 20, 29] {
        let f = decode_frame(&mut Cursor::new(&enc.bytes), &reg, Limits::default(), t).unwrap();
        assert_eq!(f, rec.frame(t), "frame {t}");
    }
}

fn setup_and_packets(anim: &Animation, p: &PcaAoiParams) -> (Vec<u8>, Vec<Packet>, PcaAoiEncoder) {
    let setup = EncoderSetup {
        topology: anim.topology(),
        frame_count: anim.frame_count(),
        frame_rate: 30.0,
        want_reconstruction: false,
    };
    let mut enc = PcaAoiEncoder::new(p, &setup).unwrap();
    let mut packets: Vec<Packet> = enc.push_frames(anim.positions()).unwrap().into_iter().map(|e| e.packet).collect();
    packets.extend(enc.finish().unwrap().into_iter().map(|e| e.packet));
    (enc.config(), packets, enc)
}

fn info(anim: &Animation, codec_version: u16) -> StreamInfo {
    StreamInfo {
        fourcc: PcaAoi.fourcc(),
        codec_version,
        topology: anim.topology().clone(),
        frame_count: anim.frame_count(),
        frame_rate: 30.0,
    }
}

#[test]
fn corrupt_packets_and_configs_error_without_panicking() {
    let anim = flag(6, 5, 12);
    for p in [
        PcaAoiParams { block: 6, clusters: 2, ..Default::default() },
        PcaAoiParams { block: 6, domain: Domain::Spatial, ..Default::default() },
        PcaAoiParams { block: 6, clusters: 2, coding: Coding::Paper, ..Default::default() },
        PcaAoiParams { block: 6, domain: Domain::Spatial, coding: Coding::Paper, ..Default::default() },
    ] {
        let (config, packets, _) = setup_and_packets(&anim, &p);
        let mut dec = PcaAoi.new_decoder(&info(&anim, 2), &config, &Limits::default()).unwrap();
        let good = dec.decode_packet(&packets[0]).unwrap();
        let data = &packets[0].data;
        for cut in 0..data.len() {
            let bad = Packet { data: data[..cut].to_vec(), ..packets[0].clone() };
            assert!(dec.decode_packet(&bad).is_err(), "truncated to {cut} bytes decoded");
        }
        for i in 0..data.len() {
            for flip in [0x01u8, 0x80, 0xff] {
                let mut bad = packets[0].clone();
                bad.data[i] ^= flip;
                // Either an error or some frames of the right size; never a panic.
                if let Ok(f) = dec.decode_packet(&bad) {
                    assert_eq!(f.len(), good.len());
                }
            }
        }
        let wrong_frames = Packet { frame_count: 5, ..packets[0].clone() };
        assert!(dec.decode_packet(&wrong_frames).is_err());
        let zero = Packet { frame_count: 0, ..packets[0].clone() };
        assert!(dec.decode_packet(&zero).is_err());
        let mut extra = packets[0].clone();
        extra.data.push(0);
        let e = dec.decode_packet(&extra).unwrap_err().to_string();
        assert!(e.contains("pca-aoi"), "{e}");
    }
    // Version 1 configs (dict_bits, feat_bits, clusters), then version 2's (coding first).
    for config in [vec![], vec![14], vec![3, 12, 1], vec![14, 12, 0], vec![14, 12, 200, 1], vec![14, 12, 1, 0]] {
        let e = PcaAoi.new_decoder(&info(&anim, 1), &config, &Limits::default()).err().expect("bad config accepted");
        assert!(e.to_string().contains("pca-aoi"), "{e}");
    }
    for config in [
        vec![],
        vec![2, 14, 12, 1],
        vec![0, 3, 12, 1],
        vec![0, 14, 12, 0],
        vec![1, 2],
        vec![1, 4, 1, 1],
        vec![1, 2, 1, 0],
        vec![1, 2, 1, 1, 0],
    ] {
        let e = PcaAoi.new_decoder(&info(&anim, 2), &config, &Limits::default()).err().expect("bad config accepted");
        assert!(e.to_string().contains("pca-aoi"), "{e}");
    }
    for v in [0, 3] {
        assert!(PcaAoi.new_decoder(&info(&anim, v), &[0, 14, 12, 1], &Limits::default()).is_err());
    }
    // A tiny allocation limit is enforced before decoding, for both codings.
    for coding in [Coding::Toolkit, Coding::Paper] {
        let (config, packets, _) = setup_and_packets(&anim, &PcaAoiParams { block: 6, coding, ..Default::default() });
        let limits = Limits { max_alloc_bytes: 64, ..Limits::default() };
        let mut dec = PcaAoi.new_decoder(&info(&anim, 2), &config, &limits).unwrap();
        assert!(dec.decode_packet(&packets[0]).is_err());
    }
}

#[test]
fn paper_coding_packets_are_version_1_packets() {
    // `coding=paper` writes version 1's packets inside a version 2 stream; its config is
    // version 1's behind the coding byte 0, so a version 1 decoder setup decodes the same
    // packets to the same frames.
    let anim = flag(7, 6, 20);
    let p = PcaAoiParams { block: 8, clusters: 2, coding: Coding::Paper, ..Default::default() };
    let (config, packets, _) = setup_and_packets(&anim, &p);
    assert_eq!(config[0], 0);
    let mut v2 = PcaAoi.new_decoder(&info(&anim, 2), &config, &Limits::default()).unwrap();
    let mut v1 = PcaAoi.new_decoder(&info(&anim, 1), &config[1..], &Limits::default()).unwrap();
    for packet in &packets {
        assert_eq!(v1.decode_packet(packet).unwrap(), v2.decode_packet(packet).unwrap());
    }
}

/// A grid whose motion is simple, then rich (extra ripple modes), then simple again.
fn phased(cols: usize, rows: usize, frames: usize) -> Animation {
    let base = flag(cols, rows, frames);
    let (topology, mut pos, rate) = base.into_parts();
    for t in 0..frames {
        let rich = (frames / 3..2 * frames / 3).contains(&t);
        if !rich {
            continue;
        }
        let tt = t as f32 * 0.3;
        for y in 0..rows {
            for x in 0..cols {
                let (u, v) = (x as f32 / cols as f32, y as f32 / rows as f32);
                let i = ((t * rows + y) * cols + x) * 3;
                pos[i + 2] += 0.05 * (9.0 * v + tt).sin() * (7.0 * u - 0.5 * tt).cos()
                    + 0.04 * (13.0 * u * v + 1.7 * tt).sin()
                    + 0.03 * (5.0 * (u + v) - 2.3 * tt).cos();
                pos[i] += 0.02 * (11.0 * v - tt).sin();
            }
        }
    }
    Animation::new(topology, pos, rate).unwrap()
}

#[test]
fn qaoi_blocks_stay_in_band_and_stats_are_reported() {
    let anim = phased(12, 10, 96);
    let p = PcaAoiParams { mode: Mode::Qaoi, block: 8, eps_low: 0.003, eps_high: 0.02, ..Default::default() };
    let (_, packets, enc) = setup_and_packets(&anim, &p);
    assert_eq!(packets.len(), 12);
    let stats = enc.stats();
    assert_eq!(stats.len(), 12);
    assert_eq!(stats[0].method, Method::Init);
    assert!(stats.iter().all(|s| s.residual <= p.eps_high), "{stats:?}");
    assert!(stats.iter().filter(|s| s.method == Method::Aoi).count() >= 8, "{stats:?}");
    // k follows the content: larger in the rich middle third than in the simple outer thirds.
    let k: Vec<usize> = stats.iter().map(|s| s.k).collect();
    let (outer, middle) = (k[..4].iter().chain(&k[8..]).max().unwrap(), k[4..8].iter().min().unwrap());
    assert!(middle > outer, "k per block {k:?}");
    assert!(k[11] < k[7], "k must shrink again: {k:?}");
}

#[test]
fn drift_guard_off_never_reinitializes() {
    let anim = flag(12, 10, 64);
    let off = PcaAoiParams { block: 8, k: 2, drift: 0.0, ..Default::default() };
    let (_, _, enc) = setup_and_packets(&anim, &off);
    assert!(enc.stats().iter().skip(1).all(|s| s.method == Method::Aoi));
    let strict = PcaAoiParams { drift: 1.0, ..off };
    let (_, _, enc) = setup_and_packets(&anim, &strict);
    // With factor 1 an AOI block is kept only if its residual is within the reference: the
    // residual of the latest SVD block, floored at DRIFT_FLOOR.
    let mut reference = 0.0f64;
    for s in enc.stats() {
        match s.method {
            Method::Init | Method::Reinit => reference = s.residual,
            Method::Aoi => assert!(s.residual <= reference.max(codec_pca_aoi::dictionary::DRIFT_FLOOR), "{s:?}"),
            Method::Svd => unreachable!(),
        }
    }
}

#[test]
fn parameters_validate_with_ranges() {
    let e = PcaAoiParams { k: 0, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("pca-aoi") && e.contains("'k'") && e.contains("1..=512"), "{e}");
    let e = PcaAoiParams { eps_low: 0.1, eps_high: 0.01, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("eps_low") && e.contains("below eps_high"), "{e}");
    let e = PcaAoiParams { drift: 0.5, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("drift"), "{e}");
    let p = PcaAoiParams { mode: Mode::Qaoi, domain: Domain::Spatial, z: 3, ..Default::default() };
    assert_eq!(PcaAoiParams::from_param_set(&p.to_param_set().unwrap()).unwrap(), p);
    let specs = PcaAoi.param_specs();
    let mut set = PcaAoi.default_params();
    let e = PcaAoiParams { kg: 0.0, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("'kg'") && e.contains("0.001"), "{e}");
    let e = PcaAoiParams { max_k: 0, ..Default::default() }.validate().unwrap_err().to_string();
    assert!(e.contains("'max_k'") && e.contains("1..=512"), "{e}");
    let qaoi = PcaAoiParams { mode: Mode::Qaoi, coding: Coding::Paper, ..Default::default() }.to_param_set().unwrap();
    assert_eq!(PcaAoi.rate_ladder(&qaoi), qaoi_rate_ladder());
    assert_eq!(PcaAoi.rate_ladder(&set), toolkit_rate_ladder());
    let paper = PcaAoiParams { coding: Coding::Paper, ..Default::default() }.to_param_set().unwrap();
    assert_eq!(PcaAoi.rate_ladder(&paper).param, "k");
    for ladder in [PcaAoi.rate_ladder(&set), qaoi_rate_ladder(), PcaAoi.rate_ladder(&paper)] {
        for step in ladder.steps {
            set.set(&specs, ladder.param, step).unwrap();
            PcaAoi.validate(&set).unwrap();
        }
    }
}

#[test]
fn bytes_do_not_depend_on_thread_count() {
    let anim = flag(10, 9, 24);
    let params = PcaAoiParams { block: 6, clusters: 5, mode: Mode::Qaoi, ..Default::default() }.to_param_set().unwrap();
    let encode = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| encode_animation_fed(&PcaAoi, &params, &anim, false, 24).unwrap().bytes)
    };
    assert!(encode(1) == encode(3));
}

#[test]
fn paper_coding_reproduces_the_version_1_golden_packets_byte_for_byte() {
    // tests/golden/pca-aoi-v1.anim was written by stream version 1 with default parameters
    // from the golden input (tests/tests/golden.rs); `coding=paper` must write the same packets
    // and, behind its coding byte 0, the same config.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/golden/pca-aoi-v1.anim");
    // The golden file is committed: its absence is a failure, not a skip.
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = codec_core::container::ContainerReader::new(&bytes[..], Limits::default()).unwrap();
    let golden_config = reader.header().config.clone();
    let mut golden = Vec::new();
    while let Some(section) = reader.next_section() {
        if let codec_core::container::Section::Packet(p) = section.unwrap() {
            golden.push(p);
        }
    }
    let anim = animcodec_synth::waving_flag(8, 6, 16);
    let p = PcaAoiParams { coding: Coding::Paper, ..Default::default() };
    let (config, packets, _) = setup_and_packets(&anim, &p);
    assert_eq!(config[0], 0);
    assert_eq!(config[1..], golden_config[..]);
    assert_eq!(packets.len(), golden.len());
    for (a, b) in packets.iter().zip(&golden) {
        assert_eq!(a.data, b.data, "packet at frame {}", a.first_frame);
    }
}

/// A tiny config must not make the decoder build one cluster (and
/// one coding order) per vertex, and a toolkit packet longer than any block the encoder writes
/// is refused before decoding (it would bound nothing on the rank and the work per value).
#[test]
fn cluster_count_and_packet_length_are_bounded_by_the_encoders_ranges() {
    // 300 × 240 = 72 000 vertices: more than MAX_CLUSTERS (65 536).
    let big = flag(300, 240, 1);
    for (version, prefix) in [(1u16, vec![14u8, 12]), (2, vec![1u8, 2, 1])] {
        let mut w = codec_core::bytes::ByteWriter::new();
        for b in &prefix {
            w.u8(*b);
        }
        w.varint(65_537);
        let config = w.into_vec();
        let e = PcaAoi.new_decoder(&info(&big, version), &config, &Limits::default()).err().expect("accepted");
        assert!(e.to_string().contains("config.clusters") && e.to_string().contains("65536"), "{e}");
    }
    let anim = flag(6, 5, 12);
    let (config, packets, _) = setup_and_packets(&anim, &PcaAoiParams { block: 6, ..Default::default() });
    let mut dec = PcaAoi.new_decoder(&info(&anim, 2), &config, &Limits::default()).unwrap();
    let long = Packet { frame_count: 4097, ..packets[0].clone() };
    let e = dec.decode_packet(&long).unwrap_err().to_string();
    assert!(e.contains("packet.frame_count") && e.contains("4096"), "{e}");
}

/// Specs, parsing and printing of every parameter agree (one declaration each), so a
/// parameter cannot be documented with one range and parsed with another.
#[test]
fn parameter_declaration_agrees_with_specs_parsing_and_printing() {
    codec_core::testing::check_declared_params::<PcaAoiParams>();
    assert_eq!(PcaAoi.param_specs(), PcaAoiParams::specs());
}
