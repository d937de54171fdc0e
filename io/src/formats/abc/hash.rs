//! The two hashes Alembic files carry, written from their public-domain specifications.
//!
//! - **MurmurHash3_x64_128** (Austin Appleby), seed 0: the 16-byte key in front of every
//!   sample's data. The reference library's read cache is keyed by it, so two different samples
//!   must never share a key: it is computed, never zeroed.
//! - **SpookyHash V2** (Bob Jenkins), 128-bit: the hashes of properties and child objects in the
//!   32-byte trailer of each object's header block (readers do not check them; tools compare
//!   them to find identical objects). Only the one-shot form is needed: the reference writer's
//!   incremental `Update`/`Final` gives the hash of the concatenated message, which is what
//!   [`spooky128`] computes.

/// MurmurHash3_x64_128 of `data` with seed 0, as the two little-endian words the reference
/// library stores (`h1`, `h2`).
pub(crate) fn murmur3_x64_128(data: &[u8]) -> [u64; 2] {
    const C1: u64 = 0x87c3_7b91_1142_53d5;
    const C2: u64 = 0x4cf5_ad43_2745_937f;
    let (mut h1, mut h2) = (0u64, 0u64);
    let word = |b: &[u8]| b.iter().rev().fold(0u64, |acc, &x| (acc << 8) | u64::from(x));
    let mix_k1 = |k1: u64| k1.wrapping_mul(C1).rotate_left(31).wrapping_mul(C2);
    let mix_k2 = |k2: u64| k2.wrapping_mul(C2).rotate_left(33).wrapping_mul(C1);
    let mut blocks = data.chunks_exact(16);
    for block in &mut blocks {
        h1 ^= mix_k1(word(&block[..8]));
        h1 = h1.rotate_left(27).wrapping_add(h2).wrapping_mul(5).wrapping_add(0x52dc_e729);
        h2 ^= mix_k2(word(&block[8..]));
        h2 = h2.rotate_left(31).wrapping_add(h1).wrapping_mul(5).wrapping_add(0x3849_5ab5);
    }
    let tail = blocks.remainder();
    if tail.len() > 8 {
        h2 ^= mix_k2(word(&tail[8..]));
    }
    if !tail.is_empty() {
        h1 ^= mix_k1(word(&tail[..tail.len().min(8)]));
    }
    h1 ^= data.len() as u64;
    h2 ^= data.len() as u64;
    h1 = h1.wrapping_add(h2);
    h2 = h2.wrapping_add(h1);
    let fmix = |mut k: u64| {
        k ^= k >> 33;
        k = k.wrapping_mul(0xff51_afd7_ed55_8ccd);
        k ^= k >> 33;
        k = k.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        k ^ (k >> 33)
    };
    h1 = fmix(h1);
    h2 = fmix(h2);
    h1 = h1.wrapping_add(h2);
    h2 = h2.wrapping_add(h1);
    [h1, h2]
}

/// The 16 bytes of a 128-bit hash as stored in files (two little-endian words).
pub(crate) fn digest_bytes(h: [u64; 2]) -> [u8; 16] {
    let mut out = [0u8; 16];
    out[..8].copy_from_slice(&h[0].to_le_bytes());
    out[8..].copy_from_slice(&h[1].to_le_bytes());
    out
}

/// SpookyHash V2's constant: odd, not too regular.
const SPOOKY_CONST: u64 = 0xdead_beef_dead_beef;
/// Words in SpookyHash's long-message state and block.
const SPOOKY_VARS: usize = 12;
/// Bytes per long-message block.
const SPOOKY_BLOCK: usize = SPOOKY_VARS * 8;
/// Messages shorter than this use the short form.
const SPOOKY_BUF: usize = 2 * SPOOKY_BLOCK;

fn le_word(bytes: &[u8]) -> u64 {
    bytes.iter().rev().fold(0u64, |acc, &x| (acc << 8) | u64::from(x))
}

