//! `animcodec inspect`: shows the `stseg` spatio-temporal segmentation of an animation
//! (Luo et al. 2020, ACM TOMM): temporal segments and per-vertex group labels as JSON, a human
//! summary, and the groups as vertex colours in a PLY or OBJ mesh any viewer opens.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use animcodec::core::{Animation, ParamSet};
use animcodec::output::{commit_all, OutputPolicy};
use animcodec::stseg::{segment_animation, BlockKind, Segment, Segmentation, StsegParams};
use serde_json::{json, Value};

use animcodec::params::params_json;

use super::args::ReadArgs;
use super::{emit, load, CmdResult};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `animcodec inspect`.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// Input animation: .pc2, .mdd, .gltf/.glb, an OBJ directory or pattern, or
    /// `synth:NAME[:small|medium|large]`.
    #[arg(value_name = "INPUT")]
    pub input: String,

    /// stseg parameter as key=value (repeatable; see `animcodec list`). Only the segmentation
    /// parameters (omega_seg, w, gamma_init, gamma_max, lambda, cut_threshold, groups, rho)
    /// change the result.
    #[arg(short = 'p', long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,

    /// Write JSON to F (`-`: print it instead of the summary): {input, vertices, frames,
    /// triangles, params, boundaries, detected_boundaries, segments: [{index, first_frame,
    /// last_frame, frame_count, case, kind, detected_boundary, ends_at, window, group_count,
    /// group_sizes, label_set}], label_sets: [[label per vertex], …]}. Segments sharing a
    /// grouping share one label set.
    #[arg(long, value_name = "F")]
    pub json: Option<PathBuf>,

    /// Write the mesh at `--frame` with each vertex coloured by its group label in the segment
    /// containing that frame: `.ply` (ASCII, `red green blue` uchar vertex properties) or
    /// `.obj` (`v x y z r g b`, colours 0..1). Colours: hue k·0.618… (golden-ratio steps) for
    /// label k, so they are the same in every run.
    #[arg(long, value_name = "F.ply|F.obj")]
    pub mesh: Option<PathBuf>,

    /// Replace existing output files (without it, an existing output is an error). An output
    /// that is also an input is refused even with it.
    #[arg(short, long)]
    pub force: bool,

    /// Frame shown by `--mesh` (0-based).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub frame: usize,

    /// How the input is read.
    #[command(flatten)]
    pub read: ReadArgs,
}

/// Mesh formats `--mesh` writes, chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MeshFormat {
    /// PLY ASCII with `red green blue` uchar vertex properties.
    Ply,
    /// OBJ with the `v x y z r g b` vertex-colour extension (floats in 0..1).
    Obj,
}

impl MeshFormat {
    /// Picks the format from the extension (case-insensitive); the error names the allowed ones.
    fn from_path(path: &Path) -> CmdResult<Self> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("ply") => Ok(MeshFormat::Ply),
            Some("obj") => Ok(MeshFormat::Obj),
            _ => Err(format!(
                "inspect: cannot write mesh '{}': unknown extension; allowed extensions: .ply, .obj",
                path.display()
            )
            .into()),
        }
    }
}

