//! Stream version 3: the per-frame affine transforms (§2.3) quantized and arithmetic coded.
//!
//! Versions 1 and 2 store each frame's inverse transform as 12 raw `f32` (48 bytes per frame,
//! little compressed by zstd): on chicken-crossing (400 frames, 3030 vertices) 19 KB, half of
//! a small hosvd stream (0.12 of 0.22 bits per vertex per frame). The transforms move smoothly,
//! so version 3 (toolkit coding) quantizes the 9 linear and 3 translation entries with
//! power-of-two steps (`2^-12` for the linear part; `2^-12` × the frame-0 radius rounded to a
//! power of two for the translation), predicts each from the two previous frames (linear
//! extrapolation; frame 0 from the identity, frame 1 from frame 0) in closed loop, and codes
//! the residuals with the toolkit's adaptive arithmetic coder (a class per entry, context from
//! the entry's previous residual). The encoder normalises the frames with the *dequantized*
//! transforms ([`crate::tensor::remove_affine_motion_with`]), so the decoder's inverse is
//! exact and quantization adds no error of its own beyond a change of frame of reference
//! (a slightly less rigid normalised tensor). Steps measured at `ss = 0.97` (bytes, KG):
//! chicken-crossing 2^-16: 52 659, 2.348; 2^-12: 50 060, 2.383; 2^-8: 50 393, 2.393; samba
//! 2^-16: 51 105, 2.891; 2^-12: 49 881, 2.890; 2^-8: 48 674, 2.915.
//! Powers of two make the identity (and 0) exact.
//!
//! The steps are written in the block, so the encoder may choose them (`motion_bits`; the
//! decoder of every version 3+ stream reads any power-of-two step). Under an edge-noise cap
//! (`edge_noise > 0`, the STED-targeted configurations) the automatic choice
//! ([`auto_bits`]) makes the transforms' quantization error about the size of the shape's
//! noise cap: that error is one affine map per frame, which moves every edge of a
//! neighbourhood alike and so is invisible to STED (relative edge-length changes), while at
//! the low rates those configurations serve the 12 numbers per frame at `2^-12` are a large
//! part of the stream (measured on chicken-crossing at `f = 1`, 400 frames,
//! rigid: 0.0877 bits per vertex per frame at `2^-12`, 0.0756 at `2^-8`, STED 0.089 both).

use codec_core::toolkit::adaptive::{magnitude_bucket, AdaptiveDecoder, AdaptiveEncoder, MAX_MAGNITUDE};
use codec_core::{Error, Result};

use crate::tensor::{mat3_inverse, Affine, Centroids};
use crate::NAME;

/// Entries per transform: 9 linear, 3 translation.
const ENTRIES: usize = 12;
/// Largest |code| a decoder accepts (far beyond any real transform at these steps).
const MAX_CODE: i64 = 1 << 52;

/// Bits of the default steps: the linear part's step is `2^-DEFAULT_BITS` (stream version 3's
/// only choice, still the default without an edge-noise cap).
pub const DEFAULT_BITS: u32 = 12;
/// Coarsest automatic choice: a linear step of `2^-6` already moves a point at the RMS radius
/// by half a percent of it per frame.
pub const MIN_AUTO_BITS: u32 = 6;
/// Finest step an explicit `motion_bits` may ask for (far below `f32` noise of the entries).
pub const MAX_BITS: u32 = 24;

/// Step of the linear part at `bits`.
pub fn linear_step(bits: u32) -> f32 {
    2.0f32.powi(-(bits.min(MAX_BITS) as i32))
}

/// Step of the translation for a model of RMS radius `radius` (about its centroid) at `bits`:
/// the radius rounded to a power of two, times the linear step, so both parts move a point at
/// that radius by about the same amount.
pub fn translation_step(radius: f64, bits: u32) -> f32 {
    let e = if radius.is_finite() && radius > 0.0 { radius.log2().round().clamp(-100.0, 100.0) as i32 } else { 0 };
    2.0f32.powi(e - bits.min(MAX_BITS) as i32)
}

