//! Helpers of the C library's tests: the C ABI called from Rust, the golden streams, the built
//! library's directory.

#![allow(dead_code)]

use std::ffi::CStr;
use std::path::{Path, PathBuf};

use animcodec_capi::*;

/// The message of this thread's last failure.
pub fn last_error() -> String {
    // SAFETY: a NUL-terminated string the library owns until this thread's next failing call.
    unsafe { CStr::from_ptr(ac_last_error()) }.to_string_lossy().into_owned()
}

/// An open stream, freed on drop.
pub struct Stream(pub *mut ac_stream);

impl Drop for Stream {
    fn drop(&mut self) {
        // SAFETY: a handle from `ac_stream_open_*`, freed once.
        unsafe { ac_stream_free(self.0) }
    }
}

// SAFETY: the header documents `ac_stream` as usable from several threads.
unsafe impl Send for Stream {}
// SAFETY: as above.
unsafe impl Sync for Stream {}

impl Stream {
    /// `ac_stream_open_memory`, or the status and message.
    pub fn open_memory(bytes: &[u8], limits: Option<&ac_limits>) -> Result<Self, (ac_status, String)> {
        let mut h = std::ptr::null_mut();
        let l = limits.map_or(std::ptr::null(), |l| l as *const ac_limits);
        // SAFETY: valid buffer, limits and out pointer.
        match unsafe { ac_stream_open_memory(bytes.as_ptr(), bytes.len(), l, &mut h) } {
            ac_status::AC_OK => Ok(Self(h)),
            s => {
                assert!(h.is_null(), "a failed open leaves *out NULL");
                Err((s, last_error()))
            }
        }
    }

    /// `ac_stream_get_info`.
    pub fn info(&self) -> ac_stream_info {
        let mut info = std::mem::MaybeUninit::<ac_stream_info>::uninit();
        // SAFETY: a live handle and a writable struct.
        assert_eq!(unsafe { ac_stream_get_info(self.0, info.as_mut_ptr()) }, ac_status::AC_OK);
        // SAFETY: written on success.
        unsafe { info.assume_init() }
    }

    /// `ac_decode_frame` into a new buffer.
    pub fn frame(&self, t: usize) -> Result<Vec<f32>, (ac_status, String)> {
        let mut out = vec![0f32; self.info().vertices * 3];
        // SAFETY: a live handle and `out.len()` writable floats.
        match unsafe { ac_decode_frame(self.0, t, out.as_mut_ptr(), out.len()) } {
            ac_status::AC_OK => Ok(out),
            s => Err((s, last_error())),
        }
    }
}

/// Every `.anim` under `tests/golden`, sorted.
pub fn goldens() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("tests/golden") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "anim") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&workspace().join("tests").join("golden"), &mut out);
    out.sort();
    assert!(out.len() >= 20, "golden streams: {}", out.len());
    out
}

/// The workspace root.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace").to_path_buf()
}

/// The directory cargo put this crate's `libanimcodec_capi.so` / `.a` in (`target/debug`).
pub fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    // target/debug/deps/TEST-hash → target/debug
    exe.parent().and_then(Path::parent).expect("target dir").to_path_buf()
}
