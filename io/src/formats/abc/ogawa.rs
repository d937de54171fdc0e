//! The Ogawa container under Alembic files (`lib/Alembic/Ogawa` in the Alembic sources).
//!
//! A file is a 16-byte header — the magic `Ogawa`, a "frozen" byte (`0xff` once the writer
//! finished), a big-endian `u16` format version (1) and the little-endian `u64` offset of the
//! root group — followed by **data** blocks (`u64` length, then the bytes) and **groups**
//! (`u64` child count, then one `u64` reference per child). A reference with bit 63 set names a
//! data block, otherwise a group; the low 63 bits are its offset. Offset 0 is the empty group
//! (no children) or the empty data block (no bytes). Everything after the header is
//! little-endian.
//!
//! Nothing here trusts the file: every offset, count and length is checked (in `u64`, without
//! overflow) against the file's size before anything is read, and groups are read child by
//! child from the file's bytes, so nothing is allocated from a count.

use codec_core::{Error, Result};

/// The first five bytes of every Ogawa file.
pub(super) const MAGIC: &[u8; 5] = b"Ogawa";
/// Size of the header: magic, frozen byte, version, root offset.
pub(super) const HEADER_LEN: u64 = 16;
/// The frozen byte of a file whose writer finished.
pub(super) const FROZEN: u8 = 0xff;
/// The only format version there is.
pub(super) const VERSION: u16 = 1;
/// Bit 63 of a child reference: set for data, clear for a group.
pub(super) const DATA_BIT: u64 = 1 << 63;

/// One child of a group: where it is (0: the empty group / empty data).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Child {
    /// A group at this offset.
    Group(u64),
    /// A data block at this offset.
    Data(u64),
}

/// A group: its offset and child count (both checked against the file).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Group {
    /// Offset of the group's count (0 for the empty group).
    pub(super) offset: u64,
    /// Number of children.
    pub(super) len: u64,
}

/// An Ogawa file held in memory.
pub(super) struct Ogawa<'a> {
    bytes: &'a [u8],
    file: &'a str,
}

impl<'a> Ogawa<'a> {
    /// Checks the header and returns the container and its root group.
    pub(super) fn open(bytes: &'a [u8], file: &'a str) -> Result<(Self, Group)> {
        let og = Self { bytes, file };
        if bytes.len() < HEADER_LEN as usize || &bytes[..5] != MAGIC {
            return Err(og.bad("header", "not an Ogawa file (no `Ogawa` magic)"));
        }
        if bytes[5] != FROZEN {
            return Err(og.bad(
                "header",
                format!(
                    "the file was not closed by its writer (frozen byte {:#04x}, 0xff expected): it is incomplete",
                    bytes[5]
                ),
            ));
        }
        let version = u16::from_be_bytes([bytes[6], bytes[7]]);
        if version != VERSION {
            return Err(Error::Unsupported {
                context: file.to_owned().into(),
                detail: format!("Ogawa format version {version} (only version {VERSION} exists)"),
            });
        }
        let root = og.u64_at(8)?;
        if root & DATA_BIT != 0 || root == 0 {
            return Err(og.bad("header", format!("the root reference {root:#x} does not name a group")));
        }
        let root = og.group(root)?;
        Ok((og, root))
    }

    /// The file's size in bytes.
    pub(super) fn size(&self) -> u64 {
        self.bytes.len() as u64
    }

