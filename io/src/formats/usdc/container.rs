//! The crate file's container: the bootstrap header, the table of contents and the six
//! structural sections (tokens, strings, fields, field sets, paths, specs), as laid out by
//! `pxr/usd/usd/crateFile.cpp` (`_ReadBootStrap`, `_ReadTOC`, `_ReadTokens`, …,
//! `_BuildDecompressedPathsImpl`).
//!
//! - **Bootstrap** (88 bytes): `PXR-USDC`, version bytes (major, minor, patch, 5 unused), the
//!   `i64` offset of the table of contents, 8 reserved `i64`s.
//! - **Table of contents**: `u64 n`, then n × { 16-byte NUL-padded name, `i64` start, `i64`
//!   size }.
//! - **TOKENS**: `u64` count, `u64` decoded size, `u64` compressed size, LZ4-wrapped
//!   NUL-terminated strings. **STRINGS**: `u64` count + `u32` token indexes.
//! - **FIELDS**: `u64` count, compressed `u32` token indexes (the field names), then a `u64`
//!   size and the LZ4-wrapped `u64` value representations.
//! - **FIELDSETS**: `u64` count, compressed `u32` field indexes; each set ends with `!0`.
//! - **PATHS**: `u64` path count, `u64` encoded count, then three compressed arrays: the path
//!   index of each item, its element token (negative: a property name), and its jump (−2: a
//!   leaf; −1: the next item is its first child; 0: the next item is its next sibling; > 0:
//!   both, the sibling `jump` items further on). Item 0 is the root `/`.
//! - **SPECS**: `u64` count, then compressed path indexes, field set indexes and spec types.
//!
//! Every count, size and offset is checked against the file and against the read's memory
//! budget before anything is allocated; the path tree is walked with an explicit stack, each
//! item visited at most once (a jump cycle is an error, not a hang).

use codec_core::{Error, Result};

use super::super::gltf_buffers::Budget;
use super::compression::{decode_ints, decompress, encoded_bound};

/// Sections beyond this count are not a crate file (upstream writes six).
const MAX_SECTIONS: u64 = 64;
/// The field set terminator.
pub const FIELD_SET_END: u32 = u32::MAX;

/// `SdfSpecType` values read here.
pub const SPEC_ATTRIBUTE: u32 = 1;
pub const SPEC_PRIM: u32 = 6;
pub const SPEC_PSEUDO_ROOT: u32 = 7;
pub const SPEC_RELATIONSHIP: u32 = 8;
/// Spec types past this are not defined (`SdfNumSpecTypes`).
const SPEC_TYPE_COUNT: u32 = 12;

/// A bounds-checked little-endian reader over `bytes[pos..end]`.
#[derive(Clone)]
pub struct Cursor<'a> {
    pub bytes: &'a [u8],
    pub pos: usize,
    pub end: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(bytes: &'a [u8], start: u64, end: u64) -> Option<Self> {
        let (start, end) = (usize::try_from(start).ok()?, usize::try_from(end).ok()?);
        (start <= end && end <= bytes.len()).then_some(Self { bytes, pos: start, end })
    }

    pub fn remaining(&self) -> usize {
        self.end - self.pos
    }

    pub fn take(&mut self, n: u64) -> std::result::Result<&'a [u8], String> {
        match usize::try_from(n) {
            Ok(n) if n <= self.remaining() => {
                self.pos += n;
                Ok(&self.bytes[self.pos - n..self.pos])
            }
            _ => Err(format!("{n} bytes at offset {} run past the end of their section", self.pos)),
        }
    }

    pub fn u8(&mut self) -> std::result::Result<u8, String> {
        Ok(self.take(1)?[0])
    }

    pub fn u32(&mut self) -> std::result::Result<u32, String> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    pub fn u64(&mut self) -> std::result::Result<u64, String> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
    }

    pub fn i64(&mut self) -> std::result::Result<i64, String> {
        self.u64().map(|v| v as i64)
    }
}

/// One spec: its path, its fields (a start in [`Crate::field_sets`]) and its `SdfSpecType`.
#[derive(Debug, Clone, Copy)]
pub struct Spec {
    pub path: u32,
    pub field_set: u32,
    pub spec_type: u32,
}

