//! Self-contained HTML viewer pages: a reference animation and candidates played side by side
//! with a shared camera, each candidate coloured by its per-vertex error (a heat map), and the
//! rate-distortion report of `sweep --html` built on the same pieces.
//!
//! The page needs no network: three.js (`assets/three/`, release r180 with its MIT licence)
//! and the viewer script are embedded, and the geometry travels inside the page as JSON with
//! base64 payloads. Positions are quantized to 16 bits per coordinate over one box shared by
//! every animation of the page, delta-coded frame to frame and zlib-compressed (the browser
//! inflates them with its built-in `DecompressionStream`); heat values are 8-bit over the
//! colour bar's range. Only the compact form is held in the browser; a frame is expanded when
//! it is shown, so 10k vertices × 400 frames stay usable.

use std::io::Write as _;

use animcodec::core::{Animation, Error, Result};
use animcodec::metrics::{MetricReport, StedParams};
use base64::Engine as _;
use serde::Serialize;
use serde_json::{json, Value};

/// three.js core module (r180), embedded so the page works offline.
const THREE_CORE: &str = include_str!("../assets/three/three.core.min.js");
/// three.js module entry (r180); imports the core module by relative path.
const THREE_MODULE: &str = include_str!("../assets/three/three.module.min.js");
/// three.js's OrbitControls add-on (r180); imports `three`.
const ORBIT_CONTROLS: &str = include_str!("../assets/three/OrbitControls.js");
/// three.js licence, carried into every page that embeds it.
const THREE_LICENSE: &str = include_str!("../assets/three/LICENSE");
/// The viewer: mounts players into containers (`mountViewer(element, data, THREE, OrbitControls)`).
const VIEWER_JS: &str = include_str!("../assets/viewer.js");
/// Page styles shared by the viewer and the report.
const VIEWER_CSS: &str = include_str!("../assets/viewer.css");

/// Which per-vertex error the heat map shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HeatMetric {
    /// Euclidean distance between the candidate's vertex and the reference's, model units.
    Euclidean,
    /// STED's local deviation `σ_v^f` (relative edge-length change around the vertex).
    Sted,
}

/// Options of a viewer page.
#[derive(Debug, Clone)]
pub struct ViewerOptions {
    /// Per-vertex error shown as the heat map. Default Euclidean.
    pub heat: HeatMetric,
    /// Top of the colour bar; `None` = the [`HEAT_PERCENTILE`]th percentile over every
    /// candidate, vertex and frame (larger values get the top colour).
    pub heat_max: Option<f64>,
    /// STED parameters (for `HeatMetric::Sted`).
    pub sted: StedParams,
    /// Page title.
    pub title: String,
}

impl Default for ViewerOptions {
    fn default() -> Self {
        Self { heat: HeatMetric::Euclidean, heat_max: None, sted: StedParams::default(), title: "animcodec".into() }
    }
}

/// One candidate shown against the reference.
pub struct Candidate<'a> {
    /// Panel title (a file name, or `codec k=v`).
    pub label: String,
    /// The decoded animation.
    pub animation: &'a Animation,
    /// Shown in the panel header: codec, params, bytes, bpvf, … (any JSON object).
    pub info: Value,
    /// Its metrics against the reference (KG, STED, … shown in the header).
    pub report: Option<MetricReport>,
}

/// zlib-compressed, base64-encoded bytes.
fn pack(bytes: &[u8]) -> String {
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(6));
    // Writing to a Vec cannot fail.
    let _ = z.write_all(bytes);
    let packed = z.finish().unwrap_or_default();
    base64::engine::general_purpose::STANDARD.encode(packed)
}

/// The box every animation of the page is quantized over (so they share units and camera).
fn shared_box(animations: &[&Animation]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for a in animations {
        let (l, h) = a.bounding_box();
        for k in 0..3 {
            lo[k] = lo[k].min(l[k]);
            hi[k] = hi[k].max(h[k]);
        }
    }
    (lo, hi)
}

