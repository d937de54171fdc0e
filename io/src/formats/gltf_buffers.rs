//! The bottom of the glTF reader: what every part of it shares — the read's memory
//! [`Budget`], the bytes of the buffers ([`BufferData`]), accessor checks made before the `gltf`
//! crate reads an accessor ([`check_accessor`], [`collect_exact`]) and the error helper
//! [`bad`]. The document reader (`gltf.rs`), the scene player (`gltf_scene.rs`) and the
//! meshopt and Draco decoders (`gltf_meshopt.rs`, `gltf_draco.rs`) import from here; nothing
//! here imports them, so the modules form no circle.

use std::sync::atomic::{AtomicU64, Ordering};

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::Accessor;
use codec_core::{Error, Result};

/// Memory a glTF read may hold when neither the caller nor the process sets a budget: 1 GiB,
/// far above any real animated character (RobotExpressive baked at 24 fps: 5 MB) and far
/// below the 3 GB a 20 000-instance scene asks for.
pub const DEFAULT_MEMORY_BUDGET: u64 = 1 << 30;

static PROCESS_MEMORY_BUDGET: AtomicU64 = AtomicU64::new(DEFAULT_MEMORY_BUDGET);

/// Sets the memory budget of every later read that names none (the binary's `--max-memory`).
pub fn set_default_memory_budget(bytes: u64) {
    PROCESS_MEMORY_BUDGET.store(bytes, Ordering::Relaxed);
}

/// Bytes held by one read, counted against its budget before each allocation.
pub(super) struct Budget {
    file: String,
    limit: u64,
    held: u64,
}

impl Budget {
    pub(super) fn new(file: &str, limit: Option<u64>) -> Self {
        Self {
            file: file.to_owned(),
            limit: limit.unwrap_or_else(|| PROCESS_MEMORY_BUDGET.load(Ordering::Relaxed)),
            held: 0,
        }
    }

    /// Bytes the read may still hold.
    pub(super) fn remaining(&self) -> u64 {
        self.limit.saturating_sub(self.held)
    }

    /// Fails as [`Budget::take`] would, without counting `bytes`: for what is held only
    /// briefly, or counted later once its final size is known.
    pub(super) fn check(&self, what: &str, bytes: u64) -> Result<()> {
        let held = self.held.saturating_add(bytes);
        if held > self.limit {
            return Err(Error::LimitExceeded {
                context: self.file.clone().into(),
                field: format!("total memory of the read, {what} included (--max-memory raises it)").into(),
                value: held,
                limit: self.limit,
            });
        }
        Ok(())
    }

    /// Counts `bytes` more (for `what`), or fails naming the total and the budget.
    pub(super) fn take(&mut self, what: &str, bytes: u64) -> Result<()> {
        self.check(what, bytes)?;
        self.held = self.held.saturating_add(bytes);
        Ok(())
    }
}

/// `text` with every control character (ANSI escapes, newlines) written as a Rust-style escape
/// (`\u{1b}`, `\n`), for printing names taken from a file on a terminal.
pub fn printable(text: &str) -> String {
    text.chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
}

/// The extension that allows 8/16-bit integer positions (and morph target displacements).
pub(super) const KHR_MESH_QUANTIZATION: &str = "KHR_mesh_quantization";

pub(super) fn bad(file: &str, field: &'static str, detail: impl Into<String>) -> Error {
    Error::malformed(file.to_owned(), field, detail)
}

/// Checks an accessor's dimensions and component type against what `field` allows.
pub(super) fn check_accessor_kind(
    file: &str,
    field: &'static str,
    accessor: &Accessor,
    dims: Dimensions,
    types: &[DataType],
) -> Result<()> {
    let what = format!("accessor {}", accessor.index());
    if accessor.dimensions() != dims {
        return Err(bad(file, field, format!("{what} is {:?}, expected {dims:?}", accessor.dimensions())));
    }
    if !types.contains(&accessor.data_type()) {
        return Err(bad(
            file,
            field,
            format!("{what} has component type {:?}, expected {types:?}", accessor.data_type()),
        ));
    }
    Ok(())
}

/// Checks an accessor before handing it to the `gltf` reader: dimensions, component type,
/// non-zero counts (the reader computes `count - 1`), the vertex limit, and its byte layout
/// ([`check_layout`]). Returns the count.
pub(super) fn check_accessor(
    file: &str,
    field: &'static str,
    accessor: &Accessor,
    dims: Dimensions,
    types: &[DataType],
    buffers: &[BufferData],
) -> Result<usize> {
    check_accessor_kind(file, field, accessor, dims, types)?;
    let what = format!("accessor {}", accessor.index());
    if accessor.count() == 0 {
        return Err(bad(file, field, format!("{what} is empty")));
    }
    if accessor.sparse().is_some_and(|s| s.count() == 0) {
        return Err(bad(file, field, format!("{what} has an empty sparse block")));
    }
    let limits = super::reader_limits();
    if accessor.count() > limits.max_triangles * 3 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: field.into(),
            value: accessor.count() as u64,
            limit: (limits.max_triangles * 3) as u64,
        });
    }
    check_layout(file, field, accessor, buffers)?;
    Ok(accessor.count())
}

