//! Interrupts never leave a partial file: on SIGINT, SIGTERM or SIGHUP the pending temporary
//! outputs are deleted before the process exits (`animcodec::output::delete_pending_and_exit`),
//! and a write beyond `ulimit -f` is an ordinary error (SIGXFSZ no longer kills the process).
//! This lives in the binary: a library (or the Python package, inside an interpreter that has
//! its own handlers) must not take over a process's signals.

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
                animcodec::output::delete_pending_and_exit(128 + signal, "\ninterrupted: no output file was changed");
            }
        });
    }
}