/// One node of the path tree: its parent's path index (`None` for the root) and its name.
#[derive(Debug, Clone, Copy)]
pub struct PathNode {
    pub parent: Option<u32>,
    pub token: u32,
    pub is_property: bool,
}

/// The structural sections of a crate file, checked.
pub struct Crate<'a> {
    pub file: &'a str,
    pub bytes: &'a [u8],
    /// Major, minor, patch.
    pub version: [u8; 3],
    /// Every token, NUL-terminated, as UTF-8.
    token_text: String,
    /// (start, end) of each token in `token_text` (each end at a NUL).
    token_spans: Vec<(u32, u32)>,
    /// Token index of each string.
    strings: Vec<u32>,
    /// (name token, value representation) of each field.
    pub fields: Vec<(u32, u64)>,
    pub field_sets: Vec<u32>,
    /// By path index; `None` for a path index no item names.
    pub paths: Vec<Option<PathNode>>,
    pub specs: Vec<Spec>,
}

impl<'a> Crate<'a> {
    pub fn err(&self, field: impl Into<String>, detail: impl Into<String>) -> Error {
        Error::malformed(self.file.to_owned(), field.into(), detail.into())
    }

    /// Token `i`, or an error naming `what` refers to it.
    pub fn token(&self, i: u32, what: &str) -> Result<&str> {
        let &(a, b) = self
            .token_spans
            .get(i as usize)
            .ok_or_else(|| self.err(what, format!("token index {i} is past the {} tokens", self.token_spans.len())))?;
        // Spans start and end at NULs (or the start), always character boundaries.
        self.token_text.get(a as usize..b as usize).ok_or_else(|| self.err(what, format!("token {i} is not UTF-8")))
    }

    /// String `i` (a string index refers to a token).
    pub fn string(&self, i: u32, what: &str) -> Result<&str> {
        let t = *self
            .strings
            .get(i as usize)
            .ok_or_else(|| self.err(what, format!("string index {i} is past the {} strings", self.strings.len())))?;
        self.token(t, what)
    }

    /// The fields of the set starting at `start`: (name token, value representation).
    pub fn field_set(&self, start: u32) -> impl Iterator<Item = (u32, u64)> + '_ {
        self.field_sets[start as usize..].iter().take_while(|&&f| f != FIELD_SET_END).map(|&f| self.fields[f as usize])
    }

    /// Path `i` as text (`/a/b.prop`), for messages and prim paths.
    pub fn path_text(&self, i: u32) -> Result<String> {
        self.path_text_within(i, usize::MAX)
    }

    /// Path `i` as text, or an error when it has more than `max_names` names (a relationship
    /// target deeper than any prim kept: a file may hold many, so each walk is bounded).
    pub fn path_text_within(&self, i: u32, max_names: usize) -> Result<String> {
        let mut names = Vec::new();
        let mut at = Some(i);
        // Parents always come earlier in the walk that built the tree, so this ends; the
        // count bound makes that certain.
        while let Some(p) = at {
            if names.len() > max_names {
                return Err(self.err("PATHS", format!("a relationship target deeper than {max_names} prims")));
            }
            if names.len() > self.paths.len() {
                return Err(self.err("PATHS", "the path tree has a cycle"));
            }
            let node = self
                .paths
                .get(p as usize)
                .copied()
                .flatten()
                .ok_or_else(|| self.err("PATHS", format!("path index {p} names no path")))?;
            if node.parent.is_some() {
                names.push((self.token(node.token, "PATHS")?, node.is_property));
            }
            at = node.parent;
        }
        let mut text = String::new();
        for (name, property) in names.iter().rev() {
            text.push(if *property { '.' } else { '/' });
            text.push_str(name);
        }
        if text.is_empty() {
            text.push('/');
        }
        Ok(text)
    }
}

/// A section's bytes, by name (the first one of that name), or `None` when absent.
fn section<'a>(toc: &[([u8; 16], u64, u64)], bytes: &'a [u8], name: &str) -> Option<Cursor<'a>> {
    let (_, start, size) = toc.iter().find(|(n, _, _)| n.split(|&b| b == 0).next() == Some(name.as_bytes()))?;
    Cursor::new(bytes, *start, *start + *size)
}

