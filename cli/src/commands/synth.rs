//! `animcodec synth`: write a built-in synthetic animation to a file.

use animcodec::formats::{self, WriteOptions};
use animcodec::output::OutputPolicy;
use codec_core::synth;

use super::{emit, CmdResult};
use crate::SynthArgs;

/// Runs `synth`.
pub fn run(args: &SynthArgs) -> CmdResult {
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
        args.output.display()
    ))
}
