//! Times every metric on a real animation perturbed by uniform quantization, and optionally
//! dumps the arrays and results for the independent numpy check in `metrics/tools/`.
//!
//! ```text
//! cargo build --release -p metrics --example metric_timing
//! target/release/examples/metric_timing [PATH_PREFIX] [--bits 10] [--dump DIR] [--repeat 3]
//! ```
//!
//! `PATH_PREFIX` names `PREFIX.pc2` + `PREFIX.obj` (default: samba in `../shared/data`).
//! The readers below are deliberately tiny (positions and `f` lines only); the real readers
//! live in the `animcodec` crate, which `metrics` must not depend on.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use codec_core::Animation;
use metrics::{
    displacement_stats, evaluate, hausdorff, kg_error, per_vertex_displacement, point_triangle_distance, sted,
    sted_with_fields, vertex_to_surface_distances, EvalOptions, StedParams,
};

#[path = "support/legacy_sted.rs"]
mod legacy_sted;
#[path = "support/readers.rs"]
mod readers;

use readers::{read_obj_triangles, read_pc2, Res};

/// Uniform quantization of every coordinate to `bits` over the animation's bounding box.
fn quantize(a: &Animation, bits: u32) -> Res<Animation> {
    let (lo, hi) = a.bounding_box();
    let levels = ((1u64 << bits) - 1) as f64;
    let p = a
        .positions()
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            let (l, h) = (lo[i % 3] as f64, hi[i % 3] as f64);
            if h <= l {
                return x;
            }
            let q = ((x as f64 - l) / (h - l) * levels).round();
            (l + q / levels * (h - l)) as f32
        })
        .collect();
    Ok(Animation::from_parts(a.vertex_count(), a.triangles().to_vec(), p, a.frame_rate())?)
}

/// Runs `f` `repeat` times and returns the last result and the fastest time in ms.
fn time<T>(repeat: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        out = Some(std::hint::black_box(f()));
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (out.unwrap(), best)
}

fn write_f32(path: &Path, data: &[f32]) -> Res<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    for x in data {
        w.write_all(&x.to_le_bytes())?;
    }
    Ok(())
}

