//! Inputs a search or a sweep reads frame by frame, as often as it needs
//! ([`InputSource`]): a PC2/MDD cache or an OBJ sequence ([`CacheSource`]) and the synthetic
//! flag `synth:flag:COLSxROWSxFRAMES` ([`FlagSource`], generated again for every read).

use std::path::Path;

use animcodec::core::Topology;
use animcodec::formats::stream as cache_stream;
use animcodec::formats::ReadOptions;
use animcodec::front;
use animcodec::harness::{self, CacheSource, FrameRead, InputSource};
use animcodec::synth;

use super::CmdResult;

/// `input` as a source read frame by frame, when it can be (a `.pc2`/`.mdd` cache, an OBJ
/// sequence, `synth:flag:COLSxROWSxFRAMES`); `None` for any other input (read whole).
pub fn streamable(input: &str, options: &ReadOptions, fps: Option<f32>) -> CmdResult<Option<Box<dyn InputSource>>> {
    Ok(match front::streamed_flag(input)? {
        Some((cols, rows, frames)) => Some(Box::new(FlagSource::new(input, cols, rows, frames, fps))),
        None if cache_stream::is_streamable(Path::new(input)) => {
            Some(Box::new(CacheSource::open(Path::new(input), options)?))
        }
        None => None,
    })
}

/// `synth:flag:COLSxROWSxFRAMES` as a [`InputSource`]: its frames generated one at a time for
/// every read, its mesh held.
pub struct FlagSource {
    name: String,
    cols: usize,
    rows: usize,
    frames: usize,
    frame_rate: f32,
    topology: Topology,
}

impl FlagSource {
    /// The flag of `cols × rows` vertices and `frames` frames at `fps` (default: synth's rate).
    pub fn new(name: &str, cols: usize, rows: usize, frames: usize, fps: Option<f32>) -> Self {
        let topology = synth::flag_topology(cols, rows);
        Self { name: name.to_owned(), cols, rows, frames, frame_rate: fps.unwrap_or(synth::FRAME_RATE), topology }
    }
}

/// A read of a [`FlagSource`]: the next frame to generate.
struct FlagReader<'a> {
    flag: &'a FlagSource,
    next: usize,
    frame: Vec<f32>,
}

impl FrameRead for FlagReader<'_> {
    fn read_frames(&mut self, frames: usize, out: &mut Vec<f32>) -> animcodec::core::Result<usize> {
        out.clear();
        let n = frames.min(self.flag.frames - self.next);
        for t in self.next..self.next + n {
            synth::flag_frame(self.flag.cols, self.flag.rows, t, self.flag.frames, &mut self.frame);
            out.extend_from_slice(&self.frame);
        }
        self.next += n;
        Ok(n)
    }
}

impl InputSource for FlagSource {
    fn topology(&self) -> &Topology {
        &self.topology
    }
    fn frame_count(&self) -> usize {
        self.frames
    }
    fn frame_rate(&self) -> f32 {
        self.frame_rate
    }
    fn open(&self) -> harness::Result<Box<dyn FrameRead + '_>> {
        Ok(Box::new(FlagReader { flag: self, next: 0, frame: Vec::new() }))
    }
    fn name(&self) -> String {
        self.name.clone()
    }
}
