//! Machine-readable codec parameters.
//!
//! Each codec keeps its parameters in a typed struct with `Default` and `validate()`. To sit
//! behind the object-safe [`AnimationCodec`](crate::AnimationCodec) trait, it also describes
//! them as a list of [`ParamSpec`]s and converts to and from a [`ParamSet`] of typed
//! [`ParamValue`]s. Strings appear only at the CLI edge, in [`ParamSpec::parse`].
//!
//! The struct, its `Default`, its specs and both conversions come from one declaration per
//! parameter ([`declare_params!`](crate::declare_params)): the name, kind, range, default and
//! help of a parameter are written once, so the three views cannot disagree. Choice parameters
//! are enums implementing [`ParamChoice`] ([`param_choice!`](crate::param_choice)).

use std::fmt;

use crate::error::{Error, Result};

/// The kind of a parameter and its allowed values.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamKind {
    /// An integer in `min ..= max`.
    Int {
        /// Smallest allowed value.
        min: i64,
        /// Largest allowed value.
        max: i64,
    },
    /// A real number in `min ..= max`.
    Float {
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// `true` or `false`.
    Bool,
    /// One of a fixed set of names.
    Choice(&'static [&'static str]),
}

impl fmt::Display for ParamKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamKind::Int { min, max } => write!(f, "integer {min}..={max}"),
            ParamKind::Float { min, max } => write!(f, "number {min}..={max}"),
            ParamKind::Bool => write!(f, "true|false"),
            ParamKind::Choice(options) => write!(f, "{}", options.join("|")),
        }
    }
}

/// A parameter value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// Integer value.
    Int(i64),
    /// Real value.
    Float(f64),
    /// Boolean value.
    Bool(bool),
    /// One of the names of a [`ParamKind::Choice`].
    Choice(&'static str),
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Int(v) => write!(f, "{v}"),
            ParamValue::Float(v) => write!(f, "{v}"),
            ParamValue::Bool(v) => write!(f, "{v}"),
            ParamValue::Choice(v) => write!(f, "{v}"),
        }
    }
}

/// Description of one codec parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Name, as used in `-p name=value`.
    pub name: &'static str,
    /// Kind and allowed values.
    pub kind: ParamKind,
    /// Default value.
    pub default: ParamValue,
    /// One-line description.
    pub doc: &'static str,
}

impl ParamSpec {
    /// An integer parameter in `min ..= max`.
    pub const fn int(name: &'static str, min: i64, max: i64, default: i64, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Int { min, max }, default: ParamValue::Int(default), doc }
    }

    /// A real parameter in `min ..= max`.
    pub const fn float(name: &'static str, min: f64, max: f64, default: f64, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Float { min, max }, default: ParamValue::Float(default), doc }
    }

    /// A `true`/`false` parameter.
    pub const fn boolean(name: &'static str, default: bool, doc: &'static str) -> Self {
        Self { name, kind: ParamKind::Bool, default: ParamValue::Bool(default), doc }
    }

    /// A parameter naming one of `options`.
    pub const fn choice(
        name: &'static str,
        options: &'static [&'static str],
        default: &'static str,
        doc: &'static str,
    ) -> Self {
        Self { name, kind: ParamKind::Choice(options), default: ParamValue::Choice(default), doc }
    }

    /// Checks that `value` has this parameter's kind and lies in its range.
    pub fn check(&self, codec: &'static str, value: &ParamValue) -> Result<()> {
        let bad = |msg: String| Err(Error::parameter(codec, self.name, msg));
        match (&self.kind, value) {
            (ParamKind::Int { min, max }, ParamValue::Int(v)) => {
                if v < min || v > max {
                    return bad(format!("{v} is outside the allowed range {min}..={max}"));
                }
            }
            (ParamKind::Float { min, max }, ParamValue::Float(v)) => {
                if !(v.is_finite() && v >= min && v <= max) {
                    return bad(format!("{v} is outside the allowed range {min}..={max}"));
                }
            }
            (ParamKind::Bool, ParamValue::Bool(_)) => {}
            (ParamKind::Choice(options), ParamValue::Choice(v)) => {
                if !options.contains(v) {
                    return bad(format!("'{v}' is not one of {}", options.join(", ")));
                }
            }
            (kind, v) => return bad(format!("{v} is not a {kind}")),
        }
        Ok(())
    }

    /// Parses a command-line string into a value of this parameter's kind, checking the range.
    pub fn parse(&self, codec: &'static str, text: &str) -> Result<ParamValue> {
        let bad =
            |what: &str| Error::parameter(codec, self.name, format!("'{text}' is not {what} (expected {})", self.kind));
        let value = match &self.kind {
            ParamKind::Int { .. } => ParamValue::Int(text.trim().parse().map_err(|_| bad("an integer"))?),
            ParamKind::Float { .. } => ParamValue::Float(text.trim().parse().map_err(|_| bad("a number"))?),
            ParamKind::Bool => ParamValue::Bool(match text.trim() {
                "true" | "1" | "yes" | "on" => true,
                "false" | "0" | "no" | "off" => false,
                _ => return Err(bad("a boolean")),
            }),
            ParamKind::Choice(options) => {
                ParamValue::Choice(options.iter().find(|o| **o == text.trim()).ok_or_else(|| bad("a valid choice"))?)
            }
        };
        self.check(codec, &value)?;
        Ok(value)
    }
}

