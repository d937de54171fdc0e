//! Streaming: PC2/MDD and OBJ-sequence encodes read frame by frame, decodes to PC2/MDD written
//! frame by frame, `synth flag:CxRxF` written frame by frame, and `encode --memory`. The streamed
//! paths must give the same bytes as the in-memory ones; memory itself is measured by
//! `bench/scale.sh`.

mod common;

use common::{fails, ok, ok_json, Scratch};

/// A small flag cache (`flag:COLSxROWSxFRAMES`) written by `synth` frame by frame.
fn flag_cache(s: &Scratch, name: &str, dims: &str) -> String {
    let pc2 = s.path(name);
    ok(&["synth", &format!("flag:{dims}"), "-o", &pc2]);
    pc2
}

#[test]
fn synth_writes_the_streamed_flag_frame_by_frame_equal_to_the_generated_one() {
    let s = Scratch::new("stream-synth");
    let pc2 = flag_cache(&s, "f.pc2", "9x7x13");
    // The same flag encoded from the generator and from the file: same bytes (lossless enough
    // to show the frames agree: quant-delta at 24 bits on the same input is deterministic).
    let (a, b) = (s.path("a.anim"), s.path("b.anim"));
    ok(&["encode", "synth:flag:9x7x13", "-c", "quant-delta", "-p", "bits=24", "-o", &a]);
    ok(&["encode", &pc2, "-c", "quant-delta", "-p", "bits=24", "-o", &b]);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    fails(&["synth", "flag:9x7x13", "-o", &s.path("f.glb")], &["frame by frame", ".pc2 or .mdd"]);
}

#[test]
fn streamed_encodes_equal_the_in_memory_encodes_for_every_codec() {
    let s = Scratch::new("stream-encode");
    let pc2 = flag_cache(&s, "f.pc2", "12x10x40");
    let mdd = s.path("f.mdd");
    ok(&["decode", &encode_lossless(&s, &pc2), "-o", &mdd]);
    let registry = animcodec::registry();
    for codec in registry.iter().map(|c| c.name()) {
        let p = match codec {
            "hosvd" => "ss=0.9",
            "pca-aoi" => "block=16",
            "quant-delta" => "bits=12",
            "laplacian" => "block=16",
            _ => "level=3",
        };
        for input in [&pc2, &mdd] {
            // The cache streams; the whole read encodes in memory.
            let streamed = s.path("s.anim");
            ok(&["encode", input, "-c", codec, "-p", p, "--feed", "7", "-o", &streamed, "-f"]);
            assert_eq!(std::fs::read(&streamed).unwrap(), whole_encode(input, codec, p), "{codec} on {input}");
        }
    }
}

/// The stream of `input` read whole and encoded in memory with `-p param` (what `encode` does
/// with a file it does not read frame by frame).
fn whole_encode(input: &str, codec: &str, param: &str) -> Vec<u8> {
    let animation = animcodec::formats::read_animation(input.as_ref(), &Default::default()).unwrap();
    let registry = animcodec::registry();
    let codec = registry.by_name(codec).unwrap();
    let params = animcodec::front::params_from_text(codec, &[param.to_owned()]).unwrap();
    animcodec::core::encode_animation(codec, &params, &animation).unwrap()
}

