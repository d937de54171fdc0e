//! The committed fuzz corpora of the stream targets (`fuzz/corpus/container`: any bytes as an
//! `.anim` stream; `fuzz/corpus/codec_*`: structure-aware codec inputs, turned into streams by
//! `conformance_tests::fuzz::codec_container`) replayed through the C ABI:
//! `ac_stream_open_memory`, then `ac_decode_frame` of the first, middle and last frame, a player
//! over every frame and `ac_decode_all`. Any status is fine except `AC_ERR_INTERNAL` (a panic
//! caught at the boundary); every message is one line of plain text; `Ok` frames are finite.

mod common;

use animcodec_capi::*;
use common::{last_error, Stream};
use conformance_tests::fuzz;

fn check_message(what: &str, status: ac_status, message: &str) {
    assert_ne!(status, ac_status::AC_ERR_INTERNAL, "{what}: a panic: {message}");
    assert!(!message.is_empty() && !message.contains('\n'), "{what}: message {message:?}");
    assert!(!message.contains("panicked"), "{what}: {message}");
}

fn replay(what: &str, bytes: &[u8]) {
    let l = fuzz::fuzz_limits();
    let limits = ac_limits { max_memory: l.max_alloc_bytes as u64, max_work: l.max_work };
    let stream = match Stream::open_memory(bytes, Some(&limits)) {
        Ok(s) => s,
        Err((status, message)) => return check_message(what, status, &message),
    };
    let info = stream.info();
    let frames = info.frames;
    for t in [0, frames / 2, frames.saturating_sub(1), frames] {
        match stream.frame(t) {
            Ok(xyz) => assert!(xyz.iter().all(|x| x.is_finite()), "{what}: frame {t} not finite"),
            Err((status, message)) => check_message(&format!("{what} frame {t}"), status, &message),
        }
    }
    let mut player = std::ptr::null_mut();
    // SAFETY: a live handle and a writable out pointer.
    assert_eq!(unsafe { ac_player_new(stream.0, &mut player) }, ac_status::AC_OK);
    let mut xyz = vec![0f32; info.vertices * 3];
    for t in 0..frames.min(64) {
        // SAFETY: a live player and `xyz.len()` writable floats.
        let status = unsafe { ac_player_decode_frame(player, t, xyz.as_mut_ptr(), xyz.len()) };
        if status != ac_status::AC_OK {
            check_message(&format!("{what} player frame {t}"), status, &last_error());
        }
    }
    // SAFETY: the player is not used again.
    unsafe { ac_player_free(player) };
    if let Some(n) = frames.checked_mul(info.vertices * 3).filter(|&n| n <= 1 << 22) {
        let mut all = vec![0f32; n];
        // SAFETY: a live handle and `n` writable floats.
        let status = unsafe { ac_decode_all(stream.0, all.as_mut_ptr(), n) };
        if status != ac_status::AC_OK {
            check_message(&format!("{what} all"), status, &last_error());
        }
    }
}

#[test]
fn every_stream_corpus_file_goes_through_the_c_api_without_a_panic() {
    let dir = fuzz::corpus_dir();
    let mut files = 0;
    for target in fuzz::targets() {
        let codec = target.strip_prefix("codec_").map(|c| c.replace('_', "-"));
        if codec.is_none() && target != "container" {
            continue; // a file reader's corpus: not streams
        }
        let mut paths: Vec<_> =
            std::fs::read_dir(dir.join(&target)).expect("corpus").map(|e| e.expect("entry").path()).collect();
        paths.sort();
        for path in paths {
            let data = std::fs::read(&path).expect("corpus file");
            let what = path.display().to_string();
            match &codec {
                None => replay(&what, &data),
                Some(c) => {
                    if let Some(bytes) = fuzz::codec_container(c, &data) {
                        replay(&what, &bytes);
                    }
                }
            }
            files += 1;
        }
    }
    assert!(files > 1000, "{files} corpus files");
}