/// Parses and checks the structural sections of the crate file `bytes`.
pub fn read_crate<'a>(bytes: &'a [u8], file: &'a str, budget: &mut Budget) -> Result<Crate<'a>> {
    let bad = |field: &str, detail: String| Error::malformed(file.to_owned(), field.to_owned(), detail);
    if bytes.len() < 88 || &bytes[..8] != b"PXR-USDC" {
        return Err(bad("bootstrap", format!("{} bytes: too short for a crate file's 88-byte header", bytes.len())));
    }
    let version = [bytes[8], bytes[9], bytes[10]];
    if version[0] != 0 || version[1] < 4 || version[1] > 11 {
        return Err(Error::Unsupported {
            context: file.to_owned().into(),
            detail: format!(
                "USD crate version {}.{}.{} (versions 0.4.0 to 0.11.x are read; re-save the file with a current USD)",
                version[0], version[1], version[2]
            ),
        });
    }
    let toc_offset = i64::from_le_bytes(bytes[16..24].try_into().unwrap_or_default());
    let mut toc_cursor = u64::try_from(toc_offset)
        .ok()
        .and_then(|o| Cursor::new(bytes, o, bytes.len() as u64))
        .filter(|c| c.remaining() >= 8)
        .ok_or_else(|| {
            bad(
                "table of contents",
                format!("at offset {toc_offset}, past the end of the {}-byte file (truncated?)", bytes.len()),
            )
        })?;
    let toc_err = |e: String| bad("table of contents", e);
    let n = toc_cursor.u64().map_err(toc_err)?;
    if n > MAX_SECTIONS {
        return Err(bad("table of contents", format!("{n} sections (a crate file has six)")));
    }
    let mut toc = Vec::with_capacity(n as usize);
    for _ in 0..n {
        let name: [u8; 16] = toc_cursor.take(16).map_err(toc_err)?.try_into().unwrap_or_default();
        let start = toc_cursor.i64().map_err(toc_err)?;
        let size = toc_cursor.i64().map_err(toc_err)?;
        let printable = String::from_utf8_lossy(name.split(|&b| b == 0).next().unwrap_or_default()).into_owned();
        let (Ok(s), Ok(z)) = (u64::try_from(start), u64::try_from(size)) else {
            return Err(bad("table of contents", format!("section {printable:?} has a negative start or size")));
        };
        if s.checked_add(z).is_none_or(|e| e > bytes.len() as u64) {
            return Err(bad(
                "table of contents",
                format!(
                    "section {:?} ({z} bytes at {s}) runs past the end of the {}-byte file",
                    super::super::gltf::printable(&printable),
                    bytes.len()
                ),
            ));
        }
        toc.push((name, s, z));
    }
    let get = |name: &str| section(&toc, bytes, name).ok_or_else(|| bad(name, "the section is missing".into()));
    let mut krate = Crate {
        file,
        bytes,
        version,
        token_text: String::new(),
        token_spans: Vec::new(),
        strings: Vec::new(),
        fields: Vec::new(),
        field_sets: Vec::new(),
        paths: Vec::new(),
        specs: Vec::new(),
    };
    read_tokens(&mut krate, get("TOKENS")?, budget)?;
    read_strings(&mut krate, get("STRINGS")?, budget)?;
    read_fields(&mut krate, get("FIELDS")?, budget)?;
    read_field_sets(&mut krate, get("FIELDSETS")?, budget)?;
    read_paths(&mut krate, get("PATHS")?, budget)?;
    read_specs(&mut krate, get("SPECS")?, budget)?;
    Ok(krate)
}

/// A compressed-integer stream of `n` integers (`u64` size, LZ4-wrapped coded integers) of
/// `width` bytes, counted against the budget.
pub fn compressed_ints(
    c: &mut Cursor,
    n: u64,
    width: u64,
    budget: &mut Budget,
    what: &str,
) -> std::result::Result<Vec<i64>, String> {
    let size = c.u64()?;
    let data = c.take(size).map_err(|_| format!("{what}: {size} compressed bytes run past the end of the section"))?;
    let bound = encoded_bound(n, width).ok_or_else(|| format!("{what}: {n} integers overflow"))?;
    budget.take(what, bound.saturating_add(n.saturating_mul(8))).map_err(|e| e.to_string())?;
    let bound = usize::try_from(bound).map_err(|_| format!("{what}: {n} integers overflow"))?;
    let encoded = decompress(data, bound).map_err(|e| format!("{what}: {e}"))?;
    decode_ints(&encoded, n as usize, width as usize).map_err(|e| format!("{what}: {e}"))
}

