//! Progress on the terminal for every command that can run long (`encode`, `decode`,
//! `export`, `view`, `sweep`, `demo`): drawn on stderr only when stderr is a terminal and the
//! command does not print JSON to stdout, so piped and scripted runs (and `--json -`) see no
//! progress text at all (`cli/tests/cli.rs`, `no_progress_text_off_a_terminal`;
//! `cli/tests/progress_tty.rs` checks the drawn text on a pseudo-terminal).
//!
//! One display, three shapes:
//! - [`Progress::counter`]: `COMMAND [bar] 12/40 frames, 0:03 (ETA 0:07) message` — a known
//!   total (frames decoded or encoded, sweep points);
//! - [`Progress::estimate`]: `COMMAND 7/~12 points, …` — an expected total (a search's points),
//!   raised when the work outruns it and set to the final count when the work ends, so the
//!   last total drawn is the count the command reports;
//! - [`Progress::stages`]: `COMMAND [2/4] stage` with a spinner — a few long stages whose work
//!   cannot be counted (a glTF export's principal components).
//!
//! `ANIMCODEC_PROGRESS=never` turns every display off, even on a terminal (logs recorded
//! through a pseudo-terminal, screen readers).

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The environment variable that turns progress off on a terminal (`never`).
pub const ENV: &str = "ANIMCODEC_PROGRESS";

/// Whether progress may be drawn: stderr is a terminal, stdout does not carry JSON, and
/// [`ENV`] is not `never`.
pub fn enabled(json_on_stdout: bool) -> bool {
    std::env::var(ENV).map_or(true, |v| v.trim() != "never") && std::io::stderr().is_terminal() && !json_on_stdout
}

/// How the total of a display is known.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Exact: the work has this many units.
    Exact,
    /// Expected: the work may end sooner or run longer.
    Expected,
    /// Stages with a spinner.
    Stages,
}

/// A progress display on stderr (hidden unless [`enabled`]); cleared when dropped.
pub struct Progress {
    bar: ProgressBar,
    kind: Kind,
    unit: &'static str,
    /// Whether the display may be drawn ([`enabled`]).
    visible: bool,
}

impl Progress {
    fn new(command: &str, total: u64, unit: &'static str, kind: Kind, json_on_stdout: bool) -> Self {
        // Styled before it is shown: nothing is drawn in indicatif's default style. A display
        // whose total is not known yet (0: a sweep before its phases are counted) is shown by
        // [`Progress::set_total`].
        let progress = Self { bar: ProgressBar::hidden(), kind, unit, visible: enabled(json_on_stdout) };
        progress.bar.set_length(total);
        progress.restyle();
        progress.bar.set_prefix(command.to_owned());
        if total > 0 {
            progress.show();
        }
        progress
    }

    /// Draws the display on stderr from now on (when [`enabled`]).
    fn show(&self) {
        if self.visible && self.bar.is_hidden() {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
            // The elapsed time and ETA keep moving while one unit takes long (a search point
            // is a whole encode, decode and measurement).
            self.bar.enable_steady_tick(Duration::from_millis(250));
        }
    }

    /// `total` `unit`s of `command` (frames, points), with a bar and an ETA.
    pub fn counter(command: &str, total: u64, unit: &'static str, json_on_stdout: bool) -> Self {
        Self::new(command, total, unit, Kind::Exact, json_on_stdout)
    }

    /// About `expected` `unit`s of `command`: drawn `done/~expected`, raised when the count
    /// reaches it, and exact once [`Progress::finish`] sets it to the count.
    pub fn estimate(command: &str, expected: u64, unit: &'static str, json_on_stdout: bool) -> Self {
        Self::new(command, expected.max(1), unit, Kind::Expected, json_on_stdout)
    }

    /// `total` stages of `command`; [`Progress::stage`] starts each.
    pub fn stages(command: &str, total: u64, json_on_stdout: bool) -> Self {
        Self::new(command, total, "", Kind::Stages, json_on_stdout)
    }

    fn restyle(&self) {
        let unit = self.unit;
        let template = match self.kind {
            Kind::Exact => {
                format!("{{prefix}} {{bar:24}} {{pos}}/{{len}} {unit}, {{elapsed}} (ETA {{eta}}) {{wide_msg}}")
            }
            Kind::Expected => {
                format!("{{spinner}} {{prefix}} {{pos}}/~{{len}} {unit}, {{elapsed}} (ETA ~{{eta}}) {{wide_msg}}")
            }
            Kind::Stages => "{spinner} {elapsed:>4} {prefix} [{pos}/{len}] {wide_msg}".to_owned(),
        };
        if let Ok(style) = ProgressStyle::with_template(&template) {
            self.bar.set_style(style);
        }
    }

    /// Sets how many units are done.
    pub fn set(&self, done: u64) {
        self.raise_to(done);
        self.bar.set_position(done);
    }

    /// Counts `n` more units done.
    pub fn inc(&self, n: u64) {
        self.raise_to(self.bar.position() + n);
        self.bar.inc(n);
    }

