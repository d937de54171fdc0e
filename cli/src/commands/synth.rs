//! `animcodec synth`: write a built-in synthetic animation to a file.

use animcodec::formats::stream::{is_streamable_output, CacheWriter};
use animcodec::formats::{self, WriteOptions};
use animcodec::output::OutputPolicy;
use animcodec::synth;

use super::{emit, shown, CmdResult};
use crate::SynthArgs;

/// Runs `synth`.
pub fn run(args: &SynthArgs) -> CmdResult {
    if let Some((cols, rows, frames)) = super::encode::parse_streamed_flag(&format!("synth:{}", args.name))? {
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
