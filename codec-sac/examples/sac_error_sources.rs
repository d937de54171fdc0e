//! Where `sac`'s error floor comes from: the KG error of one animation at
//! one `bases` under pipelines that switch the error sources on one at a time.
//!
//! ```text
//! cargo build --release -p codec-sac --example sac_error_sources
//! target/release/examples/sac_error_sources [--bases 100] [--bits 18] [--frames N] DATASET...
//! ```
//!
//! Rows (all with the basis of frame 0, polar decomposition, per-component translation as in
//! the codec):
//! 1. *Poisson only*: exact gradients of the original frame against the original previous
//!    frame, through the Poisson solve (paper Eq. 12). Conditioning / representation loss.
//! 2. *+ truncation, open loop*: the rotation/stretch fields projected on `bases` harmonics
//!    (Eq. 8–11), no quantization, reference = the original previous frame (no accumulation).
//! 3. *+ quantization, open loop*: row 2 with the codec's `bits`-bit descriptor quantization.
//! 4. *truncation, closed loop*: row 2 with reference = the previous reconstruction (§3.1).
//! 5. *truncation + quantization, closed loop*: the codec's P-frame pipeline without the guard.
//! 6. *the codec*: `Sac` at these parameters (I-frame quantization, guard, refresh frames).
//!
//! KG = 100·‖A−Â‖_F / ‖A−E(A)‖_F as in `sac_bench`; frame 0 is the original in rows 1–5.

use std::time::Instant;

use codec_core::{Animation, AnimationCodec, EncoderSetup};
use codec_sac::geometry::{self, Svd3, M3, V3};
use codec_sac::harmonics::{self, Transfer};
use codec_sac::poisson::PoissonSystem;
use codec_sac::{coding, Sac, SacParams};
use faer::Mat;

#[path = "support/data.rs"]
mod data;

use data::{data_root, kg, load_named, to_v3};

#[derive(Clone, Copy)]
enum Spectral {
    /// Exact gradients, no projection.
    Exact,
    /// Projected on the bases; `Some(bits)` also quantizes.
    Projected(Option<u8>),
}

struct Setup<'a> {
    tris: &'a [[usize; 3]],
    transfer: &'a Transfer,
    analysis: &'a Mat<f64>,
    poisson: &'a PoissonSystem,
    component: &'a [usize],
    sizes: &'a [usize],
}

/// One frame: gradients `reference → target`, optionally through the spectral path, Poisson
/// solve, per-component centroid translation, f32 rounding (as the codec does).
fn frame(s: &Setup<'_>, reference: &[V3], target: &[V3], mode: Spectral) -> codec_core::Result<Vec<f32>> {
    let grads = geometry::deformation_gradients(s.tris, reference, target);
    let m = s.tris.len();
    let targets: Vec<M3> = match mode {
        Spectral::Exact => grads,
        Spectral::Projected(bits) => {
            let mut fields = vec![vec![0.0f64; m]; 9];
            let mut svd = Svd3::new();
            for (j, g) in grads.iter().enumerate() {
                let (u, p) = svd.polar(g).unwrap_or((geometry::IDENTITY, geometry::IDENTITY));
                let w = geometry::log_rotation(&u);
                let vals = [w[0], w[1], w[2], p[0][0] - 1.0, p[1][1] - 1.0, p[2][2] - 1.0, p[0][1], p[0][2], p[1][2]];
                for (ch, v) in vals.into_iter().enumerate() {
                    fields[ch][j] = v;
                }
            }
            let mut coeffs: Vec<Vec<f64>> = fields.iter().map(|f| harmonics::analyze(s.analysis, f)).collect();
            if let Some(bits) = bits {
                for range in [0..3, 3..9] {
                    let amax = coeffs[range.clone()].iter().flatten().fold(0.0f64, |a, &c| a.max(c.abs()));
                    let step = coding::step(coding::amplitude(amax), bits);
                    for c in coeffs[range].iter_mut().flatten() {
                        *c = coding::quantize(*c, step, bits) as f64 * step;
                    }
                }
            }
            let synth: Vec<Vec<f64>> = coeffs
                .iter()
                .map(|c| {
                    let mut f = vec![0.0; m];
                    s.transfer.synthesize(c, &mut f);
                    f
                })
                .collect();
            (0..m)
                .map(|j| {
                    let f = |ch: usize| synth[ch][j];
                    let u = geometry::exp_rotation([f(0), f(1), f(2)]);
                    let (a, b, c, d, e, ff) = (1.0 + f(3), 1.0 + f(4), 1.0 + f(5), f(6), f(7), f(8));
                    geometry::mul(&u, &[[a, d, e], [d, b, ff], [e, ff, c]])
                })
                .collect()
        }
    };
    let solved = s.poisson.solve(reference, &targets)?;
    let mut sums = vec![[0.0f64; 3]; s.sizes.len()];
    for (v, p) in solved.iter().enumerate() {
        for k in 0..3 {
            sums[s.component[v]][k] += target[v][k] - p[k];
        }
    }
    let mut out = Vec::with_capacity(solved.len() * 3);
    for (v, p) in solved.iter().enumerate() {
        let c = s.component[v];
        for k in 0..3 {
            let shift = (sums[c][k] / s.sizes[c] as f64) as f32;
            out.push((p[k] + shift as f64) as f32);
        }
    }
    Ok(out)
}

