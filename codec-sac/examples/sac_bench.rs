//! Release benchmark of `sac` on the real animations in `/work/shared/data`.
//!
//! ```text
//! cargo build --release -p codec-sac --example sac_bench
//! target/release/examples/sac_bench [--frames N] [--bases 4,16,100] [--no-polar-at 16,100] [--bits 18] \
//!     [--no-stages x] [--dump-laplacian DIR] DATASET...
//! ```
//!
//! `--no-stages` takes a (dummy) value and skips the stage timing; `--dump-laplacian` also runs
//! `examples/eigsh_bench.py` (python3 + scipy) on the dumped matrices in the same run. The
//! baseline `quant-delta` at 8/10/12 bits is measured first for context.
//!
//! `--eigen 100,250 --dump-laplacian DIR` only compares eigensolvers: for
//! each count, sac's manifold harmonics of frame 0 and scipy's `eigsh` in shift-invert mode
//! (ARPACK + SuperLU) on the very same dumped matrices, alternately, `--repeat` times each, and
//! the largest relative difference of the eigenvalues.
//!
//! For each dataset: (1) per-frame time of every stage of the paper's outline (§3.7, the
//! columns of its Table 1) on the closed loop at 100 bases; (2) rate points: stream bytes,
//! bpvf, KG error (computed here: 100·‖A−Â‖_F / ‖A−E(A)‖_F, E(A) the per-frame centroid of the
//! original, f64), refresh frames, encode and decode times, with and without polar
//! decomposition, all measured in this run. `--dump-laplacian DIR` writes the stiffness and
//! mass matrices of frame 0 (Matrix Market) so an independent eigensolver can be timed on
//! exactly the same problem.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use codec_core::{Animation, AnimationCodec, EncoderSetup, Limits, StreamInfo};
use codec_sac::geometry::{self, Svd3};
use codec_sac::poisson::PoissonSystem;
use codec_sac::{coding, harmonics, Sac, SacParams};

#[path = "support/data.rs"]
mod data;

use data::{data_root, kg, load_named, to_v3};

