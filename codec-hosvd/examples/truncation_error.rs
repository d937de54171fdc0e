//! Dev aid for `tools/compare_tensorly.py`: the unquantized truncated HO-SVD of a PC2 file
//! (no motion removal, no HOOI unless asked), printed as one JSON line per `(v, f)` pair.
//!
//! ```text
//! target/release/examples/truncation_error FILE.pc2 V F [V F ...] [--rigid | --rotation] [--hooi N]
//! ```
//!
//! `err_reconstruction` is ‖T − T̂‖_F with T̂ the f32 reconstruction the codec would produce;
//! `err_energy` is √(‖T‖² − ‖C̃‖²) in f64; `seconds` is the time of the decomposition and
//! reconstruction for that pair (the PC2 read excluded).

use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().expect("usage: truncation_error FILE.pc2 V F [V F ...] [--rigid | --rotation] [--hooi N]");
    let rotation = args.iter().any(|a| a == "--rotation");
    let rigid = rotation || args.iter().any(|a| a == "--rigid");
    let hooi = args.iter().position(|a| a == "--hooi").map(|i| args[i + 1].parse::<usize>().unwrap()).unwrap_or(0);
    let nums: Vec<usize> =
        args[1..].iter().take_while(|a| !a.starts_with("--")).map(|a| a.parse().expect("ranks are integers")).collect();
    let b = std::fs::read(path).expect("read pc2");
    assert!(b.len() >= 32 && &b[..12] == b"POINTCACHE2\0", "not a PC2 file");
    let i32_at = |o: usize| i32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let (k, f) = (i32_at(16) as usize, i32_at(28) as usize);
    let pos: Vec<f32> =
        b[32..32 + k * f * 12].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    let norm = pos.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
    for pair in nums.chunks_exact(2) {
        let t0 = Instant::now();
        let (rec, err2) =
            codec_hosvd::truncated_reconstruction_with(&pos, k, pair[0], pair[1], rigid, !rotation, hooi).unwrap();
        let secs = t0.elapsed().as_secs_f64();
        let err = pos.iter().zip(&rec).map(|(a, b)| (*a as f64 - *b as f64).powi(2)).sum::<f64>().sqrt();
        println!(
            "{{\"v\": {}, \"f\": {}, \"err_reconstruction\": {err:.17e}, \"err_energy\": {:.17e}, \"norm\": {norm:.17e}, \"seconds\": {secs:.6}}}",
            pair[0],
            pair[1],
            err2.sqrt()
        );
    }
}
