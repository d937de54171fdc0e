//! The C API called from Rust on the golden streams: every frame by random access (in a
//! scrambled order), by a player (forwards, backwards), by range and in bulk equals the Rust
//! library's decode; a shared handle decodes correctly from several threads; errors have the
//! right status and the command line's message.

mod common;

use std::path::Path;
use std::process::Command;

use animcodec::core::{decode_animation, Limits};
use animcodec_capi::*;
use common::{last_error, Stream};

fn reference(bytes: &[u8]) -> animcodec::core::Animation {
    decode_animation(bytes, &animcodec::registry(), Limits::default()).expect("golden decodes")
}

#[test]
fn every_access_path_decodes_what_the_library_decodes_on_every_golden_stream() {
    for path in common::goldens() {
        let bytes = std::fs::read(&path).unwrap();
        let want = reference(&bytes);
        let what = path.display();
        let s = Stream::open_memory(&bytes, None).unwrap_or_else(|e| panic!("{what}: {e:?}"));
        let info = s.info();
        assert_eq!(
            (info.frames, info.vertices, info.triangles),
            (want.frame_count(), want.vertex_count(), want.triangles().len())
        );
        assert_eq!(info.frame_rate, want.frame_rate());
        assert_eq!(info.stream_bytes, bytes.len() as u64);
        let v3 = info.vertices * 3;
        let frame = |t: usize| &want.positions()[t * v3..(t + 1) * v3];
        // Random access in a scrambled order (a stride coprime with the frame count).
        let n = info.frames;
        let stride = (1..).map(|k| 7 * k + 3).find(|s| gcd(*s, n) == 1).unwrap();
        for i in 0..n {
            let t = (i * stride) % n;
            assert!(s.frame(t).unwrap() == frame(t), "{what}: ac_decode_frame({t})");
        }
        // A player forwards then backwards.
        let mut player = std::ptr::null_mut();
        // SAFETY: live handle, writable out.
        assert_eq!(unsafe { ac_player_new(s.0, &mut player) }, ac_status::AC_OK);
        let mut xyz = vec![0f32; v3];
        for t in (0..n).chain((0..n).rev()) {
            // SAFETY: live player, `v3` writable floats.
            assert_eq!(unsafe { ac_player_decode_frame(player, t, xyz.as_mut_ptr(), v3) }, ac_status::AC_OK);
            assert!(xyz == frame(t), "{what}: player frame {t}");
        }
        // The zero-copy view, in a scrambled order.
        for i in 0..n {
            let t = (i * stride) % n;
            let mut view = std::ptr::null();
            // SAFETY: live player, writable out.
            assert_eq!(unsafe { ac_player_frame_view(player, t, &mut view) }, ac_status::AC_OK);
            // SAFETY: `v3` floats, valid until the next call on the player.
            let got = unsafe { std::slice::from_raw_parts(view, v3) };
            assert!(got == frame(t), "{what}: view of frame {t}");
        }
        // SAFETY: not used again.
        unsafe { ac_player_free(player) };
        // A range across packets, and everything.
        let (first, count) = (n / 3, n - n / 3);
        let mut range = vec![0f32; count * v3];
        // SAFETY: live handle, `range.len()` writable floats.
        assert_eq!(unsafe { ac_decode_range(s.0, first, count, range.as_mut_ptr(), range.len()) }, ac_status::AC_OK);
        assert!(range == want.positions()[first * v3..], "{what}: range");
        let mut all = vec![0f32; n * v3];
        // SAFETY: as above.
        assert_eq!(unsafe { ac_decode_all(s.0, all.as_mut_ptr(), all.len()) }, ac_status::AC_OK);
        assert!(all == want.positions(), "{what}: all");
        let mut tris = vec![0u32; info.triangles * 3];
        // SAFETY: as above.
        assert_eq!(unsafe { ac_copy_triangles(s.0, tris.as_mut_ptr(), tris.len()) }, ac_status::AC_OK);
        assert!(tris.chunks(3).zip(want.triangles()).all(|(a, b)| a == b), "{what}: triangles");
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

#[test]
fn a_shared_stream_decodes_correctly_from_several_threads_at_once() {
    for path in common::goldens().iter().filter(|p| {
        p.to_string_lossy().contains("hosvd-v6")
            || p.to_string_lossy().contains("sac-v3")
            || p.to_string_lossy().contains("quant-delta-v1.anim")
    }) {
        let bytes = std::fs::read(path).unwrap();
        let want = reference(&bytes);
        let s = Stream::open_memory(&bytes, None).unwrap();
        let (n, v3) = (want.frame_count(), want.vertex_count() * 3);
        std::thread::scope(|scope| {
            for k in 0..4 {
                let (s, want) = (&s, &want);
                scope.spawn(move || {
                    for round in 0..3 {
                        for i in 0..n {
                            let t = if (k + round) % 2 == 0 { i } else { n - 1 - i };
                            assert!(
                                s.frame(t).unwrap() == want.positions()[t * v3..(t + 1) * v3],
                                "thread {k} frame {t}"
                            );
                        }
                    }
                });
            }
        });
    }
}

#[test]
fn bad_arguments_have_their_status_and_a_message() {
    let bytes = std::fs::read(common::workspace().join("tests/golden/hosvd-v6.anim")).unwrap();
    let s = Stream::open_memory(&bytes, None).unwrap();
    let info = s.info();
    let (status, message) = s.frame(info.frames).unwrap_err();
    assert_eq!(status, ac_status::AC_ERR_OUT_OF_RANGE);
    assert_eq!(message, format!("frame {} is past the end of the stream ({} frames)", info.frames, info.frames));
    let mut small = vec![0f32; 5];
    // SAFETY: a live handle and 5 writable floats.
    let status = unsafe { ac_decode_frame(s.0, 0, small.as_mut_ptr(), small.len()) };
    assert_eq!(status, ac_status::AC_ERR_BUFFER_TOO_SMALL);
    assert!(last_error().contains("holds 5 floats"), "{}", last_error());
    // SAFETY: NULL handle and NULL buffer are refused, not dereferenced.
    let status = unsafe { ac_decode_frame(std::ptr::null(), 0, std::ptr::null_mut(), 0) };
    assert_eq!(status, ac_status::AC_ERR_INVALID_ARGUMENT);
    assert_eq!(last_error(), "the stream handle is NULL");
    // SAFETY: NULL out pointer is refused.
    let status = unsafe { ac_stream_open_memory(bytes.as_ptr(), bytes.len(), std::ptr::null(), std::ptr::null_mut()) };
    assert_eq!(status, ac_status::AC_ERR_INVALID_ARGUMENT);
    let tight = ac_limits { max_memory: 1000, max_work: 0 };
    // The header fits; the first packet's decode does not.
    let (status, message) = Stream::open_memory(&bytes, Some(&tight)).unwrap().frame(0).unwrap_err();
    assert_eq!(status, ac_status::AC_ERR_LIMIT, "{message}");
    assert!(message.contains("memory limit"), "{message}");
    let (status, message) = Stream::open_memory(b"not a stream", None).err().unwrap();
    assert_eq!(status, ac_status::AC_ERR_FORMAT, "{message}");
    // SAFETY: a static string.
    let name = unsafe { std::ffi::CStr::from_ptr(ac_status_name(ac_status::AC_ERR_LIMIT)) };
    assert_eq!(name.to_str().unwrap(), "AC_ERR_LIMIT");
}

/// `ac_stream_open_file` + decode of `path` → the message, or `None` on success.
fn c_api_error(path: &Path, limits: Option<&ac_limits>) -> Option<String> {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    let mut h = std::ptr::null_mut();
    let l = limits.map_or(std::ptr::null(), |l| l as *const ac_limits);
    // SAFETY: a NUL-terminated path, valid limits, writable out.
    if unsafe { ac_stream_open_file(c.as_ptr(), l, &mut h) } != ac_status::AC_OK {
        return Some(last_error());
    }
    let s = Stream(h);
    let frames = s.info().frames;
    (0..frames).find_map(|t| s.frame(t).err()).map(|(_, m)| m)
}

#[test]
fn errors_carry_the_message_the_command_line_prints() {
    let test = "errors_carry_the_message_the_command_line_prints";
    let Some(cli) = Some(common::library_dir().join("animcodec")).filter(|p| p.is_file()) else {
        return codec_core::testing::skip(test, "the animcodec binary is not built (cargo build -p animcodec-cli)");
    };
    let dir = std::env::temp_dir().join(format!("animcodec-capi-messages-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let golden = std::fs::read(common::workspace().join("tests/golden/hosvd-v6.anim")).unwrap();
    let mut header_flip = golden.clone();
    header_flip[20] ^= 0x40;
    let mut magic = golden.clone();
    magic[0] = b'X';
    // (file name, its bytes (none: missing), --max-memory)
    type Case = (&'static str, Option<Vec<u8>>, Option<u64>);
    let cases: Vec<Case> = vec![
        ("missing.anim", None, None),
        ("header-flip.anim", Some(header_flip), None),
        ("magic.anim", Some(magic), None),
        ("tight.anim", Some(golden), Some(2000)),
    ];
    for (name, bytes, memory) in cases {
        let path = dir.join(name);
        if let Some(b) = &bytes {
            std::fs::write(&path, b).unwrap();
        }
        let mut cmd = Command::new(&cli);
        if let Some(m) = memory {
            cmd.arg("--max-memory").arg(m.to_string());
        }
        let run = cmd.arg("decode").arg(&path).arg("-o").arg(dir.join("out.pc2")).output().unwrap();
        assert!(!run.status.success(), "{name}: the CLI succeeded");
        let stderr = String::from_utf8_lossy(&run.stderr);
        let cli_message = stderr.lines().find_map(|l| l.strip_prefix("error: ")).unwrap_or_else(|| panic!("{stderr}"));
        let limits = memory.map(|m| ac_limits { max_memory: m, max_work: 0 });
        let ours = c_api_error(&path, limits.as_ref()).unwrap_or_else(|| panic!("{name}: the C API succeeded"));
        assert_eq!(ours, cli_message, "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