    /// An expected total the work is about to pass grows with it (by half again: the work
    /// did not end where expected, so more is likely to come).
    fn raise_to(&self, done: u64) {
        if self.kind == Kind::Expected && done >= self.bar.length().unwrap_or(0) {
            self.bar.set_length(done + done.div_ceil(2).max(1));
        }
    }

    /// Replaces the total (a sweep's later phases once planned: exact where an upper bound
    /// stood).
    pub fn set_total(&self, total: u64) {
        self.bar.set_length(total);
        self.show();
    }

    /// The text after the counts (what is being worked on, the latest result).
    pub fn message(&self, text: impl Into<String>) {
        self.bar.set_message(text.into());
    }

    /// The text before the counts (the command, and a sweep's phase).
    pub fn prefix(&self, text: impl Into<String>) {
        self.bar.set_prefix(text.into());
    }

    /// Starts the next stage, described by `what`.
    pub fn stage(&self, what: impl Into<String>) {
        if self.bar.position() < self.bar.length().unwrap_or(0) {
            self.bar.inc(1);
        }
        self.bar.set_message(what.into());
    }

    /// The units done so far.
    pub fn done(&self) -> u64 {
        self.bar.position()
    }

    /// Ends the count: an expected total becomes the count itself, and the final state is
    /// drawn once (so the last total on the terminal is the count the command reports)
    /// before the display is cleared.
    pub fn finish(&self) {
        if self.bar.is_hidden() {
            return;
        }
        if self.kind == Kind::Expected {
            self.kind_exact();
            self.bar.set_length(self.bar.position());
        }
        self.bar.finish();
    }

    fn kind_exact(&self) {
        let template = format!("{{prefix}} {{bar:24}} {{pos}}/{{len}} {}, {{elapsed}} {{wide_msg}}", self.unit);
        if let Ok(style) = ProgressStyle::with_template(&template) {
            self.bar.set_style(style);
        }
    }
}

impl Drop for Progress {
    /// Draws the final state ([`Progress::finish`]) unless finished already, then clears the
    /// display, so the command's own output starts on a clean line.
    fn drop(&mut self) {
        if !self.bar.is_finished() {
            self.finish();
        }
        self.bar.finish_and_clear();
    }
}

/// Bytes for a progress message: `812 KiB`, `12.3 MiB`.
pub fn bytes_text(bytes: u64) -> String {
    indicatif::BinaryBytes(bytes).to_string()
}

/// Which target search a command runs, for [`expected_search_points`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Search {
    /// One rate ladder ([`animcodec::harness::search_target`], `--ladder`).
    Ladder,
    /// The declared parameter space ([`animcodec::harness::search_space_target`], `--target`).
    Space,
    /// The default encode's search ([`animcodec::harness::search_default_quality`]).
    DefaultQuality,
}

/// The points a target search of `codec` on `base` (the `fixed` parameters kept) is expected
/// to measure, for [`Progress::estimate`]; the sum over codecs for `-c auto`.
///
/// - the ladder search: the top step, the binary search (`⌈log₂ n⌉` points on `n` steps),
///   the check below the answer, and `refine` points between two float steps (one between
///   two integer steps; none between choices). A non-monotone ladder adds a linear scan the
///   estimate does not foresee.
/// - the default quality: the codec's defaults, and when they miss the band a gallop and
///   bisection (`⌈log₂ n⌉`); one point when the defaults land in the band.
/// - the space search: the first configuration as the ladder search without the top step,
///   then about two points per other configuration (warm-started at the first one's answer,
///   most are abandoned after one or two), and for a STED target every configuration's
///   smallest step.
pub fn expected_search_points(
    codec: &dyn animcodec::core::AnimationCodec,
    base: &animcodec::core::ParamSet,
    fixed: &[&str],
    target: animcodec::harness::Target,
    search: Search,
    refine: usize,
) -> u64 {
    use animcodec::core::{DistortionKind, ParamValue, SearchSpace};
    let log2 = |n: usize| u64::from(usize::BITS - n.saturating_sub(1).leading_zeros());
    let between = |ladder: &animcodec::core::RateLadder| match ladder.steps.first() {
        Some(ParamValue::Float(_)) => refine as u64,
        Some(ParamValue::Int(_)) => (refine as u64).min(1),
        _ => 0,
    };
    match search {
        Search::Ladder => {
            let ladder = codec.rate_ladder(base);
            let n = ladder.steps.len();
            1 + log2(n) + u64::from(n >= 3) + between(&ladder)
        }
        Search::DefaultQuality => 1 + log2(codec.rate_ladder(base).steps.len()),
        Search::Space => {
            let specs = codec.param_specs();
            let space = codec.search_space_for(base, target.distortion_kind()).without(fixed);
            let runs: Vec<_> = space
                .configurations()
                .iter()
                .filter_map(|config| SearchSpace::apply(base, &specs, config).ok())
                .filter(|params| codec.validate(params).is_ok())
                .collect();
            let Some(first) = runs.first() else { return 1 };
            let ladder = codec.rate_ladder(first);
            let mut points = log2(ladder.steps.len()) + 1 + between(&ladder) + 2 * (runs.len() as u64 - 1);
            if target.distortion_kind() == DistortionKind::Shape {
                points += runs.len() as u64;
            }
            points
        }
    }
}
