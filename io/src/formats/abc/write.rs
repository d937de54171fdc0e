//! The Alembic writer: one Xform holding one PolyMesh, laid out as the reference library
//! (`AbcCoreOgawa`'s `AwImpl`, `OwData`, `CpwData`, `ApwImpl`, `SpwImpl`, `WriteUtil`) lays out
//! the same content, so that the archive is what Alembic itself would write: the same
//! property flags, sample sharing, indexed metadata, time samplings, MurmurHash3 sample keys
//! and SpookyHash V2 object trailers.

use std::collections::HashMap;

use codec_core::{Animation, Result};

use super::core::{Pod, PropKind};
use super::hash::{digest_bytes, murmur3_x64_128, spooky128, spooky_short_end};
use super::ogawa::{Child, OgawaWriter};

/// The Ogawa file version written (`ALEMBIC_OGAWA_FILE_VERSION`).
const FILE_VERSION: i32 = 0;
/// The library version recorded: the reference library whose layout is written (1.8.12).
const LIBRARY_VERSION: i32 = 10812;

/// Metadata of the properties and objects written (as the reference schemas serialize it:
/// keys sorted, `;`-separated).
const MD_BOX: &str = "interpretation=box";
const MD_POINTS: &str = "geoScope=vtx;interpretation=point";
const MD_GEOM: &str = "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1";
const MD_MESH: &str =
    "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1;schemaObjTitle=AbcGeom_PolyMesh_v1:.geom";
const MD_XFORM_SCHEMA: &str = "schema=AbcGeom_Xform_v3";
const MD_XFORM: &str = "schema=AbcGeom_Xform_v3;schemaObjTitle=AbcGeom_Xform_v3:.xform";

/// The archive being written, with what the reference writer keeps archive-wide: the data
/// already written (identical samples are stored once) and the indexed metadata.
struct Writer {
    og: OgawaWriter,
    written: HashMap<([u64; 2], usize), Child>,
    metadata: Vec<String>,
}

impl Writer {
    /// A sample's data block (key + payload), shared with an identical one already written.
    fn sample(&mut self, key: [u64; 2], payload: &[u8]) -> Child {
        if payload.is_empty() {
            return Child::Data(0);
        }
        if let Some(&c) = self.written.get(&(key, payload.len())) {
            return c;
        }
        let c = self.og.data(&[&digest_bytes(key), payload]);
        self.written.insert((key, payload.len()), c);
        c
    }

    /// The metadata index of `md` (`MetaDataMap::getIndex`): 0 for none, 1..=254 for short
    /// strings in order of first use, 255 for inline.
    fn md_index(&mut self, md: &str) -> u32 {
        if md.is_empty() {
            return 0;
        }
        if md.len() < 256 {
            if let Some(i) = self.metadata.iter().position(|m| m == md) {
                return i as u32 + 1;
            }
            if self.metadata.len() < 254 {
                self.metadata.push(md.to_owned());
                return self.metadata.len() as u32;
            }
        }
        255
    }
}

/// A uniform time sampling: its index in the archive, seconds per cycle, and first time.
#[derive(Clone, Copy)]
struct Sampling {
    index: u32,
    time_per_cycle: f64,
    start: f64,
}

const DEFAULT_SAMPLING: Sampling = Sampling { index: 0, time_per_cycle: 1.0, start: 0.0 };

/// A scalar or array property being written (`SpwImpl` / `ApwImpl`).
struct Prop {
    name: &'static str,
    md: &'static str,
    kind: PropKind,
    pod: Pod,
    extent: u8,
    sampling: Sampling,
    next: u32,
    first: u32,
    last: u32,
    children: Vec<Child>,
    previous: Option<([u64; 2], usize, Child)>,
    hash: [u64; 2],
    scalar_like: bool,
    homogeneous: bool,
    points: u64,
}

impl Prop {
    fn new(name: &'static str, md: &'static str, kind: PropKind, pod: Pod, extent: u8, sampling: Sampling) -> Self {
        Self {
            name,
            md,
            kind,
            pod,
            extent,
            sampling,
            next: 0,
            first: 0,
            last: 0,
            children: Vec::new(),
            previous: None,
            hash: [0, 0],
            scalar_like: true,
            homogeneous: true,
            points: 0,
        }
    }

