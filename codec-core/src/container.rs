//! The `.anim` container: a versioned, little-endian format holding one coded animation.
//!
//! Layout (documented field by field in `FORMAT.md`): header with codec FourCC, counts,
//! frame rate, codec configuration and compressed topology; then packets, each tagged with
//! its frame range and a CRC-32; then an index of packet offsets and a trailer pointing at
//! it, so a reader can seek to the packet holding frame `t`.
//!
//! Writing is streaming ([`ContainerWriter`] over any `Write`); reading is streaming too
//! ([`ContainerReader`] over any `Read`), and [`read_index`] seeks on `Read + Seek` sources.
//! Every size read from a stream is checked against [`Limits`] and against what the
//! stream can still hold before anything is allocated.

use std::io::{Read, Seek, SeekFrom, Write};

use crate::animation::Topology;
use crate::bytes::{ByteReader, ByteWriter};
use crate::codec::{FourCc, Packet, StreamInfo};
use crate::entropy;
use crate::error::{Error, Result};
pub use crate::limits::{Limits, DEFAULT_MAX_MEMORY, DEFAULT_MAX_WORK};
use crate::metadata::SceneMetadata;

/// File magic: `ANIMCDC` then 0x1A (stops `type` on DOS, catches text-mode mangling).
pub const MAGIC: [u8; 8] = *b"ANIMCDC\x1a";
/// Newest container version this library reads and writes. It writes 5 when the topology
/// block uses the predicted traversal coding (method 3; the metadata block is then present,
/// possibly empty), else 4 when the stream carries scene metadata ([`crate::metadata`]; a
/// block after the topology), else 3 when the topology block uses the traversal coding
/// (method 2), else 2 (the same bytes as before versions 3 to 5).
pub const CONTAINER_VERSION: u16 = 5;
/// First container version with the scene-metadata block.
pub const METADATA_CONTAINER_VERSION: u16 = 4;
/// Tag opening every packet.
pub const PACKET_TAG: [u8; 4] = *b"APKT";
/// Tag opening the index.
pub const INDEX_TAG: [u8; 4] = *b"AIDX";
/// Tag closing the trailer.
pub const TRAILER_TAG: [u8; 4] = *b"AEND";
/// Bytes in the fixed part of the header (magic … frame rate).
pub const FIXED_HEADER_BYTES: usize = 32;
/// Bytes per index entry.
pub const INDEX_ENTRY_BYTES: usize = 25;
/// Bytes in the trailer (index offset + tag).
pub const TRAILER_BYTES: usize = 12;
/// Bytes of packet framing around the payload (tag, first frame, count, flags, length, CRC).
pub const PACKET_OVERHEAD_BYTES: usize = 21;

const CTX: &str = "container";

fn limit(field: &'static str, value: u64, limit: usize) -> Result<()> {
    if value > limit as u64 {
        return Err(Error::LimitExceeded { context: CTX.into(), field: field.into(), value, limit: limit as u64 });
    }
    Ok(())
}

/// Everything in a container header.
#[derive(Debug, Clone)]
pub struct Header {
    /// Container version found in the stream.
    pub container_version: u16,
    /// Stream information handed to the decoder.
    pub info: StreamInfo,
    /// Codec configuration bytes.
    pub config: Vec<u8>,
    /// Size of the whole header in bytes, checksum included.
    pub header_bytes: usize,
    /// Size of the compressed topology section in bytes.
    pub topology_bytes: usize,
    /// The source's scene metadata (empty before container version 4).
    pub metadata: SceneMetadata,
}

/// One entry of the packet index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IndexEntry {
    /// Byte offset of the packet tag from the start of the stream.
    pub offset: u64,
    /// First frame of the packet.
    pub first_frame: u32,
    /// Number of frames in the packet.
    pub frame_count: u32,
    /// True for a random-access packet.
    pub keyframe: bool,
    /// Payload bytes.
    pub payload_bytes: u32,
}

impl IndexEntry {
    /// Bytes the packet takes in the stream, framing included.
    pub fn stored_bytes(&self) -> u64 {
        self.payload_bytes as u64 + PACKET_OVERHEAD_BYTES as u64
    }
}

/// Topology block method byte (container version 2): version 1's varint list + zstd.
const TOPOLOGY_LIST: u8 = 0;
/// Topology block method byte (container version 2): [`crate::connectivity`]'s adaptive
/// arithmetic coding.
const TOPOLOGY_CONNECTIVITY: u8 = 1;
/// Topology block method byte (container version 3): [`crate::traversal`]'s walk over the
/// mesh (an older reader would not know it, hence the version).
const TOPOLOGY_TRAVERSAL: u8 = 2;
/// Topology block method byte (container version 5): the same walk with each new vertex
/// named by candidate kinds ([`crate::traversal::encode_predicted`]).
const TOPOLOGY_PREDICTED: u8 = 3;
/// First container version with topology method 3.
const PREDICTED_CONTAINER_VERSION: u16 = 5;

/// Container version 1's topology coding: per triangle, zigzag varints of the first index's
/// delta from the previous triangle's first index and of the other two indices relative to
/// the first; then zstd.
pub fn encode_topology_list(topology: &Topology) -> Vec<u8> {
    let mut w = ByteWriter::new();
    let mut prev = 0i64;
    for t in topology.triangles() {
        let a = t[0] as i64;
        w.varint_signed(a - prev);
        w.varint_signed(t[1] as i64 - a);
        w.varint_signed(t[2] as i64 - a);
        prev = a;
    }
    entropy::compress(w.as_slice(), entropy::DEFAULT_LEVEL)
}

