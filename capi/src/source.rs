//! Where a stream's bytes come from: a copy in memory, or a file read at offsets. Both are
//! read through positioned reads (`&self`), so any number of threads decode from one stream
//! at once without sharing a file position.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};

/// The bytes of one `.anim` stream.
pub(crate) enum Source {
    /// A copy of the caller's buffer.
    Memory(Vec<u8>),
    /// An open file and its length when opened.
    File { file: File, len: u64 },
}

impl Source {
    /// Length of the stream in bytes.
    pub(crate) fn len(&self) -> u64 {
        match self {
            Source::Memory(bytes) => bytes.len() as u64,
            Source::File { len, .. } => *len,
        }
    }

    /// Reads up to `buf.len()` bytes at `offset`; fewer only at the end of the stream.
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<usize> {
        match self {
            Source::Memory(bytes) => {
                let start = usize::try_from(offset).unwrap_or(usize::MAX).min(bytes.len());
                let n = buf.len().min(bytes.len() - start);
                buf[..n].copy_from_slice(&bytes[start..start + n]);
                Ok(n)
            }
            Source::File { file, .. } => read_file_at(file, offset, buf),
        }
    }

    /// A `Read + Seek` view with its own position, what the container reader takes.
    pub(crate) fn cursor(&self) -> At<'_> {
        At { source: self, pos: 0 }
    }
}

#[cfg(unix)]
fn read_file_at(file: &File, offset: u64, buf: &mut [u8]) -> io::Result<usize> {
    std::os::unix::fs::FileExt::read_at(file, buf, offset)
}

#[cfg(windows)]
fn read_file_at(file: &File, offset: u64, buf: &mut [u8]) -> io::Result<usize> {
    std::os::windows::fs::FileExt::seek_read(file, buf, offset)
}

/// A position in a [`Source`].
pub(crate) struct At<'a> {
    source: &'a Source,
    pos: u64,
}

impl Read for At<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        // A file that shrank after opening reads as ended at its new length (the container
        // reader reports the truncated field); reads never go past the length seen at open.
        let left = self.source.len().saturating_sub(self.pos);
        let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
        let n = self.source.read_at(self.pos, &mut buf[..want])?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl Seek for At<'_> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let base = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.source.len().checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        self.pos =
            base.ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "seek before the start of the stream"))?;
        Ok(self.pos)
    }
}
