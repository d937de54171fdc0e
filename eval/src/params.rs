//! Codec parameters as JSON — the one conversion every document uses (`list`, `encode`,
//! `inspect`, sweep rows, the Python package): a value is a JSON number, boolean or string
//! (choices), a parameter set an object of them.
//!
//! (`ParamValue` and `ParamSet` live in `codec-core`, which knows nothing of JSON; the
//! conversion lives here, above it, once.)

use codec_core::params::find_spec;
use codec_core::{AnimationCodec, ParamKind, ParamSet, ParamSpec, ParamValue};

use crate::error::EvalError;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::{Map, Value};

/// A parameter value as JSON: integers and floats as numbers, booleans, choices as strings.
pub fn param_value_json(value: &ParamValue) -> Value {
    match value {
        ParamValue::Int(v) => Value::from(*v),
        ParamValue::Float(v) => Value::from(*v),
        ParamValue::Bool(v) => Value::from(*v),
        ParamValue::Choice(v) => Value::from(*v),
    }
}

/// A parameter value as a front end received it, before the parameter's kind types it: the
/// command line's `-p key=value` text, a Python value, a JSON value. [`ParamInput::typed`] is
/// the one place any of them becomes a [`ParamValue`].
#[derive(Debug, Clone, PartialEq)]
pub enum ParamInput {
    /// Text parsed by the parameter's kind ([`ParamSpec::parse`]): `-p bits=12`.
    Text(String),
    /// A string value: only a choice takes it.
    Str(String),
    /// A boolean: only a boolean parameter takes it.
    Bool(bool),
    /// An integer: an integer or a float parameter takes it.
    Int(i64),
    /// A number: only a float parameter takes it.
    Float(f64),
    /// A value of no type a parameter takes, as it is shown in messages.
    Other(String),
}

impl ParamInput {
    /// The value `json` holds: numbers as integers when they are, booleans, strings; anything
    /// else (arrays, objects, null) as [`ParamInput::Other`].
    pub fn from_json(json: &Value) -> Self {
        match json {
            Value::Number(n) => {
                n.as_i64().map_or_else(|| n.as_f64().map_or(Self::Other(n.to_string()), Self::Float), Self::Int)
            }
            Value::Bool(b) => Self::Bool(*b),
            Value::String(s) => Self::Str(s.clone()),
            other => Self::Other(other.to_string()),
        }
    }

    /// The value for the parameter `spec`, or `None` when its type does not fit the parameter's
    /// kind (an integer parameter takes integers only; a float parameter any number; text is
    /// parsed by the kind). Ranges are checked for text and choices here, for the rest when the
    /// value is set in a [`ParamSet`].
    pub fn typed(&self, codec: &'static str, spec: &ParamSpec) -> Option<codec_core::Result<ParamValue>> {
        match (&spec.kind, self) {
            (_, Self::Text(text)) => Some(spec.parse(codec, text)),
            (ParamKind::Int { .. }, Self::Int(i)) => Some(Ok(ParamValue::Int(*i))),
            (ParamKind::Float { .. }, Self::Int(i)) => Some(Ok(ParamValue::Float(*i as f64))),
            (ParamKind::Float { .. }, Self::Float(x)) => Some(Ok(ParamValue::Float(*x))),
            (ParamKind::Bool, Self::Bool(b)) => Some(Ok(ParamValue::Bool(*b))),
            (ParamKind::Choice(_), Self::Str(s)) => Some(spec.parse(codec, s)),
            _ => None,
        }
    }

    /// The value as a message shows it (a string quoted, as Python prints it).
    pub fn shown(&self) -> String {
        match self {
            Self::Text(t) | Self::Other(t) => t.clone(),
            Self::Str(s) => format!("'{s}'"),
            Self::Bool(b) => if *b { "True" } else { "False" }.to_owned(),
            Self::Int(i) => i.to_string(),
            Self::Float(x) => format!("{x:?}"),
        }
    }
}

/// The value `json` holds for the parameter `spec` (the inverse of [`param_value_json`]), or
/// `None` when its JSON type does not fit the parameter's kind ([`ParamInput::typed`]).
pub fn param_value_from_json(
    codec: &'static str,
    spec: &ParamSpec,
    json: &Value,
) -> Option<codec_core::Result<ParamValue>> {
    ParamInput::from_json(json).typed(codec, spec)
}

/// The parameter set of `codec`: its defaults with `entries` (name, value) set, each typed by
/// its parameter's kind ([`ParamInput::typed`]), then validated by the codec. The one path from
/// what a user gives (`-p key=value` on the command line, a dict in Python) to a [`ParamSet`].
/// Errors name the codec and the parameter, and list the valid names or the allowed range; a
/// parameter given twice is refused.
pub fn param_set<'a>(
    codec: &dyn AnimationCodec,
    entries: impl IntoIterator<Item = (&'a str, ParamInput)>,
) -> Result<ParamSet, EvalError> {
    let specs = codec.param_specs();
    let mut params = codec.default_params();
    let mut seen: Vec<&str> = Vec::new();
    for (key, value) in entries {
        let spec = find_spec(codec.name(), &specs, key.trim())?;
        if seen.contains(&spec.name) {
            let given = match &value {
                ParamInput::Text(t) => format!(" (-p {key}={t})"),
                _ => String::new(),
            };
            return Err(EvalError::Message(format!(
                "{}: parameter '{}' is given more than once{given}; give each parameter once",
                codec.name(),
                spec.name
            )));
        }
        seen.push(spec.name);
        let typed = value.typed(codec.name(), spec).ok_or_else(|| {
            EvalError::Message(format!(
                "{}: parameter '{key}' = {} is not a {}",
                codec.name(),
                value.shown(),
                spec.kind
            ))
        })??;
        params.set(&specs, spec.name, typed)?;
    }
    codec.validate(&params)?;
    Ok(params)
}

/// `key=value` text (`-p bits=12`) as a (name, value) entry of [`param_set`]; the codec names
/// the error.
pub fn text_entry<'a>(codec: &str, pair: &'a str) -> Result<(&'a str, ParamInput), EvalError> {
    let (key, value) = pair
        .split_once('=')
        .ok_or_else(|| EvalError::Message(format!("{codec}: parameter '{pair}' is not of the form key=value")))?;
    Ok((key, ParamInput::Text(value.to_owned())))
}

/// The parameter set of `codec` from `key=value` texts ([`text_entry`], [`param_set`]).
pub fn param_set_from_text(codec: &dyn AnimationCodec, pairs: &[String]) -> Result<ParamSet, EvalError> {
    let entries = pairs.iter().map(|p| text_entry(codec.name(), p)).collect::<Result<Vec<_>, _>>()?;
    param_set(codec, entries)
}

/// A parameter set as a JSON object `{name: value}`.
pub fn params_json(params: &ParamSet) -> Value {
    Value::Object(params.iter().map(|(name, value)| (name.to_owned(), param_value_json(value))).collect())
}

/// A parameter set as it travels in a serde document: `{name: value}` in the codec's order
/// (the sweep CSV writes its `params` field in that order; a JSON map would sort the names).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamsObject(pub Vec<(String, Value)>);

impl From<&ParamSet> for ParamsObject {
    fn from(params: &ParamSet) -> Self {
        Self(params.iter().map(|(name, value)| (name.to_owned(), param_value_json(value))).collect())
    }
}

impl Serialize for ParamsObject {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.0.iter().map(|(name, value)| (name, value)))
    }
}

impl<'de> Deserialize<'de> for ParamsObject {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Ok(Self(Map::<String, Value>::deserialize(deserializer)?.into_iter().collect()))
    }
}
