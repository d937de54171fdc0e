//! `animcodec view` and `sweep --html`: the pages' contents, their errors, and — where Debian's
//! Chromium and playwright-core are installed (`cli/tests/browser/install.sh`) — the pages in a
//! real headless browser: no console error, the frame slider changes the image, and the heat
//! map's colours match a candidate whose error is on one half of the mesh only.

use std::path::{Path, PathBuf};
use std::process::Command;

use animcodec::synth;
use codec_core::Animation;
use serde_json::Value;

mod common;
use common::*;

/// The synthetic flag and a candidate moved by 5% of its size on the vertices right of the
/// middle only (exact elsewhere); also returns the triangles wholly in each half.
fn half_error_case(s: &Scratch) -> (String, String, Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let a = synth::waving_flag(24, 12, 8);
    let n = a.vertex_count();
    let (lo, hi) = a.bounding_box();
    let mid = 0.5 * (lo[0] + hi[0]);
    let shift = 0.05 * a.bounding_box_diagonal() as f32;
    let moved = |p: &[f32]| p[0] > mid;
    let p: Vec<f32> = a
        .positions()
        .chunks(3)
        .flat_map(|c| if moved(c) { [c[0], c[1], c[2] + shift] } else { [c[0], c[1], c[2]] })
        .collect();
    let b = Animation::from_parts(n, a.triangles().to_vec(), p, a.frame_rate()).unwrap();
    let (ra, rb) = (s.path("ref.pc2"), s.path("half.pc2"));
    animcodec::formats::write_animation(Path::new(&ra), &a).unwrap();
    animcodec::formats::write_animation(Path::new(&rb), &b).unwrap();
    let f0 = a.frame(0);
    let side = |t: &[u32; 3]| t.map(|i| moved(&f0[3 * i as usize..3 * i as usize + 3]));
    let left = a.triangles().iter().filter(|t| side(t) == [false; 3]).copied().collect();
    let right = a.triangles().iter().filter(|t| side(t) == [true; 3]).copied().collect();
    (ra, rb, left, right)
}

