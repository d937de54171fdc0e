//! [`Limits`]: the memory and work budgets every decoder and reader is held to.
//!
//! Its own module because both the codec interface (`codec.rs`: decoders receive limits) and the
//! container (`container.rs`: the reader checks every size against them) use it; with `Limits`
//! inside the container the two modules imported each other.

use crate::error::{Error, Result};

/// Bounds on what a decoder (or a stream reader) accepts, checked before anything is
/// allocated or computed.
///
/// `max_alloc_bytes` and `max_work` are budgets for the *whole* decode: a decoder subtracts
/// what it keeps (its state, the decoded animation) with [`Limits::reserve`] and hands the rest
/// to the next step, so the sum of what it holds at once stays within `max_alloc_bytes`, and
/// the operations it is about to spend (estimated from sizes it knows before the work starts,
/// so the count is the same on every machine) stay within `max_work`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Most vertices a stream may declare.
    pub max_vertices: usize,
    /// Most frames a stream may declare.
    pub max_frames: usize,
    /// Most triangles a stream may declare.
    pub max_triangles: usize,
    /// Most bytes a decode (or a read) driven by stream contents may hold at once, in total:
    /// payloads, decoded packets and animation, the decoder's state and its numeric workspaces
    /// (`--max-memory` on the command line).
    pub max_alloc_bytes: usize,
    /// Most arithmetic operations (multiply-adds, counted from sizes before the work starts)
    /// a decode may spend: bounds its time deterministically, whatever the machine.
    pub max_work: u64,
}

/// Default total memory of one decode: 1 GiB (representable on 32-bit targets too, never 0).
/// Large enough for every real animation the project measures with (a 100 000-vertex,
/// 300-frame cache decodes to 360 MB), small enough that a crafted stream of a few hundred
/// bytes claiming 2^24 vertices is refused before its coding-order graph (64 bytes a vertex)
/// is built: a bound of 1 GB for any hostile input. Larger decodes ask for it with
/// `--max-memory` (image-rs makes the same trade with a 512 MiB default).
pub const DEFAULT_MAX_MEMORY: usize = 1 << 30;

/// Default work budget of one decode (operations). Decoding the largest real animation the
/// project measures with (sac, default parameters) estimates about 2 % of it; a crafted stream
/// asking for a 1000-vector harmonic basis on 100 000 vertices, or a Cholesky factor of an
/// expander graph, estimates far more and is refused in well under a second
/// (`docs/notes/issue-27-simd-limits.md`).
pub const DEFAULT_MAX_WORK: u64 = 200_000_000_000;

/// Work charged per arithmetic-decoded value ([`crate::toolkit::adaptive`]: a few adaptive
/// binary decisions, each a division and two model updates), in multiply-adds. Every
/// decoder charges its coded values at this rate, with its dense products at one per
/// multiply-add, before it starts (`--max-work`).
pub const WORK_PER_CODED_VALUE: u64 = 16;

/// Work charged per byte a decoder inflates from a zstd block and splits into byte planes.
pub const WORK_PER_PLANE_BYTE: u64 = 1;

/// Work charged per decoded output coordinate on top of its codec's arithmetic (dequantizing,
/// the finite check, the copy into the decoded frames).
pub const WORK_PER_COORDINATE: u64 = 4;

impl Default for Limits {
    /// 16 M vertices, 10 M frames, 32 M triangles, [`DEFAULT_MAX_MEMORY`] in total,
    /// [`DEFAULT_MAX_WORK`] operations.
    fn default() -> Self {
        Self {
            max_vertices: 1 << 24,
            max_frames: 10_000_000,
            max_triangles: 1 << 25,
            max_alloc_bytes: DEFAULT_MAX_MEMORY,
            max_work: DEFAULT_MAX_WORK,
        }
    }
}

impl Limits {
    /// No bound at all: for encoders, which read no untrusted stream.
    pub const UNLIMITED: Limits = Limits {
        max_vertices: usize::MAX,
        max_frames: usize::MAX,
        max_triangles: usize::MAX,
        max_alloc_bytes: usize::MAX,
        max_work: u64::MAX,
    };

    /// Fails with [`Error::AllocLimit`] if holding `bytes` more would exceed the memory budget
    /// (`max_alloc_bytes`); `field` says in words what would be allocated.
    pub fn check_alloc(&self, context: &'static str, field: &'static str, bytes: u64) -> Result<()> {
        if bytes > self.max_alloc_bytes as u64 {
            return Err(Error::AllocLimit {
                context: context.into(),
                what: field.into(),
                bytes,
                limit: self.max_alloc_bytes as u64,
            });
        }
        Ok(())
    }

    /// Checks that `bytes` fit ([`Limits::check_alloc`]) and returns the limits left for
    /// everything else the decode holds while these bytes are held.
    pub fn reserve(&self, context: &'static str, field: &'static str, bytes: u64) -> Result<Limits> {
        self.check_alloc(context, field, bytes)?;
        Ok(Limits { max_alloc_bytes: self.max_alloc_bytes - bytes as usize, ..*self })
    }

    /// Fails with [`Error::WorkLimit`] if `ops` operations exceed the work budget.
    pub fn check_work(&self, context: &'static str, what: &'static str, ops: u64) -> Result<()> {
        if ops > self.max_work {
            return Err(Error::WorkLimit { context: context.into(), what: what.into(), ops, limit: self.max_work });
        }
        Ok(())
    }

    /// Work of `a × b × c × …` operations, saturating (sizes come from untrusted streams).
    pub fn product(factors: &[u64]) -> u64 {
        factors.iter().fold(1u64, |acc, &x| acc.saturating_mul(x))
    }

    /// Checks `ops` ([`Limits::check_work`]) and returns the limits left after spending them.
    pub fn spend(&self, context: &'static str, what: &'static str, ops: u64) -> Result<Limits> {
        self.check_work(context, what, ops)?;
        Ok(Limits { max_work: self.max_work - ops, ..*self })
    }
}
