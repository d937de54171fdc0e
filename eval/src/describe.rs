//! Machine-readable descriptions shared by the command line (`list --json`, `info --json`)
//! and the Python package: a codec with its parameters and rate ladder, and what an `.anim`
//! container holds.

use std::io::{Read, Seek};

use codec_core::container::{self, Header, IndexEntry, INDEX_ENTRY_BYTES, TRAILER_BYTES};
use codec_core::{AnimationCodec, CodecRegistry, Limits, ParamKind, ParamSpec};
use serde::Serialize;
use serde_json::{json, Map, Value};

use crate::params::param_value_json;

/// One codec as JSON: `{name, fourcc, stream_version, summary, params, rate_ladder,
/// search_space}` (`search_space`: `{primary, secondary: [{param, values}]}`, what
/// quality-targeted encoding searches on top of the defaults).
pub fn codec_json(codec: &dyn AnimationCodec) -> Value {
    let ladder = codec.rate_ladder(&codec.default_params());
    let space = codec.search_space(&codec.default_params());
    json!({
        "name": codec.name(),
        "fourcc": codec.fourcc().to_string(),
        "stream_version": codec.stream_version(),
        "summary": codec.summary(),
        "params": codec.param_specs().iter().map(spec_json).collect::<Vec<_>>(),
        "rate_ladder": {
            "param": ladder.param,
            "steps": ladder.steps.iter().map(param_value_json).collect::<Vec<_>>(),
        },
        "search_space": {
            "primary": space.primary.param,
            "secondary": space.secondary.iter().map(|a| json!({
                "param": a.param,
                "values": a.values.iter().map(param_value_json).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        },
    })
}

/// One parameter as JSON: `{name, kind, default, min?, max?, choices?, doc}`.
pub fn spec_json(spec: &ParamSpec) -> Value {
    let mut m = Map::new();
    m.insert("name".into(), spec.name.into());
    let kind = match &spec.kind {
        ParamKind::Int { min, max } => {
            m.insert("min".into(), (*min).into());
            m.insert("max".into(), (*max).into());
            "int"
        }
        ParamKind::Float { min, max } => {
            m.insert("min".into(), (*min).into());
            m.insert("max".into(), (*max).into());
            "float"
        }
        ParamKind::Bool => "bool",
        ParamKind::Choice(options) => {
            m.insert("choices".into(), options.iter().map(|o| Value::from(*o)).collect());
            "choice"
        }
    };
    m.insert("kind".into(), kind.into());
    m.insert("default".into(), param_value_json(&spec.default));
    m.insert("doc".into(), spec.doc.into());
    Value::Object(m)
}

/// Reads a container's header and index and verifies every checksum (header, index, each
/// packet's payload; payloads are read one at a time, not decoded). Errors name the packet.
pub fn read_verified<R: Read + Seek>(src: &mut R, limits: Limits) -> codec_core::Result<(Header, Vec<IndexEntry>)> {
    let (header, index) = container::read_index(src, limits)?;
    for (i, entry) in index.iter().enumerate() {
        container::read_packet_at(src, entry, &header, limits).map_err(|e| {
            codec_core::Error::InvalidAnimation(format!(
                "packet {i} of {} (frames {}..{}, offset {}): {e}",
                index.len(),
                entry.first_frame,
                entry.first_frame as u64 + entry.frame_count as u64,
                entry.offset
            ))
        })?;
    }
    Ok((header, index))
}

/// The sizes of a container, from its header and index.
#[derive(Debug, Clone, Copy)]
pub struct ContainerSizes {
    /// Whole file.
    pub total: u64,
    /// Packets with their framing.
    pub packet_bytes: u64,
    /// Packet payloads only.
    pub payload_bytes: u64,
    /// Index and trailer.
    pub index_bytes: u64,
}

/// Sizes of a container whose header and index [`container::read_index`] has checked (it
/// checks that header, packets, index and trailer tile the file exactly, so the total is their sum).
pub fn container_sizes(header: &Header, index: &[IndexEntry]) -> ContainerSizes {
    let packet_bytes: u64 = index.iter().map(|e| e.stored_bytes()).sum();
    let payload_bytes: u64 = index.iter().map(|e| e.payload_bytes as u64).sum();
    let index_bytes = (8 + index.len() * INDEX_ENTRY_BYTES + 4 + TRAILER_BYTES) as u64;
    ContainerSizes {
        total: header.header_bytes as u64 + packet_bytes + index_bytes,
        packet_bytes,
        payload_bytes,
        index_bytes,
    }
}

/// The stream's scene metadata as JSON: each field the source stated, null when it did not.
pub fn metadata_json(m: &codec_core::SceneMetadata) -> Value {
    json!({
        "up_axis": m.up_axis.map(|a| a.name()),
        "meters_per_unit": m.meters_per_unit,
        "time_codes_per_second": m.time_codes_per_second,
        "start_time_code": m.start_time_code,
    })
}

/// The scene metadata in one line for people (`None` when the source stated none).
pub fn metadata_line(m: &codec_core::SceneMetadata) -> Option<String> {
    if m.is_empty() {
        return None;
    }
    let mut parts = Vec::new();
    if let Some(a) = m.up_axis {
        parts.push(format!("+{} up", a.name()));
    }
    if let Some(u) = m.meters_per_unit {
        parts.push(format!("{u} m per unit"));
    }
    if let Some(t) = m.time_codes_per_second {
        parts.push(format!("{t} time codes/s"));
    }
    if let Some(s) = m.start_time_code {
        parts.push(format!("frame 0 at time code {s}"));
    }
    Some(parts.join(", "))
}

/// `info --json`: codec, sizes, bpvf, checksums verified and every packet, for a container
/// verified by [`read_verified`].
pub fn info_json(registry: &CodecRegistry, header: &Header, index: &[IndexEntry]) -> Value {
    serde_json::to_value(InfoDocument::new(registry, header, index)).unwrap_or(Value::Null)
}

/// What an `.anim` container holds, every checksum verified: the document of `info --json`
/// and of the Python package's `info()` ([`info_json`]).
#[derive(Debug, Clone, Serialize)]
pub struct InfoDocument {
    /// The codec's name (`None`: a FourCC no registered codec has).
    pub codec: Option<&'static str>,
    /// The codec's FourCC.
    pub fourcc: String,
    /// The codec's stream version.
    pub stream_version: u16,
    /// The container's version.
    pub container_version: u16,
    /// Frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// The container's size.
    pub bytes: u64,
    /// Header bytes (topology included).
    pub header_bytes: usize,
    /// Codec configuration bytes.
    pub config_bytes: usize,
    /// Topology bytes.
    pub topology_bytes: usize,
    /// Packet bytes (with their framing).
    pub packet_bytes: u64,
    /// Packet payload bytes.
    pub payload_bytes: u64,
    /// Index bytes (with the trailer).
    pub index_bytes: u64,
    /// Bits per vertex per frame of the whole container.
    pub bpvf: Option<f64>,
    /// Bits per vertex per frame of the packet payloads alone.
    pub geometry_bpvf: Option<f64>,
    /// Keyframe packets.
    pub keyframes: usize,
    /// The scene metadata ([`metadata_json`]).
    pub metadata: Value,
    /// The checksums verified.
    pub verified: Verified,
    /// Every packet.
    pub packets: Vec<PacketEntry>,
}

/// The checksums an [`InfoDocument`] verified.
#[derive(Debug, Clone, Serialize)]
pub struct Verified {
    /// The header's.
    pub header_checksum: bool,
    /// The index's.
    pub index_checksum: bool,
    /// Packets whose checksum was verified.
    pub packet_checksums: usize,
}

/// One packet of an [`InfoDocument`].
#[derive(Debug, Clone, Serialize)]
pub struct PacketEntry {
    /// Its first frame.
    pub first_frame: u32,
    /// Frames it holds.
    pub frames: u32,
    /// Whether it decodes without the packets before it.
    pub keyframe: bool,
    /// Payload bytes.
    pub bytes: u32,
    /// Offset in the container.
    pub offset: u64,
}

impl InfoDocument {
    /// The document of a verified container's header and index.
    pub fn new(registry: &CodecRegistry, header: &Header, index: &[IndexEntry]) -> Self {
        let sizes = container_sizes(header, index);
        let info = &header.info;
        let (v, f) = (info.vertex_count(), info.frame_count);
        // `read_index` refuses containers without vertices or frames, so bpvf is always defined.
        let bpvf = |bytes: u64| metrics::bpvf(bytes, v, f).ok();
        Self {
            codec: registry.by_fourcc(info.fourcc).ok().map(|c| c.name()),
            fourcc: info.fourcc.to_string(),
            stream_version: info.codec_version,
            container_version: header.container_version,
            frames: f,
            vertices: v,
            triangles: info.topology.triangle_count(),
            frame_rate: info.frame_rate,
            bytes: sizes.total,
            header_bytes: header.header_bytes,
            config_bytes: header.config.len(),
            topology_bytes: header.topology_bytes,
            packet_bytes: sizes.packet_bytes,
            payload_bytes: sizes.payload_bytes,
            index_bytes: sizes.index_bytes,
            bpvf: bpvf(sizes.total),
            geometry_bpvf: bpvf(sizes.payload_bytes),
            keyframes: index.iter().filter(|e| e.keyframe).count(),
            metadata: metadata_json(&header.metadata),
            verified: Verified { header_checksum: true, index_checksum: true, packet_checksums: index.len() },
            packets: index
                .iter()
                .map(|e| PacketEntry {
                    first_frame: e.first_frame,
                    frames: e.frame_count,
                    keyframe: e.keyframe,
                    bytes: e.payload_bytes,
                    offset: e.offset,
                })
                .collect(),
        }
    }
}