/// The JSON embedded in a page.
fn page_data(html: &str) -> Value {
    let start = html.find(r#"id="animcodec-data">"#).unwrap() + r#"id="animcodec-data">"#.len();
    let end = start + html[start..].find("</script>").unwrap();
    serde_json::from_str(&html[start..end]).unwrap()
}

#[test]
fn view_writes_a_self_contained_page_with_headers_and_heat_maps() {
    let s = Scratch::new("view");
    let (reference, half, _, _) = half_error_case(&s);
    let page = s.path("v.html");
    let text = ok(&["view", &reference, &half, "quant-delta:bits=6", "-o", &page]);
    assert!(text.contains("2 candidate(s)") && text.contains("heat euclidean"), "{text}");
    let html = std::fs::read_to_string(&page).unwrap();
    // No network at view time: nothing is fetched from elsewhere.
    for external in ["src=\"http", "href=\"http", "import('http", "import(\"http"] {
        assert!(!html.contains(external), "external resource: {external}");
    }
    assert!(html.contains("Copyright © 2010-") && html.contains("three.js authors"), "three.js licence embedded");
    let data = page_data(&html);
    let anims = data["animations"].as_array().unwrap();
    assert_eq!(anims.len(), 3);
    assert_eq!(anims[2]["info"]["codec"], "quant-delta");
    assert_eq!(anims[2]["info"]["params"]["bits"], 6);
    assert!(anims[2]["info"]["bpvf"].as_f64().unwrap() > 0.0);
    for key in ["kg", "sted", "hausdorff"] {
        assert!(anims[1]["metrics"][key].as_f64().unwrap() > 0.0, "{key}");
    }
    // The half-moved candidate has the largest error: the colour bar tops at its shift.
    let diag = data["diagonal"].as_f64().unwrap();
    assert!((data["heat_max"].as_f64().unwrap() - 0.05 * diag).abs() < 1e-4 * diag);

    // The colour bar's top: the 99.5th percentile by default, or as given.
    assert_eq!(data["heat_max_rule"], "99.5th percentile");
    ok(&["view", &reference, &half, "-o", &page, "-f", "--heat-max", "0.125"]);
    let data = page_data(&std::fs::read_to_string(&page).unwrap());
    assert_eq!((data["heat_max"].as_f64(), data["heat_max_rule"].as_str()), (Some(0.125), Some("given")));

    let sted_page = s.path("s.html");
    ok(&["view", &reference, &half, "-o", &sted_page, "--heat", "sted"]);
    let data = page_data(&std::fs::read_to_string(&sted_page).unwrap());
    assert_eq!(data["heat_metric"], "sted");

    // A bad --heat is a usage error (clap's, exit code 2) naming the valid metrics.
    let o = animcodec(&["view", &reference, &half, "-o", &page, "--heat", "loud"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("'loud' is not a heat metric; valid: euclidean, sted"), "{}", stderr(&o));
    let other = s.path("tumble.pc2");
    ok(&["synth", "tumble", "-o", &other]);
    fails(&["view", &reference, &other, "-o", &page, "-f"], &["tumble.pc2"]);
    fails(&["view", &reference, "hosvd:ss=7", "-o", &page, "-f"], &["ss"]);
    fails(&["view", &reference, &half, "-o", &page], &["already exists", "--force"]);
    fails(&["view", &reference, &half, "-o", &half, "-f"], &["also an input"]);
}

/// `sweep --html` of quant-delta and hosvd on the flag, 3 ladder points each, with a player of
/// hosvd's first point; returns the report's path.
fn sweep_report(s: &Scratch) -> String {
    let report = s.path("r.html");
    ok(&[
        "sweep",
        "synth:flag",
        "-c",
        "quant-delta,hosvd",
        "--ladder",
        "--points",
        "3",
        "--html",
        &report,
        "--view-points",
        "hosvd:0",
    ]);
    report
}

#[test]
fn sweep_html_report_holds_every_row_and_the_chosen_viewers() {
    let s = Scratch::new("sweep-html");
    let report = sweep_report(&s);
    let data = page_data(&std::fs::read_to_string(&report).unwrap());
    let rows = data["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    assert!(rows.iter().all(|r| r["kg"].is_number() && r["sted"].is_number() && r["bytes"].is_number()));
    let viewers = data["viewers"].as_array().unwrap();
    assert_eq!(viewers.len(), 1);
    assert_eq!(viewers[0]["animations"][1]["info"]["codec"], "hosvd");
    fails(
        &["sweep", "synth:flag", "-c", "hosvd", "--points", "2", "--html", &report, "-f", "--view-points", "sac:0"],
        &["sac:0"],
    );
    fails(
        &["sweep", "synth:flag", "-c", "hosvd", "--points", "2", "--html", &report, "-f", "--view-points", "hosvd:9"],
        &["hosvd:9"],
    );
}

/// Node, Chromium and playwright-core, or the reason the browser test skips.
fn browser() -> Result<PathBuf, String> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/browser"));
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        return Err(format!("{chromium} not found (bash cli/tests/browser/install.sh installs it)"));
    }
    if !dir.join("node_modules/playwright-core").exists() {
        return Err("playwright-core not installed (bash cli/tests/browser/install.sh)".into());
    }
    if Command::new("node").arg("--version").output().is_err() {
        return Err("node not found".into());
    }
    Ok(dir.join("check_page.mjs"))
}

/// Runs `check_page.mjs` on `page`; `env` sets its switches (`NO_WEBGL`, `VIEWPORT`, `FULL_PAGE`).
fn run_browser_with(script: &Path, page: &str, shot: &Path, samples: Option<&Path>, env: &[(&str, &str)]) -> Value {
    let mut cmd = Command::new("node");
    cmd.arg(script).arg(page).arg(shot).envs(env.iter().copied());
    if let Some(s) = samples {
        cmd.arg(s);
    }
    let out = cmd.output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let v: Value = serde_json::from_str(text.trim())
        .unwrap_or_else(|e| panic!("{e}: {text} {}", String::from_utf8_lossy(&out.stderr)));
    assert!(v.get("failure").is_none(), "{v}");
    assert!(shot.exists() && std::fs::metadata(shot).unwrap().len() > 10_000, "screenshot {}", shot.display());
    v
}

fn run_browser(script: &Path, page: &str, shot: &Path, samples: Option<&Path>) -> Value {
    let v = run_browser_with(script, page, shot, samples, &[]);
    assert_eq!(v["consoleErrors"], serde_json::json!([]), "{v}");
    v
}

fn number(v: &Value, what: &str) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{what}: {v}"))
}

/// The reference fills its panel (its larger side ≥ 70 % of the panel's) and sits in the
/// middle (centre within 10 % of the panel's).
fn assert_framed(v: &Value) {
    let f = &v["framing"];
    let fill = number(&f["fillX"], "fillX").max(number(&f["fillY"], "fillY"));
    assert!((0.7..=1.0).contains(&fill), "the model fills {fill:.2} of its panel: {f}");
    for k in ["offX", "offY"] {
        assert!(number(&f[k], k).abs() <= 0.1, "off centre: {f}");
    }
}

/// Five colour-bar ticks from 0 up to the top value, increasing.
fn assert_colour_bar_ticks(v: &Value) {
    let ticks: Vec<f64> = v["colorbarTicks"]
        .as_array()
        .unwrap_or_else(|| panic!("{v}"))
        .iter()
        .map(|t| t.as_str().unwrap().parse::<f64>().unwrap())
        .collect();
    assert_eq!(ticks.len(), 5, "{v}");
    assert_eq!(ticks[0], 0.0);
    assert!(ticks.windows(2).all(|w| w[1] > w[0]), "{ticks:?}");
}

