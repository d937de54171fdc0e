//! `animcodec decode`: `.anim` container → animation file.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use std::time::Instant;

use animcodec::formats::stream::{self as cache_stream, CacheWriter};
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
    if cache_stream::is_streamable_output(&args.output) {
        return run_streaming(args, limits, &options);
    }
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

/// `decode` to a `.pc2`/`.mdd` file (issue 30): each packet's frames are written as soon as they
/// are decoded, so memory holds one packet (and the codec decoder's state), never the whole
/// animation; `limits` are charged the same way ([`StreamDecoder::new_streaming`]). The file is
/// pending until the last frame is written: a failure leaves nothing.
fn run_streaming(args: &DecodeArgs, limits: Limits, options: &WriteOptions) -> CmdResult {
    let registry = animcodec::registry();
    let name = || args.input.display().to_string();
    let mut decoder = StreamDecoder::new_streaming(open(&args.input)?, &registry, limits).in_file(&name())?;
    let codec = decoder.codec_name();
    let info = decoder.header().info.clone();
    let mut writer = CacheWriter::create(&args.output, &info.topology, info.frame_count, info.frame_rate, options)?;
    let start = Instant::now();
    let (mut decode_seconds, mut write_seconds) = (0.0, 0.0);
    loop {
        let t = Instant::now();
        let Some(packet) = decoder.next_packet() else { break };
        let packet = packet.in_file(&name())?;
        decode_seconds += t.elapsed().as_secs_f64();
        let t = Instant::now();
        writer.write_frames(&packet.positions)?;
        write_seconds += t.elapsed().as_secs_f64();
    }
    let t = Instant::now();
    let written = writer.finish()?;
    write_seconds += t.elapsed().as_secs_f64();
    let _ = start;
    let (v, f, t) = (info.vertex_count(), info.frame_count, info.topology.triangle_count());
    if args.json {
        return emit_json(&json!({
            "codec": codec,
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "files": written.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "frames": f,
            "vertices": v,
            "triangles": t,
            "frame_rate": info.frame_rate,
            "decode_seconds": decode_seconds,
            "write_seconds": write_seconds,
        }));
    }
    emit(&format!(
        "{input}: {codec}, {f} frames × {v} vertices, {t} triangles, {fps} fps, decoded in {decode_seconds:.2} s\n\
         → {out} ({files}, written frame by frame in {write_seconds:.2} s)\n",
        input = args.input.display(),
        fps = info.frame_rate,
        out = args.output.display(),
        files = if written.len() == 1 { "1 file".to_owned() } else { format!("{} files", written.len()) },
    ))
}
