//! The layer model both USD readers fill: the text parser ([`super::usd`]) and the crate
//! reader ([`super::usdc`]).
//!
//! A [`Layer`] holds the prims of the played-back scene only (`def` prims under `def`s, none
//! inactive), in the order `UsdStage::Traverse` visits them (depth first, authored order),
//! each with its parent, its type name, its applied API schemas and the attributes a vertex
//! cache needs (the mesh's `points`, `faceVertexCounts`, `faceVertexIndices`, `orientation`,
//! `xformOpOrder` / `xformOp:*` of every prim, and the `UsdSkel` ones), each with its default
//! value, time samples and primvar metadata (`elementSize`, `interpolation`); the `UsdSkel`
//! relationships and their targets; and the layer's metadata (time codes, up axis, units).
//! `usd_assemble` makes the animation from it.

use codec_core::Error;

/// How to flatten a composed stage into one layer, with what `pip install usd-core` installs
/// (its wheel has the `pxr` module, not the `usdcat` tool).
pub(super) const FLATTEN_ADVICE: &str =
    "with usd-core: python3 -c \"from pxr import Usd; Usd.Stage.Open('IN.usd').Export('OUT.usda')\"";

/// Deepest nesting of prims, lists, tuples and metadata the readers follow: far above real
/// scenes (character rigs nest prims 10–20 deep), far below what would exhaust the stack.
pub const MAX_DEPTH: usize = 256;

/// USD's default `timeCodesPerSecond` (and `framesPerSecond`) when the layer authors none.
pub const USD_DEFAULT_TIME_CODES_PER_SECOND: f64 = 24.0;

/// The stage metadata and time codes both USD writers author for an animation: what its
/// source said ([`codec_core::SceneMetadata`]), else USD's conventions for a vertex cache (+Y
/// up, metres, one time code per frame from 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct StageTimeLine {
    pub up_axis: &'static str,
    pub meters_per_unit: f64,
    pub time_codes_per_second: f64,
    pub frames_per_second: f64,
    start: f64,
    step: f64,
}

impl StageTimeLine {
    pub fn of(animation: &codec_core::Animation) -> Self {
        let meta = animation.metadata();
        let fps = animation.frame_rate() as f64;
        Self {
            up_axis: meta.up_axis.map_or("Y", |a| a.name()),
            meters_per_unit: meta.meters_per_unit.unwrap_or(1.0),
            time_codes_per_second: meta.time_codes_per_second.unwrap_or(fps),
            frames_per_second: fps,
            start: meta.start_time_code.unwrap_or(0.0),
            step: meta.time_codes_per_frame(animation.frame_rate()),
        }
    }

    /// The time code of frame `t`.
    pub fn time_code(&self, t: usize) -> f64 {
        self.start + t as f64 * self.step
    }
}

/// An attribute value as far as the readers need it. Tuples are flattened: `arity` is the
/// tuple size (1 for scalars), and an array of k tuples holds k × arity values. Quaternions
/// are held as (real, i, j, k), as USDA writes them.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Value {
    /// `float`/`half` values and tuples (points, `float3`, `quatf`, …).
    Floats { arity: usize, values: Vec<f32> },
    /// `double` values, tuples and matrices (`double3`, `matrix4d` with arity 16, …).
    Doubles { arity: usize, values: Vec<f64> },
    /// Integers of any width.
    Ints(Vec<i64>),
    /// A token, string or asset path.
    Token(String),
    /// A token array.
    Tokens(Vec<String>),
    /// A value of a type not needed here.
    Other,
}

/// One attribute: its default (`None`: none, or blocked) and its time samples, sorted by time
/// (`None`: a blocked sample).
#[derive(Debug, Default)]
pub(super) struct Attribute {
    pub name: String,
    pub default: Option<Value>,
    pub samples: Vec<(f64, Option<Value>)>,
    /// The `elementSize` metadata (primvars: values per element), when authored.
    pub element_size: Option<i64>,
    /// The `interpolation` metadata (primvars: `constant`, `vertex`, …), when authored.
    pub interpolation: Option<String>,
}

/// One relationship: its target paths (absolute, as authored; list ops composed within the
/// one layer: prepended, added and appended targets, in that order).
#[derive(Debug, Default)]
pub(super) struct Relationship {
    pub name: String,
    pub targets: Vec<String>,
}