fn section_err<'f>(file: &'f str, name: &str) -> impl Fn(String) -> Error + 'f {
    let name = name.to_owned();
    move |e| Error::malformed(file.to_owned(), name.clone(), e)
}

/// Indexes below `limit`, as u32.
fn indexes(values: Vec<i64>, limit: u64, what: &str) -> std::result::Result<Vec<u32>, String> {
    values
        .into_iter()
        .map(|v| {
            let u = v as u32 as u64; // stored as u32
            if u < limit {
                Ok(u as u32)
            } else {
                Err(format!("{what} {u} is out of range (below {limit} expected)"))
            }
        })
        .collect()
}

fn read_tokens(k: &mut Crate, mut c: Cursor, budget: &mut Budget) -> Result<()> {
    let e = section_err(k.file, "TOKENS");
    let count = c.u64().map_err(&e)?;
    let raw = c.u64().map_err(&e)?;
    let size = c.u64().map_err(&e)?;
    let data = c.take(size).map_err(&e)?;
    if count > raw {
        return Err(e(format!("{count} tokens cannot fit in {raw} bytes")));
    }
    budget.take("tokens", raw.saturating_add(count.saturating_mul(8)))?;
    let raw_usize = usize::try_from(raw).map_err(|_| e(format!("{raw} bytes of tokens")))?;
    let bytes = decompress(data, raw_usize).map_err(&e)?;
    if bytes.len() != raw_usize {
        return Err(e(format!("the tokens decode to {} bytes, not the {raw} stated", bytes.len())));
    }
    if u32::try_from(raw).is_err() {
        return Err(e(format!("{raw} bytes of tokens (at most 4 GiB are read)")));
    }
    // Checked once here (a token may be named by many fields): an invalid sequence becomes
    // U+FFFD, which keeps every NUL where it is but may lengthen the buffer.
    let text = match String::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => {
            let text = String::from_utf8_lossy(e.as_bytes()).into_owned();
            budget.take("tokens", text.len() as u64)?;
            text
        }
    };
    let bytes = text.as_bytes();
    if u32::try_from(bytes.len()).is_err() {
        return Err(e(format!("{} bytes of tokens (at most 4 GiB are read)", bytes.len())));
    }
    let mut spans = Vec::with_capacity(count as usize);
    let mut at = 0usize;
    while spans.len() < count as usize {
        let len = bytes[at..]
            .iter()
            .position(|&b| b == 0)
            .ok_or_else(|| e(format!("{} NUL-terminated tokens found, {count} stated", spans.len())))?;
        spans.push((at as u32, (at + len) as u32));
        at += len + 1;
    }
    k.token_text = text;
    k.token_spans = spans;
    Ok(())
}

fn read_strings(k: &mut Crate, mut c: Cursor, budget: &mut Budget) -> Result<()> {
    let e = section_err(k.file, "STRINGS");
    let count = c.u64().map_err(&e)?;
    let data = c.take(count.saturating_mul(4)).map_err(&e)?;
    budget.take("strings", count.saturating_mul(4))?;
    let tokens = k.token_spans.len() as u64;
    k.strings = indexes(
        data.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64).collect(),
        tokens,
        "string token index",
    )
    .map_err(&e)?;
    Ok(())
}

fn read_fields(k: &mut Crate, mut c: Cursor, budget: &mut Budget) -> Result<()> {
    let e = section_err(k.file, "FIELDS");
    let count = c.u64().map_err(&e)?;
    // Each field takes at least 2 bits of codes; the reps take 8 bytes each before LZ4.
    let names = compressed_ints(&mut c, count, 4, budget, "field names").map_err(&e)?;
    let names = indexes(names, k.token_spans.len() as u64, "field name token").map_err(&e)?;
    let size = c.u64().map_err(&e)?;
    let data = c.take(size).map_err(&e)?;
    let want = count.checked_mul(8).ok_or_else(|| e(format!("{count} fields overflow")))?;
    budget.take("fields", want)?;
    let reps = decompress(data, want as usize).map_err(&e)?;
    if reps.len() as u64 != want {
        return Err(e(format!("the value representations decode to {} bytes, not {want}", reps.len())));
    }
    k.fields = names
        .into_iter()
        .zip(reps.chunks_exact(8))
        .map(|(n, b)| (n, u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])))
        .collect();
    Ok(())
}