fn main() -> Res<()> {
    let mut args = std::env::args().skip(1);
    let mut prefix = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/samba/samba"));
    let (mut bits, mut dump, mut repeat) = (10u32, None::<PathBuf>, 3usize);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--bits" => bits = args.next().ok_or("--bits needs a value")?.parse()?,
            "--dump" => dump = Some(args.next().ok_or("--dump needs a directory")?.into()),
            "--repeat" => repeat = args.next().ok_or("--repeat needs a value")?.parse()?,
            _ => prefix = a.into(),
        }
    }
    if !(1..=24).contains(&bits) {
        return Err("--bits must be in 1..=24".into());
    }
    let pc2 = prefix.with_extension("pc2");
    if !pc2.exists() {
        println!("SKIP: {} not found", pc2.display());
        return Ok(());
    }
    let (v, f, p) = read_pc2(&pc2)?;
    let tris = read_obj_triangles(&prefix.with_extension("obj"))?;
    let reference = Animation::from_parts(v, tris, p, 30.0)?;
    let candidate = quantize(&reference, bits)?;
    println!(
        "{}: {} vertices, {} triangles, {} frames; candidate = {bits}-bit uniform quantization; {} rayon threads; best of {repeat}",
        prefix.display(),
        v,
        reference.triangles().len(),
        f,
        rayon::current_num_threads()
    );

    let (r, c) = (&reference, &candidate);
    let params = StedParams::default();
    // Baseline: one sequential pass summing squared differences (the memory-bound floor).
    let (_, t_base) =
        time(repeat, || r.positions().iter().zip(c.positions()).map(|(a, b)| ((a - b) as f64).powi(2)).sum::<f64>());
    let (kg, t_kg) = time(repeat, || kg_error(r, c));
    let (disp, t_disp) = time(repeat, || displacement_stats(r, c));
    let (_, t_pv) = time(repeat, || per_vertex_displacement(r, c));
    let (legacy, t_legacy) = time(repeat, || legacy_sted::legacy_sted(r, c));
    let (st, t_sted) = time(repeat, || sted(r, c, &params));
    let (stf, t_stedf) = time(repeat, || sted_with_fields(r, c, &params));
    let (h, t_h) = time(repeat, || hausdorff(r, c));
    let (report, t_eval) = time(repeat, || evaluate(r, c, &EvalOptions::default()));
    let (kg, disp, st, stf, h, report) = (kg?, disp?, st?, stf?, h?, report?);
    // Brute-force baseline for one frame of the Hausdorff search (reference → candidate).
    let tris = r.triangles();
    let (fast0, t_fast0) = time(repeat, || vertex_to_surface_distances(r.frame(0), c.frame(0), tris));
    let (brute0, t_brute0) = time(1, || brute_force(r.frame(0), c.frame(0), tris));
    let fast0 = fast0?;
    let worst = fast0.iter().zip(&brute0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);

    println!("{:<44} {:>10}", "metric", "ms");
    for (name, ms) in [
        ("baseline: one pass of squared differences", t_base),
        ("kg_error", t_kg),
        ("displacement_stats (mse/rmse/max)", t_disp),
        ("per_vertex_displacement", t_pv),
        ("sted (the author's tool's definition)", t_sted),
        ("baseline: the earlier STED definition (legacy_sted)", t_legacy),
        ("sted_with_fields", t_stedf),
        ("hausdorff (all frames, both directions)", t_h),
        ("evaluate (everything)", t_eval),
        ("hausdorff one frame, one direction (BVH)", t_fast0),
        ("same by brute force (baseline)", t_brute0),
    ] {
        println!("{name:<44} {ms:>10.2}");
    }
    println!("frame 0 BVH vs brute force: largest difference {worst:e}");
    println!("kg = {kg:.6}  rmse = {:.6e}  max_error = {:.6e}", disp.rmse, disp.max_error);
    println!(
        "sted = {:.6e}  spatial = {:.6e}  temporal = {:.6e}  params = {:?}",
        st.sted, st.spatial, st.temporal, st.params
    );
    println!("sted / old sted time: {:.2}x", t_sted / t_legacy);
    println!("old definition: sted = {:.6e}  spatial = {:.6e}  temporal = {:.6e}", legacy.0, legacy.1, legacy.2);
    println!("hausdorff max = {:.6e}  mean = {:.6e}  ({:?})", h.max, h.mean, h.mode);

    if let Some(dir) = dump {
        std::fs::create_dir_all(&dir)?;
        write_f32(&dir.join("reference.f32"), r.positions())?;
        write_f32(&dir.join("candidate.f32"), c.positions())?;
        let mut w = std::io::BufWriter::new(std::fs::File::create(dir.join("triangles.u32"))?);
        for t in tris.iter().flatten() {
            w.write_all(&t.to_le_bytes())?;
        }
        w.flush()?;
        let pv = per_vertex_displacement(r, c)?;
        let back0 = vertex_to_surface_distances(c.frame(0), r.frame(0), tris)?;
        let json = serde_json::json!({
            "vertex_count": v,
            "frame_count": f,
            "triangle_count": tris.len(),
            "report": report,
            "hausdorff_per_frame": h.per_frame,
            "frame_rmse": disp.frame_rmse,
            "per_vertex_rms": pv.rms,
            "per_vertex_max": pv.max,
            "sted_spatial_per_vertex": stf.spatial_per_vertex,
            "frame0_ref_to_cand": fast0,
            "frame0_cand_to_ref": back0,
        });
        std::fs::write(dir.join("results.json"), serde_json::to_string(&json)?)?;
        println!("dumped to {}", dir.display());
    }
    Ok(())
}

/// Every vertex of `from` against every triangle of `to` with the exported point-triangle
/// distance, bypassing the search structure entirely.
fn brute_force(from: &[f32], to: &[f32], tris: &[[u32; 3]]) -> Vec<f64> {
    use rayon::prelude::*;
    let pt = |f: &[f32], i: usize| [f[3 * i] as f64, f[3 * i + 1] as f64, f[3 * i + 2] as f64];
    (0..from.len() / 3)
        .into_par_iter()
        .map(|v| {
            let p = pt(from, v);
            tris.iter()
                .map(|t| {
                    point_triangle_distance(p, pt(to, t[0] as usize), pt(to, t[1] as usize), pt(to, t[2] as usize))
                })
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}
