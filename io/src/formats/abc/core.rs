//! Alembic's layout on Ogawa (`lib/Alembic/AbcCoreOgawa` in the Alembic sources): the archive's
//! root, indexed metadata, time samplings, object and property headers, and samples.
//!
//! - **Root group**: [0] `i32` file version (0), [1] `i32` library version, [2] the group of the
//!   top object `/`, [3] the archive's metadata, [4] the time samplings, [5] the indexed
//!   metadata.
//! - **Object group**: child 0 is the group of its top compound property; children `1..=k` are
//!   its child objects; the last child is data holding the child objects' headers followed by a
//!   32-byte trailer (SpookyHash V2 of the properties and of the children).
//! - **Compound property group**: child `i` is sub-property `i`; the last child is data holding
//!   the property headers.
//! - **Scalar property group**: one data block per stored sample. **Array property group**: two
//!   per stored sample, the data (`2·slot`) and its dimensions (`2·slot + 1`). Each data block is
//!   a 16-byte key (MurmurHash3 of the payload) followed by the payload.
//! - Samples equal to their neighbours are stored once: a property stores the samples from
//!   `firstChanged` to `lastChanged`, and sample `i` lives in slot 0 before `firstChanged`,
//!   the last slot from `lastChanged` on, and `i − firstChanged + 1` between.

use codec_core::{Error, Result};

use super::ogawa::{Child, Group, Ogawa};
use super::Meter;

/// `TimeSamplingType::AcyclicTimePerCycle()`: the time per cycle that marks acyclic sampling.
pub(super) const ACYCLIC_TIME_PER_CYCLE: f64 = f64::MAX / 32.0;
/// The Ogawa file version this reader knows (`ALEMBIC_OGAWA_FILE_VERSION`).
const FILE_VERSION: i32 = 0;
/// Bytes of the hash trailer after an object's child headers.
pub(super) const OBJECT_TRAILER: usize = 32;
/// Bytes of the key in front of every sample's payload.
pub(super) const KEY_LEN: usize = 16;
/// The indexed metadata block may be at most this long (the reference reader's limit).
const MAX_INDEXED_METADATA: usize = 65_536;
/// Longest object or property name read (names are short identifiers in practice).
pub(super) const MAX_NAME: usize = 65_536;
/// Longest inline metadata string read.
const MAX_METADATA: usize = 1 << 20;

/// Plain old data types (`Alembic::Util::PlainOldDataType`), in their file numbering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Pod {
    Bool,
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F16,
    F32,
    F64,
    String,
    WString,
}

impl Pod {
    fn from_code(code: u32) -> Option<Self> {
        use Pod::*;
        Some(match code {
            0 => Bool,
            1 => U8,
            2 => I8,
            3 => U16,
            4 => I16,
            5 => U32,
            6 => I32,
            7 => U64,
            8 => I64,
            9 => F16,
            10 => F32,
            11 => F64,
            12 => String,
            13 => WString,
            _ => return None,
        })
    }

    /// The file's number for this type.
    pub(super) fn code(self) -> u32 {
        self as u32
    }

    /// Bytes per value (strings: per character).
    pub(super) fn size(self) -> usize {
        use Pod::*;
        match self {
            Bool | U8 | I8 | String => 1,
            U16 | I16 | F16 => 2,
            U32 | I32 | F32 | WString => 4,
            U64 | I64 | F64 => 8,
        }
    }
}

/// What a property is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum PropKind {
    Compound,
    Scalar,
    Array,
}

/// One property header.
#[derive(Debug, Clone)]
pub(super) struct PropHeader {
    pub(super) name: String,
    pub(super) kind: PropKind,
    pub(super) pod: Pod,
    pub(super) extent: u8,
    /// Number of samples (`nextSampleIndex`).
    pub(super) count: u32,
    pub(super) first_changed: u32,
    pub(super) last_changed: u32,
    /// Index into the archive's time samplings.
    pub(super) time_sampling: u32,
    pub(super) metadata: String,
}

impl PropHeader {
    /// The stored slot that holds sample `i`.
    pub(super) fn slot(&self, i: u32) -> u32 {
        let (first, last) = (self.first_changed, self.last_changed);
        if (first == 0 && last == 0) || i < first {
            0
        } else if i >= last {
            last - first + 1
        } else {
            i - first + 1
        }
    }

