//! The rate-distortion plot of a sweep as one self-contained SVG document: two panels side by
//! side, bpvf vs KG error (left) and bpvf vs STED (right), one line per series, error axes in
//! log₁₀ scale (points with a zero, missing or non-finite error are left out of a panel). In
//! the STED panel, points whose KG is too far from any target for their STED to mean anything
//! ([`sted_degenerate`]) are drawn open and off the line.
//!
//! Written by hand rather than with a plotting crate: the document is a few dozen elements, its
//! text is plain SVG `<text>` (no font files), and the Python package can draw it without
//! pulling a plotting library into its build.

use std::fmt::Write as _;
use std::path::Path;

use metrics::MetricReport;

use crate::error::Result;
use crate::harness::{sted_degenerate, write_text, Point, STED_DEGENERATE_KG};

const WIDTH: f64 = 1200.0;
const HEIGHT: f64 = 520.0;
const TITLE_HEIGHT: f64 = 40.0;
/// Plot-area margins inside each panel: left (y labels), right, top (caption), bottom (x labels).
const MARGIN: (f64, f64, f64, f64) = (84.0, 24.0, 40.0, 56.0);
/// Tick marks per axis, about.
const TICKS: usize = 6;
/// Distinct line colours, cycled (a colour-blind-safe qualitative palette, Okabe–Ito).
const PALETTE: [&str; 8] = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442"];

/// Writes the rate-distortion plot of `points` ([`rd_svg`]) to `path` (replacing it, through a
/// temporary file: [`write_text`]).
pub fn write_rd_svg(path: &Path, title: &str, points: &[Point]) -> Result<()> {
    write_text(path, &rd_svg(title, points))
}

/// The SVG document of the two panels under `title`.
pub fn rd_svg(title: &str, points: &[Point]) -> String {
    let mut svg = String::new();
    let _ = write!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif">"#
    );
    svg.push('\n');
    let _ = writeln!(svg, r#"<rect width="{WIDTH}" height="{HEIGHT}" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<text x="{}" y="26" font-size="20" text-anchor="middle">{}</text>"#,
        WIDTH / 2.0,
        escape(title)
    );
    let panels = [
        ("KG error (%)", panel_data(points, |r| r.kg, |_| false)),
        ("STED", panel_data(points, |r| r.sted, sted_degenerate)),
    ];
    let panel_width = WIDTH / panels.len() as f64;
    for (i, (label, data)) in panels.iter().enumerate() {
        draw_panel(&mut svg, i as f64 * panel_width, panel_width, label, data);
    }
    svg.push_str("</svg>\n");
    svg
}

/// Per series (in the order first met), its `(bpvf, log₁₀ error, degenerate)` points.
type PanelData = Vec<(String, Vec<(f64, f64, bool)>)>;

fn panel_data(
    points: &[Point],
    metric: impl Fn(&MetricReport) -> Option<f64>,
    degenerate: impl Fn(&MetricReport) -> bool,
) -> PanelData {
    let mut out: PanelData = Vec::new();
    for p in points {
        let Some(y) = metric(&p.report).filter(|y| *y > 0.0 && y.is_finite()) else { continue };
        if !p.bpvf.is_finite() {
            continue;
        }
        let point = (p.bpvf, y.log10(), degenerate(&p.report));
        match out.iter_mut().find(|(c, _)| *c == p.series) {
            Some((_, v)) => v.push(point),
            None => out.push((p.series.clone(), vec![point])),
        }
    }
    out
}