    /// Sets the next sample (`points` elements of `extent` values).
    fn set(&mut self, w: &mut Writer, payload: &[u8], points: u64) {
        let key = murmur3_x64_128(payload);
        let changed = self.next == 0 || self.previous.is_none_or(|(k, len, _)| k != key || len != payload.len());
        if changed {
            if self.first != 0 {
                // Samples equal to the last stored one since it was stored: written out again
                // (as references to the same data) now that the value changes.
                if let Some((_, _, prev)) = self.previous {
                    for _ in self.last + 1..self.next {
                        self.push_slot(prev);
                    }
                }
            }
            let c = w.sample(key, payload);
            self.push_slot(c);
            if self.kind == PropKind::Array {
                self.scalar_like &= points == 1;
                // The reference compares the point count with the stored value count.
                self.homogeneous &= points == points * u64::from(self.extent);
            }
            self.points = points;
            if self.first == 0 {
                self.first = self.next;
            }
            self.last = self.next;
            self.previous = Some((key, payload.len(), c));
        }
        self.fold(key);
    }

    /// Repeats the previous sample (`setFromPreviousSample`).
    fn set_previous(&mut self) {
        if let Some((key, _, _)) = self.previous {
            self.fold(key);
        }
    }

    fn push_slot(&mut self, data: Child) {
        self.children.push(data);
        if self.kind == PropKind::Array {
            // Dimensions of a rank-1, non-string array: empty.
            self.children.push(Child::Data(0));
        }
    }

    /// Folds a sample's key into the property's running hash.
    fn fold(&mut self, key: [u64; 2]) {
        let digest = if self.kind == PropKind::Array {
            // `HashDimensions`: the rank-1 dimensions hashed with the key.
            let mut m = self.points.to_le_bytes().to_vec();
            m.extend_from_slice(&digest_bytes(key));
            spooky128(&m, [0, 0])
        } else {
            key
        };
        if self.next == 0 {
            self.hash = digest;
        } else {
            let mut h = [self.hash[0], self.hash[1], digest[0], digest[1]];
            spooky_short_end(&mut h);
            self.hash = [h[0], h[1]];
        }
        self.next += 1;
    }

    /// Samples the archive records for this property's time sampling.
    fn recorded_samples(&self) -> u32 {
        if self.last == 0 && self.next > 0 {
            1
        } else {
            self.next
        }
    }

    /// Writes the property's group; returns it and the property's hash.
    fn finish(&self, w: &mut Writer) -> (Child, [u64; 2]) {
        let group = w.og.group(&self.children);
        let mut m = header_hash_bytes(self.name, self.md, Some(self));
        if self.recorded_samples() != 0 {
            m.extend_from_slice(&digest_bytes(self.hash));
        }
        (group, spooky128(&m, [0, 0]))
    }

    /// Appends the property's header (`WritePropertyInfo`).
    fn header(&self, w: &mut Writer, out: &mut Vec<u8>) {
        let index = w.md_index(self.md);
        let max = [self.md.len() as u32, self.name.len() as u32, self.next, self.sampling.index]
            .into_iter()
            .max()
            .unwrap_or(0);
        let hint = size_hint(max);
        let mut info = (hint << 2) | (index << 20);
        info |= match self.kind {
            PropKind::Array => 2,
            _ => 1,
        };
        info |= u32::from(self.scalar_like);
        info |= self.pod.code() << 4;
        if self.sampling.index != 0 {
            info |= 0x100;
        }
        let explicit = if self.first == 0 && self.last == 0 {
            info |= 0x800;
            false
        } else if self.first != 1 || self.last != self.next.wrapping_sub(1) {
            info |= 0x200;
            true
        } else {
            false
        };
        info |= u32::from(self.extent) << 12;
        if self.homogeneous {
            info |= 0x400;
        }
        out.extend_from_slice(&info.to_le_bytes());
        push_hinted(out, self.next, hint);
        if explicit {
            push_hinted(out, self.first, hint);
            push_hinted(out, self.last, hint);
        }
        if self.sampling.index != 0 {
            push_hinted(out, self.sampling.index, hint);
        }
        push_name_md(out, self.name, self.md, index, hint);
    }
}

/// A compound property's header.
fn compound_header(w: &mut Writer, name: &str, md: &str, out: &mut Vec<u8>) {
    let index = w.md_index(md);
    let hint = size_hint(md.len().max(name.len()) as u32);
    let info = (hint << 2) | (index << 20);
    out.extend_from_slice(&info.to_le_bytes());
    push_name_md(out, name, md, index, hint);
}

fn push_name_md(out: &mut Vec<u8>, name: &str, md: &str, index: u32, hint: u32) {
    push_hinted(out, name.len() as u32, hint);
    out.extend_from_slice(name.as_bytes());
    if index == 255 {
        push_hinted(out, md.len() as u32, hint);
        out.extend_from_slice(md.as_bytes());
    }
}

fn size_hint(max: u32) -> u32 {
    match max {
        0..=255 => 0,
        256..=65535 => 1,
        _ => 2,
    }
}

fn push_hinted(out: &mut Vec<u8>, v: u32, hint: u32) {
    let b = v.to_le_bytes();
    out.extend_from_slice(&b[..[1, 2, 4][hint as usize]]);
}

