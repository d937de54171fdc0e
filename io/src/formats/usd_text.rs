//! The text (`.usda`) layer parser [`super::usd`] reads with: a layer's prims and the few
//! attributes and relationships a vertex cache needs, filled into the layer model
//! ([`super::usd_layer`]) the crate reader fills too. Everything else is parsed (so a syntax
//! error is an error) and dropped. Tokens come from [`super::usd_lexer`].

use codec_core::{Error, Result};

use super::gltf_buffers::Budget;
use super::usd_layer::{
    is_kept_attribute, is_kept_relationship, shown, unsupported, Attribute, Layer, Prim, Relationship, Value,
    FLATTEN_ADVICE, MAX_DEPTH,
};
use super::usd_lexer::{describe, Lexer, Tok};

/// The USDA header every text layer starts with.
pub(super) const USDA_MAGIC: &[u8] = b"#usda ";

/// A value as far as this reader needs it.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum TextValue<'a> {
    /// A number, identifier or string.
    Atom(Tok<'a>),
    /// `[a, b, …]` of atoms or of tuples, flattened: `arity` is the tuple size (0: atoms).
    Array { items: Vec<Tok<'a>>, arity: usize },
    /// Anything else (dictionaries, tuples, nested lists): parsed and dropped.
    Other,
}

/// Time samples of one attribute: time code (as written) → value (`None` = a blocked sample).
pub(super) type Samples<'a> = Vec<(f64, Option<TextValue<'a>>)>;

pub(super) struct Parser<'a, 'b> {
    pub(super) lexer: Lexer<'a>,
    pub(super) peeked: Option<Tok<'a>>,
    pub(super) budget: &'b mut Budget,
    /// Prims open around the current token (for the nesting error).
    pub(super) prim_depth: usize,
}

/// Layer or prim metadata that brings in other layers or prims: not composed here.
pub(super) const COMPOSITION_ARCS: &[&str] =
    &["subLayers", "references", "payload", "inherits", "specializes", "clips"];