fn read_field_sets(k: &mut Crate, mut c: Cursor, budget: &mut Budget) -> Result<()> {
    let e = section_err(k.file, "FIELDSETS");
    let count = c.u64().map_err(&e)?;
    let sets = compressed_ints(&mut c, count, 4, budget, "field sets").map_err(&e)?;
    let fields = k.fields.len() as u64;
    let sets: Vec<u32> = sets.into_iter().map(|v| v as u32).collect();
    if let Some(bad) = sets.iter().find(|&&f| f != FIELD_SET_END && f as u64 >= fields) {
        return Err(e(format!("field index {bad} is past the {fields} fields")));
    }
    if sets.last().is_some_and(|&f| f != FIELD_SET_END) {
        return Err(e("the last field set is not terminated".into()));
    }
    k.field_sets = sets;
    Ok(())
}

fn read_paths(k: &mut Crate, mut c: Cursor, budget: &mut Budget) -> Result<()> {
    let e = section_err(k.file, "PATHS");
    let count = c.u64().map_err(&e)?;
    let encoded = c.u64().map_err(&e)?;
    // Every path but the empty one is encoded: more paths than items is a lie.
    if count > encoded.saturating_add(1) || encoded > count {
        return Err(e(format!("{count} paths but {encoded} encoded items")));
    }
    let path_indexes = compressed_ints(&mut c, encoded, 4, budget, "path indexes").map_err(&e)?;
    let path_indexes = indexes(path_indexes, count, "path index").map_err(&e)?;
    let tokens = compressed_ints(&mut c, encoded, 4, budget, "path element tokens").map_err(&e)?;
    let jumps = compressed_ints(&mut c, encoded, 4, budget, "path jumps").map_err(&e)?;
    budget.take("paths", count.saturating_mul(16).saturating_add(encoded))?;
    let nodes = path_tree(&path_indexes, &tokens, &jumps, count as usize, k.token_spans.len() as u64).map_err(&e)?;
    k.paths = nodes;
    Ok(())
}

fn read_specs(k: &mut Crate, mut c: Cursor, budget: &mut Budget) -> Result<()> {
    let e = section_err(k.file, "SPECS");
    let count = c.u64().map_err(&e)?;
    let paths = compressed_ints(&mut c, count, 4, budget, "spec paths").map_err(&e)?;
    let paths = indexes(paths, k.paths.len() as u64, "spec path index").map_err(&e)?;
    let sets = compressed_ints(&mut c, count, 4, budget, "spec field sets").map_err(&e)?;
    let sets = indexes(sets, k.field_sets.len() as u64, "spec field set index").map_err(&e)?;
    let types = compressed_ints(&mut c, count, 4, budget, "spec types").map_err(&e)?;
    let types = indexes(types, SPEC_TYPE_COUNT as u64, "spec type").map_err(&e)?;
    budget.take("specs", count.saturating_mul(12))?;
    let mut specs = Vec::with_capacity(count as usize);
    for ((path, set), ty) in paths.into_iter().zip(sets).zip(types) {
        if k.paths[path as usize].is_none() {
            return Err(e(format!("a spec names path index {path}, which no path item defines")));
        }
        if set > 0 && k.field_sets[set as usize - 1] != FIELD_SET_END {
            return Err(e(format!("field set index {set} is not the start of a set")));
        }
        specs.push(Spec { path, field_set: set, spec_type: ty });
    }
    k.specs = specs;
    Ok(())
}