    /// The file's name, for messages.
    pub(super) fn file(&self) -> &'a str {
        self.file
    }

    /// An error about this file.
    pub(super) fn bad(&self, field: &'static str, detail: impl Into<String>) -> Error {
        Error::malformed(self.file.to_owned(), field, detail)
    }

    /// The little-endian `u64` at `offset`, checked.
    fn u64_at(&self, offset: u64) -> Result<u64> {
        let end = offset.checked_add(8).filter(|&e| e <= self.size());
        match end {
            Some(end) => {
                let b = &self.bytes[offset as usize..end as usize];
                Ok(u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
            }
            None => Err(self.bad(
                "offset",
                format!("a reference points at byte {offset}, past the end of the file ({} bytes)", self.size()),
            )),
        }
    }

    /// The group at `offset` (0: the empty group), its children checked to lie in the file.
    pub(super) fn group(&self, offset: u64) -> Result<Group> {
        if offset == 0 {
            return Ok(Group { offset: 0, len: 0 });
        }
        if offset < HEADER_LEN {
            return Err(self.bad("group", format!("a group reference points into the header (byte {offset})")));
        }
        let len = self.u64_at(offset)?;
        // The count and the references must fit: offset + 8 + 8·len ≤ size.
        let fits = len.checked_mul(8).and_then(|b| b.checked_add(8)).and_then(|b| b.checked_add(offset));
        if fits.is_none_or(|end| end > self.size()) {
            return Err(self.bad(
                "group",
                format!(
                    "the group at byte {offset} claims {len} children, more than the file ({} bytes) can hold",
                    self.size()
                ),
            ));
        }
        Ok(Group { offset, len })
    }

    /// Child `index` of `group`, or an error naming what was expected (`what`).
    pub(super) fn child(&self, group: Group, index: u64, what: &str) -> Result<Child> {
        if index >= group.len {
            return Err(self.bad(
                "group",
                format!("{what}: child {index} is missing (the group at byte {} has {})", group.offset, group.len),
            ));
        }
        let r = self.u64_at(group.offset + 8 + 8 * index)?;
        Ok(if r & DATA_BIT != 0 { Child::Data(r & !DATA_BIT) } else { Child::Group(r) })
    }

    /// Child `index` of `group`, which must be a group.
    pub(super) fn child_group(&self, group: Group, index: u64, what: &str) -> Result<Group> {
        match self.child(group, index, what)? {
            Child::Group(o) if o == group.offset && o != 0 => {
                Err(self.bad("group", format!("{what}: the group at byte {o} contains itself")))
            }
            Child::Group(o) => self.group(o),
            Child::Data(_) => Err(self.bad("group", format!("{what}: a data block where a group belongs"))),
        }
    }

    /// Child `index` of `group`, which must be data: its bytes.
    pub(super) fn child_data(&self, group: Group, index: u64, what: &str) -> Result<(u64, &'a [u8])> {
        match self.child(group, index, what)? {
            Child::Data(o) => Ok((o, self.data(o)?)),
            Child::Group(_) => Err(self.bad("data", format!("{what}: a group where a data block belongs"))),
        }
    }

    /// The bytes of the data block at `offset` (0: empty).
    pub(super) fn data(&self, offset: u64) -> Result<&'a [u8]> {
        if offset == 0 {
            return Ok(&[]);
        }
        if offset < HEADER_LEN {
            return Err(self.bad("data", format!("a data reference points into the header (byte {offset})")));
        }
        let len = self.u64_at(offset)?;
        let start = offset + 8;
        match start.checked_add(len).filter(|&e| e <= self.size()) {
            Some(end) => Ok(&self.bytes[start as usize..end as usize]),
            None => Err(self.bad(
                "data",
                format!(
                    "the data block at byte {offset} claims {len} bytes, past the end of the file ({} bytes)",
                    self.size()
                ),
            )),
        }
    }
}

/// Builds an Ogawa file: data blocks are appended as they come, groups after their children
/// (as the reference writer does), and the header is completed last.
pub(super) struct OgawaWriter {
    out: Vec<u8>,
}

impl OgawaWriter {
    /// A file holding only the (unfinished) header.
    pub(super) fn new() -> Self {
        let mut out = Vec::with_capacity(4096);
        out.extend_from_slice(MAGIC);
        out.push(0); // frozen: set when finished
        out.extend_from_slice(&VERSION.to_be_bytes());
        out.extend_from_slice(&0u64.to_le_bytes());
        Self { out }
    }