/// Runs `inspect`.
pub fn run(args: &InspectArgs) -> CmdResult {
    // Parameters and the mesh extension first: a typo should not cost a long read and
    // segmentation.
    let registry = animcodec::registry();
    let codec = registry.by_name("stseg")?;
    let param_set = animcodec::front::params_from_text(codec, &args.params)?;
    let params = StsegParams::from_param_set(&param_set)?;
    params.validate()?;
    let mesh_format = args.mesh.as_deref().map(MeshFormat::from_path).transpose()?;
    let mut policy = OutputPolicy::new(args.force);
    if !args.input.starts_with("synth:") {
        policy = policy.with_input(&args.input);
    }
    if let Some(t) = &args.read.topology {
        policy = policy.with_input(t);
    }
    let json_file = args.json.as_deref().filter(|p| *p != Path::new("-"));
    let outputs: Vec<&Path> = [json_file, args.mesh.as_deref()].into_iter().flatten().collect();
    policy.check_all(&outputs)?;

    let options = args.read.options(None);
    let animation =
        load(&args.input, &options, animcodec::core::Limits::default(), animcodec::front::Streams::Refuse)?.animation;
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check_all(&outputs)?;
    let frames = animation.frame_count();
    let frame = args.frame;
    if frame >= frames {
        return Err(format!(
            "inspect: --frame {frame} is out of range: '{}' has {frames} frames (0..={})",
            args.input,
            frames.saturating_sub(1)
        )
        .into());
    }

    let start = Instant::now();
    let segmentation = segment_animation(&animation, &params)?;
    let segment_seconds = start.elapsed().as_secs_f64();

    let json_to_stdout = args.json.as_deref().is_some_and(|p| p == Path::new("-"));
    let mut notes = Vec::new();
    let mut staged = Vec::new();
    let mut stage = |path: &Path, text: &str| -> CmdResult {
        staged.push(policy.stage(path, text.as_bytes())?);
        Ok(())
    };
    if let (Some(path), Some(format)) = (args.mesh.as_deref(), mesh_format) {
        let seg_index = segment_of(&segmentation, frame).ok_or_else(|| {
            format!("inspect: no segment contains frame {frame} (segments do not tile the animation)")
        })?;
        let text = mesh_text(&animation, &segmentation, frame, seg_index, format, &args.input);
        stage(path, &text)?;
        let seg = &segmentation.segments[seg_index];
        notes.push(format!(
            "wrote {} (frame {frame}, segment {seg_index}: frames {}..{}, {} group{})",
            path.display(),
            seg.first_frame,
            seg.first_frame + seg.frame_count - 1,
            seg.group_count,
            if seg.group_count == 1 { "" } else { "s" }
        ));
    }
    if let Some(path) = args.json.as_deref() {
        let text = segmentation_json(&args.input, &animation, &param_set, &segmentation, segment_seconds)?;
        if json_to_stdout {
            emit(&text)?;
        } else {
            stage(path, &text)?;
            notes.push(format!("wrote {}", path.display()));
        }
    }
    // Both outputs are staged first and renamed together: both are replaced, or neither.
    commit_all(staged, &[])?;
    if !json_to_stdout {
        let mut out = summary(&args.input, &animation, &param_set, &segmentation, segment_seconds);
        for n in notes {
            out.push_str(&n);
            out.push('\n');
        }
        emit(&out)?;
    }
    Ok(())
}

/// Index of the segment containing `frame`.
fn segment_of(segmentation: &Segmentation, frame: usize) -> Option<usize> {
    segmentation.segments.iter().position(|s| (s.first_frame..s.first_frame + s.frame_count).contains(&frame))
}

/// Short name of a §4.5 block case, for JSON and the summary.
fn kind_name(kind: BlockKind) -> &'static str {
    match kind {
        BlockKind::NoCut => "no_cut",
        BlockKind::Detected => "detected",
        BlockKind::MaxLength => "max_length",
        BlockKind::Reused => "reused",
    }
}

/// What a block case means, for the summary.
fn kind_text(kind: BlockKind) -> &'static str {
    match kind {
        BlockKind::NoCut => "case I: no initial cut, one group",
        BlockKind::Detected => "case II: new grouping",
        BlockKind::MaxLength => "case III: new grouping",
        BlockKind::Reused => "case IV: previous grouping reused",
    }
}

/// Why a segment ends: `detected_boundary` (Alg. 2 found a change), `end_of_animation`,
/// `gamma_init` (case I takes the initial-cut range) or `gamma_max` (longest segment).
fn end_reason(seg: &Segment, frames: usize) -> &'static str {
    if seg.detected_boundary {
        "detected_boundary"
    } else if seg.first_frame + seg.frame_count >= frames {
        "end_of_animation"
    } else if seg.kind == BlockKind::NoCut {
        "gamma_init"
    } else {
        "gamma_max"
    }
}

/// Number of vertices in each group of a segment.
fn group_sizes(seg: &Segment) -> Vec<usize> {
    let mut sizes = vec![0usize; seg.group_count.max(1)];
    for &l in &seg.labels {
        let l = l as usize;
        if l >= sizes.len() {
            sizes.resize(l + 1, 0);
        }
        sizes[l] += 1;
    }
    sizes
}