#[test]
fn pages_work_in_headless_chromium() {
    let script = match browser() {
        Ok(s) => s,
        Err(why) => return codec_core::testing::skip("pages_work_in_headless_chromium", &why),
    };
    let s = Scratch::new("browser");
    let (reference, half, left, right) = half_error_case(&s);
    let page = s.path("v.html");
    ok(&["view", &reference, &half, "-o", &page]);
    let samples = s.path("samples.json");
    let picked: Vec<[u32; 3]> = left.iter().step_by(7).chain(right.iter().step_by(7)).copied().collect();
    let n_left = left.iter().step_by(7).count();
    std::fs::write(&samples, serde_json::json!({"panel": 1, "triangles": picked}).to_string()).unwrap();
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("view-half-error.png");
    let v = run_browser(&script, &page, &shot, Some(Path::new(&samples)));
    println!("viewer: {v}\nscreenshot: {}", shot.display());
    assert_eq!(v["kind"], "viewer");
    assert_eq!(v["frameChangesImage"], true, "{v}");
    assert!(v["nonBackgroundPixels"].as_u64().unwrap() > 10_000, "{v}");
    assert_eq!(v["webgl"], true, "{v}");
    assert_framed(&v);
    assert_colour_bar_ticks(&v);
    // Zero error is the colour bar's blue end, the shifted half its red end (lighting scales
    // the channels, the dominant one stays).
    let colours = v["samples"].as_array().unwrap();
    assert_eq!(colours.len(), picked.len());
    for (i, c) in colours.iter().enumerate() {
        let (r, b) = (c[0].as_i64().unwrap(), c[2].as_i64().unwrap());
        if i < n_left {
            assert!(b > r + 60, "exact triangle {:?} drawn {c}", picked[i]);
        } else {
            assert!(r > b + 60, "moved triangle {:?} drawn {c}", picked[i]);
        }
    }

    let report = sweep_report(&s);
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("sweep-report.png");
    let v = run_browser(&script, &report, &shot, None);
    println!("report: {v}");
    assert_eq!(v["kind"], "report");
    assert_eq!((v["reportPoints"].as_u64(), v["reportViewers"].as_u64()), (Some(6), Some(1)), "{v}");
    assert_eq!(v["plotPoints"].as_u64(), Some(12), "6 points in each of the KG and STED plots: {v}");
    let tip = v["tooltip"].as_str().unwrap();
    assert!(tip.contains("bytes") && tip.contains("KG") && tip.contains("STED"), "{tip}");
    assert_eq!(v["frameChangesImage"], true, "{v}");
    // The table: the swept parameters (quant-delta's bits, hosvd's ss) as columns, no column of
    // whole parameter JSON, the full set on hover, and sizes and errors on a 1400-px screen.
    let table = &v["table"];
    let heads: Vec<&str> = table["heads"].as_array().unwrap().iter().map(|h| h.as_str().unwrap()).collect();
    for column in ["bits", "ss", "bytes", "bpvf", "KG (%)", "STED"] {
        assert!(heads.contains(&column), "no {column} column: {heads:?}");
    }
    for constant in ["params", "level", "quant", "edge_weight"] {
        assert!(!heads.contains(&constant), "{constant} does not vary here: {heads:?}");
    }
    let title = table["firstRowTitle"].as_str().unwrap();
    assert!(title.contains("\"level\":"), "full parameters on hover: {title}");
    for column in ["bytes", "KG (%)", "STED"] {
        assert!(number(&table["right"][column], column) <= 1400.0, "{column} off a 1400-px screen: {table}");
    }
    // The plots: each codec's points spread over at least a fifth of the plot width (a
    // 30-bpvf codec must not squeeze a 1-bpvf one into a corner); one envelope line per codec.
    for plot in v["plotSpread"].as_array().unwrap() {
        assert_eq!(plot["envelopeLines"], 2, "{plot}");
        for (codec, spread) in plot["spread"].as_object().unwrap() {
            assert!(number(spread, codec) >= 0.2, "{codec} squeezed into {spread} of the {} plot", plot["metric"]);
        }
    }
    assert_framed(&v);

    // Without WebGL the viewer says so, on screen, instead of showing empty panels; the only
    // console errors are three.js's own about the missing context.
    let page = s.path("v.html");
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("view-no-webgl.png");
    let v = run_browser_with(&script, &page, &shot, None, &[("NO_WEBGL", "1")]);
    println!("no WebGL: {v}");
    assert_eq!((v["kind"].as_str(), v["webgl"].as_bool()), (Some("viewer"), Some(false)), "{v}");
    let message = &v["webglMessage"];
    assert_eq!(message["visible"], true, "{v}");
    assert!(message["text"].as_str().unwrap().contains("WebGL"), "{message}");
    for e in v["consoleErrors"].as_array().unwrap() {
        assert!(e.as_str().unwrap().starts_with("THREE.WebGLRenderer"), "unexpected console error {e}");
    }
}