fn run(s: &Setup<'_>, anim: &Animation, mode: Spectral, closed: bool) -> codec_core::Result<Vec<f32>> {
    let mut out = anim.frame(0).to_vec();
    let mut prev = to_v3(anim.frame(0));
    for t in 1..anim.frame_count() {
        let target = to_v3(anim.frame(t));
        let reference = if closed { prev.clone() } else { to_v3(anim.frame(t - 1)) };
        let rec = frame(s, &reference, &target, mode)?;
        prev = to_v3(&rec);
        out.extend(rec);
    }
    Ok(out)
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut take = |flag: &str| -> Option<String> {
        let i = args.iter().position(|a| a == flag)?;
        let v = args.get(i + 1).cloned();
        args.drain(i..(i + 2).min(args.len()));
        v
    };
    let bases: usize = take("--bases").and_then(|v| v.parse().ok()).unwrap_or(100);
    let bits: u8 = take("--bits").and_then(|v| v.parse().ok()).unwrap_or(18);
    let max_frames: usize = take("--frames").and_then(|v| v.parse().ok()).unwrap_or(usize::MAX);
    let names = if args.is_empty() { vec!["horse-gallop".to_string()] } else { args };
    let Some(root) = data_root() else { return };
    for name in names {
        let Some(anim) = load_named(&root, &name, max_frames) else { continue };
        let (n, f) = (anim.vertex_count(), anim.frame_count());
        let tris: Vec<[usize; 3]> = anim
            .triangles()
            .iter()
            .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        println!("{name}: {n} vertices, {} triangles, {f} frames, {bases} bases, {bits} bits", tris.len());
        let t0 = Instant::now();
        let frame0 = to_v3(anim.frame(0));
        let h = harmonics::harmonics_by_component(&frame0, &tris, bases).expect("harmonics");
        let transfer = Transfer::new(&h, &tris);
        let analysis = transfer.analysis(&geometry::triangle_areas(&frame0, &tris)).expect("analysis");
        let (component, pins) = geometry::components(n, &tris);
        let mut sizes = vec![0usize; pins.len()];
        for &c in &component {
            sizes[c] += 1;
        }
        let poisson = PoissonSystem::new(n, &tris, &pins).expect("poisson");
        let s = Setup {
            tris: &tris,
            transfer: &transfer,
            analysis: &analysis,
            poisson: &poisson,
            component: &component,
            sizes: &sizes,
        };
        println!("  setup (basis, analysis, symbolic) {:.1} s", t0.elapsed().as_secs_f64());
        let rows: [(&str, Spectral, bool); 5] = [
            ("1 Poisson only (exact gradients, open loop)", Spectral::Exact, false),
            ("2 + truncation to the bases (open loop)", Spectral::Projected(None), false),
            ("3 + quantization (open loop)", Spectral::Projected(Some(bits)), false),
            ("4 truncation, closed loop", Spectral::Projected(None), true),
            ("5 truncation + quantization, closed loop (no guard)", Spectral::Projected(Some(bits)), true),
        ];
        for (label, mode, closed) in rows {
            match run(&s, &anim, mode, closed) {
                Ok(rec) => println!("  {label:55} KG {:9.4}", kg(&anim, &rec)),
                Err(e) => println!("  {label:55} failed: {e}"),
            }
        }
        let p = SacParams { bases: bases as u32, bits, ..Default::default() };
        let setup = EncoderSetup {
            topology: anim.topology(),
            frame_count: anim.frame_count(),
            frame_rate: 30.0,
            want_reconstruction: true,
        };
        let mut enc = Sac.new_encoder(&p.to_param_set().expect("params"), &setup).expect("encoder");
        let packets = enc.push_frames(anim.positions()).expect("encode");
        let refresh = packets.iter().filter(|p| p.packet.data[0] == 2).count();
        let rec: Vec<f32> = packets.iter().flat_map(|p| p.reconstruction.clone().unwrap()).collect();
        println!("  {:55} KG {:9.4}  ({refresh} refresh frames)", "6 the codec (I-frame, guard)", kg(&anim, &rec));
    }
}
