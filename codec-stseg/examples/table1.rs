//! The Table-1 analogue of Luo et al. 2020 for `stseg`: one animation of `../shared/data`,
//! the paper's parameters (or any `key=value` override), and per run: segment lengths, the
//! components kept per group, the paper's rate estimate (Eq. 8–9) for our segmentation, the
//! real `.anim` bpvf (whole container), KG error, and encode / decode seconds.
//!
//! `cargo build --release -p codec-stseg --example table1 && target/release/examples/table1 NAME [key=value]...`
//! (for example `horse-gallop w=3 gamma_init=12 gamma_max=20 groups=4 omega=0.99`). Set
//! `STSEG_THREADS=1` for a single-thread timing. Skips with a message when the data is absent.

use std::path::Path;
use std::time::Instant;

use codec_core::{decode_animation, encode_animation, Animation, AnimationCodec, CodecRegistry, Limits, Topology};
use codec_stseg::{
    encode_with_segmentation, fixed_block_segmentation, paper_rate_estimate, segment_animation, segment_components,
    Stseg, StsegParams,
};

#[path = "support/data.rs"]
mod data;

use data::{kg_error, read_obj_triangles, read_pc2};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(name) = args.first() else {
        eprintln!("usage: table1 NAME [key=value]...");
        std::process::exit(2);
    };
    if let Some(n) = std::env::var("STSEG_THREADS").ok().and_then(|x| x.parse::<usize>().ok()) {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().unwrap();
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    let dir = root.join(name);
    let (v, f, pos) = match read_pc2(&dir.join(format!("{name}.pc2"))) {
        Ok(x) => x,
        Err(e) => {
            println!("SKIP {name}: {e}");
            return;
        }
    };
    let tris = read_obj_triangles(&dir.join(format!("{name}.obj"))).unwrap();
    let anim = Animation::new(Topology::new(v, tris).unwrap(), pos, 30.0).unwrap();
    let specs = Stseg.param_specs();
    let mut ps = Stseg.default_params();
    for kv in &args[1..] {
        let (k, val) = kv.split_once('=').expect("key=value");
        let spec = specs.iter().find(|s| s.name == k).unwrap_or_else(|| panic!("unknown parameter {k}"));
        ps.set(&specs, k, spec.parse("stseg", val).unwrap()).unwrap();
    }
    let p = StsegParams::from_param_set(&ps).unwrap();
    let vf = (v * f) as f64;

    let t = Instant::now();
    let seg = segment_animation(&anim, &p).unwrap();
    let seg_s = t.elapsed().as_secs_f64();
    let lens: Vec<usize> = seg.segments.iter().map(|s| s.frame_count).collect();
    let cases: Vec<u8> = seg.segments.iter().map(|s| s.kind.case()).collect();
    let ks: Vec<Vec<usize>> = seg.segments.iter().map(|s| segment_components(&anim, &p, s).unwrap()).collect();
    let est = paper_rate_estimate(&anim, &p, &seg).unwrap();

    let t = Instant::now();
    let bytes = encode_animation(&Stseg, &ps, &anim).unwrap();
    let enc_s = t.elapsed().as_secs_f64();
    let registry = CodecRegistry::new(vec![Box::new(Stseg)]).unwrap();
    let t = Instant::now();
    let dec = decode_animation(&bytes, &registry, Limits::default()).unwrap();
    let dec_s = t.elapsed().as_secs_f64();
    let kg = kg_error(&anim, dec.positions());
    println!("{name} V={v} F={f} params: {ps}");
    println!("  segments {} lengths {lens:?} cases {cases:?} detected {:?}", lens.len(), seg.detected_boundaries());
    println!("  k per segment (per group) {ks:?}");
    println!(
        "  Eq.8 Q/(VF) {:.3} bpvf; Eq.9 (zstd-6 ratio {:.3}) {:.3} bpvf",
        est.bpvf_uncompressed,
        est.compressed_bytes as f64 / est.raw_bytes.max(1) as f64,
        est.bpvf
    );
    println!(
        "  real .anim {:.3} bpvf ({} bytes)  KG {:.3}  segmentation {:.2}s  encode {:.2}s  decode {:.3}s",
        bytes.len() as f64 * 8.0 / vf,
        bytes.len(),
        kg,
        seg_s,
        enc_s,
        dec_s
    );
    // The same coder on fixed blocks of gamma_max frames (one group): what segments as long as
    // the paper allows would cost, packet payloads only (the container adds topology + index).
    let fixed = fixed_block_segmentation(v, f, p.gamma_max as usize);
    let (packets, rec) = encode_with_segmentation(&anim, &p, &fixed).unwrap();
    let payload = packets.iter().map(|q| q.data.len()).sum::<usize>() as f64 * 8.0 / vf;
    let fest = paper_rate_estimate(&anim, &p, &fixed).unwrap();
    let container = bytes.len() as f64 * 8.0 / vf;
    let (stp, _) = encode_with_segmentation(&anim, &p, &seg).unwrap();
    let st_payload = stp.iter().map(|q| q.data.len()).sum::<usize>() as f64 * 8.0 / vf;
    println!(
        "  fixed {}-frame blocks: payload {:.3} bpvf (+{:.3} container overhead) KG {:.3}; Eq.9 {:.3} bpvf",
        p.gamma_max,
        payload,
        container - st_payload,
        kg_error(&anim, &rec),
        fest.bpvf
    );
}