/// The automatic `motion_bits` under an edge-noise cap `edge_noise` (η) on a model of RMS
/// radius `radius` and RMS edge length `edge`: the coarsest power-of-two step whose uniform
/// quantization error on the linear part, `R·s/√12` per coordinate (three entries of error
/// `s/√12` each, on coordinates of RMS `R/√3`), stays within the cap `η·L̄`; clamped to
/// [`MIN_AUTO_BITS`]..=[`DEFAULT_BITS`]. Without a cap (or a degenerate model) the default.
pub fn auto_bits(edge_noise: f64, radius: f64, edge: f64) -> u32 {
    let cap = edge_noise * edge;
    if !(cap > 0.0 && radius > 0.0 && cap.is_finite() && radius.is_finite()) {
        return DEFAULT_BITS;
    }
    // R·2^-b/√12 ≤ η·L̄  ⇔  b ≥ log2(R / (√12·η·L̄)).
    let bits = (radius / (12f64.sqrt() * cap)).log2().ceil();
    bits.clamp(MIN_AUTO_BITS as f64, DEFAULT_BITS as f64) as u32
}

fn steps(linear: f32, translation: f32) -> [f64; ENTRIES] {
    std::array::from_fn(|i| if i < 9 { linear as f64 } else { translation as f64 })
}

/// Linear extrapolation from the last two frames' codes, clamped to ±[`MAX_CODE`] so every
/// code (between the prediction and a clamped target) stays inside it.
fn prediction(history: &[[i64; ENTRIES]], identity: &[i64; ENTRIES]) -> [i64; ENTRIES] {
    let p = match history {
        [] => *identity,
        [one] => *one,
        [.., a, b] => std::array::from_fn(|i| 2 * b[i] - a[i]),
    };
    p.map(|x| x.clamp(-MAX_CODE, MAX_CODE))
}

fn identity_codes(step: &[f64; ENTRIES]) -> [i64; ENTRIES] {
    std::array::from_fn(|i| Affine::IDENTITY.m.get(i).map_or(0, |&v| (v as f64 / step[i]).round() as i64))
}

fn dequantize(codes: &[i64; ENTRIES], step: &[f64; ENTRIES]) -> Affine {
    let v = |i: usize| (codes[i] as f64 * step[i]) as f32;
    Affine { m: std::array::from_fn(v), c: std::array::from_fn(|j| v(9 + j)) }
}

/// Closed-loop quantizer and coder of the transforms, one frame at a time.
pub struct MotionEncoder {
    linear: f32,
    translation: f32,
    step: [f64; ENTRIES],
    identity: [i64; ENTRIES],
    history: Vec<[i64; ENTRIES]>,
    last: [i32; ENTRIES],
    coder: AdaptiveEncoder,
    history_frames: usize,
}

impl MotionEncoder {
    /// A coder for a model of RMS radius `radius`, with steps of `bits` ([`linear_step`],
    /// [`translation_step`]).
    pub fn new(radius: f64, bits: u32) -> Self {
        let (linear, translation) = (linear_step(bits), translation_step(radius, bits));
        let step = steps(linear, translation);
        let identity = identity_codes(&step);
        Self {
            linear,
            translation,
            step,
            identity,
            history: Vec::new(),
            last: [0; ENTRIES],
            coder: AdaptiveEncoder::new(ENTRIES),
            history_frames: 0,
        }
    }

    fn quantize(&self, a: &Affine, pred: &[i64; ENTRIES]) -> [i64; ENTRIES] {
        let value = |i: usize| if i < 9 { a.m[i] } else { a.c[i - 9] } as f64;
        std::array::from_fn(|i| {
            let code = (value(i) / self.step[i]).round();
            let code = if code.is_finite() { (code as i64).clamp(-MAX_CODE, MAX_CODE) } else { pred[i] };
            code.clamp(pred[i] - MAX_MAGNITUDE as i64, pred[i] + MAX_MAGNITUDE as i64)
        })
    }

    /// Stores the next frame's transform: `proposed`'s linear part quantized (or
    /// `fallback`'s, when the quantized one is not invertible), then the translation that
    /// maps the centroids with the *quantized* linear part, `c = μ_t − μ_0·M̂`, quantized.
    /// (Quantizing `proposed.c` instead would add `μ_0·(M − M̂)` to every frame: jitter that
    /// grows with the model's distance from the origin.) Returns what the decoder rebuilds.
    pub fn store(&mut self, proposed: Affine, fallback: Affine, centroids: Centroids) -> Affine {
        let pred = prediction(&self.history, &self.identity);
        let mut codes = self.quantize(&proposed, &pred);
        if mat3_inverse(&dequantize(&codes, &self.step).m.map(|v| v as f64)).is_none() {
            codes = self.quantize(&fallback, &pred);
        }
        let m = dequantize(&codes, &self.step).m.map(|v| v as f64);
        let (mu0, mut_) = (centroids.first, centroids.this);
        let c = Affine {
            m: [0.0; 9],
            c: std::array::from_fn(|j| (mut_[j] - (0..3).map(|i| mu0[i] * m[i * 3 + j]).sum::<f64>()) as f32),
        };
        let c_codes = self.quantize(&c, &pred);
        codes[9..].copy_from_slice(&c_codes[9..]);
        for i in 0..ENTRIES {
            let r = (codes[i] - pred[i]) as i32;
            self.coder.encode(r, i, magnitude_bucket(self.last[i].unsigned_abs() as u64, 1));
            self.last[i] = r;
        }
        self.history.push(codes);
        if self.history.len() > 2 {
            self.history.remove(0);
        }
        self.history_frames += 1;
        dequantize(&codes, &self.step)
    }