    /// True when every sample is the same stored slot.
    pub(super) fn is_constant(&self) -> bool {
        self.count <= 1 || (self.first_changed == 0 && self.last_changed == 0)
    }
}

/// One child object's header.
#[derive(Debug, Clone)]
pub(super) struct ObjectHeader {
    pub(super) name: String,
    pub(super) metadata: String,
}

/// An object: its group and its children's headers (child `i` is group child `i + 1`).
pub(super) struct Object {
    pub(super) group: Group,
    pub(super) children: Vec<ObjectHeader>,
}

/// A compound property: its group and its sub-properties' headers (property `i` is group
/// child `i`).
pub(super) struct Compound {
    pub(super) group: Group,
    pub(super) props: Vec<PropHeader>,
}

impl Compound {
    /// The sub-property named `name`, with its index.
    pub(super) fn find(&self, name: &str) -> Option<(u64, &PropHeader)> {
        self.props.iter().enumerate().find(|(_, p)| p.name == name).map(|(i, p)| (i as u64, p))
    }
}

/// A time sampling: uniform (one time, `time_per_cycle` apart), cyclic (several times per
/// cycle) or acyclic (every sample's time listed).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct TimeSampling {
    pub(super) time_per_cycle: f64,
    pub(super) times: Vec<f64>,
    /// The most samples any property with this sampling has (as the writer recorded it).
    pub(super) max_samples: u32,
}

impl TimeSampling {
    pub(super) fn is_acyclic(&self) -> bool {
        self.time_per_cycle == ACYCLIC_TIME_PER_CYCLE
    }

    /// The time of sample `i` (seconds), or `None` for an acyclic sample past the listed times.
    pub(super) fn time(&self, i: u64) -> Option<f64> {
        let n = self.times.len() as u64;
        if self.is_acyclic() {
            return self.times.get(usize::try_from(i).ok()?).copied();
        }
        Some(self.times[(i % n) as usize] + (i / n) as f64 * self.time_per_cycle)
    }
}

/// An opened archive.
pub(super) struct Archive<'a> {
    pub(super) og: Ogawa<'a>,
    pub(super) time_samplings: Vec<TimeSampling>,
    indexed: Vec<String>,
    pub(super) metadata: String,
    /// The group of the top object `/`.
    pub(super) top: Group,
}

/// `key=value;key=value` metadata: the value of `key`.
pub(super) fn meta_get<'m>(metadata: &'m str, key: &str) -> Option<&'m str> {
    metadata.split(';').find_map(|kv| kv.split_once('=').filter(|(k, _)| *k == key).map(|(_, v)| v))
}

fn utf8(og: &Ogawa, field: &'static str, bytes: &[u8]) -> Result<String> {
    std::str::from_utf8(bytes)
        .map(str::to_owned)
        .map_err(|e| og.bad(field, format!("a string is not UTF-8 (byte {})", e.valid_up_to())))
}

/// Reads little-endian integers from a header block, each length checked.
struct Cursor<'b> {
    bytes: &'b [u8],
    pos: usize,
}