/// The bytes `[start, start + stride·(count−1) + element)` of a view, checked: `stride` at
/// least the element, the range inside the view, the view inside its (loaded) buffer. `what`
/// names the accessor (and part) in errors.
#[allow(clippy::too_many_arguments)]
fn check_range(
    file: &str,
    field: &'static str,
    what: &str,
    view: &::gltf::buffer::View,
    offset: usize,
    count: usize,
    element: usize,
    buffers: &[BufferData],
) -> Result<()> {
    let v = view.index();
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(bad(
            file,
            field,
            format!("{what}: bufferView {v} has byteStride {stride}, smaller than the {element}-byte element"),
        ));
    }
    let held = buffers.get(view.buffer().index()).map_or(0, |b| b.0.len());
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > held) {
        return Err(bad(
            file,
            field,
            format!(
                "{what}: bufferView {v} (byteOffset {}, byteLength {}) overflows or lies outside buffer {} ({held} bytes)",
                view.offset(),
                view.length(),
                view.buffer().index()
            ),
        ));
    }
    let end = stride
        .checked_mul(count.saturating_sub(1))
        .and_then(|x| x.checked_add(element))
        .and_then(|x| x.checked_add(offset));
    match end {
        Some(end) if end <= view.length() => Ok(()),
        _ => Err(bad(
            file,
            field,
            format!(
                "{what}: {count} elements of {element} bytes at byteOffset {offset}, byteStride {stride} overflow \
                 bufferView {v} (byteLength {})",
                view.length()
            ),
        )),
    }
}

/// Checks an accessor's bytes (see [`check_range`]) and its sparse block: indices of an index
/// component type, strictly increasing and below the accessor's count, values in range.
fn check_layout(file: &str, field: &'static str, accessor: &Accessor, buffers: &[BufferData]) -> Result<()> {
    let what = format!("accessor {}", accessor.index());
    let element = accessor.size();
    let count = accessor.count();
    if let Some(view) = accessor.view() {
        check_range(file, field, &what, &view, accessor.offset(), count, element, buffers)?;
    }
    let Some(sparse) = accessor.sparse() else { return Ok(()) };
    let n = sparse.count();
    if n > count {
        return Err(bad(file, field, format!("{what}: a sparse block of {n} for {count} elements")));
    }
    let indices = sparse.indices();
    let index_size = match indices.index_type() {
        ::gltf::accessor::sparse::IndexType::U8 => 1,
        ::gltf::accessor::sparse::IndexType::U16 => 2,
        ::gltf::accessor::sparse::IndexType::U32 => 4,
    };
    let index_view = indices.view();
    let at = format!("{what} sparse indices");
    // Sparse index and value views are tightly packed (spec: no byteStride); the crate reads
    // them with the view's stride when one is given, so that stride is checked as well.
    check_range(file, field, &at, &index_view, indices.offset(), n, index_size, buffers)?;
    let values = sparse.values();
    let at_values = format!("{what} sparse values");
    check_range(file, field, &at_values, &values.view(), values.offset(), n, element, buffers)?;
    let data = &buffers[index_view.buffer().index()].0;
    let stride = index_view.stride().unwrap_or(index_size);
    let start = index_view.offset() + indices.offset();
    let mut previous: Option<u64> = None;
    for k in 0..n {
        let b = &data[start + k * stride..start + k * stride + index_size];
        let index = match index_size {
            1 => u64::from(b[0]),
            2 => u64::from(u16::from_le_bytes([b[0], b[1]])),
            _ => u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        };
        if index >= count as u64 {
            return Err(bad(file, field, format!("{at}: index {k} is {index}, out of range for {count} elements")));
        }
        if previous.is_some_and(|p| index <= p) {
            return Err(bad(file, field, format!("{at}: index {k} ({index}) does not increase")));
        }
        previous = Some(index);
    }
    Ok(())
}

/// Collects exactly `count` items from a reader, or fails (the reader yields fewer items when the
/// buffer view is too short for the accessor).
pub(super) fn collect_exact<T>(
    file: &str,
    field: &'static str,
    iter: Option<impl Iterator<Item = T>>,
    count: usize,
) -> Result<Vec<T>> {
    let items: Vec<T> = iter.ok_or_else(|| bad(file, field, "buffer data is missing"))?.take(count).collect();
    if items.len() != count {
        return Err(bad(file, field, format!("accessor holds {} items, {count} declared", items.len())));
    }
    Ok(items)
}

/// The bytes of one glTF buffer (empty when no geometry accessor reads it).
pub(super) struct BufferData(pub(super) Vec<u8>);