/// The distinct per-vertex labellings in segment order, and for each segment the index of
/// its labelling. Segments that reuse a grouping (case IV) share one entry, so a long
/// animation does not repeat `V` labels per segment.
fn label_sets(segmentation: &Segmentation) -> (Vec<&[u8]>, Vec<usize>) {
    let mut sets: Vec<&[u8]> = Vec::new();
    let mut index = Vec::with_capacity(segmentation.segments.len());
    for s in &segmentation.segments {
        match sets.iter().position(|l| *l == s.labels.as_slice()) {
            Some(i) => index.push(i),
            None => {
                index.push(sets.len());
                sets.push(&s.labels);
            }
        }
    }
    (sets, index)
}

/// The JSON document of `--json`, as text ending in a newline.
///
/// `Segmentation::to_json` repeats the labels in every segment; here each distinct labelling
/// is stored once in `label_sets` and segments refer to it by `label_set`. The document is
/// pretty-printed except that each label set is one line (pretty-printing would put every
/// vertex's label on its own line).
fn segmentation_json(
    input: &str,
    animation: &Animation,
    params: &ParamSet,
    segmentation: &Segmentation,
    segment_seconds: f64,
) -> CmdResult<String> {
    let (sets, index) = label_sets(segmentation);
    let segments: Vec<Value> = segmentation
        .segments
        .iter()
        .zip(&index)
        .enumerate()
        .map(|(i, (s, &set))| {
            json!({
                "index": i,
                "first_frame": s.first_frame,
                "last_frame": s.first_frame + s.frame_count - 1,
                "frames": s.frame_count,
                "case": s.kind.case(),
                "kind": kind_name(s.kind),
                "detected_boundary": s.detected_boundary,
                "ends_at": end_reason(s, animation.frame_count()),
                "window": s.window,
                "group_count": s.group_count,
                "group_sizes": group_sizes(s),
                "label_set": set,
            })
        })
        .collect();
    let doc = json!({
        "input": input,
        "vertices": animation.vertex_count(),
        "frames": animation.frame_count(),
        "triangles": animation.topology().triangle_count(),
        "frame_rate": animation.frame_rate(),
        "codec": "stseg",
        "params": params_json(params),
        "segment_seconds": segment_seconds,
        "boundaries": segmentation.boundaries(),
        "detected_boundaries": segmentation.detected_boundaries(),
        "segments": segments,
    });
    let pretty = serde_json::to_string_pretty(&doc)?;
    // `doc` is an object, so its pretty form ends in "\n}"; `label_sets` goes last.
    let body = pretty.strip_suffix("\n}").ok_or("inspect: unexpected JSON layout")?;
    let lines = sets.iter().map(serde_json::to_string).collect::<Result<Vec<_>, _>>()?;
    Ok(format!("{body},\n  \"label_sets\": [\n    {}\n  ]\n}}\n", lines.join(",\n    ")))
}

/// The human summary printed unless `--json -`.
fn summary(
    input: &str,
    animation: &Animation,
    params: &ParamSet,
    segmentation: &Segmentation,
    segment_seconds: f64,
) -> String {
    let list = |v: &[usize]| v.iter().map(|b| b.to_string()).collect::<Vec<_>>().join(", ");
    let (sets, index) = label_sets(segmentation);
    let mut out = format!(
        "{input}: {} frames × {} vertices, {} triangles\n\
         stseg segmentation [{params}] in {segment_seconds:.2} s: {} segments, {} distinct groupings\n\
         boundaries: [{}]; detected by Alg. 2: [{}]\n",
        animation.frame_count(),
        animation.vertex_count(),
        animation.topology().triangle_count(),
        segmentation.segments.len(),
        sets.len(),
        list(&segmentation.boundaries()),
        list(&segmentation.detected_boundaries()),
    );
    for (i, (s, set)) in segmentation.segments.iter().zip(&index).enumerate() {
        let sizes = group_sizes(s).iter().map(|n| n.to_string()).collect::<Vec<_>>().join(", ");
        let _ = writeln!(
            out,
            "  segment {i}: frames {}..{} ({} frames), {}, ends at {}; {} group{} (grouping {set}), sizes [{sizes}]",
            s.first_frame,
            s.first_frame + s.frame_count - 1,
            s.frame_count,
            kind_text(s.kind),
            end_reason(s, animation.frame_count()).replace('_', " "),
            s.group_count,
            if s.group_count == 1 { "" } else { "s" },
        );
    }
    out
}