/// Codes a triangle list exactly as the container stores it: a method byte, then the
/// smallest of [`crate::traversal::encode_predicted`] and [`crate::traversal::encode`] (each
/// used only when decoding it gives back exactly `topology`: the stream encoder's
/// [`crate::connectivity::canonical_order`]), [`crate::connectivity::encode`] and version 1's
/// list coding; ties keep the older method. Returns the container version the block needs
/// (5 for method 3, 3 for method 2, else 2) with the block.
pub fn encode_topology(topology: &Topology) -> (u16, Vec<u8>) {
    let list = encode_topology_list(topology);
    let nonempty = topology.triangle_count() > 0;
    let connectivity = nonempty.then(|| crate::connectivity::encode(topology)).flatten();
    // The encoder checks its own output: the block must decode to this very list.
    let traversal = nonempty.then(|| crate::traversal::encode(topology)).flatten().filter(|b| {
        crate::traversal::decode(b, topology.vertex_count(), topology.triangle_count()).is_ok_and(|t| t == *topology)
    });
    let predicted = nonempty.then(|| crate::traversal::encode_predicted(topology)).flatten().filter(|b| {
        crate::traversal::decode_predicted(b, topology.vertex_count(), topology.triangle_count())
            .is_ok_and(|t| t == *topology)
    });
    let mut best = (2, TOPOLOGY_LIST, list);
    for (version, method, body) in [
        (2, TOPOLOGY_CONNECTIVITY, connectivity),
        (3, TOPOLOGY_TRAVERSAL, traversal),
        (PREDICTED_CONTAINER_VERSION, TOPOLOGY_PREDICTED, predicted),
    ] {
        if let Some(body) = body.filter(|b| b.len() < best.2.len()) {
            best = (version, method, body);
        }
    }
    let (version, method, body) = best;
    let mut out = Vec::with_capacity(body.len() + 1);
    out.push(method);
    out.extend_from_slice(&body);
    (version, out)
}

/// Inverse of [`encode_topology`] for `container_version` (1: the list coding alone; 2: the
/// method byte first, methods 0 and 1; 3 and 4: also method 2; 5: also method 3), checking every index against
/// `vertex_count`.
pub fn decode_topology(
    block: &[u8],
    container_version: u16,
    vertex_count: usize,
    triangle_count: usize,
    limits: &Limits,
) -> Result<Topology> {
    if container_version < 2 {
        return decode_topology_list(block, vertex_count, triangle_count, limits);
    }
    let (&method, body) =
        block.split_first().ok_or_else(|| Error::malformed(CTX, "topology", "empty topology block"))?;
    type DecoderBytes = fn(usize, usize) -> u64;
    type Decode = fn(&[u8], usize, usize) -> Result<Topology>;
    let (decoder_bytes, decode): (DecoderBytes, Decode) = match method {
        TOPOLOGY_LIST => return decode_topology_list(body, vertex_count, triangle_count, limits),
        TOPOLOGY_CONNECTIVITY => (crate::connectivity::decoder_bytes, crate::connectivity::decode),
        TOPOLOGY_TRAVERSAL if container_version >= 3 => (crate::traversal::decoder_bytes, crate::traversal::decode),
        TOPOLOGY_PREDICTED if container_version >= PREDICTED_CONTAINER_VERSION => {
            (crate::traversal::decoder_bytes_predicted, crate::traversal::decode_predicted)
        }
        m => return Err(Error::malformed(CTX, "topology", format!("unknown topology coding method {m}"))),
    };
    // An arithmetic-coded block (methods 1 to 3): the triangles and the decoder's own state
    // are checked against `limits` before `decode` allocates them.
    limits.check_alloc(CTX, "triangle_count", triangle_count as u64 * 12)?;
    if triangle_count > 0 {
        limits.check_alloc(CTX, "vertex_count", decoder_bytes(vertex_count, triangle_count))?;
    }
    decode(body, vertex_count, triangle_count)
}

/// Container version 1's topology decoding (inverse of [`encode_topology_list`]).
fn decode_topology_list(block: &[u8], vertex_count: usize, triangle_count: usize, limits: &Limits) -> Result<Topology> {
    // Each index takes at most 5 varint bytes for a 32-bit delta (zigzag of ±2^32 fits 5–6 bytes).
    let max_raw = triangle_count.saturating_mul(3 * 6);
    let raw = entropy::decompress(block, CTX, "topology", max_raw.min(limits.max_alloc_bytes))?;
    limits.check_alloc(CTX, "triangle_count", triangle_count as u64 * 12)?;
    let mut r = ByteReader::new(&raw, CTX);
    let mut triangles = Vec::with_capacity(triangle_count);
    let mut prev = 0i64;
    for t in 0..triangle_count {
        let a = prev + r.varint_signed("topology")?;
        let b = a + r.varint_signed("topology")?;
        let c = a + r.varint_signed("topology")?;
        for i in [a, b, c] {
            if i < 0 || i >= vertex_count as i64 {
                return Err(
                    r.malformed("topology", format!("triangle {t} has index {i}, vertex count is {vertex_count}"))
                );
            }
        }
        triangles.push([a as u32, b as u32, c as u32]);
        prev = a;
    }
    r.expect_end("topology")?;
    Topology::new(vertex_count, triangles).map_err(|e| Error::malformed(CTX, "topology", e.to_string()))
}

