//! Hostile streams for the decoders, as the probe scripts of
//! `../shared/probe-round4/` ran them (`forged-vertex-count`, `hosvd-work`, `sac-config`, the
//! forged frame rate of `misc`). Every input is built here: streams encoded from `synth:`
//! inputs by the binary, then forged (header fields changed, the header CRC recomputed), or
//! crafted from nothing like `hosvd-work/craft_hosvd.py`.

use animcodec::core::container::ContainerWriter;
use animcodec::core::{entropy, FourCc, Packet, Topology};

mod common;
use common::*;

/// The byte range of a stream's header before its CRC (FORMAT.md: 36 fixed bytes and the
/// config, then the topology block).
fn header_end(bytes: &[u8]) -> usize {
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
    let config = u32_at(32);
    let topology = u32_at(36 + config);
    36 + config + 4 + topology
}

/// `bytes` with `edit` applied to its header and the header CRC recomputed.
fn forge(bytes: &[u8], edit: impl FnOnce(&mut [u8])) -> Vec<u8> {
    let mut b = bytes.to_vec();
    edit(&mut b);
    let end = header_end(&b);
    let mut crc = flate2::Crc::new();
    crc.update(&b[..end]);
    let crc = crc.sum();
    b[end..end + 4].copy_from_slice(&crc.to_le_bytes());
    b
}

/// The probe's parameters per codec.
fn probe_params(codec: &str) -> &'static str {
    match codec {
        "quant-delta" => "bits=12",
        "sac" => "bases=16",
        "hosvd" => "ss=0.9",
        "pca-aoi" => "kg=1",
        _ => "omega=0.99",
    }
}

const CODECS: [&str; 5] = ["quant-delta", "pca-aoi", "hosvd", "stseg", "sac"];

/// Encodes `input` with `codec` and the probe's parameters into `out`; returns the bytes.
fn encode(input: &str, codec: &str, params: &str, out: &str) -> Vec<u8> {
    ok(&["encode", input, "-c", codec, "-p", params, "-o", out, "-f"]);
    std::fs::read(out).unwrap()
}

/// `forged-vertex-count`: the header's vertex count doubled (CRC fixed). pca-aoi, hosvd and
/// stseg decoded garbage with exit 0; now every codec refuses, and no output is left.
#[test]
fn a_doubled_vertex_count_is_refused_by_every_codec() {
    let s = Scratch::new("r4-forged-v");
    for codec in CODECS {
        let bytes = encode("synth:flag:30x30x40", codec, probe_params(codec), &s.path(&format!("{codec}.anim")));
        let forged = forge(&bytes, |b| {
            let v = u32::from_le_bytes(b[16..20].try_into().unwrap());
            b[16..20].copy_from_slice(&(2 * v).to_le_bytes());
        });
        let input = s.path(&format!("{codec}.V2.anim"));
        std::fs::write(&input, forged).unwrap();
        let out = s.path(&format!("{codec}.V2.pc2"));
        fails(&["decode", &input, "-o", &out, "-f"], &[codec]);
        assert!(!std::path::Path::new(&out).exists(), "{codec}: a refused decode left {out}");
    }
}

/// LEB128 of `n` (the codecs' varints).
fn leb(mut n: u64) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let c = (n & 0x7f) as u8;
        n >>= 7;
        out.push(c | if n > 0 { 0x80 } else { 0 });
        if n == 0 {
            return out;
        }
    }
}

/// `craft_hosvd.py K F V_RANK F_RANK`: a hosvd (stream version 5) stream of one toolkit packet
/// with zero triangles, `u2 = 0`, every step 1 and 8 zero bytes of codes, whose decode asks
/// for `K · V_RANK · 3F` multiply-adds (about 170 bytes for any of them).
fn hosvd_bomb(k: usize, frames: usize, v_rank: u64, f_rank: u64) -> Vec<u8> {
    let mut side = vec![0u8; 36];
    for _ in 0..2 * v_rank + f_rank {
        side.extend_from_slice(&1.0f32.to_le_bytes());
    }
    let side = entropy::compress(&side, 19);
    let mut payload = vec![2u8];
    payload.extend(leb(v_rank));
    payload.extend(leb(f_rank));
    payload.extend([2, 1]);
    payload.extend(leb(side.len() as u64));
    payload.extend(side);
    payload.extend(leb(8));
    payload.extend([0u8; 8]);
    let topology = Topology::new(k, Vec::new()).unwrap();
    let config = (frames as u32).to_le_bytes();
    let mut w = ContainerWriter::new(Vec::new(), FourCc::new(b"HOSV"), 5, &topology, frames, 30.0, &config).unwrap();
    w.write_packet(&Packet { first_frame: 0, frame_count: frames as u32, keyframe: true, data: payload }).unwrap();
    w.finish().unwrap()
}

