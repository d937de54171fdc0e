//! Searches of film-size inputs on a sample of their frames. A streamed search encodes and
//! measures every candidate over the whole input: at 1 000 000 vertices × 1 000 frames one
//! candidate is a 12 GB pass of 10–35 minutes. [`SampledSource`] serves windows of whole
//! temporal blocks spread evenly over the input (about [`SAMPLE_SHARE`] of its frames), so a
//! candidate costs a fraction of a pass; the caller then encodes the chosen parameters over the
//! whole input once and measures that stream, which is what it reports
//! (`encode`'s sampled search).
//!
//! Why whole blocks: a codec whose packets are coded from independent temporal blocks
//! ([`AnimationCodec::independent_blocks`](codec_core::AnimationCodec::independent_blocks);
//! quant-delta, hosvd, pca-aoi in its SVD mode) codes a window aligned to its blocks into the
//! very packets the whole encode writes for those frames, with the parameters fitted to the
//! whole input ([`InputSource::fit_frame_count`]). The sample's errors are then the whole's
//! errors on those frames; only the sampling (which frames) differs from the whole's figures.

use std::ops::Range;

use codec_core::{SceneMetadata, Topology};

use super::input::{FrameRead, InputSource};
use super::target::{Target, TargetMetric};
use crate::error::Result;

/// The share of the input's frames a sample holds, about: an eighth, so a search of four to
/// six candidates costs under one pass over the whole input.
pub const SAMPLE_SHARE: (usize, usize) = (1, 8);

/// The fewest windows a sample spreads over the input.
pub const MIN_SAMPLE_WINDOWS: usize = 4;

/// The shortest window, in frames (rounded up to whole blocks): STED's temporal term compares
/// speeds over consecutive frames, and each window's first frames follow a cut.
pub const MIN_WINDOW_FRAMES: usize = 16;

/// The block a sample is cut in when no codec's independent blocks apply (a codec that has
/// none, or `-c auto`'s several codecs): 32 frames, quant-delta's packet.
pub const UNALIGNED_SAMPLE_BLOCK: usize = 32;

/// How far below the target a search on a sample aims: each bound times this factor, so that
/// the whole input, which the sample only estimates, meets the target without a second pass.
pub const SAMPLE_TARGET_MARGIN: f64 = 0.9;

/// `target` with every bound multiplied by `factor(metric)` (a search on a sample aims below
/// the user's target; see [`SAMPLE_TARGET_MARGIN`]).
pub fn scaled_target(target: Target, factor: impl Fn(TargetMetric) -> f64) -> Target {
    target.bounds().fold(target, |t, (metric, bound)| t.and_bound(metric, bound * factor(metric)))
}

/// Windows of an input's frames, served in order as one shorter input (see the module).
pub struct SampledSource<'a> {
    inner: &'a dyn InputSource,
    windows: Vec<Range<usize>>,
    frames: usize,
}

impl<'a> SampledSource<'a> {
    /// A sample of `inner` in windows of whole `block`-frame blocks (at least
    /// [`MIN_WINDOW_FRAMES`]), [`MIN_SAMPLE_WINDOWS`] or more of them, together about
    /// [`SAMPLE_SHARE`] of its frames, each in the middle of its share of the input. `None` when
    /// such a sample would hold more than half the input (a search on it would save little).
    pub fn new(inner: &'a dyn InputSource, block: usize) -> Option<Self> {
        let frames = inner.frame_count();
        let block = block.max(1);
        let window = block.checked_mul(MIN_WINDOW_FRAMES.div_ceil(block))?;
        let slots = frames / window;
        let (num, den) = SAMPLE_SHARE;
        let count = frames.checked_mul(num)?.div_ceil(den.checked_mul(window)?).max(MIN_SAMPLE_WINDOWS);
        if slots == 0 || count.checked_mul(window)?.checked_mul(2)? > frames {
            return None;
        }
        // Window k takes the middle slot of the k-th of `count` equal shares of the slots;
        // `slots ≥ 2 × count`, so the windows are distinct and in order.
        let windows: Vec<Range<usize>> = (0..count)
            .map(|k| {
                let slot = (2 * k + 1) * slots / (2 * count);
                slot * window..(slot + 1) * window
            })
            .collect();
        Some(Self { inner, frames: count * window, windows })
    }

    /// The windows, in frames of the input.
    pub fn windows(&self) -> &[Range<usize>] {
        &self.windows
    }

    /// The input sampled.
    pub fn inner(&self) -> &'a dyn InputSource {
        self.inner
    }
}

impl InputSource for SampledSource<'_> {
    fn topology(&self) -> &Topology {
        self.inner.topology()
    }
    fn frame_count(&self) -> usize {
        self.frames
    }
    fn frame_rate(&self) -> f32 {
        self.inner.frame_rate()
    }
    fn metadata(&self) -> SceneMetadata {
        self.inner.metadata()
    }
    fn open(&self) -> Result<Box<dyn FrameRead + '_>> {
        Ok(Box::new(SampledReader {
            inner: self.inner.open()?,
            windows: &self.windows,
            next_window: 0,
            at: 0,
            scratch: Vec::new(),
            name: self.inner.name(),
        }))
    }
    fn name(&self) -> String {
        format!("{} (a sample of {} of its {} frames)", self.inner.name(), self.frames, self.inner.frame_count())
    }
    fn fit_frame_count(&self) -> usize {
        self.inner.fit_frame_count()
    }
}

