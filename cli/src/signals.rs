//! Interrupts never leave a partial file: on SIGINT, SIGTERM or SIGHUP the pending temporary
//! outputs are deleted before the process exits (`animcodec::output::delete_pending_and_exit_with`),
//! and a write beyond `ulimit -f` is an ordinary error (SIGXFSZ has a handler, so the write
//! fails with EFBIG instead of the signal killing the process). The message says what the
//! command had changed when the signal landed: after an OBJ sequence's commit the folder has
//! been replaced, so "no output file was changed" would be false. This lives in the binary: a
//! library (or the Python package, inside an interpreter that has its own handlers) must not
//! take over a process's signals.

use animcodec::output::Changes;

use crate::commands::shown;

/// Installs the handlers. Call once, early, from `main`. Errors (no signal support) are
/// ignored: files are still written safely, only an interruption may then leave a temporary
/// `.NAME.*.tmp` file behind.
pub fn install_cleanup() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM, SIGXFSZ};
    // With a handler installed, an oversized write fails with EFBIG instead of killing us.
    let _ = signal_hook::flag::register(SIGXFSZ, std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)));
    if let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) {
        let _ = std::thread::Builder::new().name("signal-cleanup".into()).spawn(move || {
            if let Some(signal) = signals.forever().next() {
                animcodec::output::delete_pending_and_exit_with(128 + signal, interrupted_message);
            }
        });
    }
}

/// The line printed on an interruption: what was changed before it, which is complete (files
/// are renamed into place only when whole; a half-written one is deleted), and what may not be.
pub fn interrupted_message(changes: &Changes) -> String {
    if changes.is_empty() {
        return "\ninterrupted: no output file was changed".to_owned();
    }
    let mut done = Vec::new();
    match (changes.written, &changes.first_written, &changes.last_written) {
        (0, _, _) => {}
        (1, Some(first), _) => done.push(format!("{} was written (complete)", shown(first))),
        (n, Some(first), Some(last)) => {
            done.push(format!("{n} files were written (complete): {} … {}", shown(first), shown(last)))
        }
        (n, _, _) => done.push(format!("{n} files were written (complete)")),
    }
    if changes.removed > 0 {
        done.push(format!("{} stale file(s) of the sequence replaced were removed", changes.removed));
    }
    for p in &changes.in_place {
        done.push(format!("{} was being written in place (a device or pipe) and may be incomplete", shown(p)));
    }
    format!("\ninterrupted after changing output files: {}; no other file was changed", done.join("; "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn the_message_says_what_was_changed() {
        assert_eq!(interrupted_message(&Changes::default()), "\ninterrupted: no output file was changed");
        let one = Changes {
            written: 1,
            first_written: Some(PathBuf::from("a.anim")),
            last_written: Some(PathBuf::from("a.anim")),
            ..Changes::default()
        };
        let m = interrupted_message(&one);
        assert!(m.contains("a.anim was written (complete)") && !m.contains("no output file was changed"), "{m}");
        let seq = Changes {
            written: 48,
            first_written: Some(PathBuf::from("seq/frame_0000.obj")),
            last_written: Some(PathBuf::from("seq/frame_0047.obj")),
            removed: 127,
            in_place: vec![PathBuf::from("/dev/stdout\x1b[31m")],
        };
        let m = interrupted_message(&seq);
        for needle in ["48 files", "seq/frame_0000.obj", "seq/frame_0047.obj", "127 stale", "may be incomplete"] {
            assert!(m.contains(needle), "{needle}: {m}");
        }
        assert!(!m.contains('\x1b'), "control characters are escaped: {m}");
    }
}