/// Writes a container to any `Write`, one packet at a time.
#[derive(Debug)]
pub struct ContainerWriter<W: Write> {
    sink: W,
    offset: u64,
    index: Vec<IndexEntry>,
    frame_count: usize,
    next_frame: u64,
}

impl<W: Write> ContainerWriter<W> {
    /// Writes the header. `frame_count` is the number of frames the packets will cover;
    /// [`ContainerWriter::finish`] checks it.
    pub fn new(
        sink: W,
        fourcc: FourCc,
        codec_version: u16,
        topology: &Topology,
        frame_count: usize,
        frame_rate: f32,
        config: &[u8],
    ) -> Result<Self> {
        let info = StreamInfo { fourcc, codec_version, topology: topology.clone(), frame_count, frame_rate };
        Self::with_metadata(sink, &info, config, &SceneMetadata::default())
    }

    /// Writes the header of the stream `info` describes, with the source's scene `metadata`
    /// (container version 4 when there is any, else the version the topology needs).
    pub fn with_metadata(mut sink: W, info: &StreamInfo, config: &[u8], metadata: &SceneMetadata) -> Result<Self> {
        let StreamInfo { fourcc, codec_version, ref topology, frame_count, frame_rate } = *info;
        let too_big = |what: &str| Error::InvalidAnimation(format!("{what} does not fit the container's 32-bit field"));
        crate::animation::check_stream_frame_rate(frame_rate)?;
        metadata.validate()?;
        let (topology_version, topo) = encode_topology(topology);
        let meta_block = metadata.to_block();
        // Version 5 (method 3) always has the metadata block, empty when there is none.
        let container_version =
            if meta_block.is_empty() { topology_version } else { METADATA_CONTAINER_VERSION.max(topology_version) };
        let mut w = ByteWriter::new();
        w.bytes(&MAGIC);
        w.u16(container_version);
        w.bytes(&fourcc.0);
        w.u16(codec_version);
        w.u32(u32::try_from(topology.vertex_count()).map_err(|_| too_big("vertex count"))?);
        w.u32(u32::try_from(frame_count).map_err(|_| too_big("frame count"))?);
        w.u32(u32::try_from(topology.triangle_count()).map_err(|_| too_big("triangle count"))?);
        w.f32(frame_rate);
        debug_assert_eq!(w.len(), FIXED_HEADER_BYTES);
        w.u32(u32::try_from(config.len()).map_err(|_| too_big("codec config"))?);
        w.bytes(config);
        w.u32(u32::try_from(topo.len()).map_err(|_| too_big("topology"))?);
        w.bytes(&topo);
        if container_version >= METADATA_CONTAINER_VERSION {
            w.u32(meta_block.len() as u32);
            w.bytes(&meta_block);
        }
        let crc = crc32fast::hash(w.as_slice());
        w.u32(crc);
        sink.write_all(w.as_slice()).map_err(|e| Error::io("writing container header", e))?;
        Ok(Self { sink, offset: w.len() as u64, index: Vec::new(), frame_count, next_frame: 0 })
    }

    /// Appends one packet; packets must cover consecutive frame ranges from frame 0.
    pub fn write_packet(&mut self, packet: &Packet) -> Result<()> {
        if packet.frame_count == 0 || packet.first_frame as u64 != self.next_frame {
            return Err(Error::Unsupported {
                context: CTX.into(),
                detail: format!(
                    "packet for frames {}..+{} breaks the sequence (expected first frame {})",
                    packet.first_frame, packet.frame_count, self.next_frame
                ),
            });
        }
        let payload_len = u32::try_from(packet.data.len())
            .map_err(|_| Error::InvalidAnimation("packet payload over 4 GiB".into()))?;
        let mut w = ByteWriter::new();
        w.bytes(&PACKET_TAG);
        w.u32(packet.first_frame);
        w.u32(packet.frame_count);
        w.u8(packet.keyframe as u8);
        w.u32(payload_len);
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&w.as_slice()[4..]);
        hasher.update(&packet.data);
        let crc = hasher.finalize();
        let write = |sink: &mut W, b: &[u8]| sink.write_all(b).map_err(|e| Error::io("writing packet", e));
        write(&mut self.sink, w.as_slice())?;
        write(&mut self.sink, &packet.data)?;
        write(&mut self.sink, &crc.to_le_bytes())?;
        self.index.push(IndexEntry {
            offset: self.offset,
            first_frame: packet.first_frame,
            frame_count: packet.frame_count,
            keyframe: packet.keyframe,
            payload_bytes: payload_len,
        });
        self.offset += (w.len() + packet.data.len() + 4) as u64;
        self.next_frame += packet.frame_count as u64;
        Ok(())
    }

    /// Writes the index and trailer and returns the sink. Fails if the packets do not
    /// cover exactly the declared frame count.
    pub fn finish(mut self) -> Result<W> {
        if self.next_frame != self.frame_count as u64 {
            return Err(Error::Unsupported {
                context: CTX.into(),
                detail: format!("packets cover {} frames, header declares {}", self.next_frame, self.frame_count),
            });
        }
        let mut w = ByteWriter::new();
        w.bytes(&INDEX_TAG);
        w.u32(self.index.len() as u32);
        for e in &self.index {
            w.u64(e.offset);
            w.u32(e.first_frame);
            w.u32(e.frame_count);
            w.u8(e.keyframe as u8);
            w.u32(e.payload_bytes);
            w.u32(0); // reserved
        }
        let crc = crc32fast::hash(w.as_slice());
        w.u32(crc);
        w.u64(self.offset);
        w.bytes(&TRAILER_TAG);
        self.sink.write_all(w.as_slice()).map_err(|e| Error::io("writing container index", e))?;
        self.sink.flush().map_err(|e| Error::io("flushing container", e))?;
        Ok(self.sink)
    }
}