    /// Appends a data block made of `parts` (concatenated); returns its reference. Empty data is
    /// the reference `DATA_BIT` with nothing written.
    pub(super) fn data(&mut self, parts: &[&[u8]]) -> Child {
        let len: usize = parts.iter().map(|p| p.len()).sum();
        if len == 0 {
            return Child::Data(0);
        }
        let at = self.out.len() as u64;
        self.out.extend_from_slice(&(len as u64).to_le_bytes());
        for p in parts {
            self.out.extend_from_slice(p);
        }
        Child::Data(at)
    }

    /// Appends a group of `children`; returns its reference (a group without children is the
    /// empty group, 0, with nothing written).
    pub(super) fn group(&mut self, children: &[Child]) -> Child {
        if children.is_empty() {
            return Child::Group(0);
        }
        let at = self.out.len() as u64;
        self.out.extend_from_slice(&(children.len() as u64).to_le_bytes());
        for c in children {
            let r = match *c {
                Child::Group(o) => o,
                Child::Data(o) => o | DATA_BIT,
            };
            self.out.extend_from_slice(&r.to_le_bytes());
        }
        Child::Group(at)
    }

    /// Completes the header (root offset, frozen byte) and returns the file.
    pub(super) fn finish(mut self, root: Child) -> Vec<u8> {
        let root = match root {
            Child::Group(o) => o,
            Child::Data(o) => o | DATA_BIT,
        };
        self.out[8..16].copy_from_slice(&root.to_le_bytes());
        self.out[5] = FROZEN;
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file_with(children: &[&[u8]]) -> Vec<u8> {
        let mut w = OgawaWriter::new();
        let kids: Vec<Child> = children.iter().map(|c| w.data(&[c])).collect();
        let root = w.group(&kids);
        w.finish(root)
    }

    #[test]
    fn a_written_container_reads_back() {
        let bytes = file_with(&[b"abc", b"", b"hello"]);
        let (og, root) = Ogawa::open(&bytes, "t.abc").unwrap();
        assert_eq!(root.len, 3);
        assert_eq!(og.child_data(root, 0, "x").unwrap().1, b"abc");
        assert_eq!(og.child_data(root, 1, "x").unwrap().1, b"");
        assert_eq!(og.child_data(root, 2, "x").unwrap().1, b"hello");
        assert!(og.child(root, 3, "x").unwrap_err().to_string().contains("child 3 is missing"));
        assert!(og.child_group(root, 0, "x").is_err());
    }

    #[test]
    fn bad_headers_sizes_and_self_references_are_refused() {
        let good = file_with(&[b"abc"]);
        let mut unfrozen = good.clone();
        unfrozen[5] = 0;
        assert!(Ogawa::open(&unfrozen, "t").err().unwrap().to_string().contains("not closed"));
        let mut v2 = good.clone();
        v2[7] = 2;
        assert!(Ogawa::open(&v2, "t").err().unwrap().to_string().contains("version 2"));
        assert!(Ogawa::open(b"Ogaw", "t").is_err());
        // A data block claiming 2^40 bytes.
        let mut huge = good.clone();
        huge[16..24].copy_from_slice(&(1u64 << 40).to_le_bytes());
        let (og, root) = Ogawa::open(&huge, "t").unwrap();
        assert!(og.child_data(root, 0, "x").unwrap_err().to_string().contains("past the end"));
        // A group claiming 2^61 children.
        let mut w = OgawaWriter::new();
        let d = w.data(&[b"x"]);
        let g = w.group(&[d]);
        let Child::Group(go) = g else { unreachable!() };
        let root = w.group(&[g]);
        let mut many = w.finish(root);
        many[go as usize..go as usize + 8].copy_from_slice(&(1u64 << 61).to_le_bytes());
        let (og, root) = Ogawa::open(&many, "t").unwrap();
        assert!(og.child_group(root, 0, "x").unwrap_err().to_string().contains("more than the file"));
        // A group listing itself.
        let mut w = OgawaWriter::new();
        let at = w.out.len() as u64;
        let root = w.group(&[Child::Group(at)]);
        let selfref = w.finish(root);
        let (og, root) = Ogawa::open(&selfref, "t").unwrap();
        assert!(og.child_group(root, 0, "x").unwrap_err().to_string().contains("contains itself"));
    }
}
