//! `animcodec decode`: `.anim` container → animation file.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use std::time::Instant;

use animcodec::formats::{self, WriteOptions};
use animcodec::output::OutputPolicy;
use codec_core::{Limits, StreamDecoder};
use serde_json::json;

use super::{emit, emit_json, CmdResult, WithContext};
use crate::DecodeArgs;

/// Opens `path` for reading, naming it in the error.
pub fn open(path: &Path) -> CmdResult<BufReader<File>> {
    let file = File::open(path).map_err(|e| codec_core::Error::io(format!("cannot open {}", path.display()), e))?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(format!("cannot read {}: it is a directory", path.display()).into());
    }
    Ok(BufReader::new(file))
}

/// Runs `decode`.
pub fn run(args: &DecodeArgs, limits: Limits) -> CmdResult {
    let options =
        WriteOptions { policy: OutputPolicy::new(args.force).with_input(&args.input), topology_obj: args.topology_obj };
    // Refuse a forbidden output before decoding (the sequence checks run when writing).
    if !formats::obj::is_directory_target(&args.output) {
        options.policy.check(&args.output)?;
    }
    let registry = animcodec::registry();
    let start = Instant::now();
    let stages = crate::progress::Stages::new("decode", 2, args.json);
    stages.stage(format!("decoding {}", args.input.display()));
    let name = || args.input.display().to_string();
    let decoder = StreamDecoder::new(open(&args.input)?, &registry, limits).in_file(&name())?;
    let codec = decoder.codec_name();
    let animation = decoder.decode_all().in_file(&name())?;
    let decode_seconds = start.elapsed().as_secs_f64();

    let write_start = Instant::now();
    stages.stage(format!("writing {}", args.output.display()));
    let written = formats::write_animation_with(&args.output, &animation, &options)?;
    drop(stages);
    let write_seconds = write_start.elapsed().as_secs_f64();

    let (v, f, t) = (animation.vertex_count(), animation.frame_count(), animation.triangles().len());
    if args.json {
        return emit_json(&json!({
            "codec": codec,
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "files": written.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "frames": f,
            "vertices": v,
            "triangles": t,
            "frame_rate": animation.frame_rate(),
            "decode_seconds": decode_seconds,
            "write_seconds": write_seconds,
        }));
    }
    emit(&format!(
        "{input}: {codec}, {f} frames × {v} vertices, {t} triangles, {fps} fps, decoded in {decode_seconds:.2} s\n\
         → {out} ({files}, written in {write_seconds:.2} s)\n",
        input = args.input.display(),
        fps = animation.frame_rate(),
        out = args.output.display(),
        files = if written.len() == 1 { "1 file".to_owned() } else { format!("{} files", written.len()) },
    ))
}
