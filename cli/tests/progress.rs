//! Progress display of the long commands (`encode`, `decode`, `export`, `view`, `sweep`,
//! `encode --target`): drawn on a terminal with a total whose last value is the count the
//! command reports, absent from piped output, and never mixed into a `--json` document.

mod common;

use std::path::Path;
use std::process::Command;

use animcodec::formats::write_animation;
use animcodec::synth::{self, SynthSize};
use codec_core::testing::skip;
use common::{animcodec, stderr, stdout, Scratch};

/// Markers only a progress display prints: a stage counter, the ETA, a carriage return or a
/// cursor/line escape sequence.
fn has_progress_text(text: &str) -> bool {
    text.contains("[1/") || text.contains("ETA") || text.contains('\r') || text.contains('\u{1b}')
}

/// Frames of the small synthetic flag the commands run on.
const FRAMES: u64 = 40;

/// A long command on a small animation: its arguments, the unit its display counts (`[]` for
/// a stage counter), and the final count it must end on (`None`: the count the command's
/// own output reports, read by [`reported_count`]).
struct Case {
    args: Vec<String>,
    unit: &'static str,
    last: Option<u64>,
}

/// Writes the small flag as `flag.pc2` and its stream as `flag.anim`; returns the commands.
fn commands(dir: &Scratch) -> Vec<Case> {
    let flag = synth::by_name("flag", SynthSize::Small).unwrap();
    assert_eq!(flag.frame_count() as u64, FRAMES);
    let input = dir.path("flag.pc2");
    write_animation(Path::new(&input), &flag).unwrap();
    let anim = dir.path("flag.anim");
    common::ok(&["encode", &input, "-c", "quant-delta", "-p", "bits=10", "-o", &anim, "-f"]);
    let case = |args: &[&str], unit, last| Case { args: args.iter().map(|s| s.to_string()).collect(), unit, last };
    vec![
        case(
            &["encode", &input, "-c", "quant-delta", "-p", "bits=10", "-o", &anim, "-f", "--feed", "8"],
            "frames",
            Some(FRAMES),
        ),
        case(&["decode", &anim, "-o", &dir.path("x2.glb"), "-f"], "frames", Some(FRAMES)),
        case(&["decode", &anim, "-o", &dir.path("x2.pc2"), "-f"], "frames", Some(FRAMES)),
        case(&["export", &input, "-o", &dir.path("x.glb"), "-f"], "[]", Some(4)),
        case(&["view", &input, &anim, "-o", &dir.path("v.html"), "-f"], "[]", Some(4)),
        case(&["sweep", &input, "-c", "quant-delta", "--ladder", "--points", "3"], "points", Some(3)),
        // The envelope sweep: three phases counted up front.
        case(&["sweep", &input, "-c", "quant-delta,hosvd"], "points", None),
        case(
            &["encode", &input, "-c", "quant-delta", "--target", "kg=5", "-o", &dir.path("t.anim"), "-f"],
            "points",
            None,
        ),
        case(&["encode", &input, "-c", "auto", "--target", "kg=2", "-o", &dir.path("t.anim"), "-f"], "points", None),
    ]
}

/// Every count `DONE/TOTAL` (or `DONE/~TOTAL`, an expected total) drawn before `unit`, or
/// every stage counter `[DONE/TOTAL]` for `unit` `[]`, in drawing order.
fn counts(drawn: &str, unit: &str) -> Vec<(u64, u64, bool)> {
    let tokens: Vec<&str> = drawn.split([' ', '\r', '\n']).filter(|t| !t.is_empty()).collect();
    let parse = |t: &str| -> Option<(u64, u64, bool)> {
        let (done, total) = t.split_once('/')?;
        let estimate = total.starts_with('~');
        Some((done.parse().ok()?, total.trim_start_matches('~').parse().ok()?, estimate))
    };
    let mut out = Vec::new();
    for (i, t) in tokens.iter().enumerate() {
        let count = if unit == "[]" {
            t.strip_prefix('[').and_then(|t| t.strip_suffix(']')).and_then(parse)
        } else if tokens.get(i + 1).is_some_and(|next| next.starts_with(unit)) {
            parse(t)
        } else {
            None
        };
        out.extend(count);
    }
    out
}

/// The count a command reports in its own output: a search's "searched N points", a sweep
/// table's "; N points in".
fn reported_count(text: &str) -> Option<u64> {
    let after = |marker: &str| -> Option<u64> {
        let rest = &text[text.find(marker)? + marker.len()..];
        rest.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
    };
    after("searched ").or_else(|| after("; "))
}