/// Golden-ratio conjugate: successive hues `k·φ⁻¹ mod 1` are spread as evenly as possible
/// for any number of labels, and label `k` always gets the same colour.
const GOLDEN_RATIO_CONJUGATE: f64 = 0.618_033_988_749_894_9;

/// Colour of group label `k` as 8-bit RGB: hue `k·0.618… mod 1` (label 0 is red), saturation
/// 0.75, value 0.95 (HSV). Fixed, so labels keep their colours between runs and files.
fn label_color(label: u8) -> [u8; 3] {
    let h = (label as f64 * GOLDEN_RATIO_CONJUGATE).fract() * 6.0;
    let (s, v) = (0.75, 0.95);
    let c = v * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let m = v - c;
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let byte = |f: f64| ((f + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    [byte(r), byte(g), byte(b)]
}

/// The mesh at `frame`, vertices coloured by their labels in segment `seg_index`.
fn mesh_text(
    animation: &Animation,
    segmentation: &Segmentation,
    frame: usize,
    seg_index: usize,
    format: MeshFormat,
    input: &str,
) -> String {
    let seg = &segmentation.segments[seg_index];
    let positions = animation.frame(frame);
    let triangles = animation.triangles();
    // Header comments must stay on one line whatever the input name holds.
    let input: String = input.chars().map(|c| if c.is_control() { ' ' } else { c }).collect();
    let comment = format!(
        "animcodec inspect: {input}, frame {frame}, stseg segment {seg_index} (frames {}..{}), {} groups",
        seg.first_frame,
        seg.first_frame + seg.frame_count - 1,
        seg.group_count
    );
    let mut text = String::with_capacity(positions.len() * 16 + triangles.len() * 24 + 512);
    match format {
        MeshFormat::Ply => {
            let _ = write!(
                text,
                "ply\nformat ascii 1.0\ncomment {comment}\ncomment vertex colour = stseg group label\n\
                 element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
                 property uchar red\nproperty uchar green\nproperty uchar blue\n\
                 element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
                animation.vertex_count(),
                triangles.len()
            );
            for (p, &l) in positions.chunks_exact(3).zip(&seg.labels) {
                let [r, g, b] = label_color(l);
                let _ = writeln!(text, "{} {} {} {r} {g} {b}", p[0], p[1], p[2]);
            }
            for t in triangles {
                let _ = writeln!(text, "3 {} {} {}", t[0], t[1], t[2]);
            }
        }
        MeshFormat::Obj => {
            let _ = writeln!(text, "# {comment}\n# v x y z r g b: vertex colour = stseg group label");
            for (p, &l) in positions.chunks_exact(3).zip(&seg.labels) {
                let [r, g, b] = label_color(l).map(|c| c as f64 / 255.0);
                let _ = writeln!(text, "v {} {} {} {r:.4} {g:.4} {b:.4}", p[0], p[1], p[2]);
            }
            for t in triangles {
                let _ = writeln!(text, "f {} {} {}", t[0] as u64 + 1, t[1] as u64 + 1, t[2] as u64 + 1);
            }
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_is_distinct_and_stable() {
        let colours: Vec<[u8; 3]> = (0..animcodec::stseg::MAX_GROUPS as u8).map(label_color).collect();
        assert_eq!(colours[0], [242, 61, 61], "label 0 is red (hue 0, s 0.75, v 0.95)");
        for i in 0..colours.len() {
            for j in i + 1..colours.len() {
                assert_ne!(colours[i], colours[j], "labels {i} and {j} share a colour");
            }
        }
    }

    #[test]
    fn mesh_extensions_are_checked() {
        assert_eq!(MeshFormat::from_path(Path::new("a.PLY")).unwrap(), MeshFormat::Ply);
        assert_eq!(MeshFormat::from_path(Path::new("a.obj")).unwrap(), MeshFormat::Obj);
        let e = MeshFormat::from_path(Path::new("a.stl")).unwrap_err().to_string();
        assert!(e.contains(".ply") && e.contains(".obj") && e.contains("a.stl"), "{e}");
    }
}
