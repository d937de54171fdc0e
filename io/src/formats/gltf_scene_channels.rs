//! The animations of a glTF file as [`super::gltf_scene`] samples them: each channel loaded and
//! checked, the key grid a default frame rate comes from, the animation a caller names chosen
//! and the ones a file holds listed. Only the keys are read here; playing them on the node
//! hierarchy is the bake's work.

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::{Interpolation, Property};
use codec_core::Result;

use super::gltf_anim::Track;
use super::gltf_buffers::{bad, check_accessor, collect_exact, printable, BufferData};
use super::FRAME_RATE_RANGE;

/// One animation channel, loaded and checked.
pub(super) struct Channel {
    pub(super) node: usize,
    pub(super) property: Property,
    pub(super) track: Track,
}

/// Summary of one animation of a file (`list-animations`).
#[derive(Debug, Clone, PartialEq)]
pub struct AnimationInfo {
    /// Index in the file's `animations` array.
    pub index: usize,
    /// Its name, if any.
    pub name: Option<String>,
    /// Channels (node × property).
    pub channels: usize,
    /// First key time over all its samplers (seconds).
    pub start: f64,
    /// Last key time over all its samplers (seconds).
    pub end: f64,
    /// The rate of its key grid when the keys lie on one (what `--fps` defaults to).
    pub key_rate: Option<f64>,
    /// Properties animated: a subset of translation, rotation, scale, weights.
    pub properties: Vec<&'static str>,
}

pub(super) fn property_name(p: Property) -> &'static str {
    match p {
        Property::Translation => "translation",
        Property::Rotation => "rotation",
        Property::Scale => "scale",
        Property::MorphTargetWeights => "weights",
    }
}

/// Loads and checks every channel of `animation`. `targets(node)` is the morph target count of
/// the node's mesh (for `weights` channels).
pub(super) fn load_channels(
    file: &str,
    animation: &::gltf::Animation,
    buffers: &[BufferData],
    targets: &dyn Fn(usize) -> usize,
) -> Result<Vec<Channel>> {
    let a = animation.index();
    let mut out = Vec::new();
    for channel in animation.channels() {
        let c = channel.index();
        let at = || format!("animation {a} channel {c}");
        let node = channel.target().node();
        let property = channel.target().property();
        if property != Property::MorphTargetWeights {
            if let ::gltf::scene::Transform::Matrix { .. } = node.transform() {
                return Err(bad(
                    file,
                    "animation.channels",
                    format!(
                        "{} animates node {}, which has a matrix (only TRS nodes can be animated)",
                        at(),
                        node.index()
                    ),
                ));
            }
        }
        let sampler = channel.sampler();
        let keys =
            check_accessor(file, "animation.input", &sampler.input(), Dimensions::Scalar, &[DataType::F32], buffers)?;
        let normalized = [DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16];
        let (dims, types, width): (Dimensions, &[DataType], usize) = match property {
            Property::Translation | Property::Scale => (Dimensions::Vec3, &[DataType::F32], 3),
            Property::Rotation => (Dimensions::Vec4, &normalized, 4),
            Property::MorphTargetWeights => (Dimensions::Scalar, &normalized, targets(node.index())),
        };
        if width == 0 {
            return Err(bad(
                file,
                "animation.output",
                format!("{}: a weights animation on node {}, whose mesh has no morph targets", at(), node.index()),
            ));
        }
        let outputs = check_accessor(file, "animation.output", &sampler.output(), dims, types, buffers)?;
        let interpolation = sampler.interpolation();
        let per_key = if interpolation == Interpolation::CubicSpline { 3 * width } else { width };
        let expected = keys * per_key;
        let got = if property == Property::MorphTargetWeights { outputs } else { outputs * width };
        if got != expected {
            return Err(bad(
                file,
                "animation.output",
                format!(
                    "{}: {got} values for {keys} keys × {width} ({}, {interpolation:?}); expected {expected}",
                    at(),
                    property_name(property)
                ),
            ));
        }
        let reader = channel.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let times = collect_exact(file, "animation.input", reader.read_inputs(), keys)?;
        if let Some(k) = times.iter().position(|t| !t.is_finite()) {
            return Err(bad(file, "animation.input", format!("{}: key {k} has time {}", at(), times[k])));
        }
        if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(bad(
                file,
                "animation.input",
                format!("{}: key times are not increasing at key {}", at(), k + 1),
            ));
        }
        use ::gltf::animation::util::ReadOutputs;
        let missing = || bad(file, "animation.output", format!("{}: output buffer data is missing", at()));
        let values: Vec<f32> = match reader.read_outputs().ok_or_else(missing)? {
            ReadOutputs::Translations(it) => collect_exact(file, "animation.output", Some(it), outputs)?.concat(),
            ReadOutputs::Scales(it) => collect_exact(file, "animation.output", Some(it), outputs)?.concat(),
            ReadOutputs::Rotations(r) => collect_exact(file, "animation.output", Some(r.into_f32()), outputs)?.concat(),
            ReadOutputs::MorphTargetWeights(w) => collect_exact(file, "animation.output", Some(w.into_f32()), outputs)?,
        };
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(bad(file, "animation.output", format!("{}: value {k} is {}", at(), values[k])));
        }
        let rotation = property == Property::Rotation;
        out.push(Channel {
            node: node.index(),
            property,
            track: Track { times, values, width, interpolation, rotation },
        });
    }
    Ok(out)
}