/// The path tree of the encoded items (`path_indexes[i]` < `count`, element tokens, jumps; see
/// the module documentation), by path index. Walked with an explicit stack of sibling runs,
/// each item visited at most once.
fn path_tree(
    path_indexes: &[u32],
    tokens: &[i64],
    jumps: &[i64],
    count: usize,
    token_count: u64,
) -> std::result::Result<Vec<Option<PathNode>>, String> {
    let n = path_indexes.len().min(tokens.len()).min(jumps.len());
    let mut nodes: Vec<Option<PathNode>> = vec![None; count];
    let mut visited = vec![false; n];
    // (item, parent path index): sibling runs still to walk.
    let mut stack: Vec<(usize, Option<u32>)> = Vec::new();
    if n > 0 {
        stack.push((0, None));
    }
    while let Some((mut item, mut parent)) = stack.pop() {
        loop {
            if item >= n {
                return Err(format!("a jump leads to item {item}, past the {n} encoded paths"));
            }
            if std::mem::replace(&mut visited[item], true) {
                return Err(format!("item {item} is reached twice (the jumps form a cycle)"));
            }
            let index = path_indexes[item];
            let slot = nodes.get_mut(index as usize).ok_or_else(|| format!("path index {index} is out of range"))?;
            if slot.is_some() {
                return Err(format!("path index {index} is encoded twice"));
            }
            let token = (tokens[item] as i32).unsigned_abs();
            if parent.is_some() && token as u64 >= token_count {
                return Err(format!("element token {token} is past the {token_count} tokens"));
            }
            *slot = Some(PathNode { parent, token, is_property: parent.is_some() && (tokens[item] as i32) < 0 });
            let jump = jumps[item] as i32;
            if jump < -2 {
                return Err(format!("item {item} has jump {jump} (-2 or more expected)"));
            }
            let (child, sibling) = (jump > 0 || jump == -1, jump >= 0);
            if sibling && parent.is_none() {
                return Err("the root path has a sibling".into());
            }
            if child && sibling {
                let to = item
                    .checked_add(jump as usize)
                    .filter(|&t| t < n)
                    .ok_or_else(|| format!("item {item} jumps {jump} items, past the {n} encoded paths"))?;
                stack.push((to, parent));
            }
            if child {
                parent = Some(index);
            } else if !sibling {
                break;
            }
            item += 1;
        }
    }
    Ok(nodes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree(jumps: &[i64]) -> std::result::Result<Vec<Option<PathNode>>, String> {
        let n = jumps.len();
        let indexes: Vec<u32> = (0..n as u32).collect();
        // Items 2 and 3 name properties.
        let tokens: Vec<i64> = (0..n as i64).map(|i| if i == 2 || i == 3 { -i } else { i }).collect();
        path_tree(&indexes, &tokens, jumps, n, n as u64)
    }

    /// `/`, `/a`, `/a.x`, `/a.y`, `/b`: root child-only, `/a` child and sibling 3 on, `.x`
    /// sibling-only, `.y` and `/b` leaves.
    #[test]
    fn jumps_build_the_tree() {
        let nodes = tree(&[-1, 3, 0, -2, -2]).unwrap();
        let parents: Vec<Option<u32>> = nodes.iter().map(|n| n.unwrap().parent).collect();
        assert_eq!(parents, vec![None, Some(0), Some(1), Some(1), Some(0)]);
        assert!(nodes[2].unwrap().is_property && nodes[3].unwrap().is_property && !nodes[4].unwrap().is_property);
    }

    #[test]
    fn bad_jumps_and_cycles_are_errors() {
        let cases: &[(&[i64], &str)] = &[
            (&[-1, 1, -2], "reached twice"), // the child run and the sibling run meet
            (&[-1, 0, 0], "past the"),       // a sibling-only run off the end
            (&[-1, 9, -2], "past the"),      // a jump off the end
            (&[-1, -3], "jump -3"),          // not a jump
            (&[0, -2], "root path has a sibling"),
            (&[-1, -1, -1], "past the"), // a child off the end
        ];
        for (jumps, needle) in cases {
            let e = tree(jumps).unwrap_err();
            assert!(e.contains(needle), "{jumps:?}: {e}");
        }
        // Two items naming one path, a path index or token out of range.
        assert!(path_tree(&[0, 0], &[0, 1], &[-1, -2], 2, 2).unwrap_err().contains("twice"));
        assert!(path_tree(&[0, 5], &[0, 1], &[-1, -2], 2, 2).unwrap_err().contains("out of range"));
        assert!(path_tree(&[0, 1], &[0, 7], &[-1, -2], 2, 2).unwrap_err().contains("past the 2 tokens"));
        // A long chain is walked without recursion.
        let mut jumps = vec![-1i64; 100_000];
        jumps[99_999] = -2;
        assert!(tree(&jumps).is_ok());
    }
}
