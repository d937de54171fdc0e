//! Release benchmark of `hosvd` on real animations (read straight from PC2 + OBJ).
//!
//! ```text
//! cargo build --release -p codec-hosvd --example hosvd_bench
//! target/release/examples/hosvd_bench [DATA_DIR] [NAME ...]     # default ../shared/data samba horse-gallop
//! ```
//!
//! Per animation, all in one run:
//! 1. rate-distortion: strategy ∈ {diagonal, iterative} × rigid ∈ {on, off} × ss ladder —
//!    real container bytes (bpvf), Eq. 12 bytes (d_s = 4), KG, MSE, max vertex error, timings;
//!    the `quant-delta` baseline (12 bits) encoded and decoded in the same run for time scale;
//! 2. HO-SVD vs PCA at equal size (unquantized, the paper's comparison, §2.8/Fig. 10–11);
//! 3. HOOI at equal ranks (unquantized error and quantized stream);
//! 4. temporal blocks.
//!
//! With `--speed` as the first argument only the speed check runs: per animation
//! and `ss`, encode and decode times of the paper coding and the toolkit coding (stream version
//! 2's default) and a memcpy of the decoded frames, all in one run, as ratios:
//! `target/release/examples/hosvd_bench --speed ../shared/data samba`.
//!
//! With `--sections DATA_DIR NAME KEY=VALUE…` one encode with those parameters prints where
//! the stream's bytes go (topology, coded `U1` / `U3` / core, coded transforms, side data)
//! and the KG: `target/release/examples/hosvd_bench --sections ../shared/data horse-gallop ss=0.9`.
//!
//! KG = 100·‖A−Â‖_F / ‖A−E(A)‖_F with E(A) the per-frame centroid of the original (f64).
//! MSE = mean over vertices and frames of the squared vertex distance (§2.7).

use std::path::{Path, PathBuf};
use std::time::Instant;

use codec_core::container::ContainerWriter;
use codec_core::{decode_animation, encode_animation_fed, Animation, CodecRegistry, FrameEncoder, Limits, Topology};
use codec_core::{AnimationCodec, ParamChoice};
use codec_hosvd::{
    truncated_reconstruction, truncated_reconstruction_with, BlockStats, Hosvd, HosvdEncoder, HosvdParams, Strategy,
};
use codec_quant_delta::{QuantDelta, QuantDeltaParams};
use faer::Mat;

fn read_pc2(path: &Path) -> Result<(usize, usize, Vec<f32>), String> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if b.len() < 32 || &b[..12] != b"POINTCACHE2\0" {
        return Err(format!("{}: not a PC2 file", path.display()));
    }
    let i32_at = |o: usize| i32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let (k, f) = (i32_at(16) as usize, i32_at(28) as usize);
    let need = 32 + k * f * 12;
    if b.len() < need {
        return Err(format!("{}: truncated ({} < {need} bytes)", path.display(), b.len()));
    }
    let pos = b[32..need].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    Ok((k, f, pos))
}

fn read_obj_triangles(path: &Path, k: usize) -> Result<Vec<[u32; 3]>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut tris = Vec::new();
    for line in text.lines().filter(|l| l.starts_with("f ")) {
        let idx: Vec<u32> = line[2..]
            .split_whitespace()
            .map(|tok| {
                let i: i64 = tok.split('/').next().unwrap().parse().map_err(|_| format!("bad face '{line}'"))?;
                Ok(if i < 0 { (k as i64 + i) as u32 } else { (i - 1) as u32 })
            })
            .collect::<Result<_, String>>()?;
        for w in 1..idx.len().saturating_sub(1) {
            tris.push([idx[0], idx[w], idx[w + 1]]);
        }
    }
    Ok(tris)
}

fn load(dir: &Path, name: &str) -> Result<Animation, String> {
    let (k, _f, pos) = read_pc2(&dir.join(name).join(format!("{name}.pc2")))?;
    let tris = read_obj_triangles(&dir.join(name).join(format!("{name}.obj")), k)?;
    let topo = Topology::new(k, tris).map_err(|e| e.to_string())?;
    Animation::new(topo, pos, 30.0).map_err(|e| e.to_string())
}

