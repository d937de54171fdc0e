//! Alembic (`.abc`) in and out: vertex caches stored as PolyMesh / SubD objects in the Ogawa
//! container (the format every current exporter writes: Houdini, Maya, Blender, PyAlembic).
//!
//! **Read** ([`parse_abc`]): every PolyMesh and SubD object (SubD as its control mesh), in the
//! archive's depth-first order, becomes part of one vertex cache, its points after those of the
//! meshes before it — or only the meshes at or under one object path
//! ([`ReadOptions::object`](super::ReadOptions::object), `--object /root/char/body`).
//! Polygons are fanned as OBJ polygons are and turned from Alembic's clockwise winding to the
//! counter-clockwise one of the other readers. The transforms of Xform ancestors (every
//! operation type, `.inherits`, animated or not) are baked into world positions. Frames are
//! the sample times of the meshes' points and of their animated ancestors (uniform, cyclic or
//! acyclic time sampling); they must be evenly spaced, and the frame rate is one over the step
//! (seconds), unless [`ReadOptions::frame_rate`](super::ReadOptions::frame_rate) overrides it
//! (one frame: the archive's `FramesPerTimeUnit`, else 30). A topology or point count that
//! changes over time is refused, naming the frame. An HDF5 archive (the legacy back end) is
//! recognised and refused.
//!
//! The input is untrusted: every offset, count and length is checked against the file (see
//! `ogawa.rs`), what the read keeps is counted against the memory budget (`--max-memory`) and
//! the bytes it parses against a work budget (`--max-work`) before it is done, objects nest at
//! most [`MAX_DEPTH`] deep, a group that contains itself is refused, names and metadata are
//! bounded and must be UTF-8, and stored data shared between samples is compared once.
//!
//! **Write** ([`encode_abc`]): an Xform `/animcodec` holding a PolyMesh `/animcodec/mesh` with
//! the positions of every frame as `P`, the triangles (wound clockwise) as a constant topology,
//! uniform time sampling at the frame rate, per-frame `.selfBnds`, and `FramesPerTimeUnit` in
//! the archive's metadata, laid out as the reference library lays out the same content (keys
//! are MurmurHash3, object trailers SpookyHash V2; see `hash.rs`).

mod core;
pub mod geom;
mod hash;
mod ogawa;
mod write;

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use codec_core::{Animation, Error, Result};

pub use geom::AbcMesh;
pub use write::encode_abc;

use super::gltf_buffers::Budget;
use super::{name, read_file};

/// Deepest nesting of objects followed.
pub const MAX_DEPTH: usize = 256;
/// Most objects one read visits.
pub const MAX_OBJECTS: u64 = 1 << 20;
/// Most property headers one read parses.
pub const MAX_PROPERTIES: u64 = 1 << 22;
/// Work a read may do when neither the caller nor the process sets a budget: one unit per
/// byte of headers parsed, sample compared or coordinate produced.
pub const DEFAULT_WORK_BUDGET: u64 = 20_000_000_000;

static PROCESS_WORK_BUDGET: AtomicU64 = AtomicU64::new(DEFAULT_WORK_BUDGET);

/// Sets the work budget of every later read (the binary's `--max-work`).
pub fn set_default_work_budget(units: u64) {
    PROCESS_WORK_BUDGET.store(units, Ordering::Relaxed);
}

/// The first bytes of an HDF5 file (the legacy Alembic back end).
const HDF5_MAGIC: &[u8] = b"\x89HDF\r\n\x1a\n";

/// What one read holds (memory budget) and does (work, objects, properties).
pub(super) struct Meter {
    budget: Budget,
    file: String,
    work: u64,
    work_limit: u64,
    objects: u64,
    properties: u64,
    /// Object and compound-property groups read so far: each is read once (the reference
    /// writer never shares one), so no shape of the file makes the headers be parsed twice.
    groups: std::collections::HashSet<u64>,
}

impl Meter {
    pub(super) fn new(file: &str, memory_budget: Option<u64>) -> Self {
        Self {
            budget: Budget::new(file, memory_budget),
            file: file.to_owned(),
            work: 0,
            work_limit: PROCESS_WORK_BUDGET.load(Ordering::Relaxed),
            objects: 0,
            properties: 0,
            groups: std::collections::HashSet::new(),
        }
    }

    /// Counts `bytes` more held (for `what`), or fails naming the budget.
    pub(super) fn take(&mut self, what: &str, bytes: u64) -> Result<()> {
        self.budget.take(what, bytes)
    }

    /// Counts `units` more work (for `what`), or fails naming the budget.
    pub(super) fn work(&mut self, what: &str, units: u64) -> Result<()> {
        self.work = self.work.saturating_add(units);
        if self.work > self.work_limit {
            return Err(Error::WorkLimit {
                context: self.file.clone().into(),
                what: format!("reading the archive ({what} included)").into(),
                ops: self.work,
                limit: self.work_limit,
            });
        }
        Ok(())
    }

