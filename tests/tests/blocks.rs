//! An animation encoded block by block ([`codec_core::blocks`], what the Python
//! package's Dask encode runs on its workers) and assembled gives the local encode's bytes.

use animcodec::registry;
use animcodec::synth::waving_flag;
use codec_core::blocks::{assemble_blocks, block_plan, encode_block};
use codec_core::{encode_animation, Animation, AnimationCodec, ParamSet, ParamValue};

fn params(codec: &dyn AnimationCodec, pairs: &[(&str, ParamValue)]) -> ParamSet {
    let mut p = codec.default_params();
    for (name, value) in pairs {
        p.set(&codec.param_specs(), name, value.clone()).unwrap();
    }
    p
}

/// Every block coded on its own, in reverse order (so no block can lean on an earlier one),
/// then assembled.
fn blockwise(codec: &dyn AnimationCodec, params: &ParamSet, animation: &Animation, memory: Option<u64>) -> Vec<u8> {
    let (v, f) = (animation.vertex_count(), animation.frame_count());
    let (params, plan) = block_plan(codec, params, v, f, memory).unwrap();
    let mut packets: Vec<_> = (0..plan.blocks)
        .rev()
        .map(|i| {
            let frames = plan.frames(i);
            let block = &animation.positions()[frames.start * v * 3..frames.end * v * 3];
            encode_block(codec, &params, animation.topology(), f, animation.frame_rate(), i, block).unwrap()
        })
        .collect();
    packets.reverse();
    let packets = packets.into_iter().flatten();
    assemble_blocks(codec, &params, animation.topology(), f, animation.frame_rate(), packets, Vec::new()).unwrap()
}

#[test]
fn blocks_assemble_to_the_local_encode_byte_for_byte() {
    let reg = registry();
    let animation = waving_flag(12, 10, 30);
    let cases: Vec<(&str, Vec<(&str, ParamValue)>)> = vec![
        ("quant-delta", vec![("block", ParamValue::Int(7))]),
        ("quant-delta", vec![]),
        // 30 frames in blocks of 9 (a last block of 3) and of 14 (a last block of 2, which hosvd
        // codes at full rank only when it is not the whole animation).
        ("hosvd", vec![("block", ParamValue::Int(9))]),
        ("hosvd", vec![("block", ParamValue::Int(14))]),
        ("hosvd", vec![]),
        ("pca-aoi", vec![("mode", ParamValue::Choice("svd")), ("block", ParamValue::Int(8))]),
    ];
    for (name, pairs) in cases {
        let codec = reg.by_name(name).unwrap();
        let p = params(codec, &pairs);
        let local = encode_animation(codec, &p, &animation).unwrap();
        let assembled = blockwise(codec, &p, &animation, None);
        assert!(local == assembled, "{name} {pairs:?}: assembled stream differs from the local encode");
    }
}

/// `memory` fits the parameters as `encode --memory` does: hosvd's whole-sequence block
/// becomes several, and the blocks still assemble to the local encode with the fitted params.
#[test]
fn a_memory_budget_blocks_like_the_local_encode() {
    let reg = registry();
    let codec = reg.by_name("hosvd").unwrap();
    let animation = waving_flag(12, 10, 30);
    let p = codec.default_params();
    // hosvd's model: 64 MiB of program, 2 KiB a vertex, 64 B a coordinate of the block.
    let budget = (64 << 20) + (512 << 10);
    let (fitted, plan) = block_plan(codec, &p, 120, 30, Some(budget)).unwrap();
    assert_eq!(fitted, codec.fit_memory(&p, 120, 30, budget).unwrap());
    assert!(plan.blocks > 1, "{plan:?}");
    let local = encode_animation(codec, &fitted, &animation).unwrap();
    assert!(local == blockwise(codec, &p, &animation, Some(budget)));
}

#[test]
fn codecs_with_dependent_packets_are_refused_by_name() {
    let reg = registry();
    for name in ["sac", "stseg", "pca-aoi"] {
        let codec = reg.by_name(name).unwrap();
        let e = block_plan(codec, &codec.default_params(), 120, 30, None).unwrap_err().to_string();
        assert!(e.contains(name), "{name}: {e}");
        if name == "pca-aoi" {
            assert!(e.contains("mode=svd"), "{e}");
        }
    }
}

#[test]
fn wrong_blocks_and_missing_packets_are_errors() {
    let reg = registry();
    let codec = reg.by_name("quant-delta").unwrap();
    let animation = waving_flag(12, 10, 30);
    let p = params(codec, &[("block", ParamValue::Int(10))]);
    let (v, f, fps) = (120, 30, animation.frame_rate());
    let topo = animation.topology();
    let frames = |r: std::ops::Range<usize>| &animation.positions()[r.start * v * 3..r.end * v * 3];
    // Out of range, and the wrong number of frames for the block.
    assert!(encode_block(codec, &p, topo, f, fps, 3, frames(0..10)).is_err());
    assert!(encode_block(codec, &p, topo, f, fps, 0, frames(0..9)).is_err());
    let packets: Vec<_> =
        (0..3).flat_map(|i| encode_block(codec, &p, topo, f, fps, i, frames(i * 10..i * 10 + 10)).unwrap()).collect();
    // A missing block, and blocks out of order.
    let missing = [packets[0].clone(), packets[2].clone()];
    assert!(assemble_blocks(codec, &p, topo, f, fps, missing, Vec::new()).is_err());
    let swapped = [packets[1].clone(), packets[0].clone(), packets[2].clone()];
    assert!(assemble_blocks(codec, &p, topo, f, fps, swapped, Vec::new()).is_err());
    let short = [packets[0].clone(), packets[1].clone()];
    assert!(assemble_blocks(codec, &p, topo, f, fps, short, Vec::new()).is_err());
    assert!(assemble_blocks(codec, &p, topo, f, fps, packets, Vec::new()).is_ok());
}