/// Per-frame stage times of paper Table 1, on the closed loop (reference = previous
/// reconstruction), 100 bases, polar decomposition, 18 bits.
fn stage_times(anim: &Animation, bases: usize) -> codec_core::Result<()> {
    let tris: Vec<[usize; 3]> =
        anim.triangles().iter().map(|t| [t[0] as usize, t[1] as usize, t[2] as usize]).collect();
    let n = anim.vertex_count();
    let frame0 = to_v3(anim.frame(0));
    let t = Instant::now();
    let h = harmonics::harmonics(&frame0, &tris, bases)?;
    let t_eigen = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let transfer = harmonics::Transfer::new(&h, &tris);
    let areas = geometry::triangle_areas(&frame0, &tris);
    let analysis = transfer.analysis(&areas)?;
    let t_transfer = t.elapsed().as_secs_f64();
    let (_, pins) = geometry::components(n, &tris);
    let t = Instant::now();
    let poisson = PoissonSystem::new(n, &tris, &pins)?;
    let t_symbolic = t.elapsed().as_secs_f64();
    let mut st = [0.0f64; 6];
    let mut prev = frame0.clone();
    let mut svd = Svd3::new();
    let mut ctx = coding::Contexts::new(2, 18);
    let frames = anim.frame_count();
    let m = tris.len();
    for f in 1..frames {
        let target = to_v3(anim.frame(f));
        let t = Instant::now();
        let grads = geometry::deformation_gradients(&tris, &prev, &target);
        st[0] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let polar: Vec<_> = grads.iter().map(|g| svd.polar(g).expect("svd")).collect();
        st[1] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut fields = vec![vec![0.0; m]; 9];
        for (j, (u, p)) in polar.iter().enumerate() {
            let w = geometry::log_rotation(u);
            let v = [w[0], w[1], w[2], p[0][0] - 1.0, p[1][1] - 1.0, p[2][2] - 1.0, p[0][1], p[0][2], p[1][2]];
            for c in 0..9 {
                fields[c][j] = v[c];
            }
        }
        let coeffs: Vec<Vec<f64>> = fields.iter().map(|f| harmonics::analyze(&analysis, f)).collect();
        st[2] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut codes = Vec::new();
        let mut steps = Vec::new();
        for (lo, hi) in [(0, 3), (3, 9)] {
            let amax = coeffs[lo..hi].iter().flatten().fold(0.0f64, |a, c| a.max(c.abs()));
            let s = coding::step(coding::amplitude(amax), 18);
            codes.push(coeffs[lo..hi].iter().flatten().map(|&c| coding::quantize(c, s, 18)).collect::<Vec<_>>());
            steps.push(s);
        }
        let _bytes = coding::encode(&codes, bases.min(n), &mut ctx);
        st[3] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let l = transfer.bases();
        let mut dec = Vec::new();
        for (g, group) in codes.iter().enumerate() {
            for chan in group.chunks_exact(l) {
                let c: Vec<f64> = chan.iter().map(|&q| q as f64 * steps[g]).collect();
                let mut out = vec![0.0; m];
                transfer.synthesize(&c, &mut out);
                dec.push(out);
            }
        }
        let targets: Vec<_> = (0..m)
            .map(|j| {
                let u = geometry::exp_rotation([dec[0][j], dec[1][j], dec[2][j]]);
                let (a, b, c) = (1.0 + dec[3][j], 1.0 + dec[4][j], 1.0 + dec[5][j]);
                let (d, e, ff) = (dec[6][j], dec[7][j], dec[8][j]);
                geometry::mul(&u, &[[a, d, e], [d, b, ff], [e, ff, c]])
            })
            .collect();
        st[4] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let solved = poisson.solve(&prev, &targets)?;
        st[5] += t.elapsed().as_secs_f64();
        prev = solved;
        // Keep the loop honest about translation like the codec does (centroid match).
        let mut d = [0.0; 3];
        for (p, q) in target.iter().zip(&prev) {
            for k in 0..3 {
                d[k] += (p[k] - q[k]) / n as f64;
            }
        }
        for p in prev.iter_mut() {
            for k in 0..3 {
                p[k] += d[k];
            }
        }
    }
    let pf = (frames - 1).max(1) as f64;
    println!(
        "  stages (s): T2 eigenbasis {:.3} (+ transfer/analysis setup {:.3}, poisson symbolic {:.3}, once per keyframe)",
        t_eigen, t_transfer, t_symbolic
    );
    println!(
        "  per frame (s): T3a grads {:.4}  T3b polar {:.4}  T3c log+analysis {:.4}  T3d quant+AC {:.4}  T3e synth+exp {:.4}  T3f poisson {:.4}  total {:.4}",
        st[0] / pf,
        st[1] / pf,
        st[2] / pf,
        st[3] / pf,
        st[4] / pf,
        st[5] / pf,
        st.iter().sum::<f64>() / pf
    );
    println!(
        "  eigenvalues: first {:.3e}, second {:.3e}, last {:.3e}",
        h.eigenvalues[0],
        h.eigenvalues.get(1).copied().unwrap_or(0.0),
        h.eigenvalues.last().copied().unwrap_or(0.0)
    );
    Ok(())
}

fn rate_point(anim: &Animation, p: SacParams) -> codec_core::Result<()> {
    let ps = p.to_param_set()?;
    let setup = EncoderSetup {
        topology: anim.topology(),
        frame_count: anim.frame_count(),
        frame_rate: anim.frame_rate(),
        want_reconstruction: true,
    };
    let t = Instant::now();
    let mut enc = Sac.new_encoder(&ps, &setup)?;
    let mut packets = enc.push_frames(anim.positions())?;
    packets.extend(enc.finish()?);
    let t_enc = t.elapsed().as_secs_f64();
    let bytes: usize = packets.iter().map(|p| p.packet.data.len()).sum::<usize>() + enc.config().len();
    let refresh = packets.iter().filter(|p| p.packet.data[0] == 2).count();
    let rec: Vec<f32> = packets.iter().flat_map(|p| p.reconstruction.clone().unwrap()).collect();
    let info = StreamInfo {
        fourcc: Sac.fourcc(),
        codec_version: codec_sac::STREAM_VERSION,
        topology: anim.topology().clone(),
        frame_count: anim.frame_count(),
        frame_rate: anim.frame_rate(),
    };
    let t = Instant::now();
    let mut dec = Sac.new_decoder(&info, &enc.config(), &Limits::default())?;
    let t_setup = t.elapsed().as_secs_f64();
    let mut out = Vec::with_capacity(rec.len());
    // Decoder stages: setup (topology, Poisson pattern), the first packet (I-frame + basis +
    // rest factorization), then every later packet.
    let mut per_packet = Vec::with_capacity(packets.len());
    for p in &packets {
        let tp = Instant::now();
        out.extend(dec.decode_packet(&p.packet)?);
        per_packet.push(tp.elapsed().as_secs_f64());
    }
    let t_dec = t.elapsed().as_secs_f64();
    let later = &per_packet[1.min(per_packet.len())..];
    let mut sorted = later.to_vec();
    sorted.sort_by(f64::total_cmp);
    println!(
        "    decoder: setup {:.3}s, first packet (I-frame + basis) {:.3}s, later packets mean {:.2} ms, median {:.2} ms, max {:.2} ms",
        t_setup,
        per_packet.first().copied().unwrap_or(0.0),
        1e3 * later.iter().sum::<f64>() / later.len().max(1) as f64,
        1e3 * sorted.get(sorted.len() / 2).copied().unwrap_or(0.0),
        1e3 * sorted.last().copied().unwrap_or(0.0),
    );
    assert_eq!(out, rec, "decoder output differs from the encoder's reconstruction");
    let bpvf = bytes as f64 * 8.0 / (anim.vertex_count() * anim.frame_count()) as f64;
    println!(
        "  bases {:4} polar {:5}: {:9} bytes  bpvf {:7.4}  KG {:8.4}  refresh {:3}  encode {:7.2}s  decode {:7.2}s",
        p.bases,
        p.polar,
        bytes,
        bpvf,
        kg(anim, &rec),
        refresh,
        t_enc,
        t_dec
    );
    Ok(())
}

