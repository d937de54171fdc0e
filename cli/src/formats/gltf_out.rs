//! glTF 2.0 / GLB output: the animation as one mesh with position morph targets and a
//! `weights` animation, which every glTF engine plays (three.js, Babylon, Blender, Unity's and
//! Unreal's importers) and which [`super::gltf::read_gltf`] reads back.
//!
//! Layouts:
//! - [`GltfLayout::Basis`] (default): the mean shape as the base mesh plus the `k` leading
//!   principal components of the frames (centred on that mean) as morph targets, each scaled so
//!   its weights lie in [−1, 1]; weights keyed at every frame, `LINEAR`. `k` is the smallest that
//!   meets a KG target against the frames being written (computed exactly from the PCA's
//!   discarded energy), or given.
//! - [`GltfLayout::Frames`]: frame 0 as the base mesh and one morph target per later frame
//!   (its difference from frame 0), `STEP` weights selecting one target per frame: exact, large.
//!
//! The frame rate travels in the animation's `extras` (`{"animcodec": {"fps": …}}`, glTF has no
//! field for it), keys sit at `frame / fps` seconds. A `.glb` holds the JSON and one binary
//! chunk; a `.gltf` embeds its buffer as a base64 `data:` URI, so either is one self-contained
//! file.

use base64::Engine as _;
use codec_core::{Animation, Error, Result};
use faer::{Mat, Side};
use serde_json::{json, Value};

/// How the frames become morph targets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GltfLayout {
    /// Mean shape + principal components (few targets, smooth `LINEAR` weights).
    Basis,
    /// Frame 0 + one target per frame with `STEP` weights (exact).
    Frames,
}

/// Options of [`encode_gltf`].
#[derive(Debug, Clone, PartialEq)]
pub struct GltfOptions {
    /// Layout. Default [`GltfLayout::Basis`].
    pub layout: GltfLayout,
    /// `Basis`: number of morph targets; `None` = the smallest meeting `target_kg`.
    pub targets: Option<usize>,
    /// `Basis` without `targets`: the KG error (percent) the written frames must meet, > 0.
    /// Default 0.05.
    pub target_kg: f64,
    /// Mesh, node and animation name.
    pub name: String,
}

impl Default for GltfOptions {
    fn default() -> Self {
        Self { layout: GltfLayout::Basis, targets: None, target_kg: 0.05, name: "animcodec".into() }
    }
}

/// What [`encode_gltf`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct GltfSummary {
    /// Morph targets written.
    pub targets: usize,
    /// `Basis`: KG (%) of the truncated basis against the input, before f32 rounding (0 for
    /// `Frames`).
    pub basis_kg: f64,
}

