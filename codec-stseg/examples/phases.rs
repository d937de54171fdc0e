//! Boundaries of `synth:phases` at every size:
//! `target/release/examples/phases [key=value]...` prints the true phase changes, the
//! segmentation's boundaries and segment lengths for Small, Medium and Large.

use animcodec_synth::{self as synth, SynthSize};
use codec_core::AnimationCodec;
use codec_stseg::{segment_animation, Stseg, StsegParams};

fn main() {
    let specs = Stseg.param_specs();
    let mut ps = Stseg.default_params();
    for kv in std::env::args().skip(1) {
        let (k, val) = kv.split_once('=').expect("key=value");
        let spec = specs.iter().find(|s| s.name == k).unwrap_or_else(|| panic!("unknown parameter {k}"));
        ps.set(&specs, k, spec.parse("stseg", val).unwrap()).unwrap();
    }
    let p = StsegParams::from_param_set(&ps).unwrap();
    println!("params: {ps}");
    for size in [SynthSize::Small, SynthSize::Medium, SynthSize::Large] {
        let anim = synth::by_name("phases", size).unwrap();
        let truth = synth::phase_boundaries(anim.frame_count()).to_vec();
        let s = segment_animation(&anim, &p).unwrap();
        let lens: Vec<usize> = s.segments.iter().map(|x| x.frame_count).collect();
        let miss: Vec<(usize, Option<usize>)> =
            truth.iter().map(|&t| (t, s.boundaries().iter().map(|&d| d.abs_diff(t)).min())).collect();
        println!(
            "{size:?} V={} F={}: truth {truth:?} boundaries {:?} (detected {:?}) lengths {lens:?}; distance to the nearest boundary (None: no boundary) {miss:?}",
            anim.vertex_count(),
            anim.frame_count(),
            s.boundaries(),
            s.detected_boundaries()
        );
    }
}