/// SpookyHash V2's `ShortMix`: four words mixed in twelve rotate-add-xor steps.
fn short_mix(h: &mut [u64; 4]) {
    const R: [u32; 12] = [50, 52, 30, 41, 54, 48, 38, 37, 62, 34, 5, 36];
    for (k, &r) in R.iter().enumerate() {
        let i = (k + 2) % 4;
        h[i] = h[i].rotate_left(r).wrapping_add(h[(i + 1) % 4]);
        h[(i + 2) % 4] ^= h[i];
    }
}

/// SpookyHash V2's `ShortEnd`: the final mix of four words; the hash is `h[0]`, `h[1]`. The
/// reference writer also uses it alone to fold one sample's key into a property's running hash.
pub(crate) fn spooky_short_end(h: &mut [u64; 4]) {
    const R: [u32; 11] = [15, 52, 26, 51, 28, 9, 47, 54, 32, 25, 63];
    for (k, &r) in R.iter().enumerate() {
        let (j, s) = ((k + 3) % 4, (k + 2) % 4);
        h[j] ^= h[s];
        h[s] = h[s].rotate_left(r);
        h[j] = h[j].wrapping_add(h[s]);
    }
}

/// SpookyHash V2's short form (messages under 192 bytes).
fn spooky_short(message: &[u8], seed: [u64; 2]) -> [u64; 2] {
    let mut h = [seed[0], seed[1], SPOOKY_CONST, SPOOKY_CONST];
    let mut rest = message;
    if message.len() > 15 {
        while rest.len() >= 32 {
            h[2] = h[2].wrapping_add(le_word(&rest[..8]));
            h[3] = h[3].wrapping_add(le_word(&rest[8..16]));
            short_mix(&mut h);
            h[0] = h[0].wrapping_add(le_word(&rest[16..24]));
            h[1] = h[1].wrapping_add(le_word(&rest[24..32]));
            rest = &rest[32..];
        }
        if rest.len() >= 16 {
            h[2] = h[2].wrapping_add(le_word(&rest[..8]));
            h[3] = h[3].wrapping_add(le_word(&rest[8..16]));
            short_mix(&mut h);
            rest = &rest[16..];
        }
    }
    h[3] = h[3].wrapping_add((message.len() as u64) << 56);
    match rest.len() {
        0 => {
            h[2] = h[2].wrapping_add(SPOOKY_CONST);
            h[3] = h[3].wrapping_add(SPOOKY_CONST);
        }
        n if n >= 8 => {
            h[2] = h[2].wrapping_add(le_word(&rest[..8]));
            h[3] = h[3].wrapping_add(le_word(&rest[8..]));
        }
        _ => h[2] = h[2].wrapping_add(le_word(rest)),
    }
    spooky_short_end(&mut h);
    [h[0], h[1]]
}

/// SpookyHash V2's `Mix` of one 96-byte block into the twelve-word state.
fn spooky_mix(data: &[u64; SPOOKY_VARS], s: &mut [u64; SPOOKY_VARS]) {
    const R: [u32; 12] = [11, 32, 43, 31, 17, 28, 39, 57, 55, 54, 22, 46];
    for i in 0..SPOOKY_VARS {
        s[i] = s[i].wrapping_add(data[i]);
        s[(i + 2) % 12] ^= s[(i + 10) % 12];
        s[(i + 11) % 12] ^= s[i];
        s[i] = s[i].rotate_left(R[i]);
        s[(i + 11) % 12] = s[(i + 11) % 12].wrapping_add(s[(i + 1) % 12]);
    }
}

/// SpookyHash V2's `End`: the last block added, then three rounds of `EndPartial`.
fn spooky_end(data: &[u64; SPOOKY_VARS], h: &mut [u64; SPOOKY_VARS]) {
    const R: [u32; 12] = [44, 15, 34, 21, 38, 33, 10, 13, 38, 53, 42, 54];
    for (x, d) in h.iter_mut().zip(data) {
        *x = x.wrapping_add(*d);
    }
    for _ in 0..3 {
        for (i, &r) in R.iter().enumerate() {
            let (a, b, c) = ((i + 11) % 12, (i + 1) % 12, (i + 2) % 12);
            h[a] = h[a].wrapping_add(h[b]);
            h[c] ^= h[a];
            h[b] = h[b].rotate_left(r);
        }
    }
}