/// A full, checked assignment of values to a codec's parameters, in spec order.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSet {
    codec: &'static str,
    values: Vec<(&'static str, ParamValue)>,
}

impl ParamSet {
    /// Every parameter at its default.
    pub fn defaults(codec: &'static str, specs: &[ParamSpec]) -> Self {
        Self { codec, values: specs.iter().map(|s| (s.name, s.default.clone())).collect() }
    }

    /// The codec these values belong to.
    pub fn codec(&self) -> &'static str {
        self.codec
    }

    /// Sets one parameter after checking name, kind and range against `specs`.
    /// An unknown name gives an error listing the valid ones.
    pub fn set(&mut self, specs: &[ParamSpec], name: &str, value: ParamValue) -> Result<()> {
        let spec = find_spec(self.codec, specs, name)?;
        spec.check(self.codec, &value)?;
        let slot = self.values.iter_mut().find(|(n, _)| *n == spec.name);
        match slot {
            Some(slot) => slot.1 = value,
            None => self.values.push((spec.name, value)),
        }
        Ok(())
    }

    /// Builder form of [`ParamSet::set`].
    pub fn with(mut self, specs: &[ParamSpec], name: &str, value: ParamValue) -> Result<Self> {
        self.set(specs, name, value)?;
        Ok(self)
    }

    /// The value of `name`, if set.
    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.values.iter().find(|(n, _)| *n == name).map(|(_, v)| v)
    }

    /// All `(name, value)` pairs in spec order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, &ParamValue)> {
        self.values.iter().map(|(n, v)| (*n, v))
    }

    fn missing(&self, name: &'static str, kind: &str) -> Error {
        Error::parameter(self.codec, name, format!("missing or not {kind}"))
    }

    /// Integer value of `name`.
    pub fn int(&self, name: &'static str) -> Result<i64> {
        match self.get(name) {
            Some(ParamValue::Int(v)) => Ok(*v),
            _ => Err(self.missing(name, "an integer")),
        }
    }
    /// Real value of `name` (integers are accepted too).
    pub fn float(&self, name: &'static str) -> Result<f64> {
        match self.get(name) {
            Some(ParamValue::Float(v)) => Ok(*v),
            Some(ParamValue::Int(v)) => Ok(*v as f64),
            _ => Err(self.missing(name, "a number")),
        }
    }
    /// Boolean value of `name`.
    pub fn bool(&self, name: &'static str) -> Result<bool> {
        match self.get(name) {
            Some(ParamValue::Bool(v)) => Ok(*v),
            _ => Err(self.missing(name, "a boolean")),
        }
    }
    /// Choice value of `name`.
    pub fn choice(&self, name: &'static str) -> Result<&'static str> {
        match self.get(name) {
            Some(ParamValue::Choice(v)) => Ok(v),
            _ => Err(self.missing(name, "a choice")),
        }
    }
}

impl fmt::Display for ParamSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (n, v)) in self.values.iter().enumerate() {
            if i > 0 {
                write!(f, ",")?;
            }
            write!(f, "{n}={v}")?;
        }
        Ok(())
    }
}

/// Finds the spec called `name`; the error lists every valid name.
pub fn find_spec<'a>(codec: &'static str, specs: &'a [ParamSpec], name: &str) -> Result<&'a ParamSpec> {
    specs.iter().find(|s| s.name == name).ok_or_else(|| {
        let valid: Vec<&str> = specs.iter().map(|s| s.name).collect();
        Error::parameter(codec, name.to_string(), format!("unknown parameter; valid parameters: {}", valid.join(", ")))
    })
}