/// A read of a [`SampledSource`]: the input's reader, skipping between windows.
struct SampledReader<'a> {
    inner: Box<dyn FrameRead + 'a>,
    windows: &'a [Range<usize>],
    next_window: usize,
    /// The input's frame the inner reader reads next.
    at: usize,
    scratch: Vec<f32>,
    name: String,
}

impl SampledReader<'_> {
    fn ended(&self) -> codec_core::Error {
        codec_core::Error::InvalidAnimation(format!(
            "{}: ended at frame {}, before the end of the sample's window {:?} (the input changed while it was \
             searched?)",
            self.name, self.at, self.windows[self.next_window]
        ))
    }
}

impl FrameRead for SampledReader<'_> {
    fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> codec_core::Result<usize> {
        out.clear();
        let mut got = 0;
        while got < frames {
            let Some(window) = self.windows.get(self.next_window).cloned() else { break };
            if self.at < window.start {
                let skipped = self.inner.skip_frames(window.start - self.at)?;
                self.at += skipped;
                if self.at < window.start {
                    return Err(self.ended());
                }
            }
            let take = (frames - got).min(window.end - self.at);
            let n = self.inner.read_frames(take, &mut self.scratch)?;
            if n == 0 {
                return Err(self.ended());
            }
            out.extend_from_slice(&self.scratch);
            (got, self.at) = (got + n, self.at + n);
            if self.at == window.end {
                self.next_window += 1;
            }
        }
        Ok(got)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::input::tests::InMemory;

    fn read_all(source: &dyn InputSource, feed: usize) -> Vec<f32> {
        let (mut reader, mut all, mut block) = (source.open().unwrap(), Vec::new(), Vec::new());
        while reader.read_frames(feed, &mut block).unwrap() > 0 {
            all.extend_from_slice(&block);
        }
        all
    }

    #[test]
    fn a_sample_is_the_windows_frames_in_order_whatever_the_feed() {
        let animation = animcodec_synth::tumbling_body_sized(5, 4, 400);
        let per_frame = animation.vertex_count() * 3;
        let source = InMemory(animation.clone());
        let sample = SampledSource::new(&source, 11).unwrap();
        // Windows of two 11-frame blocks (22 ≥ 16), 400 / 8 / 22 → 3, raised to 4.
        assert_eq!(sample.windows().len(), MIN_SAMPLE_WINDOWS);
        let mut expected = Vec::new();
        for (i, w) in sample.windows().iter().enumerate() {
            assert_eq!((w.start % 11, w.len()), (0, 22), "aligned to whole blocks");
            assert!(w.end <= 400);
            if i > 0 {
                assert!(sample.windows()[i - 1].end < w.start, "distinct, in order, apart");
            }
            expected.extend_from_slice(&animation.positions()[w.start * per_frame..w.end * per_frame]);
        }
        assert_eq!(sample.frame_count(), 88);
        assert_eq!(sample.fit_frame_count(), 400, "parameters are fitted to the whole input");
        for feed in [1, 5, 22, 23, 1000] {
            assert_eq!(read_all(&sample, feed), expected, "feed {feed}");
        }
    }

    #[test]
    fn a_sample_is_spread_over_the_whole_input_and_about_an_eighth() {
        let source = InMemory(animcodec_synth::tumbling_body_sized(3, 2, 1000));
        let sample = SampledSource::new(&source, 32).unwrap();
        let w = sample.windows();
        assert!(sample.frame_count() * SAMPLE_SHARE.1 >= 1000 && sample.frame_count() <= 1000 / 4);
        assert!(w[0].start < 1000 / w.len() && w[w.len() - 1].end > 1000 - 1000 / w.len(), "{w:?}");
    }

    #[test]
    fn a_short_input_is_not_sampled() {
        let source = InMemory(animcodec_synth::tumbling_body_sized(3, 2, 100));
        assert!(SampledSource::new(&source, 1).is_none(), "4 windows of 16 frames are more than half of 100");
        assert!(SampledSource::new(&source, 1000).is_none(), "a block longer than the input");
        assert!(SampledSource::new(&InMemory(animcodec_synth::tumbling_body_sized(3, 2, 128)), 1).is_some());
    }

    #[test]
    fn an_input_shorter_than_it_said_is_an_error() {
        struct Short(InMemory);
        impl InputSource for Short {
            fn topology(&self) -> &Topology {
                self.0.topology()
            }
            fn frame_count(&self) -> usize {
                400
            }
            fn frame_rate(&self) -> f32 {
                24.0
            }
            fn open(&self) -> Result<Box<dyn FrameRead + '_>> {
                self.0.open()
            }
            fn name(&self) -> String {
                "short".into()
            }
        }
        let source = Short(InMemory(animcodec_synth::tumbling_body_sized(3, 2, 200)));
        let sample = SampledSource::new(&source, 16).unwrap();
        let (mut reader, mut out) = (sample.open().unwrap(), Vec::new());
        let e = loop {
            match reader.read_frames(16, &mut out) {
                Ok(0) => panic!("ended without an error"),
                Ok(_) => continue,
                Err(e) => break e.to_string(),
            }
        };
        assert!(e.contains("short: ended at frame 200"), "{e}");
    }

    #[test]
    fn a_scaled_target_scales_every_bound() {
        let t = Target::new(TargetMetric::Kg, 0.5).and_bound(TargetMetric::Sted, 0.05);
        let s = scaled_target(t, |m| if m == TargetMetric::Kg { 0.5 } else { 0.9 });
        assert_eq!(s.bound(TargetMetric::Kg), Some(0.25));
        assert!((s.bound(TargetMetric::Sted).unwrap() - 0.045).abs() < 1e-15);
        assert_eq!(s.bound(TargetMetric::Hausdorff), None);
    }
}