/// Little-endian binary buffer with 4-byte aligned views.
struct Buffer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    /// Appends `f32` data as a view + accessor of `kind` ("SCALAR", "VEC3"); returns the accessor
    /// index. `bounds` adds the min/max glTF requires for positions and animation inputs.
    fn floats(&mut self, data: &[f32], kind: &str, target: Option<u32>, bounds: bool) -> usize {
        let width = if kind == "VEC3" { 3 } else { 1 };
        let offset = self.bin.len();
        for x in data {
            self.bin.extend_from_slice(&x.to_le_bytes());
        }
        let mut view = json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4});
        if let Some(t) = target {
            view["target"] = t.into();
        }
        self.views.push(view);
        let mut accessor = json!({"bufferView": self.views.len() - 1, "componentType": 5126, "count": data.len() / width, "type": kind});
        if bounds && !data.is_empty() {
            let (mut lo, mut hi) = (vec![f32::INFINITY; width], vec![f32::NEG_INFINITY; width]);
            for c in data.chunks_exact(width) {
                for k in 0..width {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// Appends `u32` triangle indices; returns the accessor index.
    fn indices(&mut self, data: &[u32]) -> usize {
        let offset = self.bin.len();
        for x in data {
            self.bin.extend_from_slice(&x.to_le_bytes());
        }
        self.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4, "target": 34963}));
        self.accessors.push(
            json!({"bufferView": self.views.len() - 1, "componentType": 5125, "count": data.len(), "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }
}

/// Base mesh, morph targets (each `3V` values) and per-frame weights (`F × k`, frame-major).
struct Morphs {
    base: Vec<f32>,
    targets: Vec<Vec<f32>>,
    weights: Vec<f32>,
    basis_kg: f64,
}

/// Mean + the leading principal components of the frames, from the eigen-decomposition of the
/// `F × F` Gram matrix of the centred frames (cheaper than the `3V × 3V` covariance).
fn basis_morphs(a: &Animation, options: &GltfOptions) -> Result<Morphs> {
    let (frames, n) = (a.frame_count(), a.vertex_count() * 3);
    let mut mean = vec![0.0f64; n];
    for f in 0..frames {
        for (m, &x) in mean.iter_mut().zip(a.frame(f)) {
            *m += x as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= frames as f64);
    let centred = Mat::<f64>::from_fn(frames, n, |f, i| a.frame(f)[i] as f64 - mean[i]);
    let gram = &centred * centred.transpose();
    let eig = gram.self_adjoint_eigen(Side::Lower).map_err(|e| Error::Numerical {
        context: "glTF export".into(),
        step: "eigen-decomposition of the frames' Gram matrix".into(),
        detail: codec_core::error::debug_in_words(&e),
    })?;
    // Descending eigenvalues (faer sorts them ascending).
    let order: Vec<usize> = (0..frames).rev().collect();
    let lambda: Vec<f64> = order.iter().map(|&j| eig.S().column_vector()[j].max(0.0)).collect();
    // KG's denominator: the frames about their own centroids (Karni & Gotsman).
    let mut energy = 0.0;
    for f in 0..frames {
        let frame = a.frame(f);
        let mut c = [0.0f64; 3];
        for p in frame.chunks_exact(3) {
            (0..3).for_each(|k| c[k] += p[k] as f64);
        }
        c.iter_mut().for_each(|x| *x /= a.vertex_count() as f64);
        energy += frame.chunks_exact(3).map(|p| (0..3).map(|k| (p[k] as f64 - c[k]).powi(2)).sum::<f64>()).sum::<f64>();
    }
    let kg_with = |k: usize| {
        let rest: f64 = lambda[k.min(frames)..].iter().sum();
        if energy > 0.0 {
            100.0 * (rest / energy).sqrt()
        } else {
            0.0
        }
    };
    let rank = lambda.iter().filter(|&&l| l > 1e-12 * lambda[0].max(f64::MIN_POSITIVE)).count();
    let k = match options.targets {
        Some(k) => k.min(rank),
        None => (0..=rank).find(|&k| kg_with(k) <= options.target_kg).unwrap_or(rank),
    };
    let mut targets = Vec::with_capacity(k);
    let mut weights = vec![0.0f32; frames * k];
    for (j, &col) in order.iter().take(k).enumerate() {
        let u = eig.U().col(col);
        let sigma = lambda[j].sqrt();
        // Component j: direction Xᵀu/σ (unit length), weight σ·u(f); scaled so |weights| ≤ 1.
        let scale = (0..frames).map(|f| (sigma * u[f]).abs()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let mut dir = vec![0.0f64; n];
        for f in 0..frames {
            let w = u[f] / sigma;
            for (d, &x) in dir.iter_mut().zip(centred.row(f).iter()) {
                *d += w * x;
            }
        }
        targets.push(dir.iter().map(|&d| (d * scale) as f32).collect());
        for f in 0..frames {
            weights[f * k + j] = (sigma * u[f] / scale) as f32;
        }
    }
    Ok(Morphs { base: mean.iter().map(|&m| m as f32).collect(), targets, weights, basis_kg: kg_with(k) })
}

/// Frame 0 + one target per later frame.
fn frame_morphs(a: &Animation) -> Morphs {
    let frames = a.frame_count();
    let base = a.frame(0).to_vec();
    let targets: Vec<Vec<f32>> =
        (1..frames).map(|f| a.frame(f).iter().zip(&base).map(|(x, b)| x - b).collect()).collect();
    let k = targets.len();
    let mut weights = vec![0.0f32; frames * k];
    for f in 1..frames {
        weights[f * k + f - 1] = 1.0;
    }
    Morphs { base, targets, weights, basis_kg: 0.0 }
}

/// Encodes `animation` as glTF: GLB bytes when `glb`, else glTF JSON with an embedded buffer.
pub fn encode_gltf(animation: &Animation, options: &GltfOptions, glb: bool) -> Result<(Vec<u8>, GltfSummary)> {
    if !(options.target_kg.is_finite() && options.target_kg > 0.0) {
        return Err(Error::parameter(
            "glTF export",
            "target_kg",
            format!("{} is not a finite positive KG (%)", options.target_kg),
        ));
    }
    let morphs = match options.layout {
        GltfLayout::Basis => basis_morphs(animation, options)?,
        GltfLayout::Frames => frame_morphs(animation),
    };
    let (frames, k) = (animation.frame_count(), morphs.targets.len());
    let mut buf = Buffer { bin: Vec::new(), views: Vec::new(), accessors: Vec::new() };
    let tri: Vec<u32> = animation.triangles().iter().flatten().copied().collect();
    let indices = buf.indices(&tri);
    let position = buf.floats(&morphs.base, "VEC3", Some(34962), true);
    let targets: Vec<Value> =
        morphs.targets.iter().map(|t| json!({"POSITION": buf.floats(t, "VEC3", Some(34962), true)})).collect();
    let fps = animation.frame_rate();
    let mut primitive = json!({"attributes": {"POSITION": position}, "indices": indices, "mode": 4});
    let mut mesh = json!({"name": options.name, "primitives": [], "extras": {"targetNames": (0..k).map(|j| match options.layout {
        GltfLayout::Basis => format!("component {j}"),
        GltfLayout::Frames => format!("frame {}", j + 1),
    }).collect::<Vec<_>>()}});
    let mut root = json!({
        "asset": {"version": "2.0", "generator": concat!("animcodec ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": options.name}],
    });
    if k > 0 {
        primitive["targets"] = targets.into();
        // The node starts at frame 0's weights so a viewer without animation shows frame 0.
        mesh["weights"] = json!(morphs.weights[..k]);
        if frames > 1 {
            let times: Vec<f32> = (0..frames).map(|f| f as f32 / fps).collect();
            let input = buf.floats(&times, "SCALAR", None, true);
            let output = buf.floats(&morphs.weights, "SCALAR", None, false);
            let interpolation = if options.layout == GltfLayout::Frames { "STEP" } else { "LINEAR" };
            root["animations"] = json!([{
                "name": options.name,
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
                "samplers": [{"input": input, "output": output, "interpolation": interpolation}],
                "extras": {"animcodec": {"fps": fps}},
            }]);
        }
    }
    mesh["primitives"] = json!([primitive]);
    root["meshes"] = json!([mesh]);
    root["bufferViews"] = buf.views.into();
    root["accessors"] = buf.accessors.into();
    let bin = buf.bin;
    let summary = GltfSummary { targets: k, basis_kg: morphs.basis_kg };
    if glb {
        root["buffers"] = json!([{"byteLength": bin.len()}]);
        Ok((glb_bytes(&root, &bin)?, summary))
    } else {
        let uri =
            format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
        root["buffers"] = json!([{"byteLength": bin.len(), "uri": uri}]);
        let text = serde_json::to_vec(&root).map_err(|e| Error::InvalidAnimation(format!("glTF JSON: {e}")))?;
        Ok((text, summary))
    }
}

/// GLB container (glTF spec §4.4): 12-byte header, JSON chunk padded with spaces, BIN chunk
/// padded with zeros, every chunk 4-byte aligned.
fn glb_bytes(root: &Value, bin: &[u8]) -> Result<Vec<u8>> {
    let mut json_chunk = serde_json::to_vec(root).map_err(|e| Error::InvalidAnimation(format!("glTF JSON: {e}")))?;
    while json_chunk.len() % 4 != 0 {
        json_chunk.push(b' ');
    }
    let mut bin_chunk = bin.to_vec();
    while bin_chunk.len() % 4 != 0 {
        bin_chunk.push(0);
    }
    let total = 12 + 8 + json_chunk.len() + 8 + bin_chunk.len();
    let total = u32::try_from(total)
        .map_err(|_| Error::InvalidAnimation(format!("a GLB is at most 4 GiB; this one would be {total} bytes")))?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_chunk);
    out.extend_from_slice(&(bin_chunk.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin_chunk);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use codec_core::synth;

    fn read_back(bytes: &[u8], fps: f32) -> Animation {
        super::super::gltf::parse_gltf(bytes, None, "test.glb", fps).unwrap()
    }

    fn max_diff(a: &Animation, b: &Animation) -> f32 {
        a.positions().iter().zip(b.positions()).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
    }

    /// Frames layout: our reader plays back every frame to f32 rounding of the differences.
    #[test]
    fn frames_layout_plays_back_every_frame() {
        let a = synth::waving_flag(10, 6, 12);
        for glb in [true, false] {
            let opts = GltfOptions { layout: GltfLayout::Frames, ..Default::default() };
            let (bytes, summary) = encode_gltf(&a, &opts, glb).unwrap();
            assert_eq!(summary.targets, 11);
            let b = read_back(&bytes, a.frame_rate());
            assert_eq!((b.frame_count(), b.vertex_count()), (12, a.vertex_count()));
            assert_eq!(b.triangles(), a.triangles());
            assert!(max_diff(&a, &b) < 1e-5, "{}", max_diff(&a, &b));
        }
    }

    /// Basis layout: the KG target is met on playback, more targets for a tighter target, and
    /// the number of targets given explicitly is honoured.
    #[test]
    fn basis_layout_meets_the_kg_target() {
        let a = synth::waving_flag(16, 10, 30);
        let mut last = 0;
        for t in [1.0, 0.1, 0.01] {
            let (bytes, s) = encode_gltf(&a, &GltfOptions { target_kg: t, ..Default::default() }, true).unwrap();
            let b = read_back(&bytes, a.frame_rate());
            assert_eq!(b.frame_count(), a.frame_count());
            let kg = metrics::kg_error(&a, &b).unwrap();
            assert!(s.basis_kg <= t && kg <= t * 1.05 + 1e-4, "target {t}: basis {} played {kg}", s.basis_kg);
            assert!(s.targets >= last);
            last = s.targets;
        }
        let (_, s) = encode_gltf(&a, &GltfOptions { targets: Some(3), ..Default::default() }, true).unwrap();
        assert_eq!(s.targets, 3);
        let e = encode_gltf(&a, &GltfOptions { target_kg: 0.0, ..Default::default() }, true).unwrap_err();
        assert!(e.to_string().contains("target_kg"), "{e}");
    }

    /// A frame rate other than the reader's default keeps the frame times (keys at f / fps).
    #[test]
    fn keys_sit_at_the_frame_times() {
        let a = synth::waving_flag(6, 4, 7);
        let a = Animation::from_parts(a.vertex_count(), a.triangles().to_vec(), a.positions().to_vec(), 24.0).unwrap();
        let (bytes, _) =
            encode_gltf(&a, &GltfOptions { layout: GltfLayout::Frames, ..Default::default() }, true).unwrap();
        assert_eq!(read_back(&bytes, 24.0).frame_count(), 7);
    }

    #[test]
    fn one_frame_is_a_plain_mesh() {
        let a = synth::waving_flag(6, 4, 1);
        for layout in [GltfLayout::Basis, GltfLayout::Frames] {
            let (bytes, s) = encode_gltf(&a, &GltfOptions { layout, ..Default::default() }, true).unwrap();
            assert_eq!(s.targets, 0);
            let b = read_back(&bytes, 30.0);
            assert_eq!(b.frame_count(), 1);
            assert!(max_diff(&a, &b) < 1e-6);
        }
    }
}
