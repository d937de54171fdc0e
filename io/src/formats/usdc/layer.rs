//! From a crate file's specs to the layer model ([`Layer`]): the pseudo-root's metadata, the
//! prims of the played-back scene in traversal order (children in their `primChildren`
//! order), and the kept attributes of each with their defaults and time samples.
//!
//! Only the fields read here are decoded; composition (sublayers, references, payloads,
//! inherits, specializes, variants, value clips) is refused by name, as the text reader does.

use std::collections::HashMap;

use codec_core::Result;

use super::super::gltf_buffers::Budget;
use super::super::usd_layer::{
    is_kept_attribute, is_kept_relationship, shown, unsupported, Attribute, Layer, Prim, Relationship, Value,
    FLATTEN_ADVICE, MAX_DEPTH,
};
use super::container::{Crate, SPEC_ATTRIBUTE, SPEC_PRIM, SPEC_PSEUDO_ROOT, SPEC_RELATIONSHIP};
use super::values::{ty, Rep, Values};

/// Fields that bring in other layers or prims: not composed here.
const COMPOSITION_FIELDS: &[&str] =
    &["subLayers", "references", "payload", "inherits", "specializes", "variantSetNames", "variantSelection", "clips"];

/// `SdfSpecifier::Def`.
const SPECIFIER_DEF: i64 = 0;