/// One prim of the played-back scene.
#[derive(Debug, Default)]
pub(super) struct Prim {
    /// Its own name (the path is the names of its ancestors and its own).
    pub name: String,
    /// Index of its parent in [`Layer::prims`] (always an earlier one); `None` under the root.
    pub parent: Option<usize>,
    pub type_name: String,
    pub attributes: Vec<Attribute>,
    /// The kept relationships ([`is_kept_relationship`]).
    pub relationships: Vec<Relationship>,
    /// The applied API schemas (`apiSchemas` metadata, its list op composed within the layer).
    pub api_schemas: Vec<String>,
}

impl Prim {
    pub fn attribute(&self, name: &str) -> Option<&Attribute> {
        self.attributes.iter().find(|a| a.name == name)
    }

    pub fn relationship(&self, name: &str) -> Option<&Relationship> {
        self.relationships.iter().find(|r| r.name == name)
    }

    pub fn has_api(&self, schema: &str) -> bool {
        self.api_schemas.iter().any(|s| s == schema)
    }
}

/// Layer metadata a vertex cache carries.
#[derive(Debug, Default, Clone)]
pub(super) struct Metadata {
    pub time_codes_per_second: Option<f64>,
    pub frames_per_second: Option<f64>,
    pub up_axis: Option<String>,
    pub meters_per_unit: Option<f64>,
}

/// The prims and metadata of one layer.
#[derive(Debug, Default)]
pub(super) struct Layer {
    pub metadata: Metadata,
    pub prims: Vec<Prim>,
}

/// Attributes a reader keeps (every other one is dropped as it is read).
pub(super) fn is_kept_attribute(name: &str) -> bool {
    matches!(name, "points" | "faceVertexCounts" | "faceVertexIndices" | "orientation" | "xformOpOrder")
        || name.starts_with("xformOp:")
        || SKEL_ATTRIBUTES.contains(&name)
        // A blend shape's inbetween shapes (`inbetweens:NAME`): kept to be refused by name.
        || name.starts_with("inbetweens:")
}

/// The `UsdSkel` attributes the skeleton evaluation reads (`usd_skel`): the binding's
/// primvars and orders on skinnable prims and their ancestors, the `Skeleton`'s joints and
/// transforms, the `SkelAnimation`'s joint transforms and blend shape weights, and the
/// `BlendShape`'s offsets.
pub(super) const SKEL_ATTRIBUTES: &[&str] = &[
    "primvars:skel:jointIndices",
    "primvars:skel:jointWeights",
    "primvars:skel:geomBindTransform",
    "primvars:skel:skinningMethod",
    "skel:skinningMethod",
    "skel:joints",
    "skel:blendShapes",
    "joints",
    "bindTransforms",
    "restTransforms",
    "translations",
    "rotations",
    "scales",
    "blendShapes",
    "blendShapeWeights",
    "offsets",
    "pointIndices",
    // Indexed primvars: kept to be refused by name.
    "primvars:skel:jointIndices:indices",
    "primvars:skel:jointWeights:indices",
];

/// Relationships a reader keeps: the `UsdSkel` bindings.
pub(super) fn is_kept_relationship(name: &str) -> bool {
    matches!(name, "skel:skeleton" | "skel:animationSource" | "skel:blendShapeTargets")
}

impl Layer {
    /// The path of prim `i` (`/a/b`).
    pub fn path(&self, i: usize) -> String {
        let mut names = Vec::new();
        let mut at = Some(i);
        while let Some(p) = at {
            names.push(self.prims[p].name.as_str());
            at = self.prims[p].parent;
        }
        names.iter().rev().fold(String::new(), |mut s, n| {
            s.push('/');
            s.push_str(n);
            s
        })
    }
}

pub(super) fn unsupported(file: &str, detail: impl Into<String>) -> Error {
    Error::Unsupported { context: file.to_owned().into(), detail: detail.into() }
}

/// A prim path for a message: printable, and at most 200 characters (the middle elided), since
/// a path may be megabytes long.
pub(super) fn shown(path: &str) -> String {
    const KEEP: usize = 100;
    let chars = path.chars().count();
    if chars <= 2 * KEEP {
        return super::gltf::printable(path);
    }
    let head: String = path.chars().take(KEEP).collect();
    let tail: String = path.chars().skip(chars - KEEP).collect();
    format!("{}…({} characters)…{}", super::gltf::printable(&head), chars - 2 * KEEP, super::gltf::printable(&tail))
}