/// An OBJ sequence (a directory or a file-name pattern) is read one file per frame,
/// and gives the bytes of the whole read and of the PC2 of the same frames.
#[test]
fn an_obj_sequence_streams_to_the_bytes_of_the_whole_read_and_of_its_pc2() {
    let s = Scratch::new("stream-obj");
    let pc2 = flag_cache(&s, "f.pc2", "12x10x40");
    let lossless = encode_lossless(&s, &pc2);
    // The same decoded frames as an OBJ sequence and as a PC2 (OBJ writes each f32 so that it
    // reads back identical).
    let (dir, same) = (s.path("frames/"), s.path("same.pc2"));
    ok(&["decode", &lossless, "-o", &dir]);
    ok(&["decode", &lossless, "-o", &same, "--topology-obj"]);
    let (from_pc2, streamed) = (s.path("p.anim"), s.path("s.anim"));
    let args = ["-c", "quant-delta", "-p", "bits=12"];
    ok(&[&["encode", &same][..], &args, &["-o", &from_pc2]].concat());
    let pattern = s.path("frames/frame_{}.obj");
    for input in [&dir, &pattern] {
        // The streamed path reads while it encodes (and says so), --eval too.
        let text = ok(&[&["encode", input][..], &args, &["--feed", "3", "-o", &streamed, "-f"]].concat());
        assert!(text.contains("40 frames") && text.contains("read frame by frame while encoding"), "{text}");
        let text = ok(&[&["encode", input][..], &args, &["--eval", "-o", &streamed, "-f"]].concat());
        assert!(text.contains("read frame by frame while encoding") && text.contains("decoded vs input: KG"), "{text}");
        let bytes = std::fs::read(&streamed).unwrap();
        assert_eq!(bytes, whole_encode(input, "quant-delta", "bits=12"), "{input}: streamed vs whole");
        assert_eq!(bytes, std::fs::read(&from_pc2).unwrap(), "{input}: OBJ sequence vs PC2");
    }
    // A later frame whose mesh differs fails when it is read, with the whole read's message,
    // and leaves no output.
    let frame = s.path("frames/frame_0031.obj");
    let text = std::fs::read_to_string(&frame).unwrap();
    let cut: String = text.lines().filter(|l| !l.starts_with("f ")).map(|l| format!("{l}\n")).collect();
    std::fs::write(&frame, cut).unwrap();
    let out = s.path("bad.anim");
    let streamed = fails(&[&["encode", &dir][..], &args, &["-o", &out]].concat(), &["frame_0031.obj", "triangles"]);
    let whole = animcodec::formats::read_animation(dir.as_ref(), &Default::default()).unwrap_err().to_string();
    assert!(whole.contains("frame_0031.obj") && streamed.contains("frame_0031.obj"), "{streamed} vs {whole}");
    fails(&[&["encode", &dir][..], &args, &["--eval", "-o", &out]].concat(), &["frame_0031.obj", "triangles"]);
    assert!(!std::path::Path::new(&out).exists());
    // An empty directory: the whole read's error.
    let empty = s.path("empty/");
    std::fs::create_dir_all(&empty).unwrap();
    fails(&[&["encode", &empty][..], &args, &["-o", &out]].concat(), &["no .obj file"]);
}

/// quant-delta at 24 bits, for a second cache format with the same frames (near enough).
fn encode_lossless(s: &Scratch, pc2: &str) -> String {
    let anim = s.path("lossless.anim");
    ok(&["encode", pc2, "-c", "quant-delta", "-p", "bits=24", "-o", &anim, "-f"]);
    anim
}