/// The baseline `quant-delta` at `bits`, measured in the same run for context.
fn baseline(anim: &Animation, bits: u8) -> codec_core::Result<()> {
    use codec_quant_delta::{QuantDelta, QuantDeltaParams};
    let ps = QuantDeltaParams { bits, ..Default::default() }.to_param_set()?;
    let t = Instant::now();
    let enc = codec_core::encode_animation_fed(&QuantDelta, &ps, anim, true, anim.frame_count())?;
    let dt = t.elapsed().as_secs_f64();
    let rec = enc.reconstruction.expect("asked for");
    let bpvf = enc.bytes.len() as f64 * 8.0 / (anim.vertex_count() * anim.frame_count()) as f64;
    println!(
        "  baseline quant-delta bits {bits:2}: {:9} bytes (container)  bpvf {bpvf:7.4}  KG {:8.4}  encode {dt:7.2}s",
        enc.bytes.len(),
        kg(anim, rec.positions())
    );
    Ok(())
}

fn dump_laplacian(anim: &Animation, dir: &Path, name: &str) -> std::io::Result<()> {
    let tris: Vec<[usize; 3]> =
        anim.triangles().iter().map(|t| [t[0] as usize, t[1] as usize, t[2] as usize]).collect();
    let (trip, mass, _) = harmonics::laplacian(&to_v3(anim.frame(0)), &tris);
    let n = anim.vertex_count();
    let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join(format!("{name}.L.mtx")))?);
    writeln!(f, "%%MatrixMarket matrix coordinate real symmetric\n{n} {n} {}", trip.len())?;
    for t in &trip {
        // Upper triangle as stored; Matrix Market "symmetric" wants the lower one.
        writeln!(f, "{} {} {:.17e}", t.col + 1, t.row + 1, t.val)?;
    }
    let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join(format!("{name}.M.txt")))?);
    for m in mass {
        writeln!(f, "{m:.17e}")?;
    }
    Ok(())
}

