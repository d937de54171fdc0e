//! `animcodec info`: what is inside an `.anim` container, read from its header and index
//! without decoding any packet; every checksum (header, index, each packet) is verified.

use std::fmt::Write as _;

use animcodec::core::container;
use animcodec::core::Limits;
use animcodec::describe;

use super::decode::open;
use super::{emit, emit_json, CmdResult, WithContext};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `animcodec info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Input `.anim` container (or a `.gltf`/`.glb` file: its animations are listed; an `.abc`
    /// file: its mesh objects are listed).
    #[arg(value_name = "IN.anim")]
    pub input: PathBuf,

    /// List every packet even when there are many (the text output otherwise shows the first 32).
    #[arg(long)]
    pub all_packets: bool,

    /// Print JSON: {codec, fourcc, frames, vertices, triangles, bytes, bpvf, geometry_bpvf,
    /// packets: [{first_frame, frame_count, keyframe, bytes}], …}.
    #[arg(long)]
    pub json: bool,
}

/// Packets listed by the text output unless `--all-packets` is given.
const SHOWN_PACKETS: usize = 32;

/// Runs `info`.
pub fn run(args: &InfoArgs, limits: Limits) -> CmdResult {
    let ext = args.input.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    if matches!(ext.as_deref(), Some("gltf" | "glb" | "abc")) {
        return super::animations::run(&args.input, args.json);
    }
    let mut src = open(&args.input)?;
    let (header, index) = container::read_index(&mut src, limits).context(|| args.input.display().to_string())?;
    // read_index has checked the header and index checksums; every packet's checksum and frame
    // range is checked here (payloads are read one at a time, not decoded).
    for (i, entry) in index.iter().enumerate() {
        container::read_packet_at(&mut src, entry, &header, limits).context(|| {
            format!(
                "{}: packet {i} of {} (frames {}..{}, offset {})",
                args.input.display(),
                index.len(),
                entry.first_frame,
                entry.first_frame as u64 + entry.frame_count as u64,
                entry.offset
            )
        })?;
    }
    let sizes = describe::container_sizes(&header, &index);
    let (packet_bytes, payload_bytes, index_bytes, total) =
        (sizes.packet_bytes, sizes.payload_bytes, sizes.index_bytes, sizes.total);

    let info = &header.info;
    let registry = animcodec::registry();
    let codec = registry.by_fourcc(info.fourcc).ok().map(|c| c.name());
    let (v, f, t) = (info.vertex_count(), info.frame_count, info.topology.triangle_count());
    // `read_index` refuses containers without vertices or frames.
    let rate = animcodec::metrics::bpvf(total, v, f)?;
    let geometry_rate = animcodec::metrics::bpvf(payload_bytes, v, f)?;
    let keyframes = index.iter().filter(|e| e.keyframe).count();

    if args.json {
        return emit_json(&describe::info_json(&registry, &header, &index));
    }

    let mut out = String::new();
    let _ = writeln!(out, "file       {} ({total} bytes)", args.input.display());
    let _ = writeln!(
        out,
        "codec      {} (FourCC {}, stream version {}, container version {})",
        codec.unwrap_or("unknown to this build"),
        info.fourcc,
        info.codec_version,
        header.container_version
    );
    let _ = writeln!(out, "animation  {f} frames × {v} vertices, {t} triangles, {} fps", info.frame_rate);
    if let Some(line) = describe::metadata_line(&header.metadata) {
        let _ = writeln!(out, "scene      {line} (kept from the source for the USD and Alembic writers)");
    }
    let _ = writeln!(
        out,
        "header     {} bytes (codec config {} bytes, topology {} bytes)",
        header.header_bytes,
        header.config.len(),
        header.topology_bytes
    );
    let _ = writeln!(
        out,
        "packets    {} ({keyframes} keyframes): {payload_bytes} payload bytes + {} framing; index + trailer {index_bytes} bytes",
        index.len(),
        packet_bytes - payload_bytes
    );
    let _ =
        writeln!(out, "bpvf       {rate:.4} bits/vertex/frame (geometry only, packet payloads: {geometry_rate:.4})");
    let _ = writeln!(
        out,
        "verified   header, index and all {} packet checksums OK (payloads not decoded: `decode` does that)",
        index.len()
    );
    let _ = writeln!(out, "\n{:>7}  {:>11}  {:>7}  {:>3}  {:>10}", "packet", "first_frame", "frames", "key", "bytes");
    let shown = if args.all_packets { index.len() } else { index.len().min(SHOWN_PACKETS) };
    for (i, e) in index.iter().take(shown).enumerate() {
        let key = if e.keyframe { "yes" } else { "no" };
        let _ = writeln!(out, "{i:>7}  {:>11}  {:>7}  {key:>3}  {:>10}", e.first_frame, e.frame_count, e.payload_bytes);
    }
    if shown < index.len() {
        let _ = writeln!(out, "… {} more packets (--all-packets lists them)", index.len() - shown);
    }
    emit(&out)
}