/// The layer model of a checked crate.
pub fn layer(k: &Crate, budget: &mut Budget) -> Result<Layer> {
    let values = Values { krate: k };
    // Specs by path index; prim children and attributes by parent path index.
    let mut spec_of: HashMap<u32, usize> = HashMap::new();
    let mut children: HashMap<Option<u32>, Vec<u32>> = HashMap::new();
    let mut attributes: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut relationships: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut root = None;
    budget.take("specs", (k.specs.len() as u64).saturating_mul(64))?;
    for (i, spec) in k.specs.iter().enumerate() {
        if spec_of.insert(spec.path, i).is_some() {
            return Err(k.err("SPECS", format!("path index {} has two specs", spec.path)));
        }
        let Some(node) = k.paths[spec.path as usize] else { continue };
        match spec.spec_type {
            SPEC_PSEUDO_ROOT => root = Some(spec.path),
            SPEC_PRIM if !node.is_property => children.entry(node.parent).or_default().push(spec.path),
            SPEC_ATTRIBUTE if node.is_property => {
                if let Some(parent) = node.parent {
                    attributes.entry(parent).or_default().push(spec.path);
                }
            }
            SPEC_RELATIONSHIP if node.is_property => {
                if let Some(parent) = node.parent {
                    relationships.entry(parent).or_default().push(spec.path);
                }
            }
            _ => {}
        }
    }
    let Some(root) = root else {
        return Err(k.err("SPECS", "the layer has no pseudo-root spec"));
    };
    let fields = |path: u32| -> Vec<(u32, u64)> {
        spec_of.get(&path).map(|&s| k.field_set(k.specs[s].field_set).collect()).unwrap_or_default()
    };
    let field = |path: u32, name: &str| -> Result<Option<Rep>> {
        for (token, rep) in fields(path) {
            if k.token(token, "FIELDS")? == name {
                return Ok(Some(Rep(rep)));
            }
        }
        Ok(None)
    };
    let mut layer = Layer::default();
    // Layer metadata.
    for (token, rep) in fields(root) {
        let name = k.token(token, "FIELDS")?;
        let rep = Rep(rep);
        if COMPOSITION_FIELDS.contains(&name) && !is_empty(&values, rep, budget)? {
            return Err(composition(k.file, name, "/"));
        }
        let number = |v: Value| match v {
            Value::Doubles { values, .. } if values.len() == 1 => Some(values[0]),
            Value::Floats { values, .. } if values.len() == 1 => Some(values[0] as f64),
            Value::Ints(v) if v.len() == 1 => Some(v[0] as f64),
            _ => None,
        };
        let meta = &mut layer.metadata;
        match name {
            "timeCodesPerSecond" => meta.time_codes_per_second = number(values.value(rep, name, budget)?),
            "framesPerSecond" => meta.frames_per_second = number(values.value(rep, name, budget)?),
            "metersPerUnit" => meta.meters_per_unit = number(values.value(rep, name, budget)?),
            "upAxis" => {
                if let Value::Token(t) = values.value(rep, name, budget)? {
                    meta.up_axis = Some(t);
                }
            }
            _ => {}
        }
    }
    // Prims, depth first: (path index, parent prim in layer.prims, depth).
    let mut stack: Vec<(u32, Option<usize>, usize)> = Vec::new();
    push_children(k, &values, &children, root, None, 1, &mut stack, budget, &field)?;
    while let Some((path, parent, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return Err(k.err(
                "PATHS",
                format!("prims nested {depth} deep, past the limit of {MAX_DEPTH} ({})", shown(&k.path_text(path)?)),
            ));
        }
        let node =
            k.paths[path as usize].unwrap_or(super::container::PathNode { parent: None, token: 0, is_property: false });
        let mut live = true;
        let mut type_name = String::new();
        let mut api_schemas = Vec::new();
        for (token, rep) in fields(path) {
            let name = k.token(token, "FIELDS")?;
            let rep = Rep(rep);
            if COMPOSITION_FIELDS.contains(&name) && !is_empty(&values, rep, budget)? {
                return Err(composition(k.file, name, &k.path_text(path)?));
            }
            match name {
                "specifier" => {
                    live &= matches!(values.value(rep, name, budget)?, Value::Ints(v) if v == [SPECIFIER_DEF])
                }
                "active" => live &= !matches!(values.value(rep, name, budget)?, Value::Ints(v) if v == [0]),
                "typeName" => {
                    if let Value::Token(t) = values.value(rep, name, budget)? {
                        type_name = t;
                    }
                }
                "apiSchemas" if rep.ty() == ty::TOKEN_LIST_OP => {
                    for token in values.list_op(rep, name, budget)? {
                        let t = k.token(token, "apiSchemas")?;
                        budget.take("apiSchemas", t.len() as u64 + 24)?;
                        api_schemas.push(t.to_owned());
                    }
                }
                _ => {}
            }
        }
        if !live {
            continue;
        }
        let prim_name = k.token(node.token, "PATHS")?;
        budget.take("prim paths", (prim_name.len() + std::mem::size_of::<Prim>()) as u64)?;
        let mut prim = Prim { name: prim_name.to_owned(), parent, type_name, api_schemas, ..Prim::default() };
        for &attr in attributes.get(&path).map(Vec::as_slice).unwrap_or_default() {
            let Some(attr_node) = k.paths[attr as usize] else { continue };
            let attr_name = k.token(attr_node.token, "PATHS")?;
            if !is_kept_attribute(attr_name) {
                continue;
            }
            prim.attributes.push(attribute(k, &values, attr, attr_name, &fields(attr), budget)?);
        }
        for &rel in relationships.get(&path).map(Vec::as_slice).unwrap_or_default() {
            let Some(rel_node) = k.paths[rel as usize] else { continue };
            let rel_name = k.token(rel_node.token, "PATHS")?;
            if !is_kept_relationship(rel_name) {
                continue;
            }
            let mut targets = Vec::new();
            for (token, rep) in fields(rel) {
                let rep = Rep(rep);
                if k.token(token, "FIELDS")? == "targetPaths" && rep.ty() == ty::PATH_LIST_OP {
                    for target in values.list_op(rep, rel_name, budget)? {
                        let text = k.path_text_within(target, MAX_DEPTH + 1)?;
                        budget.take("relationship targets", text.len() as u64 + 24)?;
                        targets.push(text);
                    }
                }
            }
            prim.relationships.push(Relationship { name: rel_name.to_owned(), targets });
        }
        layer.prims.push(prim);
        let index = layer.prims.len() - 1;
        push_children(k, &values, &children, path, Some(index), depth + 1, &mut stack, budget, &field)?;
    }
    Ok(layer)
}