#[test]
fn streamed_decodes_equal_the_in_memory_writes() {
    let s = Scratch::new("stream-decode");
    let pc2 = flag_cache(&s, "f.pc2", "11x9x30");
    for (codec, p) in [("quant-delta", "bits=10"), ("hosvd", "block=8"), ("pca-aoi", "block=12")] {
        let anim = s.path(&format!("{codec}.anim"));
        ok(&["encode", &pc2, "-c", codec, "-p", p, "-o", &anim, "-f"]);
        for ext in ["pc2", "mdd"] {
            // Streamed to a cache; the OBJ sequence path decodes the whole animation first.
            let streamed = s.path(&format!("{codec}.{ext}"));
            let j = ok_json(&["decode", &anim, "-o", &streamed, "--topology-obj", "-f", "--json"]);
            assert_eq!(j["frames"], 30);
            let registry = animcodec::registry();
            let bytes = std::fs::read(&anim).unwrap();
            let decoded =
                animcodec::core::decode_animation(&bytes, &registry, animcodec::core::Limits::default()).unwrap();
            let whole = s.path(&format!("{codec}-whole.{ext}"));
            animcodec::formats::write_animation(std::path::Path::new(&whole), &decoded).unwrap();
            assert_eq!(std::fs::read(&streamed).unwrap(), std::fs::read(&whole).unwrap(), "{codec} → {ext}");
        }
    }
    // A stream cut short leaves no output and no temporary file.
    let anim = s.path("quant-delta.anim");
    let bytes = std::fs::read(&anim).unwrap();
    let cut = s.path("cut.anim");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let out = s.path("cut.pc2");
    let o = common::animcodec(&["decode", &cut, "-o", &out, "--topology-obj"]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    assert!(!std::path::Path::new(&out).exists());
    let tmp: Vec<_> = std::fs::read_dir(&s.0)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(tmp.is_empty(), "{tmp:?}");
}

#[test]
fn a_memory_budget_chooses_hosvd_blocks_and_refuses_what_cannot_fit() {
    let s = Scratch::new("stream-memory");
    let pc2 = flag_cache(&s, "f.pc2", "40x30x60");
    let anim = s.path("m.anim");
    // Unbounded: one block of 60 frames.
    let j = ok_json(&["encode", &pc2, "-c", "hosvd", "-p", "ss=0.9", "-o", &anim, "-f", "--json"]);
    assert_eq!(j["params"]["block"], 0);
    // The smallest budget for which hosvd splits the 60 frames into blocks.
    let (budget, block) = hosvd_blocked_budget(1200, 60);
    let j = ok_json(&["encode", &pc2, "-c", "hosvd", "-p", "ss=0.9", "--memory", &budget, "-o", &anim, "-f", "--json"]);
    assert_eq!(j["params"]["block"].as_u64(), Some(block), "{j}");
    // Equal blocks: the last one is not a short remainder.
    let blocks = 60u64.div_ceil(block);
    assert!(blocks >= 2 && block * blocks - 60 < blocks, "{block} frames per block");
    // The blocked stream decodes (and was self-checked per packet while encoding).
    ok(&["decode", &anim, "-o", &s.path("m.pc2"), "-f"]);
    // An explicit block is kept whatever the budget.
    let j = ok_json(&[
        "encode", &pc2, "-c", "hosvd", "-p", "ss=0.9", "-p", "block=30", "--memory", &budget, "-o", &anim, "-f",
        "--json",
    ]);
    assert_eq!(j["params"]["block"], 30);
    // Too small for the smallest block: an error naming the budget, no file.
    let none = s.path("none.anim");
    fails(
        &["encode", &pc2, "-c", "hosvd", "-p", "ss=0.9", "--memory", "1K", "-o", &none],
        &["hosvd", "block", "budget"],
    );
    assert!(!std::path::Path::new(&none).exists());
    // Without -p the default-quality search keeps to the budget too: this input's whole-array
    // search fits 4G, so it is searched whole.
    let j = ok_json(&["encode", &pc2, "-c", "hosvd", "--memory", "4G", "-o", &none, "--json"]);
    assert_eq!(j["search_input"], "whole", "{j}");
    assert_eq!(j["memory_budget"].as_u64(), Some(4 << 30), "{j}");
}

/// The smallest budget (whole MiB) for which hosvd's `fit_memory` blocks `frames` frames of
/// `vertices` vertices, as a string, and the block it chooses.
fn hosvd_blocked_budget(vertices: usize, frames: usize) -> (String, u64) {
    let registry = animcodec::registry();
    let hosvd = registry.by_name("hosvd").unwrap();
    let params = hosvd.default_params();
    for mib in 1..(1 << 14) {
        let budget = mib << 20;
        if let Ok(p) = hosvd.fit_memory(&params, vertices, frames, budget) {
            let block = match p.get("block") {
                Some(animcodec::core::ParamValue::Int(b)) => *b as u64,
                other => panic!("block is {other:?}"),
            };
            if block > 0 {
                return (budget.to_string(), block);
            }
        }
    }
    panic!("no budget blocks {frames} frames of {vertices} vertices");
}

#[test]
fn pca_aoi_shortens_a_block_that_does_not_fit_the_budget() {
    let registry = animcodec::registry();
    let pca = registry.by_name("pca-aoi").unwrap();
    let params = pca.default_params();
    let block = |p: &animcodec::core::ParamSet| match p.get("block") {
        Some(animcodec::core::ParamValue::Int(b)) => *b as usize,
        other => panic!("block is {other:?}"),
    };
    let (v, f) = (100_000, 1000);
    // A budget that holds the default block keeps it.
    assert_eq!(block(&pca.fit_memory(&params, v, f, 64 << 30).unwrap()), block(&params));
    // One that does not: a shorter block, equal blocks over the frames, and it fits.
    let budget = 400 << 20;
    let fitted = pca.fit_memory(&params, v, f, budget).unwrap();
    let b = block(&fitted);
    assert!(b >= 8 && b < block(&params), "{b}");
    assert!(b * f.div_ceil(b) - f < f.div_ceil(b), "{b} frames per block leaves a short last block");
    assert!(codec_pca_aoi_fits(v, b, budget));
    // One that holds no block of 8 frames: an error naming the budget.
    let e = pca.fit_memory(&params, v, f, 1 << 20).unwrap_err().to_string();
    assert!(e.contains("budget") && e.contains("pca-aoi"), "{e}");

    // End to end: the budget's block is what the stream uses, and it decodes.
    let s = Scratch::new("stream-memory-pca");
    let pc2 = flag_cache(&s, "f.pc2", "40x30x60");
    let small = pca.fit_memory(&params, 1200, 60, 69 << 20).unwrap();
    assert!(block(&small) < block(&params), "the budget must shorten the block here");
    let anim = s.path("p.anim");
    let j = ok_json(&[
        "encode",
        &pc2,
        "-c",
        "pca-aoi",
        "-p",
        "mode=baoi",
        "--memory",
        &(69u64 << 20).to_string(),
        "-o",
        &anim,
        "--json",
    ]);
    assert_eq!(j["params"]["block"].as_u64(), Some(block(&small) as u64), "{j}");
    ok(&["decode", &anim, "-o", &s.path("p.pc2")]);
}

/// Whether pca-aoi's model (bytes per coordinate of a block, per vertex, fixed) fits `budget`:
/// the documented 32 B · 3 V · frames + 1 KiB · V + 64 MiB.
fn codec_pca_aoi_fits(vertices: usize, frames: usize, budget: u64) -> bool {
    32 * vertices as u64 * 3 * frames as u64 + 1024 * vertices as u64 + (64 << 20) <= budget
}