struct Errors {
    kg: f64,
    mse: f64,
    max_vertex: f64,
}

fn errors(a: &Animation, rec: &[f32]) -> Errors {
    let k = a.vertex_count();
    let (mut num, mut den, mut maxv) = (0.0f64, 0.0f64, 0.0f64);
    for (t, frame) in a.frames().enumerate() {
        let mut c = [0.0f64; 3];
        for p in frame.chunks_exact(3) {
            for j in 0..3 {
                c[j] += p[j] as f64;
            }
        }
        let c = c.map(|x| x / k as f64);
        for (i, p) in frame.chunks_exact(3).enumerate() {
            let r = &rec[(t * k + i) * 3..(t * k + i) * 3 + 3];
            let mut d2 = 0.0;
            for j in 0..3 {
                d2 += (p[j] as f64 - r[j] as f64).powi(2);
                den += (p[j] as f64 - c[j]).powi(2);
            }
            num += d2;
            maxv = maxv.max(d2.sqrt());
        }
    }
    Errors { kg: 100.0 * (num / den).sqrt(), mse: num / (k * a.frame_count()) as f64, max_vertex: maxv }
}

struct Run {
    bytes: usize,
    rec: Vec<f32>,
    stats: Vec<BlockStats>,
    enc_s: f64,
    dec_s: f64,
}

/// Drives the public encoder into a container (what `StreamEncoder` writes: the topology in
/// canonical order, given to both the encoder and the container) so the per-block statistics
/// are available, then decodes through the registry.
fn run(a: &Animation, p: &HosvdParams) -> Run {
    let t0 = Instant::now();
    let canonical = codec_core::connectivity::canonical_order(a.topology());
    let a = &Animation::new(canonical, a.positions().to_vec(), a.frame_rate()).expect("same animation");
    let mut enc = HosvdEncoder::new(*p, a.topology(), a.frame_count(), true);
    let mut w = ContainerWriter::new(
        Vec::new(),
        Hosvd.fourcc(),
        Hosvd.stream_version(),
        a.topology(),
        a.frame_count(),
        a.frame_rate(),
        &enc.config(),
    )
    .unwrap();
    let mut rec = Vec::new();
    for pk in enc.push_frames(a.positions()).unwrap().into_iter().chain(enc.finish().unwrap()) {
        w.write_packet(&pk.packet).unwrap();
        rec.extend(pk.reconstruction.unwrap());
    }
    let bytes = w.finish().unwrap();
    let enc_s = t0.elapsed().as_secs_f64();
    let reg = CodecRegistry::new(vec![Box::new(Hosvd)]).unwrap();
    let t1 = Instant::now();
    let dec = decode_animation(&bytes, &reg, Limits::default()).unwrap();
    let dec_s = t1.elapsed().as_secs_f64();
    assert_eq!(dec.positions(), &rec[..], "decoder disagrees with the encoder's reconstruction");
    Run { bytes: bytes.len(), rec, stats: enc.stats().to_vec(), enc_s, dec_s }
}

/// One encode: where the container's bytes go, in bytes and bits per vertex per frame.
fn sections(a: &Animation, p: &HosvdParams) {
    let r = run(a, p);
    let vf = (a.vertex_count() * a.frame_count()) as f64;
    let bpvf = |b: f64| 8.0 * b / vf;
    let s = r.stats.iter().fold(codec_hosvd::Sections::default(), |t, b| codec_hosvd::Sections {
        u1: t.u1 + b.sections.u1,
        u1_lead: t.u1_lead + b.sections.u1_lead,
        u3: t.u3 + b.sections.u3,
        core: t.core + b.sections.core,
        motion: t.motion + b.sections.motion,
        other: t.other + b.sections.other,
    });
    let payload: usize = r.stats.iter().map(|b| b.payload_bytes).sum();
    let rest = r.bytes - payload;
    let e = errors(a, &r.rec);
    let ranks: Vec<String> = r.stats.iter().map(|b| format!("({}, {})", b.v, b.f)).collect();
    println!("ranks {}  bytes {}  bpvf {:.4}  KG {:.4}", ranks.join(" "), r.bytes, bpvf(r.bytes as f64), e.kg);
    for (what, b) in [
        ("container (topology, header, index)", rest as f64),
        ("U1 columns", s.u1),
        ("of which the first three", s.u1_lead),
        ("U3 columns", s.u3),
        ("core", s.core),
        ("motion", s.motion as f64),
        ("side, header, levels, modes, centre", s.other as f64),
    ] {
        println!("{what:>38}: {b:>9.0} B  {:>6.4} bpvf  {:>5.1} %", bpvf(b), 100.0 * b / r.bytes as f64);
    }
}