/// Lowest key-grid rate used as the sampling rate: keys further apart than a second are
/// sampled at [`super::gltf_scene::FALLBACK_FPS`] instead (a 2-key, 10-second animation is not meant as 0.1 fps).
pub(super) const MIN_KEY_RATE: f64 = 1.0;

/// The rate of the key grid: `1 / Δ` for the smallest key spacing `Δ` when every key time of
/// every channel is a whole number of `Δ` after the first (within 1 % of `Δ`), rounded to an
/// integer when within 0.1 % of one; `None` otherwise. Any rate: the caller refuses one above
/// [`FRAME_RATE_RANGE`] by name.
pub(super) fn key_grid(channels: &[Channel]) -> Option<f64> {
    let mut times: Vec<f64> = channels.iter().flat_map(|c| c.track.times.iter().map(|&t| t as f64)).collect();
    times.sort_by(f64::total_cmp);
    times.dedup_by(|a, b| (*a - *b).abs() <= 1e-6 * b.abs().max(1.0));
    let step = times.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
    if !(step.is_finite() && step > 0.0) {
        return None;
    }
    let on_grid = times.iter().all(|t| {
        let k = (t - times[0]) / step;
        (k - k.round()).abs() <= 0.01
    });
    let rate = 1.0 / step;
    let rounded = rate.round();
    let rate = if (rate - rounded).abs() <= 1e-3 * rounded { rounded } else { rate };
    on_grid.then_some(rate)
}

/// The key grid's rate when it is the one sampling uses by default: between [`MIN_KEY_RATE`]
/// and the top of [`FRAME_RATE_RANGE`].
pub(super) fn key_rate(channels: &[Channel]) -> Option<f64> {
    key_grid(channels).filter(|r| (MIN_KEY_RATE..=f64::from(*FRAME_RATE_RANGE.end())).contains(r))
}

/// Time range of the channels' keys.
pub(super) fn key_range(channels: &[Channel]) -> Option<(f64, f64)> {
    let first = channels.iter().map(|c| c.track.times[0] as f64).fold(f64::INFINITY, f64::min);
    let last =
        channels.iter().map(|c| *c.track.times.last().expect("non-empty") as f64).fold(f64::NEG_INFINITY, f64::max);
    first.is_finite().then_some((first, last))
}

/// Morph target count of the mesh each node uses (0 without a mesh).
pub(super) fn node_targets(document: &::gltf::Document) -> Vec<usize> {
    document
        .nodes()
        .map(|n| n.mesh().and_then(|m| m.primitives().next()).map_or(0, |p| p.morph_targets().len()))
        .collect()
}

/// Every animation of the document, summarized.
pub(super) fn list(file: &str, document: &::gltf::Document, buffers: &[BufferData]) -> Result<Vec<AnimationInfo>> {
    let targets = node_targets(document);
    document
        .animations()
        .map(|animation| {
            let channels = load_channels(file, &animation, buffers, &|n| targets[n])?;
            let (start, end) = key_range(&channels).unwrap_or((0.0, 0.0));
            let mut properties: Vec<&'static str> = Vec::new();
            for c in &channels {
                let name = property_name(c.property);
                if !properties.contains(&name) {
                    properties.push(name);
                }
            }
            Ok(AnimationInfo {
                index: animation.index(),
                name: animation.name().map(str::to_owned),
                channels: channels.len(),
                start,
                end,
                key_rate: key_rate(&channels),
                properties,
            })
        })
        .collect()
}

/// Finds the animation `wanted` names: an exact name first, else an index; `None` = the first.
pub(super) fn choose<'a>(
    file: &str,
    document: &'a ::gltf::Document,
    wanted: Option<&str>,
) -> Result<Option<::gltf::Animation<'a>>> {
    let Some(wanted) = wanted else { return Ok(document.animations().next()) };
    if let Some(a) = document.animations().find(|a| a.name() == Some(wanted)) {
        return Ok(Some(a));
    }
    if let Some(a) = wanted.parse::<usize>().ok().and_then(|i| document.animations().nth(i)) {
        return Ok(Some(a));
    }
    let available: Vec<String> = document
        .animations()
        .map(|a| match a.name() {
            Some(n) => format!("{} '{}'", a.index(), printable(n)),
            None => a.index().to_string(),
        })
        .collect();
    let have = if available.is_empty() { "none".to_string() } else { available.join(", ") };
    Err(bad(file, "animation", format!("no animation named or numbered '{}'; the file has: {have}", printable(wanted))))
}

/// The frame rate stored by animcodec's glTF writer in the animation's `extras`.
pub(super) fn extras_fps(json: &serde_json::Value, animation: usize) -> Option<f64> {
    let fps = json.get("animations")?.get(animation)?.get("extras")?.get("animcodec")?.get("fps")?.as_f64()?;
    FRAME_RATE_RANGE.contains(&(fps as f32)).then_some(fps)
}