fn draw_panel(svg: &mut String, left: f64, width: f64, label: &str, data: &PanelData) {
    let (x0, x1) = padded_range(data.iter().flat_map(|(_, v)| v.iter().map(|p| p.0)), false);
    let any_degenerate = data.iter().any(|(_, v)| v.iter().any(|p| p.2));
    let (y0, y1) = padded_range(data.iter().flat_map(|(_, v)| v.iter().map(|p| p.1)), true);
    let area = (left + MARGIN.0, TITLE_HEIGHT + MARGIN.2, left + width - MARGIN.1, HEIGHT - MARGIN.3);
    let sx = |x: f64| area.0 + (x - x0) / (x1 - x0) * (area.2 - area.0);
    let sy = |y: f64| area.3 - (y - y0) / (y1 - y0) * (area.3 - area.1);
    let _ = writeln!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" font-size="16" text-anchor="middle">bpvf vs {}</text>"#,
        (area.0 + area.2) / 2.0,
        area.1 - 12.0,
        escape(label)
    );
    // Grid, ticks and tick labels: x in bpvf, y in decades written as the error itself.
    for x in ticks(x0, x1) {
        let px = sx(x);
        let _ = writeln!(
            svg,
            r##"<line x1="{px:.1}" y1="{:.1}" x2="{px:.1}" y2="{:.1}" stroke="#e4e4e4"/><text x="{px:.1}" y="{:.1}" font-size="12" text-anchor="middle">{x:.2}</text>"##,
            area.1,
            area.3,
            area.3 + 16.0
        );
    }
    for y in ticks(y0, y1) {
        let py = sy(y);
        let _ = writeln!(
            svg,
            r##"<line x1="{:.1}" y1="{py:.1}" x2="{:.1}" y2="{py:.1}" stroke="#e4e4e4"/><text x="{:.1}" y="{:.1}" font-size="12" text-anchor="end">{:.2e}</text>"##,
            area.0,
            area.2,
            area.0 - 6.0,
            py + 4.0,
            10f64.powf(y)
        );
    }
    let _ = writeln!(
        svg,
        r#"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="black"/>"#,
        area.0,
        area.1,
        area.2 - area.0,
        area.3 - area.1
    );
    let _ = writeln!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" font-size="13" text-anchor="middle">bits per vertex per frame</text>"#,
        (area.0 + area.2) / 2.0,
        area.3 + 40.0
    );
    let (cx, cy) = (left + 18.0, (area.1 + area.3) / 2.0);
    let _ = writeln!(
        svg,
        r#"<text x="{cx:.1}" y="{cy:.1}" font-size="13" text-anchor="middle" transform="rotate(-90 {cx:.1} {cy:.1})">{}, log scale</text>"#,
        escape(label)
    );
    // Curves, then the legend in the top-right corner of the plot area.
    for (i, (series, pts)) in data.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let path: Vec<String> =
            pts.iter().filter(|p| !p.2).map(|&(x, y, _)| format!("{:.1},{:.1}", sx(x), sy(y))).collect();
        let _ = writeln!(
            svg,
            r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"><title>{}</title></polyline>"#,
            path.join(" "),
            escape(series)
        );
        for &(x, y, degenerate) in pts {
            if degenerate {
                let _ = writeln!(
                    svg,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="3.5" fill="white" stroke="{colour}" stroke-width="1.5"><title>KG above {STED_DEGENERATE_KG} %: this STED is no result</title></circle>"#,
                    sx(x),
                    sy(y)
                );
            } else {
                let _ = writeln!(svg, r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{colour}"/>"#, sx(x), sy(y));
            }
        }
    }
    if any_degenerate {
        let _ = writeln!(
            svg,
            r##"<text x="{:.1}" y="{:.1}" font-size="11" fill="#555">open: KG above {STED_DEGENERATE_KG} %, off the line (STED cannot judge them)</text>"##,
            area.0 + 6.0,
            area.3 - 8.0
        );
    }
    if !data.is_empty() {
        let longest = data.iter().map(|(s, _)| s.chars().count()).max().unwrap_or(0) as f64;
        let box_width = 40.0 + 7.5 * longest;
        let (bx, by) = (area.2 - box_width - 8.0, area.1 + 8.0);
        let _ = writeln!(
            svg,
            r#"<rect x="{bx:.1}" y="{by:.1}" width="{box_width:.1}" height="{:.1}" fill="white" fill-opacity="0.85" stroke="black"/>"#,
            8.0 + 18.0 * data.len() as f64
        );
        for (i, (series, _)) in data.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let y = by + 16.0 + 18.0 * i as f64;
            let _ = writeln!(
                svg,
                r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{colour}" stroke-width="2"/><text x="{:.1}" y="{:.1}" font-size="12">{}</text>"#,
                bx + 6.0,
                y - 4.0,
                bx + 26.0,
                y - 4.0,
                bx + 32.0,
                y,
                escape(series)
            );
        }
    }
}