/// Positions quantized to 16 bits per coordinate over `[lo, hi]`, frame 0 as is and every
/// later frame as the wrapping difference from the previous one (smooth motion → small
/// numbers → good compression), little-endian `u16`, packed.
fn pack_positions(a: &Animation, lo: [f32; 3], hi: [f32; 3]) -> String {
    let scale: Vec<f64> =
        (0..3).map(|k| if hi[k] > lo[k] { 65535.0 / (hi[k] as f64 - lo[k] as f64) } else { 0.0 }).collect();
    let q: Vec<u16> = a
        .positions()
        .iter()
        .enumerate()
        .map(|(i, &x)| (((x as f64 - lo[i % 3] as f64) * scale[i % 3]).round()).clamp(0.0, 65535.0) as u16)
        .collect();
    let per_frame = a.vertex_count() * 3;
    let mut bytes = Vec::with_capacity(q.len() * 2);
    for (i, &v) in q.iter().enumerate() {
        let d = if i >= per_frame { v.wrapping_sub(q[i - per_frame]) } else { v };
        bytes.extend_from_slice(&d.to_le_bytes());
    }
    pack(&bytes)
}

/// Per-vertex, per-frame error of `candidate` (frame-major), in the heat metric's unit.
fn heat_field(reference: &Animation, candidate: &Animation, options: &ViewerOptions) -> Result<Vec<f32>> {
    match options.heat {
        HeatMetric::Euclidean => Ok(reference
            .positions()
            .chunks_exact(3)
            .zip(candidate.positions().chunks_exact(3))
            .map(|(a, b)| (0..3).map(|k| (a[k] as f64 - b[k] as f64).powi(2)).sum::<f64>().sqrt() as f32)
            .collect()),
        HeatMetric::Sted => animcodec::metrics::sted_local_deviations(reference, candidate, &options.sted),
    }
}

/// Default top of the colour bar: this percentile of every candidate's per-vertex, per-frame
/// errors, so that a few outliers do not paint everything else the bottom colour.
pub const HEAT_PERCENTILE: f64 = 99.5;

/// The `p`-th percentile of all values (nearest rank).
fn percentile(fields: &[Vec<f32>], p: f64) -> f64 {
    let mut all: Vec<f32> = fields.iter().flatten().copied().collect();
    if all.is_empty() {
        return 0.0;
    }
    let rank = (((p / 100.0) * all.len() as f64).ceil() as usize).clamp(1, all.len()) - 1;
    let (_, value, _) = all.select_nth_unstable_by(rank, f32::total_cmp);
    *value as f64
}