impl<'a> Parser<'a, '_> {
    pub(super) fn peek(&mut self) -> Result<Tok<'a>> {
        if self.peeked.is_none() {
            self.peeked = Some(self.lexer.next()?);
        }
        Ok(self.peeked.unwrap_or(Tok::Eof))
    }

    pub(super) fn bump(&mut self) -> Result<Tok<'a>> {
        match self.peeked.take() {
            Some(t) => Ok(t),
            None => self.lexer.next(),
        }
    }

    pub(super) fn expect(&mut self, punct: u8) -> Result<()> {
        match self.bump()? {
            Tok::Punct(p) if p == punct => Ok(()),
            other => Err(self.lexer.error(format!("expected `{}`, found {}", punct as char, describe(other)))),
        }
    }

    pub(super) fn eat(&mut self, punct: u8) -> Result<bool> {
        if self.peek()? == Tok::Punct(punct) {
            self.bump()?;
            return Ok(true);
        }
        Ok(false)
    }

    pub(super) fn depth_check(&self, depth: usize) -> Result<()> {
        if depth > MAX_DEPTH {
            // `depth` counts every nesting level, not only prims: say so, with both counts
            // (254 nested prims reach 257 levels, which "more than 256 prims deep" would hide).
            return Err(self.lexer.error(format!(
                "nested {depth} levels deep, past the limit of {MAX_DEPTH} levels ({} of them nested prims; every \
                 prim, metadata block, property, dictionary, list and tuple is one level)",
                self.prim_depth
            )));
        }
        Ok(())
    }

    pub(super) fn layer(&mut self) -> Result<Layer> {
        // The header line: `#usda 1.0`.
        let header_end = self.lexer.text.find('\n').unwrap_or(self.lexer.text.len());
        let version = self.lexer.text[USDA_MAGIC.len()..header_end].trim();
        if !version.starts_with("1.") {
            return Err(unsupported(self.lexer.file, format!("USDA version {version:?} (1.x is read)")));
        }
        self.lexer.pos = header_end;
        let mut layer = Layer::default();
        if self.eat(b'(')? {
            let meta = &mut layer.metadata;
            self.metadata(1, &mut |key, value| {
                let number = |v: &TextValue| match v {
                    TextValue::Atom(Tok::Number(n)) => n.parse::<f64>().ok(),
                    _ => None,
                };
                match key {
                    "timeCodesPerSecond" => meta.time_codes_per_second = number(value),
                    "framesPerSecond" => meta.frames_per_second = number(value),
                    "metersPerUnit" => meta.meters_per_unit = number(value),
                    "upAxis" => {
                        if let TextValue::Atom(Tok::Str(s)) = value {
                            meta.up_axis = Some((*s).to_owned());
                        }
                    }
                    _ => {}
                }
                Ok(())
            })?;
        }
        let mut path = String::new();
        loop {
            match self.peek()? {
                Tok::Eof => break,
                _ => self.prim(1, &mut path, Some(None), &mut layer)?,
            }
        }
        Ok(layer)
    }

    /// `key = value` entries (with an optional list-op keyword, or a lone doc string) up to the
    /// closing `)`; the opening `(` is consumed. Composition arcs are refused.
    pub(super) fn metadata(
        &mut self,
        depth: usize,
        on_entry: &mut dyn FnMut(&str, &TextValue<'a>) -> Result<()>,
    ) -> Result<()> {
        self.depth_check(depth)?;
        loop {
            match self.bump()? {
                Tok::Punct(b')') => return Ok(()),
                Tok::Punct(b';') | Tok::Str(_) => {}
                Tok::Ident(mut key) => {
                    // `prepend apiSchemas = …` (a list op), `string note = …` / `int[] n = …` (a
                    // typed dictionary entry): the last name before `=` is the key.
                    self.eat_brackets()?;
                    if let Tok::Ident(k) = self.peek()? {
                        self.bump()?;
                        key = k;
                        self.eat_brackets()?;
                    }
                    if COMPOSITION_ARCS.contains(&key) || key == "variants" || key == "variantSets" {
                        return Err(unsupported(
                            self.lexer.file,
                            format!(
                                "`{key}` at line {}: composition is not resolved here; flatten the stage first \
                                 ({FLATTEN_ADVICE})",
                                self.lexer.line()
                            ),
                        ));
                    }
                    self.expect(b'=')?;
                    let value = self.value(depth + 1)?;
                    on_entry(key, &value)?;
                }
                other => return Err(self.lexer.error(format!("unexpected {} in metadata", describe(other)))),
            }
        }
    }

    /// `[]` after a type name.
    pub(super) fn eat_brackets(&mut self) -> Result<bool> {
        if self.eat(b'[')? {
            self.expect(b']')?;
            return Ok(true);
        }
        Ok(false)
    }

    /// One prim spec (`def|over|class [Type] "name" [(metadata)] { … }`), with its children.
    /// `parent`: `Some(index of the parent in layer.prims, None at the root)` while the prim's
    /// parent is part of the played-back scene (a `def` under `def`s only, active); such a
    /// prim, when itself live, is added to `layer.prims` before its children.
    pub(super) fn prim(
        &mut self,
        depth: usize,
        path: &mut String,
        parent: Option<Option<usize>>,
        layer: &mut Layer,
    ) -> Result<()> {
        self.depth_check(depth)?;
        self.prim_depth += 1;
        let specifier = match self.bump()? {
            Tok::Ident(s @ ("def" | "over" | "class")) => s,
            other => {
                return Err(self
                    .lexer
                    .error(format!("expected a prim (`def`, `over`, `class`), found {}", describe(other))))
            }
        };
        let type_name = match self.peek()? {
            Tok::Ident(t) => {
                self.bump()?;
                Some(t)
            }
            _ => None,
        };
        let prim_name = match self.bump()? {
            Tok::Str(s) => s,
            other => return Err(self.lexer.error(format!("expected the prim's name, found {}", describe(other)))),
        };
        let mut active = true;
        let mut api_schemas = Vec::new();
        if self.eat(b'(')? {
            self.metadata(depth + 1, &mut |key, value| {
                if key == "active"
                    && matches!(value, TextValue::Atom(Tok::Ident("false")) | TextValue::Atom(Tok::Number("0")))
                {
                    active = false;
                }
                // `prepend apiSchemas = ["SkelBindingAPI"]`: within one layer, the prepended,
                // appended, added and explicit items are what apply (a `delete` only removes
                // from weaker layers, and there are none here).
                if key == "apiSchemas" {
                    if let TextValue::Array { items, .. } = value {
                        api_schemas.extend(items.iter().filter_map(|t| match t {
                            Tok::Str(s) | Tok::Ident(s) => Some((*s).to_owned()),
                            _ => None,
                        }));
                    }
                }
                Ok(())
            })?;
        }
        let parent_len = path.len();
        path.push('/');
        path.push_str(prim_name);
        // Only a kept prim's own name is held (a full path per prim cost the sum of every
        // prefix on deeply nested long names), counted against the budget.
        let index = match parent {
            Some(parent) if active && specifier == "def" => {
                self.budget.take("prim paths", (prim_name.len() + std::mem::size_of::<Prim>()) as u64)?;
                self.budget.take("apiSchemas", api_schemas.iter().map(|s| s.len() as u64 + 24).sum())?;
                layer.prims.push(Prim {
                    name: prim_name.to_owned(),
                    parent,
                    type_name: type_name.unwrap_or_default().to_owned(),
                    api_schemas,
                    ..Prim::default()
                });
                Some(layer.prims.len() - 1)
            }
            _ => None,
        };
        self.expect(b'{')?;
        loop {
            match self.peek()? {
                Tok::Punct(b'}') => {
                    self.bump()?;
                    break;
                }
                Tok::Punct(b';') => {
                    self.bump()?;
                }
                Tok::Ident("def" | "over" | "class") => self.prim(depth + 1, path, index.map(Some), layer)?,
                Tok::Ident("variantSet") => {
                    return Err(unsupported(
                        self.lexer.file,
                        format!(
                            "a variant set in {} at line {}: variants are not resolved here; flatten the stage \
                             first ({FLATTEN_ADVICE})",
                            shown(path),
                            self.lexer.line()
                        ),
                    ))
                }
                Tok::Ident("reorder") => {
                    // `reorder nameChildren = [...]` / `reorder properties = [...]`.
                    self.bump()?;
                    self.bump()?;
                    self.expect(b'=')?;
                    self.value(depth + 1)?;
                }
                Tok::Eof => return Err(self.lexer.error(format!("`{}` is not closed", shown(path)))),
                _ => match (index, self.property(depth + 1, path)?) {
                    (Some(i), Some(Property::Attribute(attribute))) => {
                        merge_attribute(&mut layer.prims[i].attributes, attribute)
                    }
                    (Some(i), Some(Property::Relationship(rel))) => {
                        let rels = &mut layer.prims[i].relationships;
                        match rels.iter_mut().find(|r| r.name == rel.name) {
                            // `prepend rel x = …` beside `append rel x = …`: one list op.
                            Some(r) => r.targets.extend(rel.targets),
                            None => rels.push(rel),
                        }
                    }
                    _ => {}
                },
            }
        }
        path.truncate(parent_len);
        self.prim_depth -= 1;
        Ok(())
    }

    /// One property: `[custom] [uniform|varying|config] Type[[]] name[.timeSamples|.connect|
    /// .spline] [= value] [(metadata)]`, or `rel name [= targets]`. Returns the attribute when
    /// it is one the layer keeps ([`is_kept_attribute`], [`is_kept_relationship`]), its values
    /// converted.
    pub(super) fn property(&mut self, depth: usize, path: &str) -> Result<Option<Property>> {
        let mut tok = self.bump()?;
        let mut deleted = false;
        while matches!(
            tok,
            Tok::Ident("custom" | "uniform" | "varying" | "config" | "add" | "append" | "prepend" | "delete")
        ) {
            deleted |= tok == Tok::Ident("delete");
            tok = self.bump()?;
        }
        let is_rel = tok == Tok::Ident("rel");
        let Tok::Ident(type_name) = tok else {
            return Err(self.lexer.error(format!("expected a property, found {}", describe(tok))));
        };
        if !is_rel {
            self.eat_brackets()?;
        }
        let full_name = match self.bump()? {
            Tok::Ident(n) => n,
            other => return Err(self.lexer.error(format!("expected a property name, found {}", describe(other)))),
        };
        let (prop, suffix) = match full_name.rsplit_once('.') {
            Some((p, s @ ("timeSamples" | "connect" | "spline" | "default"))) => (p, s),
            _ => (full_name, ""),
        };
        let kept = !is_rel && is_kept_attribute(prop);
        let mut attribute = None;
        if is_rel {
            let mut rel = None;
            if self.eat(b'=')? {
                let value = self.value(depth + 1)?;
                // `delete rel x = <…>` removes targets of weaker layers only: none here.
                if is_kept_relationship(prop) && !deleted && suffix.is_empty() {
                    let targets: Vec<String> = match value {
                        TextValue::Atom(Tok::Other(p)) => vec![p.to_owned()],
                        TextValue::Array { items, .. } => items
                            .iter()
                            .filter_map(|t| match t {
                                Tok::Other(p) => Some((*p).to_owned()),
                                _ => None,
                            })
                            .collect(),
                        _ => Vec::new(),
                    };
                    self.budget.take("relationship targets", targets.iter().map(|t| t.len() as u64 + 24).sum())?;
                    let targets = targets.iter().map(|t| absolute_target(path, t)).collect();
                    rel = Some(Property::Relationship(Relationship { name: prop.to_owned(), targets }));
                }
            }
            if self.eat(b'(')? {
                self.metadata(depth + 1, &mut |_, _| Ok(()))?;
            }
            return Ok(rel);
        }
        if self.eat(b'=')? {
            if suffix == "timeSamples" {
                let samples = self.time_samples(depth + 1)?;
                if kept {
                    let mut converted = Vec::with_capacity(samples.len());
                    for (time, value) in samples {
                        let value = value.map(|v| self.converted(type_name, v, path, prop)).transpose()?;
                        converted.push((time, value));
                    }
                    attribute = Some(Attribute { name: prop.to_owned(), samples: converted, ..Attribute::default() });
                }
            } else if suffix == "spline" {
                self.skip_braces(depth + 1)?;
                if prop == "points" || prop.starts_with("xformOp") {
                    return Err(unsupported(self.lexer.file, format!("spline-valued `{prop}`")));
                }
            } else {
                let value = self.value(depth + 1)?;
                // `= None`: a blocked default, no value.
                let blocked = value == TextValue::Atom(Tok::Ident("None"));
                if (suffix.is_empty() || suffix == "default") && kept {
                    let default = if blocked { None } else { Some(self.converted(type_name, value, path, prop)?) };
                    attribute = Some(Attribute { name: prop.to_owned(), default, ..Attribute::default() });
                }
            }
        }
        if self.eat(b'(')? {
            let (mut element_size, mut interpolation) = (None, None);
            self.metadata(depth + 1, &mut |key, value| {
                match (key, value) {
                    ("elementSize", TextValue::Atom(Tok::Number(n))) => element_size = n.parse::<i64>().ok(),
                    ("interpolation", TextValue::Atom(Tok::Str(s))) => interpolation = Some((*s).to_owned()),
                    _ => {}
                }
                Ok(())
            })?;
            if let Some(a) = attribute.as_mut() {
                a.element_size = element_size;
                a.interpolation = interpolation;
            }
        }
        Ok(attribute.map(Property::Attribute))
    }

    /// A text value of an attribute declared as `type_name`, in the layer model: tokens and
    /// strings as text, integer types as integers, `double`/`…d` types as doubles, the other
    /// numeric types as floats (parsed straight to `f32`, so a coordinate reads back exactly).
    pub(super) fn converted(&mut self, type_name: &str, value: TextValue<'a>, path: &str, prop: &str) -> Result<Value> {
        let file = self.lexer.file;
        let bad =
            |detail: &str| Error::malformed(file.to_owned(), format!("{} {prop}", shown(path)), detail.to_owned());
        let (items, arity, scalar) = match value {
            TextValue::Atom(t) => (vec![t], 1, true),
            TextValue::Array { items, arity } => (items, arity.max(1), false),
            TextValue::Other => return Ok(Value::Other),
        };
        if matches!(type_name, "token" | "string" | "asset") {
            let mut texts = Vec::with_capacity(items.len());
            for t in &items {
                match t {
                    Tok::Str(s) | Tok::Ident(s) | Tok::Other(s) => texts.push((*s).to_owned()),
                    _ => return Err(bad("holds a value that is not a token")),
                }
            }
            self.budget.take("tokens", texts.iter().map(|t| t.len() as u64 + 24).sum())?;
            return Ok(if scalar { Value::Token(texts.pop().unwrap_or_default()) } else { Value::Tokens(texts) });
        }
        let number = |t: &Tok<'a>| match t {
            Tok::Number(n) | Tok::Ident(n) => Some(*n),
            _ => None,
        };
        if matches!(type_name, "int" | "uint" | "int64" | "uint64" | "uchar" | "int2" | "int3" | "int4") {
            self.budget.take("integers", items.len() as u64 * 8)?;
            let ints = items.iter().map(|t| number(t).and_then(|n| n.parse::<i64>().ok())).collect::<Option<_>>();
            return Ok(Value::Ints(ints.ok_or_else(|| bad("holds a value that is not an integer"))?));
        }
        if type_name == "timecode" || type_name.starts_with("double") || type_name.ends_with('d') {
            self.budget.take("numbers", items.len() as u64 * 8)?;
            let values = items.iter().map(|t| number(t).and_then(|n| n.parse::<f64>().ok())).collect::<Option<_>>();
            return Ok(Value::Doubles {
                arity,
                values: values.ok_or_else(|| bad("holds a value that is not a number"))?,
            });
        }
        if type_name.starts_with("bool") || type_name.starts_with("matrix") || type_name == "opaque" {
            return Ok(Value::Other);
        }
        self.budget.take("numbers", items.len() as u64 * 4)?;
        let values: Option<Vec<f32>> = items.iter().map(|t| number(t).and_then(|n| n.parse::<f32>().ok())).collect();
        let mut values = values.ok_or_else(|| bad("holds a value that is not a number"))?;
        // `half` types hold what USD reads into a 16-bit float, as the crate reader does.
        if type_name.starts_with("half") || type_name.ends_with('h') {
            values.iter_mut().for_each(|v| *v = to_half_precision(*v));
        }
        Ok(Value::Floats { arity, values })
    }

    /// `{ time: value, … }` (the `{` not yet consumed).
    pub(super) fn time_samples(&mut self, depth: usize) -> Result<Samples<'a>> {
        self.depth_check(depth)?;
        self.expect(b'{')?;
        let mut samples: Samples<'a> = Vec::new();
        loop {
            match self.bump()? {
                Tok::Punct(b'}') => break,
                Tok::Punct(b',') => {}
                Tok::Number(t) => {
                    let time = t
                        .parse::<f64>()
                        .ok()
                        .filter(|t| t.is_finite())
                        .ok_or_else(|| self.lexer.error(format!("time code {t:?} is not a finite number")))?;
                    self.expect(b':')?;
                    let value = match self.peek()? {
                        Tok::Ident("None") => {
                            self.bump()?;
                            None
                        }
                        _ => Some(self.value(depth + 1)?),
                    };
                    self.budget.take("time samples", std::mem::size_of::<(f64, Option<TextValue>)>() as u64)?;
                    samples.push((time, value));
                }
                other => return Err(self.lexer.error(format!("expected a time code, found {}", describe(other)))),
            }
        }
        // USD keeps one value per time (the last one authored wins).
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        samples.reverse();
        samples.dedup_by(|a, b| a.0 == b.0);
        samples.reverse();
        Ok(samples)
    }

    /// A value: an atom, a list (of atoms or tuples: kept), a tuple, a dictionary (dropped).
    pub(super) fn value(&mut self, depth: usize) -> Result<TextValue<'a>> {
        self.depth_check(depth)?;
        match self.bump()? {
            Tok::Punct(b'[') => self.list(depth + 1),
            Tok::Punct(b'(') => {
                // A tuple (`double3 xformOp:translate = (1, 2, 3)`, a matrix of row tuples):
                // its atoms, flattened.
                let mut items = Vec::new();
                self.tuple(depth + 1, &mut items)?;
                self.budget.take("tuple", (items.len() * std::mem::size_of::<Tok>()) as u64)?;
                Ok(TextValue::Array { arity: items.len(), items })
            }
            Tok::Punct(b'{') => {
                self.peeked = Some(Tok::Punct(b'{'));
                self.skip_braces(depth)?;
                Ok(TextValue::Other)
            }
            t @ (Tok::Number(_) | Tok::Ident(_) | Tok::Str(_) | Tok::Other(_)) => Ok(TextValue::Atom(t)),
            other => Err(self.lexer.error(format!("expected a value, found {}", describe(other)))),
        }
    }

    /// The items of `[ … ]` (the `[` consumed).
    pub(super) fn list(&mut self, depth: usize) -> Result<TextValue<'a>> {
        self.depth_check(depth)?;
        let mut items = Vec::new();
        let mut arity: Option<usize> = None;
        let mut uniform = true;
        let item_bytes = std::mem::size_of::<Tok>() as u64;
        loop {
            match self.bump()? {
                Tok::Punct(b']') => break,
                Tok::Punct(b',') => {}
                Tok::Punct(b'(') => {
                    let before = items.len();
                    self.tuple(depth + 1, &mut items)?;
                    let n = items.len() - before;
                    self.budget.take("list", n as u64 * item_bytes)?;
                    uniform &= *arity.get_or_insert(n) == n;
                }
                Tok::Punct(b'[') => {
                    self.list(depth + 1)?;
                    uniform = false;
                }
                Tok::Punct(b'{') => {
                    self.peeked = Some(Tok::Punct(b'{'));
                    self.skip_braces(depth + 1)?;
                    uniform = false;
                }
                t @ (Tok::Number(_) | Tok::Ident(_) | Tok::Str(_) | Tok::Other(_)) => {
                    self.budget.take("list", item_bytes)?;
                    items.push(t);
                    uniform &= *arity.get_or_insert(0) == 0;
                }
                other => return Err(self.lexer.error(format!("unexpected {} in a list", describe(other)))),
            }
        }
        if !uniform {
            return Ok(TextValue::Other);
        }
        Ok(TextValue::Array { items, arity: arity.unwrap_or(0) })
    }

    /// The atoms of `( … )` (the `(` consumed) appended to `out`; nested tuples are flattened.
    pub(super) fn tuple(&mut self, depth: usize, out: &mut Vec<Tok<'a>>) -> Result<()> {
        self.depth_check(depth)?;
        loop {
            match self.bump()? {
                Tok::Punct(b')') => return Ok(()),
                Tok::Punct(b',') => {}
                Tok::Punct(b'(') => self.tuple(depth + 1, out)?,
                t @ (Tok::Number(_) | Tok::Ident(_) | Tok::Str(_) | Tok::Other(_)) => out.push(t),
                other => return Err(self.lexer.error(format!("unexpected {} in a tuple", describe(other)))),
            }
        }
    }

    /// Skips a balanced `{ … }` (next token), counting depth without recursing.
    pub(super) fn skip_braces(&mut self, depth: usize) -> Result<()> {
        self.expect(b'{')?;
        let mut open = 1usize;
        while open > 0 {
            match self.bump()? {
                Tok::Punct(b'{' | b'[' | b'(') => {
                    open += 1;
                    self.depth_check(depth + open)?;
                }
                Tok::Punct(b'}' | b']' | b')') => open -= 1,
                Tok::Eof => return Err(self.lexer.error("unclosed `{`")),
                _ => {}
            }
        }
        Ok(())
    }
}