    /// The block: `u32` frame count (the arithmetic decoder cannot tell where its data ends,
    /// so a packet claiming other frames is caught here), `f32` linear step, `f32`
    /// translation step, then the arithmetic-coded words.
    pub fn finish(self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(&(self.history_frames as u32).to_le_bytes());
        out.extend_from_slice(&self.linear.to_le_bytes());
        out.extend_from_slice(&self.translation.to_le_bytes());
        out.extend_from_slice(&self.coder.finish());
        out
    }
}

/// Inverse of [`MotionEncoder`]: `frames` transforms from `block`, every step, code and value
/// checked (an error naming the field, never a panic).
pub fn decode(block: &[u8], frames: usize) -> Result<Vec<Affine>> {
    let bad = |detail: String| Error::malformed(NAME, "motion", detail);
    if block.len() < 12 {
        return Err(bad(format!("{} bytes, shorter than its header", block.len())));
    }
    let word = |i: usize| [block[i], block[i + 1], block[i + 2], block[i + 3]];
    let coded_frames = u32::from_le_bytes(word(0)) as usize;
    if coded_frames != frames {
        return Err(bad(format!("{coded_frames} frames coded, the packet has {frames}")));
    }
    let (linear, translation) = (f32::from_le_bytes(word(4)), f32::from_le_bytes(word(8)));
    for (name, s) in [("linear", linear), ("translation", translation)] {
        if !(s.is_finite() && s > 0.0) {
            return Err(bad(format!("{name} step {s} is not finite and positive")));
        }
    }
    let step = steps(linear, translation);
    let identity = identity_codes(&step);
    let mut dec = AdaptiveDecoder::new(&block[12..], ENTRIES, NAME, "motion")?;
    let mut history: Vec<[i64; ENTRIES]> = Vec::with_capacity(2);
    let mut last = [0i32; ENTRIES];
    let mut out = Vec::with_capacity(frames);
    for t in 0..frames {
        let pred = prediction(&history, &identity);
        let mut codes = [0i64; ENTRIES];
        for i in 0..ENTRIES {
            let r = dec.decode(i, magnitude_bucket(last[i].unsigned_abs() as u64, 1))?;
            last[i] = r;
            codes[i] = pred[i] + r as i64;
            if codes[i].abs() > MAX_CODE {
                return Err(bad(format!("frame {t}: code {} beyond ±2^52", codes[i])));
            }
        }
        let a = dequantize(&codes, &step);
        if !a.m.iter().chain(&a.c).all(|v| v.is_finite()) {
            return Err(bad(format!("frame {t}: transform is not finite")));
        }
        out.push(a);
        history.push(codes);
        if history.len() > 2 {
            history.remove(0);
        }
    }
    dec.finish()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotation(t: f64) -> Affine {
        let (s, c) = t.sin_cos();
        Affine {
            m: [c as f32, s as f32, 0.0, -s as f32, c as f32, 0.0, 0.0, 0.0, 1.0],
            c: [(3.0 * t) as f32, (t * t) as f32, -1.5],
        }
    }

    #[test]
    fn decoder_rebuilds_what_the_encoder_stored_and_error_is_half_a_step() {
        let mut enc = MotionEncoder::new(2.0, DEFAULT_BITS);
        let frames = 200;
        let mut stored = Vec::new();
        for t in 0..frames {
            let a = rotation(t as f64 * 0.03);
            // Centroids far from the origin: the stored transform still maps μ_0 to μ_t to
            // within half a translation step (c follows the quantized linear part).
            let mu0 = [100.0, -50.0, 30.0];
            let mut_: [f64; 3] =
                std::array::from_fn(|j| a.c[j] as f64 + (0..3).map(|i| mu0[i] * a.m[i * 3 + j] as f64).sum::<f64>());
            let s = enc.store(a, Affine::IDENTITY, Centroids { first: mu0, this: mut_ });
            for (x, y) in a.m.iter().zip(&s.m) {
                assert!(((x - y).abs() as f64) <= 0.5 * linear_step(DEFAULT_BITS) as f64 + 1e-7);
            }
            for (j, &target) in mut_.iter().enumerate() {
                let mapped = s.c[j] as f64 + (0..3).map(|i| mu0[i] * s.m[i * 3 + j] as f64).sum::<f64>();
                assert!(
                    (mapped - target).abs() <= 0.5 * translation_step(2.0, DEFAULT_BITS) as f64 + 1e-4,
                    "{mapped} vs {target}"
                );
            }
            stored.push(s);
        }
        let block = enc.finish();
        assert_eq!(decode(&block, frames).unwrap(), stored);
        // Smooth motion codes small: well under the 48 raw bytes per frame.
        assert!(block.len() < frames * 16, "{} bytes", block.len());
    }

    #[test]
    fn coarser_steps_code_smaller_and_err_within_half_a_step() {
        let frames = 120;
        let mut sizes = Vec::new();
        for bits in [MIN_AUTO_BITS, 8, DEFAULT_BITS, 16] {
            let mut enc = MotionEncoder::new(3.0, bits);
            let mut stored = Vec::new();
            for t in 0..frames {
                let a = rotation(t as f64 * 0.05);
                let s = enc.store(a, Affine::IDENTITY, Centroids { first: [0.0; 3], this: a.c.map(|c| c as f64) });
                for (x, y) in a.m.iter().zip(&s.m) {
                    assert!(((x - y).abs() as f64) <= 0.5 * linear_step(bits) as f64 + 1e-7, "bits {bits}");
                }
                stored.push(s);
            }
            let block = enc.finish();
            assert_eq!(decode(&block, frames).unwrap(), stored, "bits {bits}");
            sizes.push(block.len());
        }
        assert!(sizes.windows(2).all(|w| w[0] < w[1]), "{sizes:?}");
    }

    #[test]
    fn automatic_bits_follow_the_edge_noise_cap() {
        // No cap, or a degenerate model: the default steps.
        assert_eq!(auto_bits(0.0, 1.0, 0.1), DEFAULT_BITS);
        assert_eq!(auto_bits(0.012, 0.0, 0.1), DEFAULT_BITS);
        assert_eq!(auto_bits(0.012, f64::NAN, 0.1), DEFAULT_BITS);
        // chicken-crossing's proportions (RMS edge 0.104 of the RMS radius) at η = 0.012: the
        // linear part's error R·2^-8/√12 = 1.13e-3·R is within the cap 1.25e-3·R; 2^-7 is not.
        let (radius, edge) = (1.0, 0.104);
        let bits = auto_bits(0.012, radius, edge);
        assert_eq!(bits, 8);
        let error = |b: u32| radius * linear_step(b) as f64 / 12f64.sqrt();
        assert!(error(bits) <= 0.012 * edge && error(bits - 1) > 0.012 * edge);
        // A looser cap never asks for finer steps; the clamps hold.
        assert!(auto_bits(0.02, radius, edge) <= bits);
        assert_eq!(auto_bits(1.0, 1.0, 1.0), MIN_AUTO_BITS);
        assert_eq!(auto_bits(1e-9, 1.0, 1e-3), DEFAULT_BITS);
    }

    #[test]
    fn singular_transform_falls_back_and_bad_blocks_are_errors() {
        let mut enc = MotionEncoder::new(1.0, DEFAULT_BITS);
        let singular = Affine { m: [0.0; 9], c: [1.0, 2.0, 3.0] };
        let fb = Affine { m: Affine::IDENTITY.m, c: [0.5, 0.0, 0.0] };
        let s = enc.store(singular, fb, Centroids { first: [0.0; 3], this: [0.5, 0.0, 0.0] });
        assert_eq!(s, fb, "identity and this translation are exact at power-of-two steps");
        let block = enc.finish();
        assert_eq!(decode(&block, 1).unwrap(), vec![fb]);
        assert!(decode(&block[..4], 1).is_err());
        let mut nan = block.clone();
        nan[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(decode(&nan, 1).unwrap_err().to_string().contains("step"));
        // Garbage never panics.
        for i in 12..block.len() {
            let mut b = block.clone();
            b[i] ^= 0xa5;
            let _ = decode(&b, 1);
        }
        assert!(decode(&block, 2).unwrap_err().to_string().contains("1 frames coded"));
    }
}