/// A codec's single rate knob: settings of one parameter ordered from the smallest stream
/// to the largest, so sweeps and target-error search treat every codec alike.
#[derive(Debug, Clone, PartialEq)]
pub struct RateLadder {
    /// The parameter the ladder walks.
    pub param: &'static str,
    /// Values, from the smallest stream (largest error) to the largest stream.
    pub steps: Vec<ParamValue>,
}

/// The kind of error a quality target bounds, so a codec can offer its rate control the
/// configurations worth searching for it (a lever that buys local shape at the price of
/// positional error is wasted on a positional target, and the other way round).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DistortionKind {
    /// Vertex positions: KG, RMSE, the largest displacement, Hausdorff distance.
    Position,
    /// Local shape: relative changes of edge lengths in space and time (STED).
    Shape,
    /// Positions and local shape bounded together (a joint target such as KG and STED).
    Both,
}

/// One secondary axis of a codec's rate search: a parameter and the values the search may
/// give it, the first being the value of the codec's usual configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchAxis {
    /// The parameter this axis sets.
    pub param: &'static str,
    /// Candidate values, in the order configurations are enumerated (first: the usual one).
    pub values: Vec<ParamValue>,
}

/// The parameter space a codec's rate control may search: a primary rate axis (a
/// [`RateLadder`], small streams first) walked for every configuration of the secondary
/// axes (their Cartesian product, enumerated in a fixed order, the first axis varying
/// slowest). A codec with only a ladder has no secondary axes.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchSpace {
    /// The rate axis searched within each configuration.
    pub primary: RateLadder,
    /// The axes whose value combinations make the configurations.
    pub secondary: Vec<SearchAxis>,
}

impl SearchSpace {
    /// A space of one configuration: just `ladder`.
    pub fn ladder_only(ladder: RateLadder) -> Self {
        Self { primary: ladder, secondary: Vec::new() }
    }