/// `hosvd-work`: the 171-byte streams that decoded for 40 s at 1 GB. `--max-work 1000` now
/// refuses the first from its header's sizes (it used to be ignored); the second asks for
/// more than the default budget (~2.7·10^11 multiply-adds) and is refused by default.
#[test]
fn a_tiny_hosvd_stream_asking_for_1e11_operations_is_refused_by_the_work_budget() {
    let s = Scratch::new("r4-hosvd-work");
    let bomb = s.path("bomb.anim");
    let bytes = hosvd_bomb(4000, 4000, 2000, 1);
    assert!(bytes.len() < 256, "{} bytes", bytes.len());
    std::fs::write(&bomb, &bytes).unwrap();
    let out = s.path("o.pc2");
    fails(&["decode", &bomb, "-o", &out, "-f", "--max-work", "1000"], &["hosvd", "--max-work"]);
    let bomb2 = s.path("bomb2.anim");
    std::fs::write(&bomb2, hosvd_bomb(6000, 6000, 2500, 1)).unwrap();
    fails(&["decode", &bomb2, "-o", &out, "-f"], &["hosvd", "--max-work"]);
    // The first is within the default budget: its 8 bytes of codes cannot hold the 8 million
    // values it declares, so the range decoder runs past them and the decode is refused.
    fails(&["decode", &bomb, "-o", &out, "-f"], &["hosvd", "ends before its symbols do"]);
    assert!(!std::path::Path::new(&out).exists());
}

/// `hosvd-work`, second part: `decode --max-work 1` succeeded for quant-delta, pca-aoi, hosvd
/// and stseg (only sac counted its work). Every codec refuses it now, and decodes the same
/// stream under the default budget.
#[test]
fn max_work_1_is_refused_by_every_codec() {
    let s = Scratch::new("r4-max-work");
    let out = s.path("o.pc2");
    for codec in CODECS {
        let params = if codec == "quant-delta" { "bits=8" } else { probe_params(codec) };
        let stream = s.path(&format!("p.{codec}.anim"));
        encode("synth:flag:20x20x30", codec, params, &stream);
        fails(&["decode", &stream, "-o", &out, "-f", "--max-work", "1"], &[codec, "--max-work"]);
        ok(&["decode", &stream, "-o", &out, "-f"]);
    }
}

/// `sac-config`: one config byte changed (bases 32 → 544, CRC fixed). The decoder spent the
/// 544-vector basis before finding the P-frames' descriptors malformed; the descriptors are
/// now decoded at the basis's size first. (That the basis is not computed is shown by the
/// peak memory of `tests/tests/hostile_limits.rs`; here the refusal itself.)
#[test]
fn a_sac_config_asking_for_more_bases_than_coded_is_refused() {
    let s = Scratch::new("r4-sac-config");
    let bytes = encode("synth:flag:30x30x20", "sac", "bases=32", &s.path("h_sac.anim"));
    // Config: u8 bits, then u32 bases at config offset 1 (header offset 37).
    assert_eq!(u32::from_le_bytes(bytes[37..41].try_into().unwrap()), 32);
    let forged = forge(&bytes, |b| b[38] = 2);
    let input = s.path("h_sac_bases544.anim");
    std::fs::write(&input, forged).unwrap();
    fails(&["decode", &input, "-o", &s.path("o.pc2"), "-f"], &["sac", "descriptors"]);
}

/// `misc`: a forged frame rate of 1e30 (CRC fixed) decoded to a `.usda` animcodec then
/// refused to read. The container refuses it now, naming the field and the range readers take.
#[test]
fn a_frame_rate_no_reader_accepts_is_refused_by_the_container() {
    let s = Scratch::new("r4-fps");
    let bytes = encode("synth:flag:10x10x5", "quant-delta", "bits=8", &s.path("q.anim"));
    for rate in [1e30f32, f32::INFINITY, 0.0, -1.0, 2e4] {
        let input = s.path("fps.anim");
        std::fs::write(&input, forge(&bytes, |b| b[28..32].copy_from_slice(&rate.to_le_bytes()))).unwrap();
        let out = s.path("f.usda");
        fails(&["decode", &input, "-o", &out, "-f"], &["frame_rate", "1e4"]);
        assert!(!std::path::Path::new(&out).exists());
    }
    // The top of the readers' range decodes, and the .usda it writes reads back.
    let input = s.path("fps.anim");
    std::fs::write(&input, forge(&bytes, |b| b[28..32].copy_from_slice(&1e4f32.to_le_bytes()))).unwrap();
    let usda = s.path("f.usda");
    ok(&["decode", &input, "-o", &usda, "-f"]);
    ok(&["encode", &usda, "-c", "quant-delta", "-p", "bits=8", "-o", &s.path("g.anim"), "-f"]);
}