/// `x` rounded to the nearest IEEE binary16 value (ties to even), as a `half` attribute holds
/// it: 11 significant bits, subnormals below 2⁻¹⁴, infinity from 65520 up.
pub(super) fn to_half_precision(x: f32) -> f32 {
    let a = x.abs() as f64;
    if a == 0.0 || !a.is_finite() {
        return x;
    }
    if a >= 65520.0 {
        return f32::INFINITY.copysign(x);
    }
    // The binary exponent of `a` (a normal f64, since it came from an f32), at least -14.
    let exponent = (((a.to_bits() >> 52) & 0x7ff) as i32 - 1023).max(-14);
    let quantum = 2f64.powi(exponent - 10);
    ((x as f64 / quantum).round_ties_even() * quantum) as f32
}

/// A kept property of a prim.
pub(super) enum Property {
    Attribute(Attribute),
    Relationship(Relationship),
}

/// A relationship target as an absolute prim path: `<../Skel>` and `<Anim>` are relative to
/// the prim `prim` (`/a/b`) that authors the relationship.
pub(super) fn absolute_target(prim: &str, target: &str) -> String {
    if target.starts_with('/') {
        return target.to_owned();
    }
    let mut parts: Vec<&str> = prim.split('/').filter(|p| !p.is_empty()).collect();
    for part in target.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.iter().fold(String::new(), |mut s, p| {
        s.push('/');
        s.push_str(p);
        s
    })
}