    /// Every configuration of the secondary axes as `(param, value)` lists, in a fixed order
    /// (axis 0 slowest; the first configuration takes every axis's first value).
    pub fn configurations(&self) -> Vec<Vec<(&'static str, ParamValue)>> {
        let mut out: Vec<Vec<(&'static str, ParamValue)>> = vec![Vec::new()];
        for axis in &self.secondary {
            out = out
                .into_iter()
                .flat_map(|prefix| {
                    axis.values.iter().map(move |v| {
                        let mut c = prefix.clone();
                        c.push((axis.param, v.clone()));
                        c
                    })
                })
                .collect();
        }
        out
    }

    /// The space without the secondary axes named in `fixed` (parameters the user set).
    pub fn without(mut self, fixed: &[&str]) -> Self {
        self.secondary.retain(|a| !fixed.contains(&a.param));
        self
    }

    /// `base` with the configuration `config` applied (checked against `specs`).
    pub fn apply(base: &ParamSet, specs: &[ParamSpec], config: &[(&'static str, ParamValue)]) -> Result<ParamSet> {
        let mut p = base.clone();
        for (name, value) in config {
            p.set(specs, name, value.clone())?;
        }
        Ok(p)
    }
}

/// An enum that is the value of a [`ParamKind::Choice`] parameter: its names, in the order
/// the spec lists them, and the mapping both ways. Implement it with
/// [`param_choice!`](crate::param_choice).
pub trait ParamChoice: Sized + Copy + 'static {
    /// Every name, in the order the parameter's spec lists them.
    const NAMES: &'static [&'static str];
    /// The name of this value (one of [`ParamChoice::NAMES`]).
    fn name(self) -> &'static str;
    /// The value called `name`, if any.
    fn from_name(name: &str) -> Option<Self>;
}

/// An integer type a [`ParamKind::Int`] parameter may be stored in. A [`ParamSet`] holds
/// `i64`s checked against the spec's range; the range must fit the field's type, which the
/// conversion checks instead of truncating.
pub trait IntParam: Sized + Copy {
    /// The value as a parameter value (saturating at `i64::MAX`, outside any range).
    fn to_i64(self) -> i64;
    /// The field value of `v`, if it fits.
    fn from_i64(v: i64) -> Option<Self>;
}

macro_rules! int_param {
    ($($t:ty),*) => {$(
        impl IntParam for $t {
            fn to_i64(self) -> i64 {
                i64::try_from(self).unwrap_or(i64::MAX)
            }
            fn from_i64(v: i64) -> Option<Self> {
                <$t>::try_from(v).ok()
            }
        }
    )*};
}
int_param!(u8, u16, u32, u64, usize, i8, i16, i32, i64);

/// A typed parameter struct made by [`declare_params!`](crate::declare_params): the
/// generic view the conformance check `codec_core::testing::check_declared_params` (feature
/// `testing`) works on.
///
/// `read_fields` and `write_fields` are the pure field-by-field conversions; a codec's
/// `from_param_set` / `to_param_set` add its hand-written cross-field checks (and, for `sac`,
/// its rate presets) around them.
pub trait DeclaredParams: Sized + Default + Clone + fmt::Debug + PartialEq {
    /// The codec the parameters belong to.
    const CODEC: &'static str;
    /// The parameter descriptions, in declaration order, defaults from `Default`.
    fn param_specs() -> Vec<ParamSpec>;
    /// Every declared parameter read from `p` (hidden fields at their defaults), with no
    /// cross-field check. Fails when `p` belongs to another codec.
    fn read_fields(p: &ParamSet) -> Result<Self>;
    /// Every declared parameter written into a [`ParamSet`], each checked against its spec
    /// (the first out of range fails, naming codec and field), with no cross-field check.
    fn write_fields(&self) -> Result<ParamSet>;
    /// [`DeclaredParams::read_fields`] followed by the codec's own checks (`after_read`): the
    /// parameters an encoder may run with.
    fn from_set(p: &ParamSet) -> Result<Self>;
    /// [`DeclaredParams::write_fields`] with the codec's own checks around it
    /// (`before_write`, `after_write`).
    fn to_set(&self) -> Result<ParamSet>;
}

/// One declared parameter of a codec, by name and value type: made by
/// [`declare_params!`](crate::declare_params) as an associated constant named like the field
/// (`HosvdParams::ss`), so rate ladders, search axes and parameter changes name parameters
/// the compiler checks, never a string.
///
/// ```
/// use codec_core::{ParamValue, RateLadder};
/// codec_core::declare_params! {
///     codec: "demo";
///     /// Parameters of `demo`.
///     #[derive(Debug, Clone, Copy, PartialEq)]
///     pub struct DemoParams {
///         /// Bits per value.
///         pub bits: u8 = 12 => int(1, 24, "bits per value"),
///     }
/// }
/// let ladder = RateLadder::over(DemoParams::bits, [4, 8]);
/// assert_eq!(ladder.param, "bits");
/// assert_eq!(ladder.steps, [ParamValue::Int(4), ParamValue::Int(8)]);
/// assert_eq!(DemoParams::bits.to(6), ("bits", ParamValue::Int(6)));
/// ```
///
/// ```compile_fail
/// codec_core::declare_params! {
///     codec: "demo";
///     /// Parameters of `demo`.
///     #[derive(Debug, Clone, Copy, PartialEq)]
///     pub struct DemoParams {
///         /// Bits per value.
///         pub bits: u8 = 12 => int(1, 24, "bits per value"),
///     }
/// }
/// // A misspelt parameter does not compile.
/// let _ = DemoParams::bitz.value(8);
/// ```
#[derive(Debug)]
pub struct Param<T> {
    name: &'static str,
    to_value: fn(T) -> ParamValue,
}

impl<T> Clone for Param<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Param<T> {}

impl<T> Param<T> {
    /// The parameter called `name` whose values `to_value` converts (used by
    /// [`declare_params!`](crate::declare_params)).
    #[doc(hidden)]
    pub const fn new(name: &'static str, to_value: fn(T) -> ParamValue) -> Self {
        Self { name, to_value }
    }

    /// The parameter's name (as in `-p name=value`).
    pub const fn name(self) -> &'static str {
        self.name
    }

    /// `v` as a generic parameter value.
    pub fn value(self, v: T) -> ParamValue {
        (self.to_value)(v)
    }

    /// The change "set this parameter to `v`", as rate control and
    /// [`TypedCodec::fit`](crate::TypedCodec::fit) list them.
    pub fn to(self, v: T) -> Setting {
        (self.name, self.value(v))
    }
}