/// sac's eigensolver against scipy's `eigsh` (shift-invert) on the same
/// matrices, timed alternately in this run; eigenvalues compared to 1e-6 relative.
fn eigen_comparison(anim: &Animation, name: &str, dir: &Path, counts: &[usize], repeat: usize) {
    let tris: Vec<[usize; 3]> =
        anim.triangles().iter().map(|t| [t[0] as usize, t[1] as usize, t[2] as usize]).collect();
    let frame0 = to_v3(anim.frame(0));
    dump_laplacian(anim, dir, name).expect("dump");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/eigsh_bench.py");
    for &k in counts {
        let (mut ours, mut theirs) = (Vec::new(), Vec::new());
        let mut values = Vec::new();
        for _ in 0..repeat.max(1) {
            let t = Instant::now();
            let h = harmonics::harmonics_by_component(&frame0, &tris, k).expect("harmonics");
            ours.push(t.elapsed().as_secs_f64());
            values = h.eigenvalues;
            let t = Instant::now();
            let out = std::process::Command::new("python3").arg(&script).arg(dir).arg(name).arg(k.to_string()).output();
            let wall = t.elapsed().as_secs_f64();
            match out {
                Ok(o) if o.status.success() => {
                    let text = String::from_utf8_lossy(&o.stdout);
                    // The script's own solve time (excludes python start-up and matrix reading).
                    let solve = text
                        .split("):")
                        .nth(1)
                        .and_then(|r| r.split_whitespace().next())
                        .and_then(|x| x.parse::<f64>().ok())
                        .unwrap_or(wall);
                    theirs.push(solve);
                }
                Ok(o) => {
                    println!("  scipy failed: {}", String::from_utf8_lossy(&o.stderr));
                    return;
                }
                Err(e) => {
                    println!("  scipy comparison skipped: {e}");
                    return;
                }
            }
        }
        let reference: Vec<f64> = std::fs::read_to_string(dir.join(format!("{name}.{k}.eig.txt")))
            .expect("eigenvalues")
            .lines()
            .filter_map(|l| l.trim().parse().ok())
            .collect();
        let scale = reference.last().copied().unwrap_or(1.0).abs().max(f64::MIN_POSITIVE);
        let worst = values
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1e-6 * scale))
            .fold(0.0f64, f64::max);
        let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        println!(
            "  eigen k={k}: sac {:.3} s (runs {:?}), scipy eigsh shift-invert {:.3} s (runs {:?}); ratio scipy/sac {:.2}; \
             max relative eigenvalue difference {:.2e} over {} values",
            best(&ours),
            ours.iter().map(|x| (x * 1e3).round() / 1e3).collect::<Vec<_>>(),
            best(&theirs),
            theirs.iter().map(|x| (x * 1e3).round() / 1e3).collect::<Vec<_>>(),
            best(&theirs) / best(&ours),
            worst,
            values.len().min(reference.len())
        );
    }
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut take = |flag: &str| -> Option<String> {
        let i = args.iter().position(|a| a == flag)?;
        let v = args.get(i + 1).cloned();
        args.drain(i..(i + 2).min(args.len()));
        v
    };
    let max_frames: usize = take("--frames").and_then(|v| v.parse().ok()).unwrap_or(usize::MAX);
    let bases: Vec<u32> = take("--bases")
        .map(|v| v.split(',').filter_map(|x| x.parse().ok()).collect())
        .unwrap_or_else(|| vec![4, 16, 50, 100, 200]);
    let dump = take("--dump-laplacian");
    let eigen: Option<Vec<usize>> = take("--eigen").map(|v| v.split(',').filter_map(|x| x.parse().ok()).collect());
    let repeat: usize = take("--repeat").and_then(|v| v.parse().ok()).unwrap_or(2);
    let bits: u8 = take("--bits").and_then(|v| v.parse().ok()).unwrap_or(18);
    let skip_stages = take("--no-stages").is_some();
    let refactor: u8 = take("--refactor").and_then(|v| v.parse().ok()).unwrap_or(SacParams::default().refactor);
    let no_polar = take("--no-polar-at").map(|v| v.split(',').filter_map(|x| x.parse().ok()).collect::<Vec<u32>>());
    let names = if args.is_empty() { vec!["horse-gallop".to_string()] } else { args };
    let Some(root) = data_root() else { return };
    for name in names {
        let Some(anim) = load_named(&root, &name, max_frames) else { continue };
        let (n, f) = (anim.vertex_count(), anim.frame_count());
        println!("{name}: {n} vertices, {} triangles, {f} frames", anim.topology().triangle_count());
        if let Some(counts) = &eigen {
            let dir = dump.clone().unwrap_or_else(|| std::env::temp_dir().to_string_lossy().into_owned());
            eigen_comparison(&anim, &name, Path::new(&dir), counts, repeat);
            continue;
        }
        if let Some(d) = &dump {
            dump_laplacian(&anim, Path::new(d), &name).expect("dump");
            // The independent solver, timed in this same run (needs python3 + scipy).
            let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/eigsh_bench.py");
            match std::process::Command::new("python3").arg(&script).arg(d).arg(&name).arg("100").output() {
                Ok(o) => print!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)),
                Err(e) => println!("  scipy comparison skipped: {e}"),
            }
        }
        if skip_stages {
        } else if let Err(e) = stage_times(&anim, 100) {
            println!("  stage timing failed: {e}");
        }
        for qb in [8u8, 10, 12] {
            if let Err(e) = baseline(&anim, qb) {
                println!("  baseline: {e}");
            }
        }
        for &b in &bases {
            if let Err(e) = rate_point(&anim, SacParams { bases: b, bits, refactor, ..Default::default() }) {
                println!("  bases {b}: {e}");
            }
        }
        for &b in no_polar.as_deref().unwrap_or(&[16, 100]) {
            if let Err(e) =
                rate_point(&anim, SacParams { bases: b, bits, polar: false, refactor, ..Default::default() })
            {
                println!("  bases {b} no polar: {e}");
            }
        }
    }
}