/// Runs `args` on a pseudo-terminal (util-linux `script`); `redirect` is appended to the
/// shell line (e.g. `> out.json`). Returns what the terminal showed.
fn on_terminal(args: &[String], redirect: &str) -> String {
    let bin = env!("CARGO_BIN_EXE_animcodec");
    let quote = |a: &str| format!("'{}'", a.replace('\'', "'\\''"));
    let line = std::iter::once(quote(bin)).chain(args.iter().map(|a| quote(a))).collect::<Vec<_>>().join(" ");
    let line = format!("{line} {redirect}");
    // `-e`: the command's exit status; `/dev/null`: no typescript file (the output is read
    // from script's own stdout). Without ANIMCODEC_PROGRESS, which could turn the display off.
    let o = Command::new("script")
        .args(["-qec", &line, "/dev/null"])
        .env_remove("ANIMCODEC_PROGRESS")
        .output()
        .expect("script runs");
    let drawn = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{line}: {drawn} {}", String::from_utf8_lossy(&o.stderr));
    drawn
}

/// Whether util-linux `script` is here; skips `test` visibly when not.
fn have_script(test: &str) -> bool {
    let found = Command::new("script").arg("--version").output().is_ok_and(|o| o.status.success());
    if !found {
        skip(test, "util-linux `script` not found (apt-get install bsdutils)");
    }
    found
}

#[test]
fn no_progress_text_off_a_terminal() {
    let dir = Scratch::new("progress-off");
    for case in commands(&dir) {
        let argv: Vec<&str> = case.args.iter().map(String::as_str).collect();
        let o = animcodec(&argv);
        assert!(o.status.success(), "{argv:?}: {}", stderr(&o));
        let (out, err) = (stdout(&o), stderr(&o));
        assert!(!has_progress_text(&err), "{argv:?} printed progress to a pipe: {err:?}");
        assert!(!has_progress_text(&out), "{argv:?} printed progress to stdout: {out:?}");
    }
    // `--json` output stays a bare document.
    let input = dir.path("flag.pc2");
    let o = animcodec(&["export", &input, "-o", &dir.path("j.glb"), "--json"]);
    assert!(o.status.success() && stdout(&o).trim_start().starts_with('{') && !has_progress_text(&stdout(&o)));
}

#[test]
fn progress_is_drawn_on_a_terminal_with_a_total_that_ends_at_the_count() {
    if !have_script("progress_is_drawn_on_a_terminal_with_a_total_that_ends_at_the_count") {
        return;
    }
    let dir = Scratch::new("progress-on");
    for case in commands(&dir) {
        let drawn = on_terminal(&case.args, "");
        let shown = counts(&drawn, case.unit);
        let what = format!("{:?}: {drawn:?}", case.args);
        assert!(!shown.is_empty(), "no progress count ({}) on a terminal: {what}", case.unit);
        let expected = case.last.or_else(|| reported_count(&drawn)).unwrap_or_else(|| panic!("no count in {what}"));
        let &(done, total, estimate) = shown.last().expect("checked");
        assert_eq!((done, total), (expected, expected), "the last count drawn is not the final count: {what}");
        assert!(!estimate, "the last total drawn is still an estimate: {what}");
        // A total never grows while the work goes on (a sweep counts its phases up front;
        // a search's expected total grows only when the work outruns it).
        if case.unit == "points" && case.args[0] == "sweep" {
            assert!(shown.windows(2).all(|w| w[1].1 <= w[0].1), "a sweep's total grew: {shown:?} in {what}");
            assert!(shown.iter().all(|c| c.0 <= c.1), "{shown:?}");
        }
        // The search shows the expected points before its end, not a bare spinner.
        if case.args.iter().any(|a| a == "--target") {
            assert!(shown.iter().any(|c| c.2), "no expected total while searching: {what}");
        }
    }
}