fn read_exact_or_truncated<R: Read>(src: &mut R, buf: &mut [u8], field: &'static str) -> Result<()> {
    src.read_exact(buf).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => Error::Truncated { context: CTX.into(), field: field.into() },
        _ => Error::io(format!("reading {field}"), e),
    })
}

/// Reads `len` bytes from `src` after checking `len` against `max`. Reads in chunks so a
/// lying length on a short stream never allocates more than the stream holds (plus one chunk).
fn read_vec<R: Read>(src: &mut R, len: u64, max: u64, field: &'static str) -> Result<Vec<u8>> {
    if len > max {
        return Err(Error::AllocLimit { context: CTX.into(), what: field.into(), bytes: len, limit: max });
    }
    let mut out = Vec::new();
    let mut left = len as usize;
    let mut chunk = [0u8; 64 * 1024];
    while left > 0 {
        let n = left.min(chunk.len());
        read_exact_or_truncated(src, &mut chunk[..n], field)?;
        out.extend_from_slice(&chunk[..n]);
        left -= n;
    }
    Ok(out)
}

/// Item yielded while reading a container sequentially.
#[derive(Debug)]
pub enum Section {
    /// A packet, checksum verified, frame range consistent with the header.
    Packet(Packet),
    /// The index; every packet has been read.
    End(Vec<IndexEntry>),
}

/// Reads a container sequentially from any `Read`.
#[derive(Debug)]
pub struct ContainerReader<R: Read> {
    src: R,
    header: Header,
    limits: Limits,
    next_frame: u64,
    offset: u64,
    seen: Vec<IndexEntry>,
    done: bool,
}

impl<R: Read> ContainerReader<R> {
    /// Reads and checks the header.
    pub fn new(mut src: R, limits: Limits) -> Result<Self> {
        let mut fixed = [0u8; FIXED_HEADER_BYTES + 4];
        read_exact_or_truncated(&mut src, &mut fixed[..8], "magic")?;
        if fixed[..8] != MAGIC {
            return Err(Error::malformed(CTX, "magic", "not an animcodec stream (bad magic bytes)"));
        }
        read_exact_or_truncated(&mut src, &mut fixed[8..], "header")?;
        let mut r = ByteReader::new(&fixed, CTX);
        r.take(8, "magic")?;
        let container_version = r.u16("container_version")?;
        if container_version == 0 || container_version > CONTAINER_VERSION {
            return Err(Error::Unsupported {
                context: CTX.into(),
                detail: format!("container version {container_version}; this build reads 1..={CONTAINER_VERSION}"),
            });
        }
        let mut fourcc = [0u8; 4];
        fourcc.copy_from_slice(r.take(4, "fourcc")?);
        let codec_version = r.u16("codec_version")?;
        let vertex_count = r.u32("vertex_count")? as u64;
        let frame_count = r.u32("frame_count")? as u64;
        let triangle_count = r.u32("triangle_count")? as u64;
        let frame_rate = r.f32("frame_rate")?;
        let config_len = r.u32("config_len")? as u64;
        if vertex_count == 0 {
            return Err(r.malformed("vertex_count", "zero vertices"));
        }
        if frame_count == 0 {
            return Err(r.malformed("frame_count", "zero frames"));
        }
        // The rates the file readers accept (`io`'s `FRAME_RATE_RANGE`), so
        // a decoded stream always writes a file animcodec reads back.
        if !crate::animation::FRAME_RATE_RANGE.contains(&frame_rate) {
            return Err(r.malformed(
                "frame_rate",
                format!(
                    "{frame_rate:e} frames per second is outside {:e}..={:e} (not a rate any reader accepts)",
                    crate::animation::FRAME_RATE_RANGE.start(),
                    crate::animation::FRAME_RATE_RANGE.end()
                ),
            ));
        }
        limit("vertex_count", vertex_count, limits.max_vertices)?;
        limit("frame_count", frame_count, limits.max_frames)?;
        limit("triangle_count", triangle_count, limits.max_triangles)?;
        let config = read_vec(&mut src, config_len, limits.max_alloc_bytes as u64, "config")?;
        let mut len = [0u8; 4];
        read_exact_or_truncated(&mut src, &mut len, "topology_len")?;
        let topology_len = u32::from_le_bytes(len) as u64;
        let topo_block = read_vec(&mut src, topology_len, limits.max_alloc_bytes as u64, "topology")?;
        let (meta_len, meta_block) = if container_version >= METADATA_CONTAINER_VERSION {
            let mut meta_len = [0u8; 4];
            read_exact_or_truncated(&mut src, &mut meta_len, "metadata_len")?;
            let n = u32::from_le_bytes(meta_len) as u64;
            limit("metadata_len", n, crate::metadata::MAX_METADATA_BYTES)?;
            (Some(meta_len), read_vec(&mut src, n, limits.max_alloc_bytes as u64, "metadata")?)
        } else {
            (None, Vec::new())
        };
        let mut crc_bytes = [0u8; 4];
        read_exact_or_truncated(&mut src, &mut crc_bytes, "header_crc")?;
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&fixed[..FIXED_HEADER_BYTES + 4]);
        hasher.update(&config);
        hasher.update(&len);
        hasher.update(&topo_block);
        if let Some(meta_len) = meta_len {
            hasher.update(&meta_len);
            hasher.update(&meta_block);
        }
        let computed = hasher.finalize();
        let stored = u32::from_le_bytes(crc_bytes);
        if stored != computed {
            return Err(Error::Checksum { context: CTX.into(), field: "header".into(), stored, computed });
        }
        let topology =
            decode_topology(&topo_block, container_version, vertex_count as usize, triangle_count as usize, &limits)?;
        let metadata = SceneMetadata::from_block(&meta_block)?;
        let header_bytes = FIXED_HEADER_BYTES
            + 4
            + config.len()
            + 4
            + topo_block.len()
            + meta_len.map_or(0, |l| l.len() + meta_block.len())
            + 4;
        let header = Header {
            container_version,
            info: StreamInfo {
                fourcc: FourCc(fourcc),
                codec_version,
                topology,
                frame_count: frame_count as usize,
                frame_rate,
            },
            config,
            header_bytes,
            topology_bytes: topo_block.len(),
            metadata,
        };
        Ok(Self { src, header, limits, next_frame: 0, offset: header_bytes as u64, seen: Vec::new(), done: false })
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The limits in force.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// Reads the next packet, or the index at the end. After [`Section::End`] it returns
    /// `None`. The index must agree with the packets read.
    pub fn next_section(&mut self) -> Option<Result<Section>> {
        if self.done {
            return None;
        }
        let r = self.read_section();
        if !matches!(r, Ok(Section::Packet(_))) {
            self.done = true;
        }
        Some(r)
    }