/// PCA of §2.8 ([AM00]): frames as F vectors of 3K, centred (the mean shape is stored too),
/// `p` components. Error from the trailing eigenvalues of the centred F×F Gram matrix.
fn pca_error2(a: &Animation, p: usize) -> f64 {
    let (k, f) = (a.vertex_count(), a.frame_count());
    let n = 3 * k;
    let mut mean = vec![0.0f64; n];
    for fr in a.frames() {
        for (m, &x) in mean.iter_mut().zip(fr) {
            *m += x as f64 / f as f64;
        }
    }
    let x = Mat::from_fn(f, n, |t, c| a.positions()[t * n + c] as f64 - mean[c]);
    let g = &x * x.transpose();
    let ev = g.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    // Ascending: the trailing f − p eigenvalues are the lost energy.
    ev[..f.saturating_sub(p)].iter().map(|v| v.max(0.0)).sum()
}

fn centred_energy(a: &Animation) -> f64 {
    let k = a.vertex_count();
    let mut den = 0.0;
    for frame in a.frames() {
        let mut c = [0.0f64; 3];
        for p in frame.chunks_exact(3) {
            for j in 0..3 {
                c[j] += p[j] as f64 / k as f64;
            }
        }
        for p in frame.chunks_exact(3) {
            for j in 0..3 {
                den += (p[j] as f64 - c[j]).powi(2);
            }
        }
    }
    den
}