impl<'b> Cursor<'b> {
    fn take(&mut self, n: usize) -> Option<&'b [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len())?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Some(s)
    }

    fn u32(&mut self) -> Option<u32> {
        self.take(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A `u32` stored in 1, 2 or 4 bytes (size hint 0, 1, 2).
    fn hinted(&mut self, hint: u32) -> Option<u32> {
        match hint {
            0 => self.take(1).map(|b| u32::from(b[0])),
            1 => self.take(2).map(|b| u32::from(u16::from_le_bytes([b[0], b[1]]))),
            2 => self.u32(),
            _ => None,
        }
    }

    fn done(&self) -> bool {
        self.pos >= self.bytes.len()
    }
}

impl<'a> Archive<'a> {
    /// Opens the archive: root layout, versions, time samplings, indexed metadata.
    pub(super) fn open(og: Ogawa<'a>, root: Group, meter: &mut Meter) -> Result<Self> {
        let kinds: Vec<Child> = (0..root.len.min(6)).map(|i| og.child(root, i, "archive")).collect::<Result<_>>()?;
        let layout_ok = kinds.len() == 6
            && matches!(kinds[0], Child::Data(_))
            && matches!(kinds[1], Child::Data(_))
            && matches!(kinds[2], Child::Group(_))
            && kinds[3..].iter().all(|k| matches!(k, Child::Data(_)));
        if !layout_ok {
            return Err(og.bad("archive", "the root group is not an Alembic archive's (six children expected)"));
        }
        let version = og.child_data(root, 0, "file version")?.1;
        let version = match version {
            [a, b, c, d] => i32::from_le_bytes([*a, *b, *c, *d]),
            _ => return Err(og.bad("archive", "the file version is not 4 bytes")),
        };
        if !(0..=FILE_VERSION).contains(&version) {
            return Err(Error::Unsupported {
                context: og.file().to_owned().into(),
                detail: format!("Alembic Ogawa file version {version} (up to {FILE_VERSION} is read)"),
            });
        }
        let top = og.child_group(root, 2, "top object")?;
        let metadata = og.child_data(root, 3, "archive metadata")?.1;
        if metadata.len() > MAX_METADATA {
            return Err(og.bad("metadata", format!("the archive metadata is {} bytes long", metadata.len())));
        }
        meter.work("archive metadata", metadata.len() as u64)?;
        let metadata = utf8(&og, "metadata", metadata)?;
        let ts_block = og.child_data(root, 4, "time samplings")?.1;
        meter.work("time samplings", ts_block.len() as u64)?;
        let time_samplings = read_time_samplings(&og, ts_block, meter)?;
        let md_block = og.child_data(root, 5, "indexed metadata")?.1;
        let indexed = read_indexed_metadata(&og, md_block)?;
        Ok(Self { og, time_samplings, indexed, metadata, top })
    }

    fn metadata_at(&self, index: u32, what: &str) -> Result<String> {
        self.indexed.get(index as usize).cloned().ok_or_else(|| {
            self.og.bad(
                "metadata",
                format!("{what}: metadata index {index}, but the archive has {} indexed entries", self.indexed.len()),
            )
        })
    }

    /// The object whose group is `group`: its child headers. `path` names it in errors.
    pub(super) fn object(&self, group: Group, path: &str, meter: &mut Meter) -> Result<Object> {
        meter.count_object(path)?;
        meter.visit_group(group.offset, path)?;
        let mut children = Vec::new();
        if group.len == 0 {
            return Ok(Object { group, children });
        }
        let last = group.len - 1;
        let Child::Data(at) = self.og.child(group, last, path)? else {
            return Ok(Object { group, children });
        };
        let block = self.og.data(at)?;
        if block.len() <= OBJECT_TRAILER {
            return Ok(Object { group, children });
        }
        meter.work("object headers", block.len() as u64)?;
        let mut c = Cursor { bytes: &block[..block.len() - OBJECT_TRAILER], pos: 0 };
        let err = |detail: &str| self.og.bad("object headers", format!("{path}: {detail}"));
        while !c.done() {
            let len = c.u32().ok_or_else(|| err("a child's name length is cut off"))? as usize;
            if len == 0 || len > MAX_NAME {
                return Err(err(&format!("a child's name is {len} bytes long")));
            }
            let name = c.take(len).ok_or_else(|| err("a child's name runs past its block"))?;
            let name = utf8(&self.og, "object headers", name)?;
            if name.contains('/') {
                return Err(err(&format!("the child name {name:?} contains `/`")));
            }
            let index = c.take(1).ok_or_else(|| err("a child's metadata index is missing"))?[0];
            let metadata = if index == 0xff {
                let n = c.u32().ok_or_else(|| err("a child's metadata length is cut off"))? as usize;
                if n > MAX_METADATA {
                    return Err(err(&format!("a child's metadata is {n} bytes long")));
                }
                let m = c.take(n).ok_or_else(|| err("a child's metadata runs past its block"))?;
                utf8(&self.og, "object headers", m)?
            } else {
                self.metadata_at(u32::from(index), path)?
            };
            meter.take("object names", (name.len() + metadata.len()) as u64)?;
            children.push(ObjectHeader { name, metadata });
        }
        // Child i is group child i + 1, before the header block.
        if children.len() as u64 + 1 > last {
            return Err(err(&format!(
                "{} child objects listed but the group holds {} before the headers",
                children.len(),
                last.saturating_sub(1)
            )));
        }
        Ok(Object { group, children })
    }

    /// Child object `i` of `object` (its group).
    pub(super) fn child_object_group(&self, object: &Object, i: usize, path: &str) -> Result<Group> {
        self.og.child_group(object.group, i as u64 + 1, path)
    }

    /// The top compound property of `object` (none: empty).
    pub(super) fn properties(&self, object: &Object, path: &str, meter: &mut Meter) -> Result<Compound> {
        if object.group.len == 0 {
            return Ok(Compound { group: Group { offset: 0, len: 0 }, props: Vec::new() });
        }
        match self.og.child(object.group, 0, path)? {
            Child::Group(_) => {
                let g = self.og.child_group(object.group, 0, path)?;
                self.compound(g, path, meter)
            }
            Child::Data(_) => Ok(Compound { group: Group { offset: 0, len: 0 }, props: Vec::new() }),
        }
    }

    /// Sub-property `index` of `parent`, a compound property.
    pub(super) fn sub_compound(
        &self,
        parent: &Compound,
        index: u64,
        what: &str,
        meter: &mut Meter,
    ) -> Result<Compound> {
        let g = self.og.child_group(parent.group, index, what)?;
        self.compound(g, what, meter)
    }

    fn compound(&self, group: Group, what: &str, meter: &mut Meter) -> Result<Compound> {
        meter.visit_group(group.offset, what)?;
        let mut props = Vec::new();
        if group.len == 0 {
            return Ok(Compound { group, props });
        }
        let last = group.len - 1;
        let Child::Data(at) = self.og.child(group, last, what)? else {
            return Ok(Compound { group, props });
        };
        let block = self.og.data(at)?;
        meter.work("property headers", block.len() as u64)?;
        let mut c = Cursor { bytes: block, pos: 0 };
        let err = |detail: String| self.og.bad("property headers", format!("{what}: {detail}"));
        while !c.done() {
            meter.count_property(what)?;
            let info = c.u32().ok_or_else(|| err("a header is cut off".into()))?;
            let hint = (info >> 2) & 3;
            if hint == 3 {
                return Err(err(format!("property info {info:#x} has an invalid size hint")));
            }
            let cut = || err("a header is cut off".to_owned());
            let kind = match info & 3 {
                0 => PropKind::Compound,
                1 => PropKind::Scalar,
                _ => PropKind::Array,
            };
            let mut h = PropHeader {
                name: String::new(),
                kind,
                pod: Pod::U8,
                extent: 0,
                count: 0,
                first_changed: 0,
                last_changed: 0,
                time_sampling: 0,
                metadata: String::new(),
            };
            if kind != PropKind::Compound {
                let code = (info >> 4) & 0xf;
                h.pod = Pod::from_code(code).ok_or_else(|| err(format!("unknown value type {code}")))?;
                h.extent = ((info >> 12) & 0xff) as u8;
                h.count = c.hinted(hint).ok_or_else(cut)?;
                if info & 0x200 != 0 {
                    h.first_changed = c.hinted(hint).ok_or_else(cut)?;
                    h.last_changed = c.hinted(hint).ok_or_else(cut)?;
                } else if info & 0x800 != 0 {
                    (h.first_changed, h.last_changed) = (0, 0);
                } else {
                    h.first_changed = 1;
                    h.last_changed = h.count.saturating_sub(1);
                }
                if info & 0x100 != 0 {
                    h.time_sampling = c.hinted(hint).ok_or_else(cut)?;
                }
                if h.time_sampling as usize >= self.time_samplings.len() {
                    return Err(err(format!(
                        "time sampling {} of {} defined",
                        h.time_sampling,
                        self.time_samplings.len()
                    )));
                }
                if h.extent == 0 {
                    return Err(err("a property has extent 0".into()));
                }
                if h.last_changed > h.count || (h.first_changed > h.last_changed && h.last_changed != 0) {
                    return Err(err(format!("samples {}..{} changed of {}", h.first_changed, h.last_changed, h.count)));
                }
            }
            let len = c.hinted(hint).ok_or_else(cut)? as usize;
            if len == 0 || len > MAX_NAME {
                return Err(err(format!("a property name is {len} bytes long")));
            }
            h.name = utf8(&self.og, "property headers", c.take(len).ok_or_else(cut)?)?;
            let index = (info >> 20) & 0xff;
            h.metadata = if index == 0xff {
                let n = c.hinted(hint).ok_or_else(cut)? as usize;
                if n > MAX_METADATA {
                    return Err(err(format!("metadata of {n} bytes")));
                }
                utf8(&self.og, "property headers", c.take(n).ok_or_else(cut)?)?
            } else {
                self.metadata_at(index, what)?
            };
            meter.take("property names", (h.name.len() + h.metadata.len() + 64) as u64)?;
            props.push(h);
        }
        if props.len() as u64 > last {
            return Err(err(format!("{} properties listed but the group holds {last}", props.len())));
        }
        Ok(Compound { group, props })
    }

    /// The payload (after the key) of sample `i` of property `index` of `compound`, with the
    /// data block's offset (equal offsets: the same stored data).
    pub(super) fn sample(&self, compound: &Compound, index: u64, i: u32, what: &str) -> Result<(u64, &'a [u8])> {
        let h = &compound.props[index as usize];
        if i >= h.count {
            return Err(self.og.bad("samples", format!("{what}: sample {i} of {} asked", h.count)));
        }
        let g = self.og.child_group(compound.group, index, what)?;
        let slot = u64::from(h.slot(i));
        let child = match h.kind {
            PropKind::Array => 2 * slot,
            _ => slot,
        };
        let (at, data) = self.og.child_data(g, child, what)?;
        if data.is_empty() {
            return Ok((at, data));
        }
        if data.len() < KEY_LEN {
            return Err(self
                .og
                .bad("samples", format!("{what}: sample {i} is {} bytes, shorter than its key", data.len())));
        }
        let payload = &data[KEY_LEN..];
        let unit = h.pod.size() * usize::from(h.extent);
        if !matches!(h.pod, Pod::String | Pod::WString) && payload.len() % unit != 0 {
            return Err(self.og.bad(
                "samples",
                format!("{what}: sample {i} holds {} bytes, not whole values of {unit} bytes", payload.len()),
            ));
        }
        Ok((at, payload))
    }
}

fn read_time_samplings(og: &Ogawa, block: &[u8], meter: &mut Meter) -> Result<Vec<TimeSampling>> {
    let mut c = Cursor { bytes: block, pos: 0 };
    let mut out = Vec::new();
    let bad = |detail: String| og.bad("time samplings", detail);
    while !c.done() {
        let k = out.len();
        let max_samples = c.u32().ok_or_else(|| bad(format!("time sampling {k} is cut off")))?;
        let tpc = c.take(8).map(f64_le).ok_or_else(|| bad(format!("time sampling {k} is cut off")))?;
        let n = c.u32().ok_or_else(|| bad(format!("time sampling {k} is cut off")))? as usize;
        let bytes = n.checked_mul(8).filter(|&b| n >= 1 && b <= block.len() - c.pos);
        let Some(bytes) = bytes else {
            return Err(bad(format!("time sampling {k} lists {n} times, which its block cannot hold")));
        };
        meter.take("time samplings", bytes as u64 + 32)?;
        let times: Vec<f64> = c.take(bytes).unwrap_or_default().chunks_exact(8).map(f64_le).collect();
        let ts = TimeSampling { time_per_cycle: tpc, times, max_samples };
        let valid_cycle = tpc.is_finite() && tpc > 0.0;
        if !(ts.is_acyclic() || valid_cycle) {
            return Err(bad(format!("time sampling {k} has {tpc} seconds per cycle")));
        }
        if ts.times.iter().any(|t| !t.is_finite()) || ts.times.windows(2).any(|w| w[1] < w[0]) {
            return Err(bad(format!("time sampling {k}: its times are not finite and increasing")));
        }
        if !ts.is_acyclic() && ts.times[ts.times.len() - 1] - ts.times[0] >= tpc {
            return Err(bad(format!("time sampling {k}: its times span more than one cycle ({tpc} s)")));
        }
        out.push(ts);
    }
    if out.is_empty() {
        // The default sampling (index 0) is always written; accept its absence as it.
        out.push(TimeSampling { time_per_cycle: 1.0, times: vec![0.0], max_samples: 0 });
    }
    Ok(out)
}

fn read_indexed_metadata(og: &Ogawa, block: &[u8]) -> Result<Vec<String>> {
    if block.len() > MAX_INDEXED_METADATA {
        return Err(og.bad("indexed metadata", format!("the block is {} bytes (at most 65536)", block.len())));
    }
    let mut out = vec![String::new()];
    let mut c = Cursor { bytes: block, pos: 0 };
    while !c.done() {
        let n = usize::from(c.take(1).unwrap_or(&[0])[0]);
        let s = c.take(n).ok_or_else(|| og.bad("indexed metadata", "an entry runs past the block"))?;
        if out.len() >= 255 {
            return Err(og.bad("indexed metadata", "more than 254 entries"));
        }
        out.push(utf8(og, "indexed metadata", s)?);
    }
    Ok(out)
}

/// A little-endian `f64` from 8 bytes.
pub(super) fn f64_le(b: &[u8]) -> f64 {
    f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ts(tpc: f64, times: &[f64]) -> TimeSampling {
        TimeSampling { time_per_cycle: tpc, times: times.to_vec(), max_samples: 0 }
    }

    #[test]
    fn sample_times_follow_the_sampling_type() {
        let uniform = ts(1.0 / 24.0, &[0.5]);
        assert_eq!(uniform.time(0), Some(0.5));
        assert_eq!(uniform.time(48), Some(0.5 + 48.0 / 24.0));
        let cyclic = ts(1.0, &[0.0, 0.25]);
        assert_eq!(
            (cyclic.time(0), cyclic.time(1), cyclic.time(2), cyclic.time(5)),
            (Some(0.0), Some(0.25), Some(1.0), Some(2.25))
        );
        let acyclic = ts(ACYCLIC_TIME_PER_CYCLE, &[0.0, 0.1, 0.7]);
        assert!(acyclic.is_acyclic());
        assert_eq!((acyclic.time(2), acyclic.time(3)), (Some(0.7), None));
    }

    #[test]
    fn samples_map_to_their_stored_slots() {
        let mut h = PropHeader {
            name: "P".into(),
            kind: PropKind::Array,
            pod: Pod::F32,
            extent: 3,
            count: 10,
            first_changed: 1,
            last_changed: 9,
            time_sampling: 0,
            metadata: String::new(),
        };
        assert_eq!((0..10).map(|i| h.slot(i)).collect::<Vec<_>>(), (0..10).collect::<Vec<_>>());
        (h.first_changed, h.last_changed) = (3, 5);
        assert_eq!((0..8).map(|i| h.slot(i)).collect::<Vec<_>>(), [0, 0, 0, 1, 2, 3, 3, 3]);
        (h.first_changed, h.last_changed) = (0, 0);
        assert!(h.is_constant() && h.slot(7) == 0);
        assert_eq!(meta_get("a=1;schema=AbcGeom_Xform_v3", "schema"), Some("AbcGeom_Xform_v3"));
    }

    #[test]
    fn time_sampling_blocks_are_checked() {
        let mut m = Meter::new("t", None);
        let mut w = Vec::new();
        let mut push = |max: u32, tpc: f64, times: &[f64]| {
            w.extend_from_slice(&max.to_le_bytes());
            w.extend_from_slice(&tpc.to_le_bytes());
            w.extend_from_slice(&(times.len() as u32).to_le_bytes());
            times.iter().for_each(|t| w.extend_from_slice(&t.to_le_bytes()));
        };
        push(1, 1.0, &[0.0]);
        push(3, 1.0 / 24.0, &[0.0]);
        let mut ow = crate::formats::abc::ogawa::OgawaWriter::new();
        let d = ow.data(&[b"x"]);
        let r = ow.group(&[d]);
        let file = ow.finish(r);
        let (og, _) = Ogawa::open(&file, "t").unwrap();
        let got = read_time_samplings(&og, &w, &mut m).unwrap();
        assert_eq!(got.len(), 2);
        assert_eq!(got[1].time_per_cycle, 1.0 / 24.0);
        // 2^31 times claimed in a tiny block.
        let mut bad = w.clone();
        bad[12..16].copy_from_slice(&(1u32 << 31).to_le_bytes());
        assert!(read_time_samplings(&og, &bad, &mut m).unwrap_err().to_string().contains("cannot hold"));
        let mut neg = Vec::new();
        neg.extend_from_slice(&1u32.to_le_bytes());
        neg.extend_from_slice(&(-1.0f64).to_le_bytes());
        neg.extend_from_slice(&1u32.to_le_bytes());
        neg.extend_from_slice(&0f64.to_le_bytes());
        assert!(read_time_samplings(&og, &neg, &mut m).is_err());
    }
}