    fn read_section(&mut self) -> Result<Section> {
        let mut tag = [0u8; 4];
        read_exact_or_truncated(&mut self.src, &mut tag, "packet_tag")?;
        if tag == INDEX_TAG {
            return self.read_index_section();
        }
        if tag != PACKET_TAG {
            return Err(Error::malformed(
                CTX,
                "packet_tag",
                format!("unexpected bytes {tag:02x?} at offset {}", self.offset),
            ));
        }
        let mut fields = [0u8; 13];
        read_exact_or_truncated(&mut self.src, &mut fields, "packet_header")?;
        let mut r = ByteReader::new(&fields, CTX);
        let first_frame = r.u32("first_frame")?;
        let frame_count = r.u32("packet_frame_count")?;
        let flags = r.u8("packet_flags")?;
        let payload_len = r.u32("payload_len")?;
        if first_frame as u64 != self.next_frame {
            return Err(r.malformed("first_frame", format!("{first_frame}, expected {}", self.next_frame)));
        }
        if frame_count == 0 || self.next_frame + frame_count as u64 > self.header.info.frame_count as u64 {
            return Err(r.malformed(
                "packet_frame_count",
                format!(
                    "{frame_count} frames from {first_frame} overruns the {} declared",
                    self.header.info.frame_count
                ),
            ));
        }
        if flags > 1 {
            return Err(r.malformed("packet_flags", format!("unknown flags {flags:#x}")));
        }
        let data = read_vec(&mut self.src, payload_len as u64, self.limits.max_alloc_bytes as u64, "payload")?;
        let mut crc = [0u8; 4];
        read_exact_or_truncated(&mut self.src, &mut crc, "packet_crc")?;
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&fields);
        hasher.update(&data);
        let computed = hasher.finalize();
        let stored = u32::from_le_bytes(crc);
        if stored != computed {
            return Err(Error::Checksum {
                context: CTX.into(),
                field: format!("packet at frame {first_frame}").into(),
                stored,
                computed,
            });
        }
        let entry = IndexEntry {
            offset: self.offset,
            first_frame,
            frame_count,
            keyframe: flags & 1 == 1,
            payload_bytes: payload_len,
        };
        self.offset += entry.stored_bytes();
        self.next_frame += frame_count as u64;
        self.seen.push(entry);
        Ok(Section::Packet(Packet { first_frame, frame_count, keyframe: entry.keyframe, data }))
    }

    fn read_index_section(&mut self) -> Result<Section> {
        if self.next_frame != self.header.info.frame_count as u64 {
            return Err(Error::malformed(
                CTX,
                "index",
                format!("reached after {} of {} frames", self.next_frame, self.header.info.frame_count),
            ));
        }
        let mut count = [0u8; 4];
        read_exact_or_truncated(&mut self.src, &mut count, "index_count")?;
        let n = u32::from_le_bytes(count) as usize;
        if n != self.seen.len() {
            return Err(Error::malformed(
                CTX,
                "index_count",
                format!("{n}, but the stream holds {} packets", self.seen.len()),
            ));
        }
        let body = read_vec(&mut self.src, (n * INDEX_ENTRY_BYTES) as u64, u64::MAX, "index")?;
        let mut tail = [0u8; 4 + TRAILER_BYTES];
        read_exact_or_truncated(&mut self.src, &mut tail, "index_crc")?;
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(&INDEX_TAG);
        hasher.update(&count);
        hasher.update(&body);
        check_index_tail(hasher.finalize(), &tail, self.offset)?;
        let entries = parse_index_entries(&body, n, self.header.info.frame_count)?;
        if entries != self.seen {
            return Err(Error::malformed(CTX, "index", "does not match the packets in the stream"));
        }
        let mut extra = [0u8; 1];
        match self.src.read(&mut extra) {
            Ok(0) => Ok(Section::End(entries)),
            Ok(_) => Err(Error::malformed(CTX, "trailer", "unexpected bytes after the trailer")),
            Err(e) => Err(Error::io("reading after trailer", e)),
        }
    }
}