/// Best of `reps` timings of `f`.
fn best_of(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The speed check: decode speed as a share of memcpy speed of the decoded output, and
/// the toolkit coding's encode time relative to the paper coding's, measured in one run.
fn speed(a: &Animation, name: &str) {
    use codec_hosvd::Coding;
    let out_bytes = a.positions().len() * 4;
    println!("\n## {name}: speed (best of 3; decoded output {:.1} MB)\n", out_bytes as f64 / 1e6);
    println!(
        "| ss | coding | (v, f) | bpvf | KG | encode s | decode s | memcpy s | decode speed / memcpy speed | \
         encode / paper encode | reconstruction s: plain loops / blocked 1 thread / blocked all threads |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let reg = CodecRegistry::new(vec![Box::new(Hosvd)]).unwrap();
    for ss in [0.95, 0.9, 0.8] {
        let mut paper_enc = 0.0;
        for coding in [Coding::Paper, Coding::Toolkit] {
            let p = HosvdParams { ss, coding, ..Default::default() };
            let ps = p.to_param_set().unwrap();
            let mut bytes = Vec::new();
            let enc_s =
                best_of(3, || bytes = encode_animation_fed(&Hosvd, &ps, a, false, a.frame_count()).unwrap().bytes);
            let mut dec = None;
            let dec_s = best_of(3, || dec = Some(decode_animation(&bytes, &reg, Limits::default()).unwrap()));
            let dec = dec.unwrap();
            let mut copy = vec![0.0f32; dec.positions().len()];
            let memcpy_s = best_of(5, || {
                copy.copy_from_slice(std::hint::black_box(dec.positions()));
                std::hint::black_box(&copy);
            });
            if coding == Coding::Paper {
                paper_enc = enc_s;
            }
            let e = errors(a, dec.positions());
            // The reconstruction alone, on a model of the stream's dimensions (values do not
            // change the time): the decoder's arithmetic without the entropy decoding.
            let mut enc = HosvdEncoder::new(p, a.topology(), a.frame_count(), false);
            enc.push_frames(a.positions()).unwrap();
            enc.finish().unwrap();
            let st = enc.stats()[0];
            let model = dummy_model(a.vertex_count(), a.frame_count(), st.v, st.f);
            let plain_s = best_of(2, || {
                std::hint::black_box(codec_hosvd::tensor::reconstruct_reference(&model));
            });
            let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let fast1_s = best_of(3, || {
                one.install(|| std::hint::black_box(codec_hosvd::tensor::reconstruct(&model)));
            });
            let fast_s = best_of(3, || {
                std::hint::black_box(codec_hosvd::tensor::reconstruct(&model));
            });
            println!(
                "| {ss} | {coding:?} | ({}, {}) | {:.3} | {:.3} | {enc_s:.3} | {dec_s:.4} | {memcpy_s:.5} | {:.2}% | {:.2} | \
                 {plain_s:.4} / {fast1_s:.4} / {fast_s:.4} |",
                st.v,
                st.f,
                bytes.len() as f64 * 8.0 / (a.vertex_count() * a.frame_count()) as f64,
                e.kg,
                100.0 * memcpy_s / dec_s,
                enc_s / paper_enc,
            );
        }
    }
}

fn dummy_model(k: usize, frames: usize, v: usize, f: usize) -> codec_hosvd::tensor::Model {
    let val = |i: usize| ((i as f64) * 0.618_034).fract() - 0.5;
    codec_hosvd::tensor::Model {
        k,
        frames,
        v,
        f,
        u1: (0..k * v).map(val).collect(),
        u2: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        u3: (0..frames * f).map(val).collect(),
        core: (0..v * 3 * f).map(val).collect(),
        transforms: vec![
            codec_hosvd::tensor::Affine { m: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], c: [0.0; 3] };
            frames
        ],
    }
}

fn main() {
    let mut args = std::env::args().skip(1).peekable();
    if args.peek().is_some_and(|a| a == "--kernel") {
        // Reconstruction alone at samba's ss=0.9 dimensions (K, F, v, f) = (9971, 175, 50, 70).
        let model = dummy_model(9971, 175, 50, 70);
        let plain_s = best_of(2, || {
            std::hint::black_box(codec_hosvd::tensor::reconstruct_reference(&model));
        });
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let fast1_s = best_of(5, || {
            one.install(|| std::hint::black_box(codec_hosvd::tensor::reconstruct(&model)));
        });
        let fast_s = best_of(5, || {
            std::hint::black_box(codec_hosvd::tensor::reconstruct(&model));
        });
        println!(
            "reconstruction s: plain {plain_s:.4} / blocked 1 thread {fast1_s:.4} / blocked all threads {fast_s:.4}"
        );
        return;
    }
    if args.peek().is_some_and(|a| a == "--sections") {
        args.next();
        let dir = PathBuf::from(args.next().expect("DATA_DIR"));
        let name = args.next().expect("NAME");
        let specs = HosvdParams::specs();
        let mut set = codec_core::params::ParamSet::defaults("hosvd", &specs);
        for kv in args {
            let (k, v) = kv.split_once('=').expect("KEY=VALUE");
            let spec = codec_core::params::find_spec("hosvd", &specs, k).unwrap_or_else(|e| panic!("{e}"));
            let value = spec.parse("hosvd", v).unwrap_or_else(|e| panic!("{e}"));
            set.set(&specs, k, value).unwrap_or_else(|e| panic!("{e}"));
        }
        let p = HosvdParams::from_param_set(&set).unwrap_or_else(|e| panic!("{e}"));
        let a = load(&dir, &name).unwrap_or_else(|e| panic!("{e}"));
        sections(&a, &p);
        return;
    }
    let speed_only = args.peek().is_some_and(|a| a == "--speed");
    if speed_only {
        args.next();
    }
    let dir = PathBuf::from(args.next().unwrap_or_else(|| "../shared/data".into()));
    let mut names: Vec<String> = args.collect();
    if names.is_empty() {
        names = vec!["samba".into(), "horse-gallop".into()];
    }
    if !dir.exists() {
        println!("SKIP: {} not found", dir.display());
        return;
    }
    let ladder = [0.99, 0.98, 0.95, 0.9, 0.8];
    for name in &names {
        let a = match load(&dir, name) {
            Ok(a) => a,
            Err(e) => {
                println!("SKIP {name}: {e}");
                continue;
            }
        };
        if speed_only {
            speed(&a, name);
            continue;
        }
        let (k, f) = (a.vertex_count(), a.frame_count());
        let raw = (k * f * 12) as f64;
        println!("\n## {name}: {k} vertices, {f} frames, {} triangles\n", a.topology().triangle_count());

        // Baseline in the same run, for time scale.
        let qd = QuantDeltaParams { bits: 12, ..Default::default() }.to_param_set().unwrap();
        let t0 = Instant::now();
        let enc = encode_animation_fed(&QuantDelta, &qd, &a, false, f).unwrap();
        let qd_enc = t0.elapsed().as_secs_f64();
        let reg = CodecRegistry::new(vec![Box::new(QuantDelta)]).unwrap();
        let t1 = Instant::now();
        let dec = decode_animation(&enc.bytes, &reg, Limits::default()).unwrap();
        let qd_dec = t1.elapsed().as_secs_f64();
        let e = errors(&a, dec.positions());
        println!(
            "baseline quant-delta bits=12: bpvf {:.3}, KG {:.4}, encode {:.3} s, decode {:.3} s\n",
            enc.bytes.len() as f64 * 8.0 / (k * f) as f64,
            e.kg,
            qd_enc,
            qd_dec
        );

        println!("### Rate-distortion (quant=0.25, level=19, whole sequence)\n");
        println!("| strategy | motion | ss | v | f | evals | Eq.12 bytes | stream bytes | bpvf | ratio | KG | MSE | max vertex err | trunc-only KG | enc s (decomp/search/code) | dec s |");
        println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        let den = centred_energy(&a);
        for strategy in [Strategy::Diagonal, Strategy::Iterative] {
            for (rigid, affine, motion) in [(true, true, "affine"), (true, false, "rotation"), (false, true, "off")] {
                for &ss in &ladder {
                    let p = HosvdParams { ss, strategy, rigid, affine, ..Default::default() };
                    let r = run(&a, &p);
                    let s = &r.stats[0];
                    let e = errors(&a, &r.rec);
                    // Truncation-only error, unquantized, in original coordinates.
                    let (unq, _) = truncated_reconstruction_with(a.positions(), k, s.v, s.f, rigid, affine, 0).unwrap();
                    let eu = errors(&a, &unq);
                    println!(
                        "| {} | {motion} | {ss} | {} | {} | {} | {} | {} | {:.3} | {:.1} | {:.4} | {:.3e} | {:.3e} | {:.4} | {:.2} ({:.2}/{:.3}/{:.2}) | {:.3} |",
                        strategy.name(),
                        s.v,
                        s.f,
                        s.evaluations,
                        s.paper_numbers * 4,
                        r.bytes,
                        r.bytes as f64 * 8.0 / (k * f) as f64,
                        raw / r.bytes as f64,
                        e.kg,
                        e.mse,
                        e.max_vertex,
                        eu.kg,
                        r.enc_s,
                        s.decompose_seconds,
                        s.search_seconds,
                        s.code_seconds,
                        r.dec_s
                    );
                }
            }
        }

        println!("\n### HO-SVD vs PCA at equal size (unquantized; numbers = Eq. 12 floats incl. 12F transforms for HO-SVD, (3K+F)p + 3K for PCA)\n");
        println!(
            "| ss | HO-SVD (v,f) exhaustive, affine | HO-SVD KG affine | rotation | no motion removal | PCA p | PCA KG | HO-SVD wins |"
        );
        println!("|---|---|---|---|---|---|---|---|");
        for &ss in &ladder {
            let p = HosvdParams { ss, strategy: Strategy::Exhaustive, rigid: true, ..Default::default() };
            let s = codec_hosvd::encode_block(a.positions(), k, &p, &codec_hosvd::mesh_graph(&p, a.topology()), false)
                .unwrap()
                .stats;
            let (unq, _) = truncated_reconstruction(a.positions(), k, s.v, s.f, true, 0).unwrap();
            let eh = errors(&a, &unq).kg;
            let pn = HosvdParams { rigid: false, ..p };
            let sn =
                codec_hosvd::encode_block(a.positions(), k, &pn, &codec_hosvd::mesh_graph(&pn, a.topology()), false)
                    .unwrap()
                    .stats;
            let (unqn, _) = truncated_reconstruction(a.positions(), k, sn.v, sn.f, false, 0).unwrap();
            let ehn = errors(&a, &unqn).kg;
            let pr = HosvdParams { affine: false, ..p };
            let sr =
                codec_hosvd::encode_block(a.positions(), k, &pr, &codec_hosvd::mesh_graph(&pr, a.topology()), false)
                    .unwrap()
                    .stats;
            let (unqr, _) = truncated_reconstruction_with(a.positions(), k, sr.v, sr.f, true, false, 0).unwrap();
            let ehr = errors(&a, &unqr).kg;
            let budget = (1.0 - ss) * (3 * k * f) as f64;
            let pc = ((budget - (3 * k) as f64) / (3 * k + f) as f64).floor().max(0.0) as usize;
            let ep = if pc == 0 { 100.0 } else { 100.0 * (pca_error2(&a, pc.min(f)) / den).sqrt() };
            println!(
                "| {ss} | ({}, {}) | {eh:.4} | {ehr:.4} | {ehn:.4} | {pc} | {ep:.4} | {} |",
                s.v,
                s.f,
                if eh.max(ehn).max(ehr) < ep {
                    "yes (all three)"
                } else if eh.min(ehn).min(ehr) < ep {
                    "partly"
                } else {
                    "no"
                }
            );
        }

        println!("\n### HOOI at equal ranks (iterative choice at each ss, rigid)\n");
        println!("| ss | v | f | HO-SVD KG (unq) | HOOI-3 KG (unq) | stream bytes hooi=0 | KG | stream bytes hooi=2 | KG | HOOI time s |");
        println!("|---|---|---|---|---|---|---|---|---|---|");
        for &ss in &[0.98, 0.95, 0.9] {
            let p0 = HosvdParams { ss, ..Default::default() };
            let r0 = run(&a, &p0);
            let s = r0.stats[0];
            let (u0, _) = truncated_reconstruction(a.positions(), k, s.v, s.f, true, 0).unwrap();
            let (u3, _) = truncated_reconstruction(a.positions(), k, s.v, s.f, true, 3).unwrap();
            let r2 = run(&a, &HosvdParams { hooi_iters: 2, ..p0 });
            println!(
                "| {ss} | {} | {} | {:.4} | {:.4} | {} | {:.4} | {} | {:.4} | {:.2} |",
                s.v,
                s.f,
                errors(&a, &u0).kg,
                errors(&a, &u3).kg,
                r0.bytes,
                errors(&a, &r0.rec).kg,
                r2.bytes,
                errors(&a, &r2.rec).kg,
                r2.stats[0].hooi_seconds
            );
        }

        println!("\n### Temporal blocks (iterative, rigid, ss = 0.95)\n");
        println!("| block | packets | stream bytes | bpvf | KG | enc s | dec s |");
        println!("|---|---|---|---|---|---|---|");
        for block in [0u32, 64, 32] {
            let r = run(&a, &HosvdParams { ss: 0.95, block, ..Default::default() });
            println!(
                "| {block} | {} | {} | {:.3} | {:.4} | {:.2} | {:.3} |",
                r.stats.len(),
                r.bytes,
                r.bytes as f64 * 8.0 / (k * f) as f64,
                errors(&a, &r.rec).kg,
                r.enc_s,
                r.dec_s
            );
        }
    }
}
