//! A small process-wide cache of full-rank spectra ([`Spectrum`]), keyed by the normalised
//! tensor's contents.
//!
//! Why: a target search or a sweep encodes one animation at many `ss` values of one
//! configuration, and the normalised tensor — hence its full-rank HO-SVD, most of an encode's
//! time — is the same at every one of them (the motion removal does not depend on `ss`).
//! Measured: on samba an encode spends about 1.5 of its 2.2 s there, and
//! `--target sted=0.05` measured 10 such points (9.4–9.9× one encode, over the ≤ 8× asked).
//!
//! The cached spectrum is the one [`Spectrum::new`] computes (a deterministic function of the
//! tensor), so a hit changes no byte of any stream. The key is two independent 64-bit hashes
//! of every coordinate's bits plus the shape and the squared norm. Entries are bounded: at
//! most [`ENTRIES`], each at most [`MAX_ENTRY_BYTES`] (larger spectra are recomputed, never
//! held), least recently used first out.

use std::sync::{Arc, Mutex};

use codec_core::Result;

use crate::tensor::{Spectrum, Tensor};

/// Spectra held at once: the configurations a search walks in parallel (two cores, two
/// configurations at a time, plus the one a sweep returns to).
const ENTRIES: usize = 4;
/// Largest spectrum held, in bytes of its factors (samba: 9 971 × 525 + 175² doubles, 42 MB).
const MAX_ENTRY_BYTES: usize = 64 << 20;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Key {
    k: usize,
    frames: usize,
    hash: [u64; 2],
    norm2_bits: u64,
}

static CACHE: Mutex<Vec<(Key, Arc<Spectrum>)>> = Mutex::new(Vec::new());

fn key(x: &[f64], k: usize, frames: usize, norm2: f64) -> Key {
    // FNV-1a over the words, and a multiply-rotate mix with another seed: independent enough
    // that a false hit needs two 64-bit collisions on the same shape and norm.
    let (mut a, mut b) = (0xcbf2_9ce4_8422_2325u64, 0x9e37_79b9_7f4a_7c15u64);
    for v in x {
        let w = v.to_bits();
        a = (a ^ w).wrapping_mul(0x0000_0100_0000_01b3);
        b = (b ^ w.rotate_left(29)).wrapping_mul(0xff51_afd7_ed55_8ccd).rotate_left(31);
    }
    Key { k, frames, hash: [a, b], norm2_bits: norm2.to_bits() }
}

fn bytes(s: &Spectrum) -> usize {
    8 * (s.u1.nrows() * s.u1.ncols() + s.u3.nrows() * s.u3.ncols())
}

/// The full-rank spectrum of `t`, the normalised tensor whose frame-major coordinates are `x`
/// (`F × K × 3`): from the cache, or computed (and kept, when small enough).
pub fn spectrum(t: &Tensor, x: &[f64], k: usize, frames: usize) -> Result<Arc<Spectrum>> {
    let key = key(x, k, frames, t.norm2);
    if let Ok(mut cache) = CACHE.lock() {
        if let Some(i) = cache.iter().position(|(c, _)| *c == key) {
            let entry = cache.remove(i);
            let found = entry.1.clone();
            cache.push(entry);
            return Ok(found);
        }
    }
    let computed = Arc::new(Spectrum::new(t)?);
    if bytes(&computed) <= MAX_ENTRY_BYTES {
        if let Ok(mut cache) = CACHE.lock() {
            if !cache.iter().any(|(c, _)| *c == key) {
                if cache.len() >= ENTRIES {
                    cache.remove(0);
                }
                cache.push((key, computed.clone()));
            }
        }
    }
    Ok(computed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hit_is_the_spectrum_computed_and_other_tensors_miss() {
        let (k, frames) = (40, 12);
        let x: Vec<f64> = (0..3 * k * frames).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 + (i / 120) as f64).collect();
        let t = Tensor::new(&x, k, frames);
        let first = spectrum(&t, &x, k, frames).unwrap();
        let again = spectrum(&t, &x, k, frames).unwrap();
        assert!(Arc::ptr_eq(&first, &again), "the second call recomputed");
        let fresh = Spectrum::new(&t).unwrap();
        for (v, f) in [(1, 1), (3, 2), (k.min(3 * frames), frames)] {
            assert_eq!(first.truncation_error2(v, f).to_bits(), fresh.truncation_error2(v, f).to_bits());
        }
        // One coordinate changed by one ulp: another key.
        let mut y = x.clone();
        y[17] = f64::from_bits(y[17].to_bits() + 1);
        let ty = Tensor::new(&y, k, frames);
        assert!(!Arc::ptr_eq(&first, &spectrum(&ty, &y, k, frames).unwrap()));
    }
}