#[test]
fn json_stays_a_clean_document_under_a_terminal() {
    if !have_script("json_stays_a_clean_document_under_a_terminal") {
        return;
    }
    let dir = Scratch::new("progress-json");
    let cases = commands(&dir);
    let input = dir.path("flag.pc2");
    let anim = dir.path("flag.anim");
    let runs: Vec<Vec<String>> = vec![
        cases[0].args.iter().cloned().chain(["--json".to_owned()]).collect(),
        vec!["decode".into(), anim.clone(), "-o".into(), dir.path("j.pc2"), "-f".into(), "--json".into()],
        vec!["export".into(), input.clone(), "-o".into(), dir.path("j.glb"), "-f".into(), "--json".into()],
        vec![
            "sweep".into(),
            input.clone(),
            "-c".into(),
            "quant-delta".into(),
            "--ladder".into(),
            "--json".into(),
            "-".into(),
        ],
        cases[7].args.iter().cloned().chain(["--json".to_owned()]).collect(),
    ];
    for args in runs {
        // stdout to a file, stderr on the terminal: the file is the bare document.
        let file = dir.path("out.json");
        let drawn = on_terminal(&args, &format!("> '{file}'"));
        let text = std::fs::read_to_string(&file).unwrap();
        serde_json::from_str::<serde_json::Value>(&text)
            .unwrap_or_else(|e| panic!("{args:?}: stdout is not one JSON document ({e}): {text:?}"));
        assert!(!has_progress_text(&text), "{args:?}: progress in the JSON: {text:?}");
        assert!(counts(&drawn, "points").is_empty() && counts(&drawn, "frames").is_empty(), "{args:?}: {drawn:?}");
        // Both on the terminal: what it shows is the document alone (the terminal turns
        // newlines into CRLF).
        let drawn = on_terminal(&args, "").replace("\r\n", "\n");
        serde_json::from_str::<serde_json::Value>(&drawn)
            .unwrap_or_else(|e| panic!("{args:?}: the terminal shows more than the JSON document ({e}): {drawn:?}"));
    }
}

/// The envelope sweep counts its phases (the grid's three, the refinement's rounds) before the
/// first point starts: the totals it
/// reports never grow, each phase measures the points it announced, and the last total is
/// the number of points measured (or failed) — for every registered codec, whose search
/// spaces and ladders differ.
#[test]
fn envelope_sweep_counts_every_phase_up_front() {
    use animcodec::core::{AnimationCodec, ParamSet};
    use animcodec::harness::{self, SweepEvent, SweepOptions};
    use std::sync::Mutex;

    let registry = animcodec::registry();
    let animation = synth::waving_flag(12, 9, 12);
    let codecs: Vec<(&dyn AnimationCodec, ParamSet, Vec<&'static str>)> =
        registry.iter().map(|c| (c, c.default_params(), Vec::new())).collect();
    let rounds = 2;
    let options = SweepOptions { points: Some(4), refine_rounds: rounds, ..Default::default() };
    // (phase, points, total) of every phase; points finished.
    let phases = Mutex::new(Vec::new());
    let finished = std::sync::atomic::AtomicUsize::new(0);
    let swept = harness::envelope_sweep(&registry, &codecs, &animation, &options, 2, &|event| match event {
        SweepEvent::Phase { phase, phases: count, points, total, .. } if count == 3 + rounds => {
            let done = finished.load(std::sync::atomic::Ordering::SeqCst);
            phases.lock().unwrap().push((phase, points, total, done));
        }
        SweepEvent::Phase { phases, .. } => panic!("the envelope sweep has 3 + {rounds} phases, not {phases}"),
        SweepEvent::Started { .. } => {}
        SweepEvent::Finished { .. } => {
            finished.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        }
    })
    .unwrap();
    let phases = phases.into_inner().unwrap();
    let measured = swept.points.len() + swept.failures.len();
    // The grid's three phases, then the refinement's rounds (ending early when one plans
    // nothing).
    let numbers: Vec<usize> = phases.iter().map(|p| p.0).collect();
    assert!(numbers.len() >= 4 && numbers.iter().enumerate().all(|(i, &n)| n == i + 1), "{phases:?}");
    assert!(swept.points.iter().any(|p| p.refined), "the refinement measured nothing: {phases:?}");
    assert!(phases.windows(2).all(|w| w[1].2 <= w[0].2), "a total grew: {phases:?}");
    assert_eq!(phases.last().unwrap().2, measured, "the last total is not the count: {phases:?}");
    assert_eq!(finished.into_inner(), measured);
    // Each phase starts once the one before has finished its announced points.
    let mut before = 0;
    for &(_, points, _, done) in &phases {
        assert_eq!(done, before, "{phases:?}");
        before += points;
    }
    assert_eq!(before, measured, "{phases:?}");
}
