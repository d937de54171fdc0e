//! Codec parameters as JSON — the one conversion every document uses (`list`, `encode`,
//! `inspect`, sweep rows, the Python package): a value is a JSON number, boolean or string
//! (choices), a parameter set an object of them.
//!
//! (`ParamValue` and `ParamSet` live in `codec-core`, which knows nothing of JSON; the
//! conversion lives here, above it, once.)

use codec_core::{ParamKind, ParamSet, ParamSpec, ParamValue};
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

/// The value `json` holds for the parameter `spec` (the inverse of [`param_value_json`]), or
/// `None` when its JSON type does not fit the parameter's kind (an integer parameter takes
/// integers only; a float parameter any number). Ranges are not checked here: setting the
/// value in a [`ParamSet`] does that.
pub fn param_value_from_json(
    codec: &'static str,
    spec: &ParamSpec,
    json: &Value,
) -> Option<codec_core::Result<ParamValue>> {
    match (&spec.kind, json) {
        (ParamKind::Int { .. }, Value::Number(n)) => n.as_i64().map(|i| Ok(ParamValue::Int(i))),
        (ParamKind::Float { .. }, Value::Number(n)) => n.as_f64().map(|x| Ok(ParamValue::Float(x))),
        (ParamKind::Bool, Value::Bool(b)) => Some(Ok(ParamValue::Bool(*b))),
        (ParamKind::Choice(_), Value::String(s)) => Some(spec.parse(codec, s)),
        _ => None,
    }
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