fn check_index_tail(computed: u32, tail: &[u8; 4 + TRAILER_BYTES], index_offset: u64) -> Result<()> {
    let mut r = ByteReader::new(tail, CTX);
    let stored = r.u32("index_crc")?;
    if stored != computed {
        return Err(Error::Checksum { context: CTX.into(), field: "index".into(), stored, computed });
    }
    let offset = r.u64("index_offset")?;
    if offset != index_offset {
        return Err(r.malformed("index_offset", format!("{offset}, index found at {index_offset}")));
    }
    if r.take(4, "trailer_tag")? != TRAILER_TAG {
        return Err(r.malformed("trailer_tag", "bad trailer tag"));
    }
    Ok(())
}

fn parse_index_entries(body: &[u8], n: usize, frame_count: usize) -> Result<Vec<IndexEntry>> {
    let mut r = ByteReader::new(body, CTX);
    let mut entries = Vec::with_capacity(n);
    let mut next_frame = 0u64;
    let mut prev_end = 0u64;
    for _ in 0..n {
        let e = IndexEntry {
            offset: r.u64("index_offset")?,
            first_frame: r.u32("index_first_frame")?,
            frame_count: r.u32("index_frame_count")?,
            keyframe: match r.u8("index_flags")? {
                0 => false,
                1 => true,
                f => return Err(r.malformed("index_flags", format!("unknown flags {f:#x}"))),
            },
            payload_bytes: r.u32("index_payload_bytes")?,
        };
        r.u32("index_reserved")?;
        if e.first_frame as u64 != next_frame || e.frame_count == 0 || e.offset < prev_end {
            return Err(r.malformed("index", "entries out of order or empty"));
        }
        next_frame += e.frame_count as u64;
        prev_end = e.offset + e.stored_bytes();
        entries.push(e);
    }
    if next_frame != frame_count as u64 {
        return Err(r.malformed("index", format!("covers {next_frame} frames, header declares {frame_count}")));
    }
    Ok(entries)
}

/// Reads the header and the index of a seekable stream without reading the packets,
/// leaving the source positioned after the header.
pub fn read_index<R: Read + Seek>(src: &mut R, limits: Limits) -> Result<(Header, Vec<IndexEntry>)> {
    let total = src.seek(SeekFrom::End(0)).map_err(|e| Error::io("seeking", e))?;
    src.seek(SeekFrom::Start(0)).map_err(|e| Error::io("seeking", e))?;
    let header = ContainerReader::new(&mut *src, limits)?.header;
    let min_len = header.header_bytes as u64 + 8 + 4 + TRAILER_BYTES as u64;
    if total < min_len {
        return Err(Error::Truncated { context: CTX.into(), field: "trailer".into() });
    }
    let mut trailer = [0u8; TRAILER_BYTES];
    src.seek(SeekFrom::Start(total - TRAILER_BYTES as u64)).map_err(|e| Error::io("seeking", e))?;
    read_exact_or_truncated(src, &mut trailer, "trailer")?;
    if trailer[8..] != TRAILER_TAG {
        return Err(Error::malformed(CTX, "trailer_tag", "bad trailer tag (stream truncated?)"));
    }
    let index_offset = u64::from_le_bytes(trailer[..8].try_into().expect("8 bytes"));
    if index_offset < header.header_bytes as u64 || index_offset > total - min_len + header.header_bytes as u64 {
        return Err(Error::malformed(
            CTX,
            "index_offset",
            format!("{index_offset} outside the stream of {total} bytes"),
        ));
    }
    src.seek(SeekFrom::Start(index_offset)).map_err(|e| Error::io("seeking", e))?;
    let mut head = [0u8; 8];
    read_exact_or_truncated(src, &mut head, "index")?;
    if head[..4] != INDEX_TAG {
        return Err(Error::malformed(CTX, "index", "no index tag at the offset the trailer gives"));
    }
    let n = u32::from_le_bytes(head[4..].try_into().expect("4 bytes")) as u64;
    let body_len = n * INDEX_ENTRY_BYTES as u64;
    if index_offset + 8 + body_len + 4 + TRAILER_BYTES as u64 != total {
        return Err(Error::malformed(CTX, "index_count", format!("{n} entries do not fit the stream")));
    }
    let body = read_vec(src, body_len, u64::MAX, "index")?;
    let mut tail = [0u8; 4 + TRAILER_BYTES];
    read_exact_or_truncated(src, &mut tail, "index_crc")?;
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&head);
    hasher.update(&body);
    check_index_tail(hasher.finalize(), &tail, index_offset)?;
    let entries = parse_index_entries(&body, n as usize, header.info.frame_count)?;
    if entries.first().is_some_and(|e| e.offset != header.header_bytes as u64)
        || entries.last().is_some_and(|e| e.offset + e.stored_bytes() != index_offset)
    {
        return Err(Error::malformed(CTX, "index", "packet offsets do not tile the stream"));
    }
    src.seek(SeekFrom::Start(header.header_bytes as u64)).map_err(|e| Error::io("seeking", e))?;
    Ok((header, entries))
}