/// Pushes the prim children of `path` on the stack so they pop in `primChildren` order (those
/// it does not list after, in path order).
#[allow(clippy::too_many_arguments)]
fn push_children(
    k: &Crate,
    values: &Values,
    children: &HashMap<Option<u32>, Vec<u32>>,
    path: u32,
    parent: Option<usize>,
    depth: usize,
    stack: &mut Vec<(u32, Option<usize>, usize)>,
    budget: &mut Budget,
    field: &dyn Fn(u32, &str) -> Result<Option<Rep>>,
) -> Result<()> {
    let Some(kids) = children.get(&Some(path)) else { return Ok(()) };
    let mut named: Vec<(String, u32)> = Vec::with_capacity(kids.len());
    for &kid in kids {
        let node = k.paths[kid as usize].map(|n| n.token).unwrap_or(0);
        named.push((k.token(node, "PATHS")?.to_owned(), kid));
    }
    named.sort();
    let mut ordered: Vec<u32> = Vec::with_capacity(kids.len());
    if let Some(rep) = field(path, "primChildren")? {
        if let Value::Tokens(order) = values.value(rep, "primChildren", budget)? {
            for name in &order {
                if let Ok(i) = named.binary_search_by(|(n, _)| n.as_str().cmp(name)) {
                    if named[i].1 != u32::MAX {
                        ordered.push(named[i].1);
                        named[i].1 = u32::MAX;
                    }
                }
            }
        }
    }
    ordered.extend(named.iter().map(|n| n.1).filter(|&p| p != u32::MAX));
    stack.extend(ordered.into_iter().rev().map(|p| (p, parent, depth)));
    Ok(())
}

/// Whether a composition field's value is empty (an empty list op or list authors nothing).
fn is_empty(values: &Values, rep: Rep, budget: &mut Budget) -> Result<bool> {
    if rep.is_array() && rep.payload() == 0 {
        return Ok(true);
    }
    if rep.ty() == ty::STRING_VECTOR && !rep.is_inlined() {
        return Ok(matches!(values.value(rep, "subLayers", budget)?, Value::Tokens(t) if t.is_empty())
            || values_count(values, rep) == Some(0));
    }
    Ok(false)
}

/// The `u64` count at the start of a vector value.
fn values_count(values: &Values, rep: Rep) -> Option<u64> {
    let off = usize::try_from(rep.payload()).ok()?;
    let b = values.krate.bytes.get(off..off.checked_add(8)?)?;
    Some(u64::from_le_bytes(b.try_into().ok()?))
}

fn composition(file: &str, field: &str, path: &str) -> codec_core::Error {
    unsupported(
        file,
        format!(
            "`{field}` on {}: composition is not resolved here; flatten the stage first ({FLATTEN_ADVICE})",
            shown(path)
        ),
    )
}

/// One attribute's default and time samples, decoded.
fn attribute(
    k: &Crate,
    values: &Values,
    path: u32,
    name: &str,
    fields: &[(u32, u64)],
    budget: &mut Budget,
) -> Result<Attribute> {
    let mut attr = Attribute { name: name.to_owned(), ..Attribute::default() };
    for &(token, rep) in fields {
        let field = k.token(token, "FIELDS")?;
        let rep = Rep(rep);
        match field {
            "default" if rep.ty() != ty::VALUE_BLOCK => attr.default = Some(values.value(rep, name, budget)?),
            "timeSamples" => {
                let samples = values.time_samples(rep, &format!("{name} timeSamples"), budget);
                let samples = match samples {
                    Ok(s) => s,
                    // The path is spelled out only for the message.
                    Err(e) => return Err(named(e, &k.path_text(path)?)),
                };
                for (time, value) in samples {
                    let value =
                        if value.ty() == ty::VALUE_BLOCK { None } else { Some(values.value(value, name, budget)?) };
                    attr.samples.push((time, value));
                }
            }
            "elementSize" => {
                if let Value::Ints(v) = values.value(rep, name, budget)? {
                    attr.element_size = v.first().copied();
                }
            }
            "interpolation" => {
                if let Value::Token(t) = values.value(rep, name, budget)? {
                    attr.interpolation = Some(t);
                }
            }
            "spline" => {
                return Err(unsupported(k.file, format!("spline-valued `{name}` on {}", shown(&k.path_text(path)?))))
            }
            _ => {}
        }
    }
    Ok(attr)
}

/// `e` with the (shortened) path of what it is about in front.
fn named(e: codec_core::Error, path: &str) -> codec_core::Error {
    match e {
        codec_core::Error::Malformed { context, field, detail } => {
            codec_core::Error::Malformed { context, field: format!("{} {field}", shown(path)).into(), detail }
        }
        other => other,
    }
}