fn block_words(bytes: &[u8]) -> [u64; SPOOKY_VARS] {
    let mut w = [0u64; SPOOKY_VARS];
    for (x, b) in w.iter_mut().zip(bytes.chunks_exact(8)) {
        *x = le_word(b);
    }
    w
}

/// SpookyHash V2 (128-bit) of `message` with the seeds `seed` (`Hash128`).
pub(crate) fn spooky128(message: &[u8], seed: [u64; 2]) -> [u64; 2] {
    if message.len() < SPOOKY_BUF {
        return spooky_short(message, seed);
    }
    let mut h = [0u64; SPOOKY_VARS];
    for (i, x) in h.iter_mut().enumerate() {
        *x = match i % 3 {
            0 => seed[0],
            1 => seed[1],
            _ => SPOOKY_CONST,
        };
    }
    let mut blocks = message.chunks_exact(SPOOKY_BLOCK);
    for block in &mut blocks {
        spooky_mix(&block_words(block), &mut h);
    }
    let tail = blocks.remainder();
    let mut last = [0u8; SPOOKY_BLOCK];
    last[..tail.len()].copy_from_slice(tail);
    last[SPOOKY_BLOCK - 1] = tail.len() as u8;
    spooky_end(&block_words(&last), &mut h);
    [h[0], h[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(h: [u64; 2]) -> String {
        digest_bytes(h).iter().map(|b| format!("{b:02x}")).collect()
    }

    /// Reference vectors: the widely published MurmurHash3_x64_128 value of the "quick brown fox"
    /// sentence, and sample keys read from a file written by the reference Alembic library
    /// (alembic3d 1.8.12): a bool `true` (1 byte), three `f32` points (36 bytes), three `i32`
    /// indices (12 bytes) and a `f64` box (48 bytes), which together cover every tail length
    /// class and whole blocks.
    #[test]
    fn murmur3_matches_the_reference_vectors() {
        assert_eq!(murmur3_x64_128(b""), [0, 0]);
        assert_eq!(
            hex(murmur3_x64_128(b"The quick brown fox jumps over the lazy dog")),
            "6c1b07bc7bbc4be347939ac4a93c437a"
        );
        assert_eq!(hex(murmur3_x64_128(&[1])), "16fe7483905cce7a85670e43e4678877");
        let f = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        assert_eq!(hex(murmur3_x64_128(&f(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]))), "740a45f98aeef44cba0a3ca6c0b13225");
        let i: Vec<u8> = [0i32, 2, 1].iter().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(hex(murmur3_x64_128(&i)), "53b44f80451e429a888b5e47a24e1c38");
        assert_eq!(hex(murmur3_x64_128(&3i32.to_le_bytes())), "3ba1d27b7fde4848a86e865c6c402dfa");
        let b: Vec<u8> = [0f64, 0., 0., 1., 1., 0.].iter().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(hex(murmur3_x64_128(&b)), "fdbcf0369a00973a77cc3acda4542886");
    }

    /// SpookyHash V2 reference values: Bob Jenkins' `TestResults` table (`Hash32` with seed 0,
    /// the low 32 bits of `Hash128`'s first word) for the message of bytes `128, 129, …` of
    /// each length: the short form (< 192 bytes), the long form, and both edges.
    #[test]
    fn spooky_matches_the_reference_results() {
        let msg: Vec<u8> = (0..512).map(|i| (i + 128) as u8).collect();
        let low = |len: usize| spooky128(&msg[..len], [0, 0])[0] as u32;
        for (len, want) in [
            (0, 0x6bf50919),
            (1, 0x70de1d26),
            (2, 0xa2b37298),
            (3, 0x35bc5fbf),
            (15, 0x83ec01f9),
            (16, 0xf274736c),
            (31, 0x027bca7c),
            (32, 0xe5cfc8b6),
            (63, 0x09c1afb4),
            (64, 0x069c8bb7),
            (127, 0x82356bf2),
            (128, 0x94e948ec),
            (191, 0xe13d9e19),
            (192, 0x77e012bd),
            (255, 0x2f40ee0b),
            (300, 0x37e2b1da),
            (511, 0xcc1c8250),
        ] {
            assert_eq!(low(len), want, "length {len}");
        }
    }
}