    fn count_object(&mut self, path: &str) -> Result<()> {
        self.objects += 1;
        if self.objects > MAX_OBJECTS {
            return Err(Error::LimitExceeded {
                context: self.file.clone().into(),
                field: format!("objects visited (at {})", super::gltf_buffers::printable(path)).into(),
                value: self.objects,
                limit: MAX_OBJECTS,
            });
        }
        self.work("objects", 64)
    }

    /// Notes that the object or compound group at `offset` is read (for `what`); a group read
    /// before is shared by two parents, which only a crafted file does.
    fn visit_group(&mut self, offset: u64, what: &str) -> Result<()> {
        if offset != 0 && !self.groups.insert(offset) {
            return Err(Error::malformed(
                self.file.clone(),
                "groups",
                format!(
                    "{}: the group at byte {offset} belongs to two objects or properties (files the Alembic \
                     library writes never share one)",
                    super::gltf_buffers::printable(what)
                ),
            ));
        }
        self.take("group table", 32)
    }

    fn count_property(&mut self, what: &str) -> Result<()> {
        self.properties += 1;
        if self.properties > MAX_PROPERTIES {
            return Err(Error::LimitExceeded {
                context: self.file.clone().into(),
                field: format!("property headers read (at {})", super::gltf_buffers::printable(what)).into(),
                value: self.properties,
                limit: MAX_PROPERTIES,
            });
        }
        Ok(())
    }
}

/// Opens the archive in `bytes` (refusing HDF5 and non-Alembic files).
fn open<'a>(bytes: &'a [u8], file: &'a str, meter: &mut Meter) -> Result<core::Archive<'a>> {
    if bytes.starts_with(HDF5_MAGIC) {
        return Err(Error::Unsupported {
            context: file.to_owned().into(),
            detail: "an HDF5 Alembic archive (the legacy back end); re-export it as Ogawa, the default of every \
                     current exporter (Blender, Maya, Houdini, `abcconvert -toOgawa`)"
                .into(),
        });
    }
    let (og, root) = ogawa::Ogawa::open(bytes, file)?;
    core::Archive::open(og, root, meter)
}

/// Reads an `.abc` file (see the module documentation): the meshes at or under `object`
/// (all when `None`); `frame_rate` overrides the archive's.
pub fn read_abc(path: &Path, object: Option<&str>, frame_rate: Option<f32>) -> Result<Animation> {
    let bytes = read_file(path)?;
    parse_abc(&bytes, &name(path), object, frame_rate, None)
}

/// Parses an Alembic archive held in memory. `file` names it in errors; `memory_budget`
/// bounds what the read holds beyond the input (default: the process's read budget, 1 GiB
/// unless `--max-memory` set it).
pub fn parse_abc(
    bytes: &[u8],
    file: &str,
    object: Option<&str>,
    frame_rate: Option<f32>,
    memory_budget: Option<u64>,
) -> Result<Animation> {
    let mut meter = Meter::new(file, memory_budget);
    let ar = open(bytes, file, &mut meter)?;
    geom::assemble(&ar, object, frame_rate, &mut meter)
}

/// The mesh objects of an `.abc` file, with their sizes and sample counts (what
/// [`ReadOptions::object`](super::ReadOptions::object) selects from).
pub fn list_meshes(path: &Path) -> Result<Vec<AbcMesh>> {
    let bytes = read_file(path)?;
    parse_meshes(&bytes, &name(path))
}

/// [`list_meshes`] of an archive held in memory.
pub fn parse_meshes(bytes: &[u8], file: &str) -> Result<Vec<AbcMesh>> {
    let mut meter = Meter::new(file, None);
    let ar = open(bytes, file, &mut meter)?;
    geom::list(&ar, &mut meter)
}

/// An archive about to be written must read back (with [`parse_abc`]) as exactly `animation`:
/// the same triangles and every coordinate bit for bit. One that does not is never written.
pub(super) fn check_reads_back(path: &Path, bytes: &[u8], animation: &Animation) -> Result<()> {
    let back = parse_abc(bytes, &name(path), None, Some(animation.frame_rate()), Some(u64::MAX))
        .map_err(|e| Error::InvalidAnimation(format!("the Alembic archive written does not read back: {e}")))?;
    let same = back.triangles() == animation.triangles()
        && back.positions().len() == animation.positions().len()
        && back.positions().iter().zip(animation.positions()).all(|(a, b)| a.to_bits() == b.to_bits());
    if !same {
        return Err(Error::InvalidAnimation(format!(
            "{}: the Alembic archive written does not read back as the same positions and triangles",
            name(path)
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