/// The JSON the viewer script mounts: geometry, per-candidate heat maps and headers.
pub fn viewer_data(reference: &Animation, candidates: &[Candidate<'_>], options: &ViewerOptions) -> Result<Value> {
    for c in candidates {
        animcodec::metrics::check_compatible(reference, c.animation)
            .map_err(|e| Error::InvalidAnimation(format!("{}: {e}", c.label)))?;
    }
    let mut all: Vec<&Animation> = vec![reference];
    all.extend(candidates.iter().map(|c| c.animation));
    let (lo, hi) = shared_box(&all);
    let fields: Vec<Vec<f32>> =
        candidates.iter().map(|c| heat_field(reference, c.animation, options)).collect::<Result<_>>()?;
    let largest = fields.iter().flatten().fold(0.0f32, |m, &x| m.max(x)) as f64;
    let heat_max = options.heat_max.unwrap_or_else(|| percentile(&fields, HEAT_PERCENTILE));
    if !(heat_max.is_finite() && heat_max >= 0.0) {
        return Err(Error::parameter("view", "heat_max", format!("{heat_max} is not a finite non-negative number")));
    }
    let heat_bytes = |field: &[f32]| -> Vec<u8> {
        field
            .iter()
            .map(|&x| if heat_max > 0.0 { ((x as f64 / heat_max) * 255.0).round().clamp(0.0, 255.0) as u8 } else { 0 })
            .collect()
    };
    let tri_bytes: Vec<u8> = reference.triangles().iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
    let mut animations = vec![json!({
        "label": "reference",
        "positions": pack_positions(reference, lo, hi),
        "info": {},
    })];
    for (c, field) in candidates.iter().zip(&fields) {
        let largest_here = field.iter().fold(0.0f32, |m, &x| m.max(x));
        animations.push(json!({
            "label": c.label,
            "positions": pack_positions(c.animation, lo, hi),
            "info": c.info,
            "metrics": c.report.as_ref().map(|r| json!({
                "kg": r.kg, "sted": r.sted, "hausdorff": r.hausdorff, "rmse": r.rmse, "max_error": r.max_error,
                "parts": r.parts, "worst_part_kg": r.worst_part_kg(),
            })),
            "heat": pack(&heat_bytes(field)),
            "heat_largest": largest_here,
        }));
    }
    Ok(json!({
        "title": options.title,
        "vertex_count": reference.vertex_count(),
        "frame_count": reference.frame_count(),
        "fps": reference.frame_rate(),
        "triangles": pack(&tri_bytes),
        "box_min": lo,
        "box_max": hi,
        "diagonal": reference.bounding_box_diagonal(),
        "heat_metric": options.heat,
        "heat_max": heat_max,
        "heat_largest": largest,
        "heat_max_rule": if options.heat_max.is_some() { "given".to_string() } else { format!("{HEAT_PERCENTILE}th percentile") },
        "heat_unit": match options.heat {
            HeatMetric::Euclidean => "model units",
            HeatMetric::Sted => "relative edge-length deviation",
        },
        "animations": animations,
    }))
}

/// `</script>` inside embedded text would end the script element early.
fn script_safe(text: &str) -> String {
    text.replace("</script", "<\\/script")
}

/// The `<head>` parts and embedded libraries every page carries; `body` and `main_js` are the
/// page's own markup and start-up script (which receives `THREE`, `OrbitControls`,
/// `mountViewer` and `DATA`).
fn page(title: &str, body: &str, data: &Value, main_js: &str) -> String {
    // '<' only occurs inside JSON strings, where \u003c is the same character: no tag can
    // start inside the data block.
    let data_text = serde_json::to_string(data).unwrap_or_else(|_| "null".into()).replace('<', "\\u003c");
    format!(
        r#"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>{css}</style>
</head>
<body>
{body}
<script type="application/json" id="animcodec-data">{data_text}</script>
<script type="text/plain" id="three-core">{core}</script>
<script type="text/plain" id="three-module">{module}</script>
<script type="text/plain" id="three-orbit">{orbit}</script>
<script type="text/plain" id="three-license">{license}</script>
<script type="module">
// three.js r180 (MIT, licence text embedded above) is loaded from blob URLs: the module
// entry imports the core by relative path and OrbitControls imports 'three', so both
// specifiers are pointed at the blobs before import.
const text = (id) => document.getElementById(id).textContent;
const blob = (src) => URL.createObjectURL(new Blob([src], {{ type: 'text/javascript' }}));
const coreUrl = blob(text('three-core'));
const moduleUrl = blob(text('three-module').split('"./three.core.min.js"').join(JSON.stringify(coreUrl)));
const orbitUrl = blob(text('three-orbit').split("'three'").join(JSON.stringify(moduleUrl)));
const THREE = await import(moduleUrl);
const {{ OrbitControls }} = await import(orbitUrl);
const DATA = JSON.parse(text('animcodec-data'));
{viewer}
{main_js}
</script>
</body>
</html>
"#,
        title = html_escape(title),
        css = VIEWER_CSS,
        core = script_safe(THREE_CORE),
        module = script_safe(THREE_MODULE),
        orbit = script_safe(ORBIT_CONTROLS),
        license = script_safe(THREE_LICENSE),
        viewer = script_safe(VIEWER_JS),
    )
}

/// Escapes text for HTML element content and attribute values.
pub fn html_escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// A complete viewer page for the data of [`viewer_data`].
pub fn viewer_page(data: &Value) -> String {
    let title = data["title"].as_str().unwrap_or("animcodec").to_string();
    page(
        &title,
        r#"<div id="viewer" class="viewer"></div>"#,
        data,
        "window.animcodecViewer = await mountViewer(document.getElementById('viewer'), DATA, THREE, OrbitControls);",
    )
}

/// A rate-distortion report page: `report` = `{input, rows: [...], viewers: [viewer data, ...]}`;
/// the plot and table are drawn by the viewer script's `mountReport`.
pub fn report_page(title: &str, report: &Value) -> String {
    page(
        title,
        r#"<div id="report" class="report"></div>"#,
        report,
        "window.animcodecReport = await mountReport(document.getElementById('report'), DATA, THREE, OrbitControls);",
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use animcodec::synth;

    /// Inflates what [`pack`] wrote.
    fn unpack(text: &str) -> Vec<u8> {
        use std::io::Read as _;
        let raw = base64::engine::general_purpose::STANDARD.decode(text).unwrap();
        let mut out = Vec::new();
        flate2::read::ZlibDecoder::new(raw.as_slice()).read_to_end(&mut out).unwrap();
        out
    }

    /// The packed positions undo to the quantized input within half a quantization step, and
    /// the heat bytes of a candidate with error on half the vertices are 0 exactly there.
    #[test]
    fn positions_round_trip_and_heat_marks_the_moved_half() {
        let a = synth::waving_flag(6, 4, 5);
        let n = a.vertex_count();
        let p: Vec<f32> = a
            .positions()
            .chunks(3)
            .enumerate()
            .flat_map(|(i, c)| if i % n >= n / 2 { [c[0], c[1], c[2] + 0.05] } else { [c[0], c[1], c[2]] })
            .collect();
        let b = Animation::from_parts(n, a.triangles().to_vec(), p, a.frame_rate()).unwrap();
        let cands = [Candidate { label: "half".into(), animation: &b, info: json!({}), report: None }];
        let data = viewer_data(&a, &cands, &ViewerOptions::default()).unwrap();
        let (lo, hi) = shared_box(&[&a, &b]);
        let bytes = unpack(data["animations"][0]["positions"].as_str().unwrap());
        assert_eq!(bytes.len(), a.positions().len() * 2);
        let mut prev = vec![0u16; n * 3];
        for (t, frame) in bytes.chunks(n * 6).enumerate() {
            for (i, c) in frame.chunks(2).enumerate() {
                let d = u16::from_le_bytes([c[0], c[1]]);
                prev[i] = if t == 0 { d } else { prev[i].wrapping_add(d) };
                let k = i % 3;
                let x = lo[k] as f64 + prev[i] as f64 * (hi[k] as f64 - lo[k] as f64) / 65535.0;
                let step = (hi[k] as f64 - lo[k] as f64) / 65535.0;
                assert!((x - a.frame(t)[i] as f64).abs() <= 0.51 * step + 1e-7, "frame {t} coordinate {i}");
            }
        }
        let heat = unpack(data["animations"][1]["heat"].as_str().unwrap());
        assert_eq!(heat.len(), n * a.frame_count());
        for (i, &h) in heat.iter().enumerate() {
            if i % n >= n / 2 {
                assert!(h >= 254, "moved vertex {i}: {h}");
            } else {
                assert_eq!(h, 0, "unmoved vertex {i}");
            }
        }
        assert!((data["heat_max"].as_f64().unwrap() - 0.05).abs() < 1e-6);
    }

    #[test]
    fn mismatched_candidates_and_bad_heat_max_are_errors() {
        let a = synth::waving_flag(6, 4, 5);
        let b = synth::waving_flag(6, 4, 4);
        let cands = [Candidate { label: "short".into(), animation: &b, info: json!({}), report: None }];
        let e = viewer_data(&a, &cands, &ViewerOptions::default()).unwrap_err().to_string();
        assert!(e.contains("short") && e.contains("frames"), "{e}");
        let cands = [Candidate { label: "same".into(), animation: &a, info: json!({}), report: None }];
        let bad = ViewerOptions { heat_max: Some(f64::NAN), ..Default::default() };
        assert!(viewer_data(&a, &cands, &bad).unwrap_err().to_string().contains("heat_max"));
    }

    #[test]
    fn embedded_text_cannot_close_the_script_element() {
        let data = json!({"title": "</script><script>alert(1)</script>", "animations": []});
        let html = viewer_page(&data);
        // Six script elements (data, three core, module, controls, licence, main), each
        // opened and closed once: nothing embedded opens or closes one.
        assert_eq!(html.matches("<script").count(), 6);
        assert_eq!(html.matches("</script>").count(), 6);
        assert!(html.contains("<title>&lt;/script&gt;"));
        // The HTML parser's "escaped script" states start at "<!--"; the embedded assets have none.
        for asset in [THREE_CORE, THREE_MODULE, ORBIT_CONTROLS, VIEWER_JS] {
            assert!(!asset.contains("<!--"));
        }
    }
}