/// The bytes `HashPropertyHeader` hashes: name, metadata and, for scalars and arrays, the value
/// type and the time sampling.
fn header_hash_bytes(name: &str, md: &str, prop: Option<&Prop>) -> Vec<u8> {
    let mut m = Vec::with_capacity(128);
    m.extend_from_slice(name.as_bytes());
    m.extend_from_slice(md.as_bytes());
    if let Some(p) = prop {
        m.push(p.pod.code() as u8);
        m.push(p.extent);
        if p.kind == PropKind::Scalar {
            m.push(0);
        }
        m.extend_from_slice(&p.sampling.time_per_cycle.to_le_bytes());
        m.extend_from_slice(&1u32.to_le_bytes());
        m.extend_from_slice(&p.sampling.start.to_le_bytes());
    }
    m
}

/// A compound's group and hash from its sub-properties' groups and hashes (`CpwImpl`'s
/// destructor): the headers block is written after the children.
fn finish_compound(
    w: &mut Writer,
    groups: &[Child],
    headers: &[u8],
    hashes: &[[u64; 2]],
    name: &str,
    md: &str,
) -> (Child, [u64; 2]) {
    let h = w.og.data(&[headers]);
    let mut children = groups.to_vec();
    children.push(h);
    let group = w.og.group(&children);
    let mut m: Vec<u8> = hashes.iter().flat_map(|x| digest_bytes(*x)).collect();
    m.extend_from_slice(&header_hash_bytes(name, md, None));
    (group, spooky128(&m, [0, 0]))
}

/// The object headers block of an object (its children's headers and the 32-byte trailer)
/// and the hash its parent records (`OwData::writeHeaders`, `OwImpl`'s destructor).
fn object_block(
    w: &mut Writer,
    children: &[(&str, &str, [u64; 2])],
    property_hashes: &[[u64; 2]],
) -> (Vec<u8>, Vec<u8>) {
    let mut block = Vec::new();
    for (name, md, _) in children {
        block.extend_from_slice(&(name.len() as u32).to_le_bytes());
        block.extend_from_slice(name.as_bytes());
        let index = w.md_index(md);
        block.push(index as u8);
        if index == 255 {
            block.extend_from_slice(&(md.len() as u32).to_le_bytes());
            block.extend_from_slice(md.as_bytes());
        }
    }
    let props: Vec<u8> = property_hashes.iter().flat_map(|x| digest_bytes(*x)).collect();
    let props_hash = spooky128(&props, [0, 0]);
    let kids: Vec<u8> = children.iter().flat_map(|c| digest_bytes(c.2)).collect();
    let kids_hash = if kids.is_empty() { [0, 0] } else { spooky128(&kids, [0, 0]) };
    block.extend_from_slice(&digest_bytes(props_hash));
    block.extend_from_slice(&digest_bytes(kids_hash));
    // What the object's own hash covers before its metadata and name.
    let mut own = kids;
    own.extend_from_slice(&digest_bytes(props_hash));
    (block, own)
}