/// Reads the packet an index entry points to (checksum and frame range checked).
pub fn read_packet_at<R: Read + Seek>(
    src: &mut R,
    entry: &IndexEntry,
    header: &Header,
    limits: Limits,
) -> Result<Packet> {
    src.seek(SeekFrom::Start(entry.offset)).map_err(|e| Error::io("seeking", e))?;
    let mut reader = ContainerReader {
        src: &mut *src,
        header: header.clone(),
        limits,
        next_frame: entry.first_frame as u64,
        offset: entry.offset,
        seen: Vec::new(),
        done: false,
    };
    match reader.read_section()? {
        Section::Packet(p) if p.frame_count == entry.frame_count && p.keyframe == entry.keyframe => Ok(p),
        _ => Err(Error::malformed(CTX, "index", format!("entry at offset {} does not match its packet", entry.offset))),
    }
}

/// The packet holding frame `t`, and the keyframe packet decoding must start from.
/// Returns `(start, target)` positions in `index`.
pub fn seek_packets(index: &[IndexEntry], t: usize) -> Option<(usize, usize)> {
    let target = index
        .iter()
        .position(|e| (e.first_frame as usize..e.first_frame as usize + e.frame_count as usize).contains(&t))?;
    let start = (0..=target).rev().find(|&i| index[i].keyframe).unwrap_or(0);
    Some((start, target))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn sample() -> (Topology, Vec<Packet>) {
        let topo = Topology::new(4, vec![[0, 1, 2], [2, 1, 3]]).unwrap();
        let packets = vec![
            Packet { first_frame: 0, frame_count: 3, keyframe: true, data: vec![1, 2, 3] },
            Packet { first_frame: 3, frame_count: 2, keyframe: false, data: vec![] },
            Packet { first_frame: 5, frame_count: 1, keyframe: true, data: vec![9; 100] },
        ];
        (topo, packets)
    }

    fn write(topo: &Topology, packets: &[Packet]) -> Vec<u8> {
        let mut w = ContainerWriter::new(Vec::new(), FourCc(*b"TEST"), 3, topo, 6, 25.0, b"cfg").unwrap();
        for p in packets {
            w.write_packet(p).unwrap();
        }
        w.finish().unwrap()
    }

    fn read_all(bytes: &[u8]) -> Result<(Header, Vec<Packet>, Vec<IndexEntry>)> {
        let mut r = ContainerReader::new(bytes, Limits::default())?;
        let mut packets = Vec::new();
        while let Some(s) = r.next_section() {
            match s? {
                Section::Packet(p) => packets.push(p),
                Section::End(index) => return Ok((r.header().clone(), packets, index)),
            }
        }
        unreachable!("the reader ends with Section::End or an error")
    }

    #[test]
    fn round_trip_sequential_and_indexed() {
        let (topo, packets) = sample();
        let bytes = write(&topo, &packets);
        let (header, got, index) = read_all(&bytes).unwrap();
        assert_eq!(header.info.fourcc, FourCc(*b"TEST"));
        assert_eq!(header.info.codec_version, 3);
        assert_eq!(header.info.topology, topo);
        assert_eq!(header.info.frame_rate, 25.0);
        assert_eq!(header.config, b"cfg");
        assert_eq!(got, packets);
        let mut cur = Cursor::new(&bytes);
        let (_, index2) = read_index(&mut cur, Limits::default()).unwrap();
        assert_eq!(index, index2);
        assert_eq!(seek_packets(&index, 4), Some((0, 1)));
        assert_eq!(seek_packets(&index, 5), Some((2, 2)));
        assert_eq!(seek_packets(&index, 6), None);
        let p = read_packet_at(&mut cur, &index[2], &header, Limits::default()).unwrap();
        assert_eq!(p, packets[2]);
    }

    #[test]
    fn every_truncation_and_flip_is_an_error() {
        let (topo, packets) = sample();
        let bytes = write(&topo, &packets);
        for cut in 0..bytes.len() {
            assert!(read_all(&bytes[..cut]).is_err(), "truncation at {cut} accepted");
            assert!(read_index(&mut Cursor::new(&bytes[..cut]), Limits::default()).is_err());
        }
        for i in 0..bytes.len() {
            for bit in [0x01u8, 0x80] {
                let mut b = bytes.clone();
                b[i] ^= bit;
                assert!(read_all(&b).is_err(), "flip of byte {i} bit {bit:#x} accepted");
            }
        }
    }

    #[test]
    fn metadata_makes_version_4_and_round_trips_sequentially_and_indexed() {
        use crate::metadata::UpAxis;
        let (topo, packets) = sample();
        let plain = write(&topo, &packets);
        let (header, _, _) = read_all(&plain).unwrap();
        assert!(header.container_version < METADATA_CONTAINER_VERSION && header.metadata.is_empty());
        let metadata = SceneMetadata {
            up_axis: Some(UpAxis::Z),
            meters_per_unit: Some(0.01),
            time_codes_per_second: Some(48.0),
            start_time_code: Some(101.0),
        };
        let info = StreamInfo {
            fourcc: FourCc(*b"TEST"),
            codec_version: 3,
            topology: topo.clone(),
            frame_count: 6,
            frame_rate: 25.0,
        };
        let mut w = ContainerWriter::with_metadata(Vec::new(), &info, b"cfg", &metadata).unwrap();
        for p in &packets {
            w.write_packet(p).unwrap();
        }
        let bytes = w.finish().unwrap();
        let (header, got, index) = read_all(&bytes).unwrap();
        assert_eq!(header.container_version, METADATA_CONTAINER_VERSION);
        assert_eq!(header.metadata, metadata);
        assert_eq!(got, packets);
        let (seek_header, seek_index) = read_index(&mut Cursor::new(&bytes), Limits::default()).unwrap();
        assert_eq!((seek_header.metadata, seek_index), (metadata, index));
        // The block is under the header's checksum: every flip and truncation is an error.
        for i in 0..header.header_bytes {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(read_all(&b).is_err(), "flip of header byte {i} accepted");
            assert!(read_all(&bytes[..i]).is_err());
        }
        // Metadata that is not valid is refused when written.
        let bad = SceneMetadata { meters_per_unit: Some(-1.0), ..Default::default() };
        assert!(ContainerWriter::with_metadata(Vec::new(), &info, b"", &bad).is_err());
    }

    /// A 30 × 30 grid renumbered within windows of 8 (local but irregular, like real meshes),
    /// in canonical order: topology method 3 is the smallest coding there.
    fn local_numbering() -> Topology {
        let shuffled =
            crate::traversal::tests::shuffled_within(&Topology::grid(30, 30).unwrap(), 8, 0x2545_f491_4f6c_dd1d);
        crate::connectivity::canonical_order(&shuffled)
    }

    #[test]
    fn method_3_makes_version_5_and_older_versions_refuse_it() {
        let topo = local_numbering();
        let (version, block) = encode_topology(&topo);
        assert_eq!((version, block[0]), (5, TOPOLOGY_PREDICTED));
        let method_2 = crate::traversal::encode(&topo).unwrap().len();
        assert!(block.len() - 1 < method_2, "{} vs method 2's {method_2}", block.len() - 1);
        let limits = Limits::default();
        let (n, t) = (topo.vertex_count(), topo.triangle_count());
        assert_eq!(decode_topology(&block, 5, n, t, &limits).unwrap(), topo);
        for old in [2, 3, 4] {
            let e = decode_topology(&block, old, n, t, &limits).unwrap_err().to_string();
            assert!(e.contains("unknown topology coding method 3"), "{e}");
        }
        // A whole stream: version 5 with an empty metadata block, read back exactly.
        let packets = [Packet { first_frame: 0, frame_count: 6, keyframe: true, data: vec![7; 10] }];
        let bytes = write(&topo, &packets);
        let (header, read, _) = read_all(&bytes).unwrap();
        assert_eq!((header.container_version, header.info.topology.clone(), read.len()), (5, topo, 1));
        assert!(header.metadata.is_empty());
        // Truncated or flipped topology blocks are errors or other triangle lists, never panics.
        for cut in 1..block.len() {
            let _ = decode_topology(&block[..cut], 5, n, t, &limits);
        }
        for i in 1..block.len() {
            let mut b = block.clone();
            b[i] ^= 0x10;
            let _ = decode_topology(&b, 5, n, t, &limits);
        }
    }

    #[test]
    fn writer_rejects_gaps_and_short_streams() {
        let (topo, packets) = sample();
        let mut w = ContainerWriter::new(Vec::new(), FourCc(*b"TEST"), 1, &topo, 6, 25.0, &[]).unwrap();
        assert!(w.write_packet(&packets[1]).is_err());
        w.write_packet(&packets[0]).unwrap();
        assert!(w.finish().is_err());
    }

    #[test]
    fn limits_stop_absurd_headers_before_allocation() {
        let (topo, packets) = sample();
        let bytes = write(&topo, &packets);
        let tight = Limits { max_vertices: 3, ..Limits::default() };
        assert!(matches!(ContainerReader::new(&bytes[..], tight), Err(Error::LimitExceeded { .. })));
        let e = ContainerReader::new(&bytes[..], Limits { max_alloc_bytes: 4, ..Limits::default() }).unwrap_err();
        assert!(matches!(e, Error::AllocLimit { .. }) && e.to_string().contains("bytes"), "{e}");
        // A header claiming 4 G frames and a huge config on a short stream.
        let mut b = bytes.clone();
        b[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(ContainerReader::new(&b[..], Limits::default()).is_err());
        let mut b = bytes.clone();
        b[32..36].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(ContainerReader::new(&b[..], Limits { max_alloc_bytes: 1 << 20, ..Limits::default() }).is_err());
    }
}