/// A change of one parameter: its name and new value (see [`Param::to`]).
pub type Setting = (&'static str, ParamValue);

/// The value of an integer parameter (for [`Param`]).
#[doc(hidden)]
pub fn int_value<T: IntParam>(v: T) -> ParamValue {
    ParamValue::Int(v.to_i64())
}
/// The value of a real parameter (for [`Param`]).
#[doc(hidden)]
pub fn float_value(v: f64) -> ParamValue {
    ParamValue::Float(v)
}
/// The value of a boolean parameter (for [`Param`]).
#[doc(hidden)]
pub fn bool_value(v: bool) -> ParamValue {
    ParamValue::Bool(v)
}
/// The value of a choice parameter (for [`Param`]).
#[doc(hidden)]
pub fn choice_value<T: ParamChoice>(v: T) -> ParamValue {
    ParamValue::Choice(v.name())
}

impl RateLadder {
    /// The ladder walking `param` over `steps` (smallest stream first).
    pub fn over<T>(param: Param<T>, steps: impl IntoIterator<Item = T>) -> Self {
        Self { param: param.name(), steps: steps.into_iter().map(|v| param.value(v)).collect() }
    }
}

impl SearchAxis {
    /// The axis giving `param` the `values` (the usual one first).
    pub fn over<T>(param: Param<T>, values: impl IntoIterator<Item = T>) -> Self {
        Self { param: param.name(), values: values.into_iter().map(|v| param.value(v)).collect() }
    }
}

/// The error of reading a [`ParamSet`] made for another codec.
#[doc(hidden)]
pub fn foreign_set(codec: &'static str, p: &ParamSet) -> Error {
    Error::parameter(codec, "params", format!("parameters belong to codec '{}'", p.codec()))
}

/// Reads integer parameter `name` into a field of type `T`.
#[doc(hidden)]
pub fn read_int<T: IntParam>(codec: &'static str, p: &ParamSet, name: &'static str) -> Result<T> {
    let v = p.int(name)?;
    T::from_i64(v).ok_or_else(|| Error::parameter(codec, name, format!("{v} does not fit the field's type")))
}

/// Reads choice parameter `name` into a field of type `T`.
#[doc(hidden)]
pub fn read_choice<T: ParamChoice>(codec: &'static str, p: &ParamSet, name: &'static str) -> Result<T> {
    let v = p.choice(name)?;
    T::from_name(v).ok_or_else(|| Error::parameter(codec, name, format!("'{v}' is not one of {}", T::NAMES.join(", "))))
}

/// Implements [`ParamChoice`] for an enum: each variant with its parameter name, in the
/// order the spec lists them. `param_choice!(Type, inherent)` implements it with the type's
/// own `NAMES`, `name` and `from_name` instead, for enums whose names are tied to their
/// stream codes (name = `NAMES[code]`), so the names stay spelled once.
///
/// ```
/// #[derive(Debug, Clone, Copy, PartialEq)]
/// enum Shape { Round, Square }
/// codec_core::param_choice!(Shape { Round = "round", Square = "square" });
/// use codec_core::params::ParamChoice;
/// assert_eq!(Shape::NAMES, ["round", "square"]);
/// assert_eq!(Shape::from_name("square"), Some(Shape::Square));
/// assert_eq!(Shape::Round.name(), "round");
/// ```
#[macro_export]
macro_rules! param_choice {
    ($ty:ident { $($variant:ident = $name:literal),+ $(,)? }) => {
        impl $crate::params::ParamChoice for $ty {
            const NAMES: &'static [&'static str] = &[$($name),+];
            fn name(self) -> &'static str {
                match self {
                    $(Self::$variant => $name,)+
                }
            }
            fn from_name(name: &str) -> ::core::option::Option<Self> {
                match name {
                    $($name => ::core::option::Option::Some(Self::$variant),)+
                    _ => ::core::option::Option::None,
                }
            }
        }
    };
    ($ty:ident, inherent) => {
        impl $crate::params::ParamChoice for $ty {
            const NAMES: &'static [&'static str] = {
                let names: &'static [&'static str] = &$ty::NAMES;
                names
            };
            fn name(self) -> &'static str {
                $ty::name(self)
            }
            fn from_name(name: &str) -> ::core::option::Option<Self> {
                $ty::from_name(name)
            }
        }
    };
}