/// Adds `attribute` to a prim's attributes; a second declaration of the same attribute (a
/// default beside `.timeSamples`) fills in what it authors.
pub(super) fn merge_attribute(attributes: &mut Vec<Attribute>, attribute: Attribute) {
    match attributes.iter_mut().find(|a| a.name == attribute.name) {
        Some(a) if attribute.samples.is_empty() => {
            a.default = attribute.default;
            a.element_size = attribute.element_size.or(a.element_size);
            a.interpolation = attribute.interpolation.or(a.interpolation.take());
        }
        Some(a) => {
            a.samples = attribute.samples;
            a.element_size = attribute.element_size.or(a.element_size);
            a.interpolation = attribute.interpolation.or(a.interpolation.take());
        }
        None => attributes.push(attribute),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn half_values_round_as_usd_reads_them() {
        use super::to_half_precision as h;
        assert_eq!(h(1.03), 1.0 + 31.0 / 1024.0);
        assert_eq!(h(1.0), 1.0);
        assert_eq!(h(-0.333), -1364.0 / 4096.0);
        assert_eq!(h(65504.0), 65504.0);
        assert_eq!(h(65520.0), f32::INFINITY);
        assert_eq!(h(1e-8), 0.0);
        assert_eq!(h(6e-8), 5.9604645e-8);
        // Just below a power of two rounds up to it.
        assert_eq!(h(0.99999), 1.0);
    }
}