/// Bytes of `values` in little-endian order.
fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// An Alembic archive holding `animation` (see the module documentation of [`super`]).
pub fn encode_abc(animation: &Animation) -> Result<Vec<u8>> {
    let fps = animation.frame_rate();
    let frames = animation.frame_count();
    let mut w = Writer { og: OgawaWriter::new(), written: HashMap::new(), metadata: Vec::new() };
    let version = w.og.data(&[&FILE_VERSION.to_le_bytes()]);
    let library = w.og.data(&[&LIBRARY_VERSION.to_le_bytes()]);
    let start = animation.metadata().start_seconds(fps);
    let sampling = Sampling { index: 1, time_per_cycle: 1.0 / f64::from(fps), start };

    // The Xform's `.inherits` (true): its only property, as an identity transform writes it.
    let mut inherits = Prop::new(".inherits", "", PropKind::Scalar, Pod::Bool, 1, DEFAULT_SAMPLING);
    inherits.set(&mut w, &[1], 1);

    let mut bounds = Prop::new(".selfBnds", MD_BOX, PropKind::Scalar, Pod::F64, 6, sampling);
    let mut p = Prop::new("P", MD_POINTS, PropKind::Array, Pod::F32, 3, sampling);
    let mut indices = Prop::new(".faceIndices", "", PropKind::Array, Pod::I32, 1, sampling);
    let mut counts = Prop::new(".faceCounts", "", PropKind::Array, Pod::I32, 1, sampling);
    let tris = animation.triangles();
    // Alembic winds faces clockwise.
    let index_bytes: Vec<u8> =
        tris.iter().flat_map(|t| [t[0], t[2], t[1]]).flat_map(|i| (i as i32).to_le_bytes()).collect();
    let count_bytes: Vec<u8> = tris.iter().flat_map(|_| 3i32.to_le_bytes()).collect();
    let v = animation.vertex_count() as u64;
    for t in 0..frames {
        let frame = animation.frame(t);
        p.set(&mut w, &f32_bytes(frame), v);
        if t == 0 {
            indices.set(&mut w, &index_bytes, tris.len() as u64 * 3);
            counts.set(&mut w, &count_bytes, tris.len() as u64);
        } else {
            indices.set_previous();
            counts.set_previous();
        }
        let (lo, hi) = codec_core::animation::bounding_box(frame);
        let bbox: Vec<u8> = lo.iter().chain(&hi).flat_map(|&x| f64::from(x).to_le_bytes()).collect();
        bounds.set(&mut w, &bbox, 1);
    }
    let max_samples =
        [p.recorded_samples(), bounds.recorded_samples(), indices.recorded_samples(), counts.recorded_samples()]
            .into_iter()
            .max()
            .unwrap_or(0);

    // Groups close in the reverse order of their creation, then the headers of `.geom`.
    let (counts_g, counts_h) = counts.finish(&mut w);
    let (indices_g, indices_h) = indices.finish(&mut w);
    let (p_g, p_h) = p.finish(&mut w);
    let (bounds_g, bounds_h) = bounds.finish(&mut w);
    let mut headers = Vec::new();
    for prop in [&bounds, &p, &indices, &counts] {
        prop.header(&mut w, &mut headers);
    }
    let (geom_g, geom_h) = finish_compound(
        &mut w,
        &[bounds_g, p_g, indices_g, counts_g],
        &headers,
        &[bounds_h, p_h, indices_h, counts_h],
        ".geom",
        MD_GEOM,
    );

    // The mesh object: its header block (no children), its top compound, its group.
    let (block, own) = object_block(&mut w, &[], &[geom_h]);
    let mesh_block = w.og.data(&[&block]);
    let mut top_headers = Vec::new();
    compound_header(&mut w, ".geom", MD_GEOM, &mut top_headers);
    let top_h = w.og.data(&[&top_headers]);
    let mesh_top = w.og.group(&[geom_g, top_h]);
    let mesh_g = w.og.group(&[mesh_top, mesh_block]);
    let mesh_hash = spooky128(&[own, MD_MESH.as_bytes().to_vec(), b"mesh".to_vec()].concat(), [0, 0]);

    // The Xform's `.xform` compound.
    let (inherits_g, inherits_h) = inherits.finish(&mut w);
    let mut xh = Vec::new();
    inherits.header(&mut w, &mut xh);
    let (xform_g, xform_h) = finish_compound(&mut w, &[inherits_g], &xh, &[inherits_h], ".xform", MD_XFORM_SCHEMA);

    // The Xform object.
    let (block, own) = object_block(&mut w, &[("mesh", MD_MESH, mesh_hash)], &[xform_h]);
    let x_block = w.og.data(&[&block]);
    let mut top_headers = Vec::new();
    compound_header(&mut w, ".xform", MD_XFORM_SCHEMA, &mut top_headers);
    let top_h = w.og.data(&[&top_headers]);
    let x_top = w.og.group(&[xform_g, top_h]);
    let x_g = w.og.group(&[x_top, mesh_g, x_block]);
    let x_hash = spooky128(&[own, MD_XFORM.as_bytes().to_vec(), b"animcodec".to_vec()].concat(), [0, 0]);

    // The top object `/`: no properties, one child.
    let (block, _) = object_block(&mut w, &[("animcodec", MD_XFORM, x_hash)], &[]);
    let top_block = w.og.data(&[&block]);
    let top_g = w.og.group(&[Child::Group(0), x_g, top_block]);

    let archive_md = format!("FramesPerTimeUnit={fps:.6};_ai_Application=animcodec");
    let md = w.og.data(&[archive_md.as_bytes()]);
    let mut ts = Vec::new();
    for (max, s) in [(inherits.recorded_samples(), DEFAULT_SAMPLING), (max_samples, sampling)] {
        ts.extend_from_slice(&max.to_le_bytes());
        ts.extend_from_slice(&s.time_per_cycle.to_le_bytes());
        ts.extend_from_slice(&1u32.to_le_bytes());
        ts.extend_from_slice(&s.start.to_le_bytes());
    }
    let ts = w.og.data(&[&ts]);
    let mut imd = Vec::new();
    for m in &w.metadata {
        imd.push(m.len() as u8);
        imd.extend_from_slice(m.as_bytes());
    }
    let imd = w.og.data(&[&imd]);
    let root = w.og.group(&[version, library, top_g, md, ts, imd]);
    Ok(w.og.finish(root))
}