/// Declares a codec's typed parameter struct, one line per parameter, and generates from it
/// the struct, its `Default`, `specs()`, `from_param_set()`, `to_param_set()` and
/// [`DeclaredParams`].
///
/// Each field is `name: Type = default => kind(...)`; the parameter's name is the field's.
/// Kinds, with the arguments of the matching [`ParamSpec`] constructor:
/// - `int(min, max, "help")`: any [`IntParam`] type;
/// - `float(min, max, "help")`: `f64`;
/// - `boolean("help")`: `bool`;
/// - `choice("help")`: a [`ParamChoice`] enum, its names in `NAMES` order;
/// - `hidden`: a field that is not a parameter (a test hook): not in the specs, never read
///   from or written to a [`ParamSet`]; `from_param_set` gives it its default.
///
/// Specs list the parameters in declaration order. Optional hooks after the struct keep the
/// codec's hand-written checks: `after_read: f;` (`f(Self) -> Result<Self>`, run by
/// `from_param_set` after reading every field), `before_write: f;` and `after_write: f;`
/// (`f(&Self) -> Result<()>`, run by `to_param_set` before / after writing the fields).
///
/// ```
/// #[derive(Debug, Clone, Copy, PartialEq)]
/// pub enum Shape { Round, Square }
/// codec_core::param_choice!(Shape { Round = "round", Square = "square" });
///
/// codec_core::declare_params! {
///     codec: "demo";
///     /// Parameters of `demo`.
///     #[derive(Debug, Clone, Copy, PartialEq)]
///     pub struct DemoParams {
///         /// Bits per value.
///         pub bits: u8 = 12 => int(1, 24, "bits per value"),
///         /// Step.
///         pub step: f64 = 0.5 => float(0.0, 1.0, "step size"),
///         /// Shape.
///         pub shape: Shape = Shape::Round => choice("shape of things"),
///         /// Test hook.
///         pub hook: bool = false => hidden,
///     }
///     after_write: DemoParams::check;
/// }
/// impl DemoParams {
///     fn check(&self) -> codec_core::Result<()> {
///         Ok(())
///     }
/// }
/// let specs = DemoParams::specs();
/// assert_eq!(specs.len(), 3);
/// let set = DemoParams { bits: 8, ..Default::default() }.to_param_set().unwrap();
/// assert_eq!(set.to_string(), "bits=8,step=0.5,shape=round");
/// assert_eq!(DemoParams::from_param_set(&set).unwrap().bits, 8);
/// ```
#[macro_export]
macro_rules! declare_params {
    (
        codec: $codec:expr;
        $(#[$smeta:meta])*
        $svis:vis struct $Name:ident {
            $(
                $(#[$fmeta:meta])*
                $fvis:vis $field:ident : $fty:ty = $default:expr => $kind:ident $(($($arg:expr),* $(,)?))?
            ),* $(,)?
        }
        $(after_read: $after_read:expr;)?
        $(before_write: $before_write:expr;)?
        $(after_write: $after_write:expr;)?
    ) => {
        $(#[$smeta])*
        $svis struct $Name {
            $(
                $(#[$fmeta])*
                $fvis $field: $fty,
            )*
        }

        impl ::core::default::Default for $Name {
            fn default() -> Self {
                Self { $($field: $default,)* }
            }
        }

        impl $Name {
            #[doc = concat!("Parameter descriptions, in declaration order, with the defaults of [`", stringify!($Name), "::default`].")]
            pub fn specs() -> ::std::vec::Vec<$crate::params::ParamSpec> {
                let d = <Self as ::core::default::Default>::default();
                let specs: ::std::vec::Vec<::core::option::Option<$crate::params::ParamSpec>> =
                    ::std::vec![$($crate::declare_params!(@spec d, $field, $fty, $kind $(($($arg),*))?)),*];
                specs.into_iter().flatten().collect()
            }

            /// Reads the typed parameters from a `ParamSet` made for this codec (its values are
            /// already range-checked), then runs the codec's own checks.
            pub fn from_param_set(p: &$crate::params::ParamSet) -> $crate::Result<Self> {
                let s = <Self as $crate::params::DeclaredParams>::read_fields(p)?;
                $(let s = ($after_read)(s)?;)?
                Ok(s)
            }

            /// The generic form of these parameters: fails on the first field outside its
            /// range (naming codec and field) or on the codec's own cross-field checks.
            pub fn to_param_set(&self) -> $crate::Result<$crate::params::ParamSet> {
                $(($before_write)(self)?;)?
                let set = <Self as $crate::params::DeclaredParams>::write_fields(self)?;
                $(($after_write)(self)?;)?
                Ok(set)
            }
        }

        impl $crate::params::DeclaredParams for $Name {
            const CODEC: &'static str = $codec;

            fn param_specs() -> ::std::vec::Vec<$crate::params::ParamSpec> {
                Self::specs()
            }

            fn read_fields(p: &$crate::params::ParamSet) -> $crate::Result<Self> {
                if p.codec() != $codec {
                    return Err($crate::params::foreign_set($codec, p));
                }
                Ok(Self { $($field: $crate::declare_params!(@read p, $field, $fty, $default, $kind),)* })
            }

            fn write_fields(&self) -> $crate::Result<$crate::params::ParamSet> {
                let specs = Self::specs();
                let mut set = $crate::params::ParamSet::defaults($codec, &specs);
                $($crate::declare_params!(@write set, specs, self, $field, $kind);)*
                Ok(set)
            }

            fn from_set(p: &$crate::params::ParamSet) -> $crate::Result<Self> {
                Self::from_param_set(p)
            }

            fn to_set(&self) -> $crate::Result<$crate::params::ParamSet> {
                self.to_param_set()
            }
        }

        #[allow(non_upper_case_globals)]
        impl $Name {
            $($crate::declare_params!(@key $field, $fty, $kind);)*
        }
    };

    (@key $field:ident, $fty:ty, int) => {
        #[doc = concat!("The `", stringify!($field), "` parameter, for rate ladders, search axes and settings.")]
        pub const $field: $crate::params::Param<$fty> =
            $crate::params::Param::new(stringify!($field), $crate::params::int_value::<$fty>);
    };
    (@key $field:ident, $fty:ty, float) => {
        #[doc = concat!("The `", stringify!($field), "` parameter, for rate ladders, search axes and settings.")]
        pub const $field: $crate::params::Param<$fty> =
            $crate::params::Param::new(stringify!($field), $crate::params::float_value);
    };
    (@key $field:ident, $fty:ty, boolean) => {
        #[doc = concat!("The `", stringify!($field), "` parameter, for rate ladders, search axes and settings.")]
        pub const $field: $crate::params::Param<$fty> =
            $crate::params::Param::new(stringify!($field), $crate::params::bool_value);
    };
    (@key $field:ident, $fty:ty, choice) => {
        #[doc = concat!("The `", stringify!($field), "` parameter, for rate ladders, search axes and settings.")]
        pub const $field: $crate::params::Param<$fty> =
            $crate::params::Param::new(stringify!($field), $crate::params::choice_value::<$fty>);
    };
    (@key $field:ident, $fty:ty, hidden) => {};

    (@spec $d:ident, $field:ident, $fty:ty, int($min:expr, $max:expr, $doc:expr)) => {
        ::core::option::Option::Some($crate::params::ParamSpec::int(
            stringify!($field),
            $min,
            $max,
            <$fty as $crate::params::IntParam>::to_i64($d.$field),
            $doc,
        ))
    };
    (@spec $d:ident, $field:ident, $fty:ty, float($min:expr, $max:expr, $doc:expr)) => {
        ::core::option::Option::Some($crate::params::ParamSpec::float(stringify!($field), $min, $max, $d.$field, $doc))
    };
    (@spec $d:ident, $field:ident, $fty:ty, boolean($doc:expr)) => {
        ::core::option::Option::Some($crate::params::ParamSpec::boolean(stringify!($field), $d.$field, $doc))
    };
    (@spec $d:ident, $field:ident, $fty:ty, choice($doc:expr)) => {
        ::core::option::Option::Some($crate::params::ParamSpec::choice(
            stringify!($field),
            <$fty as $crate::params::ParamChoice>::NAMES,
            <$fty as $crate::params::ParamChoice>::name($d.$field),
            $doc,
        ))
    };
    (@spec $d:ident, $field:ident, $fty:ty, hidden) => {
        ::core::option::Option::None
    };

    (@read $p:ident, $field:ident, $fty:ty, $default:expr, int) => {
        $crate::params::read_int::<$fty>(Self::CODEC, $p, stringify!($field))?
    };
    (@read $p:ident, $field:ident, $fty:ty, $default:expr, float) => {
        $p.float(stringify!($field))?
    };
    (@read $p:ident, $field:ident, $fty:ty, $default:expr, boolean) => {
        $p.bool(stringify!($field))?
    };
    (@read $p:ident, $field:ident, $fty:ty, $default:expr, choice) => {
        $crate::params::read_choice::<$fty>(Self::CODEC, $p, stringify!($field))?
    };
    (@read $p:ident, $field:ident, $fty:ty, $default:expr, hidden) => {
        $default
    };

    (@write $set:ident, $specs:ident, $self:ident, $field:ident, int) => {
        $set.set(
            &$specs,
            stringify!($field),
            $crate::params::ParamValue::Int($crate::params::IntParam::to_i64($self.$field)),
        )?
    };
    (@write $set:ident, $specs:ident, $self:ident, $field:ident, float) => {
        $set.set(&$specs, stringify!($field), $crate::params::ParamValue::Float($self.$field))?
    };
    (@write $set:ident, $specs:ident, $self:ident, $field:ident, boolean) => {
        $set.set(&$specs, stringify!($field), $crate::params::ParamValue::Bool($self.$field))?
    };
    (@write $set:ident, $specs:ident, $self:ident, $field:ident, choice) => {
        $set.set(
            &$specs,
            stringify!($field),
            $crate::params::ParamValue::Choice($crate::params::ParamChoice::name($self.$field)),
        )?
    };
    (@write $set:ident, $specs:ident, $self:ident, $field:ident, hidden) => {};
}

#[cfg(test)]
mod tests {
    use super::*;

    fn specs() -> Vec<ParamSpec> {
        vec![
            ParamSpec { name: "bits", kind: ParamKind::Int { min: 1, max: 24 }, default: ParamValue::Int(12), doc: "" },
            ParamSpec { name: "mode", kind: ParamKind::Choice(&["a", "b"]), default: ParamValue::Choice("a"), doc: "" },
            ParamSpec { name: "on", kind: ParamKind::Bool, default: ParamValue::Bool(false), doc: "" },
            ParamSpec {
                name: "eps",
                kind: ParamKind::Float { min: 0.0, max: 1.0 },
                default: ParamValue::Float(0.5),
                doc: "",
            },
        ]
    }

    #[test]
    fn constructors_build_the_same_specs_as_literals() {
        let s = specs();
        assert_eq!(ParamSpec::int("bits", 1, 24, 12, ""), s[0]);
        assert_eq!(ParamSpec::choice("mode", &["a", "b"], "a", ""), s[1]);
        assert_eq!(ParamSpec::boolean("on", false, ""), s[2]);
        assert_eq!(ParamSpec::float("eps", 0.0, 1.0, 0.5, ""), s[3]);
    }

    #[test]
    fn set_checks_name_kind_and_range() {
        let s = specs();
        let mut p = ParamSet::defaults("x", &s);
        assert_eq!(p.int("bits").unwrap(), 12);
        p.set(&s, "bits", ParamValue::Int(8)).unwrap();
        assert_eq!(p.int("bits").unwrap(), 8);
        let e = p.set(&s, "bitz", ParamValue::Int(8)).unwrap_err().to_string();
        assert!(e.contains("valid parameters: bits, mode, on, eps"), "{e}");
        let e = p.set(&s, "bits", ParamValue::Int(25)).unwrap_err().to_string();
        assert!(e.contains("1..=24"), "{e}");
        assert!(p.set(&s, "bits", ParamValue::Float(3.0)).is_err());
        assert!(p.set(&s, "mode", ParamValue::Choice("c")).is_err());
        assert!(p.set(&s, "eps", ParamValue::Float(f64::NAN)).is_err());
    }

    #[test]
    fn parse_from_text() {
        let s = specs();
        assert_eq!(s[0].parse("x", "7").unwrap(), ParamValue::Int(7));
        assert!(s[0].parse("x", "seven").is_err());
        assert!(s[0].parse("x", "99").is_err());
        assert_eq!(s[1].parse("x", "b").unwrap(), ParamValue::Choice("b"));
        assert_eq!(s[2].parse("x", "yes").unwrap(), ParamValue::Bool(true));
        assert_eq!(s[3].parse("x", "0.25").unwrap(), ParamValue::Float(0.25));
        let e = s[1].parse("x", "z").unwrap_err().to_string();
        assert!(e.contains("a|b"), "{e}");
    }
    #[test]
    fn search_space_enumerates_configurations_in_a_fixed_order() {
        let ladder = RateLadder { param: "bits", steps: vec![ParamValue::Int(4), ParamValue::Int(8)] };
        assert_eq!(SearchSpace::ladder_only(ladder.clone()).configurations(), vec![Vec::new()]);
        let space = SearchSpace {
            primary: ladder,
            secondary: vec![
                SearchAxis { param: "on", values: vec![ParamValue::Bool(false), ParamValue::Bool(true)] },
                SearchAxis { param: "eps", values: vec![ParamValue::Float(0.5), ParamValue::Float(0.1)] },
            ],
        };
        let c = space.configurations();
        assert_eq!(c.len(), 4);
        assert_eq!(c[0], vec![("on", ParamValue::Bool(false)), ("eps", ParamValue::Float(0.5))]);
        assert_eq!(c[1], vec![("on", ParamValue::Bool(false)), ("eps", ParamValue::Float(0.1))]);
        assert_eq!(c[3], vec![("on", ParamValue::Bool(true)), ("eps", ParamValue::Float(0.1))]);
        let s = specs();
        let p = SearchSpace::apply(&ParamSet::defaults("x", &s), &s, &c[3]).unwrap();
        assert!(p.bool("on").unwrap());
        assert_eq!(p.float("eps").unwrap(), 0.1);
        assert!(SearchSpace::apply(&p, &s, &[("nope", ParamValue::Bool(true))]).is_err());
    }
}
