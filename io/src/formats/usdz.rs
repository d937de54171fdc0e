//! `.usdz` packages: a zip archive whose entries are stored uncompressed (method 0, data
//! 64-byte aligned); the first entry is the root layer (a text layer or a crate file). See
//! `pxr/usd/usd/zipFile.cpp` and the usdz specification (openusd.org, "Usdz File Format
//! Specification").
//!
//! Only the root layer is read. It is checked three ways before it is used: its local header
//! must agree with its central-directory record (method, sizes, CRC), it must be stored
//! (compressed entries are refused: a usdz never has them), and its bytes must lie inside the
//! archive and match the stored CRC-32.

use codec_core::{Error, Result};

/// Zip record signatures.
const LOCAL: u32 = 0x0403_4b50;
const CENTRAL: u32 = 0x0201_4b50;
const END: u32 = 0x0605_4b50;

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at.checked_add(2)?)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at.checked_add(4)?)?.try_into().ok()?))
}

/// CRC-32 (IEEE 802.3, reflected, as zip uses), bitwise: the root layer is read once.
fn crc32(data: &[u8]) -> u32 {
    let mut table = [0u32; 256];
    for (i, slot) in table.iter_mut().enumerate() {
        let mut c = i as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
        *slot = c;
    }
    !data.iter().fold(!0u32, |c, &b| table[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8))
}