/// About [`TICKS`] round values (1, 2 or 5 × a power of ten apart) inside `[lo, hi]`.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / TICKS as f64;
    if !(raw.is_finite() && raw > 0.0) {
        return vec![lo];
    }
    let decade = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * decade).find(|s| *s >= raw).unwrap_or(10.0 * decade);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// `(min, max)` of `values` widened by 5 % (or ±1 / ±0.5 decades when empty or flat).
fn padded_range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
        let pad = if log { 0.5 } else { lo.abs().max(1.0) * 0.1 };
        return (lo - pad, hi + pad);
    }
    let pad = (hi - lo) * 0.05;
    (lo - pad, hi + pad)
}

/// `text` safe inside SVG text and attributes (file names come from the user).
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if c.is_control() => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padded_ranges_are_never_empty() {
        assert_eq!(padded_range(std::iter::empty(), false), (0.0, 1.0));
        let (a, b) = padded_range([2.0].into_iter(), true);
        assert!(a < 2.0 && b > 2.0);
        let (a, b) = padded_range([1.0, 3.0].into_iter(), false);
        assert!(a < 1.0 && b > 3.0);
    }

    #[test]
    fn ticks_are_round_and_inside() {
        assert_eq!(ticks(0.0, 1.0), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        let t = ticks(-3.3, 0.7);
        assert!(t.iter().all(|v| (-3.3..=0.7).contains(v)) && t.len() >= 3, "{t:?}");
        assert_eq!(ticks(1.0, 1.0), vec![1.0]);
    }

    #[test]
    fn points_too_far_for_sted_are_drawn_open_and_off_the_line() {
        let a = animcodec_synth::tumbling_body_sized(8, 6, 4);
        let exact = metrics::evaluate(&a, &a, &metrics::EvalOptions::default()).unwrap();
        let point = |bpvf: f64, kg: f64, sted: f64| Point {
            codec: "hosvd",
            series: "hosvd".into(),
            params: codec_core::ParamSet::defaults("hosvd", &[]),
            ladder_param: "ss",
            ladder_index: 0,
            bytes: 100,
            bpvf,
            report: MetricReport { kg: Some(kg), sted: Some(sted), worst_part: None, ..exact.clone() },
            encode_seconds: 0.0,
            decode_seconds: 0.0,
            refined: false,
        };
        // KG 125 at STED 7.6e-5: no result; the other two are.
        let svg = rd_svg("t", &[point(0.156, 125.0, 7.6e-5), point(0.5, 2.0, 0.05), point(1.0, 0.4, 0.02)]);
        assert_eq!(svg.matches(r#"fill="white" stroke="#).count(), 1, "one open point: {svg}");
        assert!(svg.contains("open: KG above 10 %"));
        // The STED polyline has the two good points only; the KG one has all three.
        let lines: Vec<usize> = svg
            .lines()
            .filter(|l| l.starts_with("<polyline"))
            .map(|l| l.split("points=\"").nth(1).unwrap().split('"').next().unwrap().split(' ').count())
            .collect();
        assert_eq!(lines, [3, 2]);
    }

    #[test]
    fn hostile_names_are_escaped() {
        let svg = rd_svg("<script>&\"x\u{1b}[31m", &[]);
        assert!(svg.contains("&lt;script&gt;&amp;&quot;x\u{fffd}[31m"), "{svg}");
        assert!(!svg.contains("<script"));
        assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count());
    }
}
