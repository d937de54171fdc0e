//! `animcodec synth`: write a built-in synthetic animation to a file.

use animcodec::formats::stream::{is_streamable_output, CacheWriter};
use animcodec::formats::{self, WriteOptions};
use animcodec::output::OutputPolicy;
use animcodec::synth;

use super::args::SizeArg;
use super::{emit, shown, CmdResult};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `animcodec synth`.
#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Animation: flag (waving cloth), cylinder (two-bone skinned bend + twist), tumble (rigid
    /// body), phases (motion changing character at frames F/4, F/2, 3F/4); or
    /// flag:COLSxROWSxFRAMES, a flag of any length written frame by frame to a .pc2/.mdd (its
    /// frames are never all held in memory, only its mesh; for scale tests).
    #[arg(value_name = "NAME")]
    pub name: String,

    /// Size preset.
    #[arg(long, value_enum, default_value_t = SizeArg::Small)]
    pub size: SizeArg,

    /// Output file: .pc2 or .mdd (with `STEM.obj` beside it holding the triangles), or an OBJ
    /// sequence (as for `decode -o`).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,

    /// Replace the existing output file (without it, an existing output is an error). It names
    /// the .pc2/.mdd only: an existing STEM.obj beside it is replaced only when it was written
    /// for this cache (by this program) or holds the same mesh; any other (the topology of
    /// another cache of the same stem, a model) is refused by name: remove it or choose another
    /// output name.
    #[arg(short, long)]
    pub force: bool,
}

/// Runs `synth`.
pub fn run(args: &SynthArgs) -> CmdResult {
    if let Some((cols, rows, frames)) = animcodec::front::streamed_flag(&format!("synth:{}", args.name))? {
        return run_streamed_flag(args, cols, rows, frames);
    }
    let animation = synth::by_name(&args.name, args.size.into())?;
    let options = WriteOptions { policy: OutputPolicy::new(args.force), topology_obj: true };
    formats::write_animation_with(&args.output, &animation, &options)?;
    emit(&format!(
        "{} ({}): {} frames × {} vertices, {} triangles, {} fps → {}\n",
        args.name,
        synth::SynthSize::from(args.size).name(),
        animation.frame_count(),
        animation.vertex_count(),
        animation.triangles().len(),
        animation.frame_rate(),
        shown(&args.output)
    ))
}

/// `synth flag:COLSxROWSxFRAMES -o OUT.pc2|.mdd`: the flag written one frame at a time
/// (scale benchmarks need caches larger than memory).
fn run_streamed_flag(args: &SynthArgs, cols: usize, rows: usize, frames: usize) -> CmdResult {
    if !is_streamable_output(&args.output) {
        return Err(format!(
            "{}: flag:COLSxROWSxFRAMES is written frame by frame, to a .pc2 or .mdd file only",
            shown(&args.output)
        )
        .into());
    }
    let topology = synth::flag_topology(cols, rows);
    let options = WriteOptions { policy: OutputPolicy::new(args.force), topology_obj: true };
    let mut writer = CacheWriter::create(&args.output, &topology, frames, synth::FRAME_RATE, &options)?;
    let mut frame = Vec::with_capacity(cols * rows * 3);
    for t in 0..frames {
        synth::flag_frame(cols, rows, t, frames, &mut frame);
        writer.write_frames(&frame)?;
    }
    writer.finish()?;
    emit(&format!(
        "flag ({cols}x{rows}x{frames}, frame by frame): {frames} frames × {} vertices, {} triangles, {} fps → {}\n",
        topology.vertex_count(),
        topology.triangle_count(),
        synth::FRAME_RATE,
        shown(&args.output)
    ))
}