/// The root layer of a usdz package: its bytes and its entry name.
pub(super) fn root_layer<'a>(bytes: &'a [u8], file: &str) -> Result<(&'a [u8], String)> {
    let bad = |detail: String| Error::malformed(file.to_owned(), "usdz", detail);
    let short = || bad("the archive ends inside a zip record (truncated?)".into());
    // The end-of-central-directory record: the last 22 bytes, or before a comment of at most
    // 65 535 bytes.
    let lowest = bytes.len().saturating_sub(22 + 65_535);
    let end = (lowest..=bytes.len().saturating_sub(22))
        .rev()
        .find(|&i| u32_at(bytes, i) == Some(END))
        .ok_or_else(|| bad("no zip end-of-central-directory record (truncated?)".into()))?;
    let entries = u16_at(bytes, end + 10).ok_or_else(short)?;
    let directory = u32_at(bytes, end + 16).ok_or_else(short)? as usize;
    if entries == 0 {
        return Err(bad("the package is empty (a usdz holds its root layer first)".into()));
    }
    if entries == 0xffff || directory == 0xffff_ffff {
        return Err(bad("a zip64 archive (a usdz is a plain zip)".into()));
    }
    if u32_at(bytes, directory) != Some(CENTRAL) {
        return Err(bad(format!("the central directory at offset {directory} is not there")));
    }
    let c_method = u16_at(bytes, directory + 10).ok_or_else(short)?;
    let c_crc = u32_at(bytes, directory + 16).ok_or_else(short)?;
    let c_packed = u32_at(bytes, directory + 20).ok_or_else(short)?;
    let c_size = u32_at(bytes, directory + 24).ok_or_else(short)?;
    let c_local = u32_at(bytes, directory + 42).ok_or_else(short)? as usize;
    // The first entry of the directory is the first file of the archive.
    if c_local != 0 || u32_at(bytes, 0) != Some(LOCAL) {
        return Err(bad(format!("the first entry's local header is at offset {c_local}, not at the start")));
    }
    let flags = u16_at(bytes, 6).ok_or_else(short)?;
    let method = u16_at(bytes, 8).ok_or_else(short)?;
    let crc = u32_at(bytes, 14).ok_or_else(short)?;
    let packed = u32_at(bytes, 18).ok_or_else(short)?;
    let size = u32_at(bytes, 22).ok_or_else(short)?;
    let name_len = u16_at(bytes, 26).ok_or_else(short)? as usize;
    let extra_len = u16_at(bytes, 28).ok_or_else(short)? as usize;
    let name_bytes = bytes.get(30..30 + name_len).ok_or_else(short)?;
    let name = String::from_utf8_lossy(name_bytes).into_owned();
    let shown = super::gltf::printable(&name);
    if method != 0 || c_method != 0 {
        return Err(Error::Unsupported {
            context: file.to_owned().into(),
            detail: format!(
                "the usdz entry {shown} is compressed (zip method {method}); a usdz stores its files uncompressed \
                 (method 0): re-package it with usd-core (`UsdUtils.CreateNewUsdzPackage`)"
            ),
        });
    }
    if flags & 8 != 0 {
        return Err(bad(format!("the entry {shown} has its sizes after its data (a data descriptor)")));
    }
    if packed != size || (c_packed, c_size, c_crc) != (packed, size, crc) {
        return Err(bad(format!(
            "the entry {shown} states {size} bytes ({packed} stored) in its header but {c_size} ({c_packed} stored) \
             in the central directory: its sizes are not consistent"
        )));
    }
    let start = 30 + name_len + extra_len;
    let data =
        start.checked_add(size as usize).filter(|&e| e <= directory).and_then(|e| bytes.get(start..e)).ok_or_else(
            || {
                bad(format!(
                    "the entry {shown} claims {size} bytes at offset {start}, past the end of its data (the archive's \
                 entries end at {directory})"
                ))
            },
        )?;
    if crc32(data) != crc {
        return Err(bad(format!("the entry {shown} does not match its CRC-32 (the archive is damaged)")));
    }
    let ext = name.rsplit('.').next().unwrap_or_default().to_ascii_lowercase();
    if !matches!(ext.as_str(), "usda" | "usdc" | "usd") {
        return Err(bad(format!("the first entry {shown} is not a USD layer (.usda, .usdc or .usd)")));
    }
    Ok((data, name))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A one-entry stored zip, as usdz packages are (used by the reader's tests).
    pub fn zip(name: &str, data: &[u8]) -> Vec<u8> {
        let crc = crc32(data);
        let mut z = Vec::new();
        let header = |z: &mut Vec<u8>, central: bool| {
            z.extend_from_slice(&(if central { CENTRAL } else { LOCAL }).to_le_bytes());
            if central {
                z.extend_from_slice(&20u16.to_le_bytes());
            }
            z.extend_from_slice(&[20, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
            z.extend_from_slice(&crc.to_le_bytes());
            z.extend_from_slice(&(data.len() as u32).to_le_bytes());
            z.extend_from_slice(&(data.len() as u32).to_le_bytes());
            z.extend_from_slice(&(name.len() as u16).to_le_bytes());
            z.extend_from_slice(&0u16.to_le_bytes());
            if central {
                z.extend_from_slice(&[0; 12]);
                z.extend_from_slice(&0u32.to_le_bytes());
            }
            z.extend_from_slice(name.as_bytes());
        };
        header(&mut z, false);
        z.extend_from_slice(data);
        let directory = z.len();
        header(&mut z, true);
        let dir_size = z.len() - directory;
        z.extend_from_slice(&END.to_le_bytes());
        z.extend_from_slice(&[0, 0, 0, 0, 1, 0, 1, 0]);
        z.extend_from_slice(&(dir_size as u32).to_le_bytes());
        z.extend_from_slice(&(directory as u32).to_le_bytes());
        z.extend_from_slice(&0u16.to_le_bytes());
        z
    }

    #[test]
    fn crc32_matches_the_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn the_root_layer_is_found_and_lies_are_refused() {
        let z = zip("a.usda", b"#usda 1.0\n");
        assert_eq!(root_layer(&z, "z").unwrap(), (&b"#usda 1.0\n"[..], "a.usda".to_owned()));
        // The local header states one byte more than the directory.
        let mut lie = z.clone();
        lie[22] += 1;
        assert!(root_layer(&lie, "z").unwrap_err().to_string().contains("not consistent"));
        // Both state a size past the data.
        let mut lie = z.clone();
        let d = u32_at(&z, z.len() - 6).unwrap() as usize;
        for at in [18, 22, d + 20, d + 24] {
            lie[at] = 0xff;
        }
        assert!(root_layer(&lie, "z").unwrap_err().to_string().contains("past the end"), "{:?}", root_layer(&lie, "z"));
        // Compressed, damaged, truncated, not a layer.
        let mut deflated = z.clone();
        deflated[8] = 8;
        assert!(root_layer(&deflated, "z").unwrap_err().to_string().contains("compressed"));
        let mut flipped = z.clone();
        flipped[40] ^= 1;
        assert!(root_layer(&flipped, "z").unwrap_err().to_string().contains("CRC"));
        for cut in 0..z.len() {
            assert!(root_layer(&z[..cut], "z").is_err());
        }
        assert!(root_layer(&zip("a.png", b"x"), "z").unwrap_err().to_string().contains("not a USD layer"));
    }
}
