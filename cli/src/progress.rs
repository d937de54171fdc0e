//! Progress on the terminal for the commands that can run long (`export`, `decode`, `view`,
//! `encode --target`, `sweep`): shown on stderr only when stderr is a terminal and the command
//! does not print JSON to stdout, so piped and scripted runs see no progress text at all
//! (`cli/tests/cli.rs`, `no_progress_text_off_a_terminal`).

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Whether progress may be drawn: stderr is a terminal and stdout does not carry JSON.
pub fn enabled(json_on_stdout: bool) -> bool {
    std::io::stderr().is_terminal() && !json_on_stdout
}

/// A spinner for a command made of a few long stages: `{spinner} {elapsed} COMMAND [k/n]
/// stage`. Call [`Stages::stage`] as each begins; the spinner ticks by itself meanwhile, so a
/// long stage (a glTF export's principal components: a minute on samba) still shows life.
pub struct Stages {
    bar: ProgressBar,
}

impl Stages {
    /// `total` stages of `command`; hidden unless [`enabled`]`(json_on_stdout)`.
    pub fn new(command: &str, total: u64, json_on_stdout: bool) -> Self {
        if !enabled(json_on_stdout) {
            return Self { bar: ProgressBar::hidden() };
        }
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template("{spinner} {elapsed:>4} {prefix} [{pos}/{len}] {msg}") {
            bar.set_style(style);
        }
        bar.set_prefix(command.to_owned());
        bar.enable_steady_tick(Duration::from_millis(200));
        Self { bar }
    }

    /// Starts the next stage, described by `what`.
    pub fn stage(&self, what: impl Into<String>) {
        if self.bar.position() < self.bar.length().unwrap_or(0) {
            self.bar.inc(1);
        }
        self.bar.set_message(what.into());
    }
}

impl Drop for Stages {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
