//! Real-data benchmark of `stseg` against the same PCA on fixed-size temporal blocks (the
//! paper's "Adapted PCA", §5.3.1), with the block size set to stseg's mean segment length.
//!
//! Build once and run the binary directly (frees the cargo lock):
//! `cargo build --release -p codec-stseg --example stseg_bench && target/release/examples/stseg_bench [NAME...]`
//!
//! Prints, per data set and ω: bpvf (whole container for stseg; packet payloads for both
//! codings so they compare like for like), KG error (computed here in f64), encode and decode
//! seconds. Skips with a message when `../shared/data` is absent.

use std::path::Path;
use std::time::Instant;

use codec_core::{decode_animation, encode_animation, Animation, CodecRegistry, Limits, Topology};
use codec_stseg::{encode_with_segmentation, fixed_block_segmentation, segment_animation, Stseg, StsegParams};

#[path = "support/data.rs"]
mod data;

use data::{kg_error, read_obj_triangles, read_pc2};

fn interpolate(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let mut pts = points.to_vec();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts.windows(2).find(|w| w[0].0 <= x && x <= w[1].0).map(|w| {
        let t = if w[1].0 > w[0].0 { (x - w[0].0) / (w[1].0 - w[0].0) } else { 0.0 };
        w[0].1 + t * (w[1].1 - w[0].1)
    })
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    if !root.exists() {
        println!("SKIP: {} not found", root.display());
        return;
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    let names: Vec<&str> = if args.is_empty() {
        vec!["samba", "chicken-crossing", "pcow"]
    } else {
        args.iter().map(|s| s.as_str()).collect()
    };
    let omegas: Vec<f64> = match std::env::var("STSEG_OMEGAS") {
        Ok(list) => list.split(',').filter_map(|x| x.parse().ok()).collect(),
        Err(_) => vec![0.95, 0.99, 0.995, 0.999, 0.9995, 0.9999],
    };
    let registry = CodecRegistry::new(vec![Box::new(Stseg)]).unwrap();
    for name in names {
        let dir = root.join(name);
        let (v, f, pos) = match read_pc2(&dir.join(format!("{name}.pc2"))) {
            Ok(x) => x,
            Err(e) => {
                println!("SKIP {name}: {e}");
                continue;
            }
        };
        let tris = read_obj_triangles(&dir.join(format!("{name}.obj"))).unwrap();
        let anim = Animation::new(Topology::new(v, tris).unwrap(), pos, 30.0).unwrap();
        let vf = (v * f) as f64;
        // Optional overrides for parameter studies: STSEG_CODING, STSEG_OMEGA_SEG, STSEG_GAMMA_MAX, STSEG_GAMMA_INIT.
        let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
        // The paper's coding unless STSEG_CODING=toolkit (the README's Fig. 8 table is the paper's).
        let coding = match std::env::var("STSEG_CODING").as_deref() {
            Ok("toolkit") => codec_stseg::Coding::Toolkit,
            _ => codec_stseg::Coding::Paper,
        };
        let mut base = StsegParams { coding, ..StsegParams::default() };
        if let Some(x) = env("STSEG_OMEGA_SEG") {
            base.omega_seg = x;
        }
        if let Some(x) = env("STSEG_GAMMA_MAX") {
            base.gamma_max = x as u32;
        }
        if let Some(x) = env("STSEG_GAMMA_INIT") {
            base.gamma_init = x as u32;
        }
        base.validate().unwrap();
        let t0 = Instant::now();
        let seg = segment_animation(&anim, &base).unwrap();
        let seg_s = t0.elapsed().as_secs_f64();
        let mean_len = f as f64 / seg.segments.len() as f64;
        let block = mean_len.round().max(1.0) as usize;
        let groups: Vec<usize> = seg.segments.iter().map(|s| s.group_count).collect();
        println!("== {name}: V={v} F={f}; segmentation {seg_s:.2}s, {} segments (mean {mean_len:.1} frames), boundaries {:?}, detected {:?}, groups {:?}",
            seg.segments.len(), seg.boundaries(), seg.detected_boundaries(), groups);
        println!("   adapted-PCA block size {block}");
        println!(
            "   {:>8} | {:>9} {:>9} {:>8} {:>8} {:>8} | {:>9} {:>8} {:>8} | {:>12}",
            "omega", "stseg_bpvf", "payload", "KG", "enc_s", "dec_s", "blk_bpvf", "KG", "enc_s", "blk KG@bpvf"
        );
        println!("   (last columns: fixed blocks of gamma_max frames: bpvf, KG, and its KG at stseg's payload bpvf)");
        let mut st_pts = Vec::new();
        let mut blk_pts = Vec::new();
        let mut rows = Vec::new();
        let mut blk50_pts = Vec::new();
        for &omega in &omegas {
            let p = StsegParams { omega, ..base };
            let ps = p.to_param_set().unwrap();
            let t = Instant::now();
            let bytes = encode_animation(&Stseg, &ps, &anim).unwrap();
            let enc_s = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let dec = decode_animation(&bytes, &registry, Limits::default()).unwrap();
            let dec_s = t.elapsed().as_secs_f64();
            let kg = kg_error(&anim, dec.positions());
            let (packets, _) = encode_with_segmentation(&anim, &p, &seg).unwrap();
            let payload = packets.iter().map(|q| q.data.len()).sum::<usize>() as f64 * 8.0 / vf;
            let fixed = fixed_block_segmentation(v, f, block);
            let fixed50 = fixed_block_segmentation(v, f, base.gamma_max as usize);
            let (bp50, brec50) = encode_with_segmentation(&anim, &p, &fixed50).unwrap();
            let b50 = (bp50.iter().map(|q| q.data.len()).sum::<usize>() as f64 * 8.0 / vf, kg_error(&anim, &brec50));
            blk50_pts.push(b50);
            let t = Instant::now();
            let (bp, brec) = encode_with_segmentation(&anim, &p, &fixed).unwrap();
            let benc_s = t.elapsed().as_secs_f64();
            let bbpvf = bp.iter().map(|q| q.data.len()).sum::<usize>() as f64 * 8.0 / vf;
            let bkg = kg_error(&anim, &brec);
            st_pts.push((payload, kg));
            blk_pts.push((bbpvf, bkg));
            rows.push((omega, bytes.len() as f64 * 8.0 / vf, payload, kg, enc_s, dec_s, bbpvf, bkg, benc_s));
        }
        for (r, b50) in rows.into_iter().zip(&blk50_pts) {
            let at = interpolate(&blk_pts, r.2).map_or("-".to_string(), |x| format!("{x:.3}"));
            let at50 = interpolate(&blk50_pts, r.2).map_or("-".to_string(), |x| format!("{x:.3}"));
            println!("   {:>8} | {:>9.3} {:>9.3} {:>8.3} {:>8.2} {:>8.3} | {:>9.3} {:>8.3} {:>8.2} | {:>12} | {:>7.3} {:>7.3} {:>8}",
                r.0, r.1, r.2, r.3, r.4, r.5, r.6, r.7, r.8, at, b50.0, b50.1, at50);
        }
    }
}
