//! USD in and out, text layers (`.usda`): time-sampled `UsdGeomMesh` prims.
//!
//! **Read** ([`parse_usda`]): every `def Mesh` of the layer (depth-first, in authored order, as
//! `UsdStage::Traverse` visits them; prims under `class`/`over` specs and `active = false` prims
//! are not part of the played-back scene and are skipped) becomes part of one vertex cache, its
//! vertices after those of the meshes before it. From each mesh: `points` (the default value
//! and/or `points.timeSamples`), `faceVertexCounts` / `faceVertexIndices` (polygons fanned into
//! triangles from their first corner) and `orientation` (`leftHanded` faces are flipped, so the
//! triangles keep the right-handed winding the other formats use).
//!
//! Frames are the union of every mesh's time codes, sorted; they must be evenly spaced (the
//! [`Animation`] has one frame rate). A mesh without a sample at a frame's time code is evaluated
//! as USD does (`UsdAttribute::Get(time)`, linear interpolation of equal-length arrays between
//! the samples around it, held before the first and after the last). The frame rate is the
//! layer's `timeCodesPerSecond` (else `framesPerSecond`, else USD's 24) divided by the time-code
//! step, unless [`ReadOptions::frame_rate`](super::ReadOptions::frame_rate) overrides it.
//!
//! What is refused by name rather than read wrongly: composition arcs (`subLayers`,
//! `references`, `payload`, `inherits`, `specializes`, variant sets: flatten the stage first,
//! `usdcat --flatten`), authored transforms (`xformOpOrder`) on a mesh or its ancestors, a
//! time-sampled topology, points whose count changes over time, value clips. Binary crate files
//! (`.usdc`) and packages (`.usdz`) are recognised and refused with the conversion to use
//! (`usdcat in.usdc -o out.usda`): see `docs/notes/issue-29-usd.md` for why.
//!
//! The input is untrusted: nesting is bounded ([`MAX_DEPTH`]), every array is counted against
//! the read's memory budget before it is kept, the cache's size is checked against
//! [`reader_limits`](super::reader_limits) and the budget before it is allocated, and every
//! coordinate must be finite.
//!
//! **Write** ([`encode_usda`]): one `Mesh` prim `/animcodec/mesh` under an `Xform`, triangles as
//! `faceVertexCounts` of 3, `points.timeSamples` at time codes 0, 1, … with
//! `timeCodesPerSecond` = `framesPerSecond` = the animation's frame rate, per-frame `extent`,
//! `upAxis = "Y"`, `metersPerUnit = 1` and `defaultPrim`, so Pixar's compliance checker passes
//! it. Coordinates are written in the shortest decimal form that reads back as the same `f32`,
//! so a round trip is exact.

use std::fmt::Write as _;
use std::path::Path;

use codec_core::{Animation, Error, Result};

use super::gltf_buffers::Budget;
use super::{check_finite_in, in_file, name, read_file, reader_limits};

/// Deepest nesting of prims, lists, tuples and metadata the reader follows: far above real
/// scenes (character rigs nest prims 10–20 deep), far below what would exhaust the stack.
pub const MAX_DEPTH: usize = 256;

/// USD's default `timeCodesPerSecond` (and `framesPerSecond`) when the layer authors none.
pub const USD_DEFAULT_TIME_CODES_PER_SECOND: f64 = 24.0;

/// The USDA header every text layer starts with.
const USDA_MAGIC: &[u8] = b"#usda ";
/// The first bytes of a binary crate file.
const USDC_MAGIC: &[u8] = b"PXR-USDC";
/// The first bytes of a zip archive (a `.usdz` package).
const ZIP_MAGIC: &[u8] = b"PK\x03\x04";

/// Reads a `.usda` / `.usd` file (see the module documentation); `frame_rate` overrides the
/// layer's rate.
pub fn read_usd(path: &Path, frame_rate: Option<f32>) -> Result<Animation> {
    let bytes = read_file(path)?;
    let budget = Budget::new(&name(path), None);
    parse_usd_with(&bytes, &name(path), frame_rate, budget)
}

/// Parses a USD text layer held in memory. `file` names the source in errors; `frame_rate`
/// overrides the layer's; `memory_budget` bounds what the read holds beyond the input (default:
/// the process's read budget, 1 GiB unless `--max-memory` set it).
pub fn parse_usda(bytes: &[u8], file: &str, frame_rate: Option<f32>, memory_budget: Option<u64>) -> Result<Animation> {
    parse_usd_with(bytes, file, frame_rate, Budget::new(file, memory_budget))
}

fn parse_usd_with(bytes: &[u8], file: &str, frame_rate: Option<f32>, mut budget: Budget) -> Result<Animation> {
    if bytes.starts_with(USDC_MAGIC) {
        return Err(unsupported(
            file,
            "a binary USD crate file (usdc): only text layers are read; convert it with \
             `usdcat IN.usdc -o OUT.usda` (usd-core on PyPI)",
        ));
    }
    if bytes.starts_with(ZIP_MAGIC) {
        return Err(unsupported(
            file,
            "a USDZ package: only text layers are read; extract and convert it with \
             `usdcat --flatten IN.usdz -o OUT.usda` (usd-core on PyPI)",
        ));
    }
    if !bytes.starts_with(USDA_MAGIC) {
        return Err(Error::malformed(file.to_owned(), "header", "not a USD text layer (no `#usda` header)"));
    }
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::malformed(file.to_owned(), "text", format!("not UTF-8 (byte {})", e.valid_up_to())))?;
    let mut parser = Parser { lexer: Lexer { text, pos: 0, file }, peeked: None, budget: &mut budget, prim_depth: 0 };
    let layer = parser.layer()?;
    assemble(file, layer, frame_rate, &mut budget)
}

fn unsupported(file: &str, detail: impl Into<String>) -> Error {
    Error::Unsupported { context: file.to_owned().into(), detail: detail.into() }
}

// ---------------------------------------------------------------------------------------------
// Lexer

#[derive(Debug, Clone, Copy, PartialEq)]
enum Tok<'a> {
    /// `( ) [ ] { } = , : ;` and `<`…`>` paths come as their own kinds.
    Punct(u8),
    /// Identifiers and keywords, with `:` namespaces and a `.timeSamples`-style suffix
    /// (`primvars:st`, `points.timeSamples`); also `inf`, `nan`, `None`.
    Ident(&'a str),
    /// A number as written (parsed later as `f32` or an integer, never through `f64`, so a
    /// coordinate reads back exactly).
    Number(&'a str),
    /// A string's content (escapes are kept as written: only names and tokens are compared).
    Str(&'a str),
    /// `@asset@` or `<path>`: kept as text, never resolved.
    Other(&'a str),
    Eof,
}

struct Lexer<'a> {
    text: &'a str,
    pos: usize,
    file: &'a str,
}

impl<'a> Lexer<'a> {
    fn line(&self) -> usize {
        self.text.as_bytes()[..self.pos.min(self.text.len())].iter().filter(|&&b| b == b'\n').count() + 1
    }

    fn error(&self, detail: impl Into<String>) -> Error {
        Error::malformed(self.file.to_owned(), format!("line {}", self.line()), detail)
    }

    fn next(&mut self) -> Result<Tok<'a>> {
        let b = self.text.as_bytes();
        // Whitespace and `#` comments (the header line is consumed before the first token).
        loop {
            while self.pos < b.len() && b[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if self.pos < b.len() && b[self.pos] == b'#' {
                while self.pos < b.len() && b[self.pos] != b'\n' {
                    self.pos += 1;
                }
                continue;
            }
            break;
        }
        if self.pos >= b.len() {
            return Ok(Tok::Eof);
        }
        let start = self.pos;
        let c = b[start];
        match c {
            b'(' | b')' | b'[' | b']' | b'{' | b'}' | b'=' | b',' | b':' | b';' => {
                self.pos += 1;
                Ok(Tok::Punct(c))
            }
            b'"' | b'\'' => self.string(c),
            b'@' => {
                // `@path@`, or `@@@path@@@` when the path holds `@`.
                let delim = if self.text[start..].starts_with("@@@") { "@@@" } else { "@" };
                let body = start + delim.len();
                match self.text[body..].find(delim) {
                    Some(end) => {
                        self.pos = body + end + delim.len();
                        Ok(Tok::Other(&self.text[body..body + end]))
                    }
                    None => Err(self.error("unterminated asset path")),
                }
            }
            b'<' => match self.text[start..].find('>') {
                Some(end) => {
                    self.pos = start + end + 1;
                    Ok(Tok::Other(&self.text[start + 1..start + end]))
                }
                None => Err(self.error("unterminated path `<…>`")),
            },
            b'-' | b'+' | b'.' | b'0'..=b'9' => {
                self.pos += 1;
                while self.pos < b.len()
                    && (b[self.pos].is_ascii_alphanumeric() || matches!(b[self.pos], b'.' | b'-' | b'+' | b'_'))
                {
                    // `1e-5`: a sign only right after an exponent mark.
                    if matches!(b[self.pos], b'-' | b'+') && !matches!(b[self.pos - 1], b'e' | b'E') {
                        break;
                    }
                    self.pos += 1;
                }
                Ok(Tok::Number(&self.text[start..self.pos]))
            }
            c if c.is_ascii_alphabetic() || c == b'_' || c >= 0x80 => {
                self.pos += 1;
                while self.pos < b.len()
                    && (b[self.pos].is_ascii_alphanumeric()
                        || matches!(b[self.pos], b'_' | b':' | b'.')
                        || b[self.pos] >= 0x80)
                {
                    self.pos += 1;
                }
                // A namespace separator never ends a name (`0: [...]` uses `:` after a number).
                while self.pos > start + 1 && b[self.pos - 1] == b':' {
                    self.pos -= 1;
                }
                if !self.text.is_char_boundary(self.pos) {
                    return Err(self.error("invalid identifier"));
                }
                Ok(Tok::Ident(&self.text[start..self.pos]))
            }
            _ => {
                Err(self.error(format!("unexpected character {:?}", self.text[start..].chars().next().unwrap_or('?'))))
            }
        }
    }

    fn string(&mut self, quote: u8) -> Result<Tok<'a>> {
        let b = self.text.as_bytes();
        let start = self.pos;
        let triple = b.len() >= start + 3 && b[start + 1] == quote && b[start + 2] == quote;
        let open = if triple { 3 } else { 1 };
        let mut i = start + open;
        while i < b.len() {
            match b[i] {
                b'\\' => i += 2,
                b'\n' if !triple => return Err(self.error("newline inside a string")),
                c if c == quote => {
                    if !triple {
                        self.pos = i + 1;
                        return Ok(Tok::Str(&self.text[start + 1..i]));
                    }
                    if b.len() >= i + 3 && b[i + 1] == quote && b[i + 2] == quote {
                        self.pos = i + 3;
                        return Ok(Tok::Str(&self.text[start + 3..i]));
                    }
                    i += 1;
                }
                _ => i += 1,
            }
        }
        Err(self.error("unterminated string"))
    }
}

// ---------------------------------------------------------------------------------------------
// Parser: a layer's prims and the few attributes a vertex cache needs; everything else is
// parsed (so a syntax error is an error) and dropped.

/// A value as far as this reader needs it.
#[derive(Debug, Clone, PartialEq)]
enum Value<'a> {
    /// A number, identifier or string.
    Atom(Tok<'a>),
    /// `[a, b, …]` of atoms or of tuples, flattened: `arity` is the tuple size (0: atoms).
    Array { items: Vec<Tok<'a>>, arity: usize },
    /// Anything else (dictionaries, tuples, nested lists): parsed and dropped.
    Other,
}

/// Time samples of one attribute: time code (as written) → value (`None` = a blocked sample).
type Samples<'a> = Vec<(f64, Option<Value<'a>>)>;

#[derive(Default)]
struct MeshSpec<'a> {
    path: String,
    points: Option<Value<'a>>,
    point_samples: Samples<'a>,
    counts: Option<Value<'a>>,
    indices: Option<Value<'a>>,
    left_handed: bool,
}

#[derive(Default)]
struct Layer<'a> {
    time_codes_per_second: Option<f64>,
    frames_per_second: Option<f64>,
    meshes: Vec<MeshSpec<'a>>,
}

struct Parser<'a, 'b> {
    lexer: Lexer<'a>,
    peeked: Option<Tok<'a>>,
    budget: &'b mut Budget,
    /// Prims open around the current token (for the nesting error).
    prim_depth: usize,
}

/// Layer or prim metadata that brings in other layers or prims: not composed here.
const COMPOSITION_ARCS: &[&str] = &["subLayers", "references", "payload", "inherits", "specializes", "clips"];

impl<'a> Parser<'a, '_> {
    fn peek(&mut self) -> Result<Tok<'a>> {
        if self.peeked.is_none() {
            self.peeked = Some(self.lexer.next()?);
        }
        Ok(self.peeked.unwrap_or(Tok::Eof))
    }

    fn bump(&mut self) -> Result<Tok<'a>> {
        match self.peeked.take() {
            Some(t) => Ok(t),
            None => self.lexer.next(),
        }
    }

    fn expect(&mut self, punct: u8) -> Result<()> {
        match self.bump()? {
            Tok::Punct(p) if p == punct => Ok(()),
            other => Err(self.lexer.error(format!("expected `{}`, found {}", punct as char, describe(other)))),
        }
    }

    fn eat(&mut self, punct: u8) -> Result<bool> {
        if self.peek()? == Tok::Punct(punct) {
            self.bump()?;
            return Ok(true);
        }
        Ok(false)
    }

    fn depth_check(&self, depth: usize) -> Result<()> {
        if depth > MAX_DEPTH {
            // `depth` counts every nesting level, not only prims: say so, with both counts
            // (issue 41: 254 nested prims were refused as "nested more than 256 deep").
            return Err(self.lexer.error(format!(
                "nested {depth} levels deep, past the limit of {MAX_DEPTH} levels ({} of them nested prims; every \
                 prim, metadata block, property, dictionary, list and tuple is one level)",
                self.prim_depth
            )));
        }
        Ok(())
    }

    fn layer(&mut self) -> Result<Layer<'a>> {
        // The header line: `#usda 1.0`.
        let header_end = self.lexer.text.find('\n').unwrap_or(self.lexer.text.len());
        let version = self.lexer.text[USDA_MAGIC.len()..header_end].trim();
        if !version.starts_with("1.") {
            return Err(unsupported(self.lexer.file, format!("USDA version {version:?} (1.x is read)")));
        }
        self.lexer.pos = header_end;
        let mut layer = Layer::default();
        if self.eat(b'(')? {
            self.metadata(1, &mut |key, value| {
                let number = |v: &Value| match v {
                    Value::Atom(Tok::Number(n)) => n.parse::<f64>().ok(),
                    _ => None,
                };
                match key {
                    "timeCodesPerSecond" => layer.time_codes_per_second = number(value),
                    "framesPerSecond" => layer.frames_per_second = number(value),
                    _ => {}
                }
                Ok(())
            })?;
        }
        let mut path = String::new();
        loop {
            match self.peek()? {
                Tok::Eof => break,
                _ => self.prim(1, &mut path, true, false, &mut layer.meshes)?,
            }
        }
        Ok(layer)
    }

    /// `key = value` entries (with an optional list-op keyword, or a lone doc string) up to the
    /// closing `)`; the opening `(` is consumed. Composition arcs are refused.
    fn metadata(&mut self, depth: usize, on_entry: &mut dyn FnMut(&str, &Value<'a>) -> Result<()>) -> Result<()> {
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
                                 (`usdcat --flatten IN -o OUT.usda`)",
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
    fn eat_brackets(&mut self) -> Result<bool> {
        if self.eat(b'[')? {
            self.expect(b']')?;
            return Ok(true);
        }
        Ok(false)
    }

    /// One prim spec (`def|over|class [Type] "name" [(metadata)] { … }`), with its children.
    /// `live`: the prim is part of the played-back scene (a `def` under `def`s only, active).
    /// `transformed`: an ancestor authors transforms.
    fn prim(
        &mut self,
        depth: usize,
        path: &mut String,
        live: bool,
        transformed: bool,
        meshes: &mut Vec<MeshSpec<'a>>,
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
        if self.eat(b'(')? {
            self.metadata(depth + 1, &mut |key, value| {
                if key == "active" && matches!(value, Value::Atom(Tok::Ident("false")) | Value::Atom(Tok::Number("0")))
                {
                    active = false;
                }
                Ok(())
            })?;
        }
        let parent_len = path.len();
        path.push('/');
        path.push_str(prim_name);
        let live = live && active && specifier == "def";
        // The path is cloned only for a mesh that is kept (counted below): a clone per prim
        // held down the whole nesting cost the sum of every prefix (issue 41: 250 nested prims
        // with 80 000-character names, a 20 MB layer, held 2.5 GB).
        let mut mesh = MeshSpec::default();
        let mut transforms = false;
        let mut children: Vec<MeshSpec<'a>> = Vec::new();
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
                Tok::Ident("def" | "over" | "class") => {
                    self.prim(depth + 1, path, live, transformed || transforms, &mut children)?
                }
                Tok::Ident("variantSet") => {
                    return Err(unsupported(
                        self.lexer.file,
                        format!(
                            "a variant set in {} at line {}: variants are not resolved here; flatten the stage \
                             first (`usdcat --flatten IN -o OUT.usda`)",
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
                _ => self.property(depth + 1, path, &mut mesh, &mut transforms)?,
            }
        }
        let is_mesh = live && type_name == Some("Mesh");
        if is_mesh {
            self.budget.take("prim paths", path.len() as u64)?;
            mesh.path = path.clone();
        }
        path.truncate(parent_len);
        self.prim_depth -= 1;
        if is_mesh && (transformed || transforms) {
            return Err(unsupported(
                self.lexer.file,
                format!(
                    "the mesh {} is under authored transforms (xformOpOrder): they are not applied here; \
                     bake them into the points first",
                    shown(&mesh.path)
                ),
            ));
        }
        if is_mesh {
            meshes.push(mesh);
        }
        if live {
            meshes.append(&mut children);
        }
        Ok(())
    }

    /// One property: `[custom] [uniform|varying|config] Type[[]] name[.timeSamples|.connect|
    /// .spline] [= value] [(metadata)]`, or `rel name [= targets]`.
    fn property(&mut self, depth: usize, path: &str, mesh: &mut MeshSpec<'a>, transforms: &mut bool) -> Result<()> {
        let mut tok = self.bump()?;
        while matches!(
            tok,
            Tok::Ident("custom" | "uniform" | "varying" | "config" | "add" | "append" | "prepend" | "delete")
        ) {
            tok = self.bump()?;
        }
        let is_rel = tok == Tok::Ident("rel");
        if !matches!(tok, Tok::Ident(_)) {
            return Err(self.lexer.error(format!("expected a property, found {}", describe(tok))));
        }
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
        if self.eat(b'=')? {
            if suffix == "timeSamples" {
                let samples = self.time_samples(depth + 1)?;
                match prop {
                    "points" => mesh.point_samples = samples,
                    "faceVertexCounts" | "faceVertexIndices" => {
                        if samples.len() > 1 {
                            return Err(unsupported(
                                self.lexer.file,
                                format!(
                                    "{}.{prop} is time-sampled: a changing topology is not a vertex cache",
                                    shown(path)
                                ),
                            ));
                        }
                        if let Some((_, v)) = samples.into_iter().next() {
                            if prop == "faceVertexCounts" {
                                mesh.counts = v;
                            } else {
                                mesh.indices = v;
                            }
                        }
                    }
                    p if p.starts_with("xformOp") => *transforms = true,
                    _ => {}
                }
            } else if suffix == "spline" {
                self.skip_braces(depth + 1)?;
                if prop == "points" || prop.starts_with("xformOp") {
                    return Err(unsupported(self.lexer.file, format!("spline-valued `{prop}`")));
                }
            } else {
                let value = self.value(depth + 1)?;
                // `= None`: a blocked default, no value.
                let blocked = value == Value::Atom(Tok::Ident("None"));
                if (suffix.is_empty() || suffix == "default") && !blocked {
                    match prop {
                        "points" => mesh.points = Some(value),
                        "faceVertexCounts" => mesh.counts = Some(value),
                        "faceVertexIndices" => mesh.indices = Some(value),
                        "orientation" => mesh.left_handed = value == Value::Atom(Tok::Str("leftHanded")),
                        "xformOpOrder" => {
                            if matches!(&value, Value::Array { items, .. } if !items.is_empty()) {
                                *transforms = true;
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
        if self.eat(b'(')? {
            self.metadata(depth + 1, &mut |_, _| Ok(()))?;
        }
        Ok(())
    }

    /// `{ time: value, … }` (the `{` not yet consumed).
    fn time_samples(&mut self, depth: usize) -> Result<Samples<'a>> {
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
                    self.budget.take("time samples", std::mem::size_of::<(f64, Option<Value>)>() as u64)?;
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
    fn value(&mut self, depth: usize) -> Result<Value<'a>> {
        self.depth_check(depth)?;
        match self.bump()? {
            Tok::Punct(b'[') => self.list(depth + 1),
            Tok::Punct(b'(') => {
                self.tuple(depth + 1, &mut Vec::new())?;
                Ok(Value::Other)
            }
            Tok::Punct(b'{') => {
                self.peeked = Some(Tok::Punct(b'{'));
                self.skip_braces(depth)?;
                Ok(Value::Other)
            }
            t @ (Tok::Number(_) | Tok::Ident(_) | Tok::Str(_) | Tok::Other(_)) => Ok(Value::Atom(t)),
            other => Err(self.lexer.error(format!("expected a value, found {}", describe(other)))),
        }
    }

    /// The items of `[ … ]` (the `[` consumed).
    fn list(&mut self, depth: usize) -> Result<Value<'a>> {
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
            return Ok(Value::Other);
        }
        Ok(Value::Array { items, arity: arity.unwrap_or(0) })
    }

    /// The atoms of `( … )` (the `(` consumed) appended to `out`; nested tuples are flattened.
    fn tuple(&mut self, depth: usize, out: &mut Vec<Tok<'a>>) -> Result<()> {
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
    fn skip_braces(&mut self, depth: usize) -> Result<()> {
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

fn describe(tok: Tok) -> String {
    match tok {
        Tok::Punct(p) => format!("`{}`", p as char),
        Tok::Ident(s) | Tok::Number(s) => {
            format!("`{}`", super::gltf::printable(&s.chars().take(40).collect::<String>()))
        }
        Tok::Str(_) => "a string".into(),
        Tok::Other(_) => "a path or asset".into(),
        Tok::Eof => "the end of the file".into(),
    }
}

// ---------------------------------------------------------------------------------------------
// From the parsed layer to an animation.

/// One mesh's topology and point samples, converted.
struct MeshData {
    vertices: usize,
    triangles: Vec<[u32; 3]>,
    /// Sorted by time: (time code, points); empty when only the default value exists.
    samples: Vec<(f64, Vec<f32>)>,
    default: Option<Vec<f32>>,
}

fn assemble(file: &str, layer: Layer, frame_rate: Option<f32>, budget: &mut Budget) -> Result<Animation> {
    if layer.meshes.is_empty() {
        return Err(Error::malformed(file.to_owned(), "meshes", "the layer defines no Mesh prim"));
    }
    let mut meshes = Vec::with_capacity(layer.meshes.len());
    for spec in &layer.meshes {
        meshes.push(mesh_data(file, spec, budget)?);
    }
    // The frame times: every sample time of every mesh.
    let mut times: Vec<f64> = meshes.iter().flat_map(|m| m.samples.iter().map(|s| s.0)).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let step = match times.len() {
        0 | 1 => 1.0,
        _ => (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64,
    };
    for w in times.windows(2) {
        if ((w[1] - w[0]) - step).abs() > step * 1e-6 {
            return Err(unsupported(
                file,
                format!(
                    "the time samples are not evenly spaced (codes {} and {} against a mean step of {step}): a \
                     vertex cache has one frame rate; resample the points first",
                    w[0], w[1]
                ),
            ));
        }
    }
    if times.is_empty() {
        times.push(0.0);
    }
    let vertices: usize = meshes.iter().map(|m| m.vertices).sum();
    let limits = reader_limits();
    if vertices as u64 > limits.max_vertices as u64 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "vertex_count".into(),
            value: vertices as u64,
            limit: limits.max_vertices as u64,
        });
    }
    if times.len() as u64 > limits.max_frames as u64 {
        return Err(Error::LimitExceeded {
            context: file.to_owned().into(),
            field: "frame_count".into(),
            value: times.len() as u64,
            limit: limits.max_frames as u64,
        });
    }
    let floats = (vertices as u64).saturating_mul(3).saturating_mul(times.len() as u64);
    limits.check_alloc("formats", "positions", floats.saturating_mul(4))?;
    budget.take("positions", floats.saturating_mul(4))?;
    let mut positions = Vec::with_capacity(floats as usize);
    for &t in &times {
        for m in &meshes {
            push_points_at(m, t, &mut positions);
        }
    }
    let mut triangles = Vec::with_capacity(meshes.iter().map(|m| m.triangles.len()).sum());
    let mut offset = 0u32;
    for m in &meshes {
        triangles.extend(m.triangles.iter().map(|t| t.map(|i| i + offset)));
        offset += m.vertices as u32;
    }
    check_finite_in(file, &positions, vertices)?;
    let tcps = layer.time_codes_per_second.or(layer.frames_per_second).unwrap_or(USD_DEFAULT_TIME_CODES_PER_SECOND);
    let fps = match frame_rate {
        Some(f) => f,
        None => {
            let fps = (tcps / step) as f32;
            super::check_frame_rate(fps).map_err(|e| in_file(file, e))?
        }
    };
    Animation::from_parts(vertices, triangles, positions, fps).map_err(|e| in_file(file, e))
}

/// Points of `mesh` at time code `t`, as `UsdAttribute::Get(t)` gives them: the sample at
/// `t`, else linear interpolation between the samples around it, held outside them; the
/// default value when the mesh has no samples.
fn push_points_at(mesh: &MeshData, t: f64, out: &mut Vec<f32>) {
    let s = &mesh.samples;
    if s.is_empty() {
        out.extend_from_slice(mesh.default.as_deref().unwrap_or(&[]));
        return;
    }
    let after = s.partition_point(|x| x.0 < t);
    if after < s.len() && s[after].0 == t {
        out.extend_from_slice(&s[after].1);
    } else if after == 0 {
        out.extend_from_slice(&s[0].1);
    } else if after == s.len() {
        out.extend_from_slice(&s[s.len() - 1].1);
    } else {
        let (t0, a) = (&s[after - 1].0, &s[after - 1].1);
        let (t1, b) = (&s[after].0, &s[after].1);
        let alpha = (t - t0) / (t1 - t0);
        out.extend(a.iter().zip(b).map(|(&x, &y)| (x as f64 + (y as f64 - x as f64) * alpha) as f32));
    }
}

/// A prim path for a message: printable, and at most 200 characters (the middle elided), since
/// a path may be megabytes long.
fn shown(path: &str) -> String {
    const KEEP: usize = 100;
    let chars = path.chars().count();
    if chars <= 2 * KEEP {
        return super::gltf::printable(path);
    }
    let head: String = path.chars().take(KEEP).collect();
    let tail: String = path.chars().skip(chars - KEEP).collect();
    format!("{}…({} characters)…{}", super::gltf::printable(&head), chars - 2 * KEEP, super::gltf::printable(&tail))
}

fn mesh_data(file: &str, spec: &MeshSpec, budget: &mut Budget) -> Result<MeshData> {
    let at = |what: &str| format!("{} {what}", shown(&spec.path));
    let bad = |field: String, detail: String| Error::malformed(file.to_owned(), field, detail);
    let floats = |value: &Value, field: &str, budget: &mut Budget| -> Result<Vec<f32>> {
        match value {
            Value::Array { items, arity: 3 } => {
                budget.take("points", items.len() as u64 * 4)?;
                items
                    .iter()
                    .map(|t| match t {
                        Tok::Number(n) => n.parse::<f32>().ok(),
                        Tok::Ident(i) => i.parse::<f32>().ok(),
                        _ => None,
                    })
                    .collect::<Option<Vec<f32>>>()
                    .ok_or_else(|| bad(at(field), "holds a value that is not a number".into()))
            }
            Value::Array { items, .. } if items.is_empty() => Ok(Vec::new()),
            _ => Err(bad(at(field), "is not a list of 3-component points".into())),
        }
    };
    let ints = |value: Option<&Value>, field: &str| -> Result<Vec<u32>> {
        match value {
            Some(Value::Array { items, arity: 0 }) => items
                .iter()
                .map(|t| match t {
                    Tok::Number(n) => n.parse::<u32>().ok(),
                    _ => None,
                })
                .collect::<Option<Vec<u32>>>()
                .ok_or_else(|| bad(at(field), "holds a value that is not a non-negative integer".into())),
            Some(_) => Err(bad(at(field), "is not a list of integers".into())),
            None => Err(bad(at(field), "is missing".into())),
        }
    };
    let default = spec.points.as_ref().map(|v| floats(v, "points", budget)).transpose()?;
    let mut samples = Vec::with_capacity(spec.point_samples.len());
    for (time, value) in &spec.point_samples {
        // A blocked sample (`None`) has no points: USD reports no value there; the frame is
        // filled from the samples around it, as for a time the mesh does not sample.
        if let Some(v) = value {
            samples.push((*time, floats(v, "points.timeSamples", budget)?));
        }
    }
    let first = samples.first().map(|s| &s.1).or(default.as_ref());
    let Some(first) = first else {
        return Err(bad(at("points"), "has no value (neither a default nor a time sample)".into()));
    };
    let vertices = first.len() / 3;
    if vertices == 0 {
        return Err(bad(at("points"), "is empty".into()));
    }
    for (time, s) in &samples {
        if s.len() != first.len() {
            return Err(unsupported(
                file,
                format!(
                    "{} has {} points at time code {time} but {vertices} at the first sample: a changing point count \
                     is not a vertex cache",
                    at("points"),
                    s.len() / 3
                ),
            ));
        }
    }
    let counts = ints(spec.counts.as_ref(), "faceVertexCounts")?;
    let indices = ints(spec.indices.as_ref(), "faceVertexIndices")?;
    let corners: u64 = counts.iter().map(|&c| c as u64).sum();
    if corners != indices.len() as u64 {
        return Err(bad(
            at("faceVertexCounts"),
            format!("sums to {corners} corners but faceVertexIndices holds {}", indices.len()),
        ));
    }
    if let Some(&i) = indices.iter().find(|&&i| i as usize >= vertices) {
        return Err(bad(at("faceVertexIndices"), format!("index {i} is out of range ({vertices} points)")));
    }
    let fan: u64 = counts.iter().map(|&c| (c as u64).saturating_sub(2)).sum();
    budget.take("triangles", fan * 12)?;
    let mut triangles = Vec::with_capacity(fan as usize);
    let mut at_corner = 0usize;
    for (face, &n) in counts.iter().enumerate() {
        let n = n as usize;
        if n < 3 {
            return Err(bad(at("faceVertexCounts"), format!("face {face} has {n} corners (at least 3 are needed)")));
        }
        let f = &indices[at_corner..at_corner + n];
        for k in 1..n - 1 {
            let tri = if spec.left_handed { [f[0], f[k + 1], f[k]] } else { [f[0], f[k], f[k + 1]] };
            triangles.push(tri);
        }
        at_corner += n;
    }
    Ok(MeshData { vertices, triangles, samples, default })
}

// ---------------------------------------------------------------------------------------------
// Writer

/// Writes `value` in the shortest decimal form that reads back as the same `f32` (Rust's
/// `Display`/`LowerExp` for `f32` are shortest-round-trip), in exponent form outside
/// [1e-4, 1e7] so huge and tiny values stay short.
fn push_f32(out: &mut String, value: f32) {
    let a = value.abs();
    if a == 0.0 || (1e-4..1e7).contains(&a) {
        let _ = write!(out, "{value}");
    } else {
        let _ = write!(out, "{value:e}");
    }
}

/// A USD text layer holding `animation` (see the module documentation).
pub fn encode_usda(animation: &Animation) -> Result<Vec<u8>> {
    let fps = animation.frame_rate();
    let (v, f) = (animation.vertex_count(), animation.frame_count());
    let tris = animation.triangles();
    // About 3 × 12 characters per vertex and frame.
    let mut s = String::with_capacity(64 + tris.len() * 16 + v * f * 40);
    let mut rate = String::new();
    push_f32(&mut rate, fps);
    let _ = write!(
        s,
        "#usda 1.0\n(\n    defaultPrim = \"animcodec\"\n    doc = \"animcodec vertex cache: {v} vertices, {f} frames\"\n    \
         endTimeCode = {}\n    framesPerSecond = {rate}\n    metersPerUnit = 1\n    startTimeCode = 0\n    \
         timeCodesPerSecond = {rate}\n    upAxis = \"Y\"\n)\n\n",
        f - 1
    );
    s.push_str("def Xform \"animcodec\" (\n    kind = \"component\"\n)\n{\n    def Mesh \"mesh\"\n    {\n");
    s.push_str("        float3[] extent.timeSamples = {\n");
    for t in 0..f {
        let frame = animation.frame(t);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in frame.chunks_exact(3) {
            for ((l, h), &x) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
                *l = l.min(x);
                *h = h.max(x);
            }
        }
        let _ = write!(s, "            {t}: [(");
        for (k, x) in lo.iter().enumerate() {
            if k > 0 {
                s.push_str(", ");
            }
            push_f32(&mut s, *x);
        }
        s.push_str("), (");
        for (k, x) in hi.iter().enumerate() {
            if k > 0 {
                s.push_str(", ");
            }
            push_f32(&mut s, *x);
        }
        s.push_str(")],\n");
    }
    s.push_str("        }\n        int[] faceVertexCounts = [");
    for i in 0..tris.len() {
        s.push_str(if i == 0 { "3" } else { ", 3" });
    }
    s.push_str("]\n        int[] faceVertexIndices = [");
    for (i, t) in tris.iter().enumerate() {
        let _ = write!(s, "{}{}, {}, {}", if i == 0 { "" } else { ", " }, t[0], t[1], t[2]);
    }
    s.push_str("]\n        point3f[] points.timeSamples = {\n");
    for t in 0..f {
        let _ = write!(s, "            {t}: [");
        for (i, p) in animation.frame(t).chunks_exact(3).enumerate() {
            s.push_str(if i == 0 { "(" } else { ", (" });
            push_f32(&mut s, p[0]);
            s.push_str(", ");
            push_f32(&mut s, p[1]);
            s.push_str(", ");
            push_f32(&mut s, p[2]);
            s.push(')');
        }
        s.push_str("],\n");
    }
    s.push_str("        }\n        uniform token subdivisionScheme = \"none\"\n    }\n}\n");
    Ok(s.into_bytes())
}

/// A layer about to be written must read back (with [`parse_usda`]) as exactly `animation`:
/// the same triangles and every coordinate bit for bit. A layer that does not is never written.
pub(super) fn check_reads_back(path: &Path, bytes: &[u8], animation: &Animation) -> Result<()> {
    let back = parse_usda(bytes, &name(path), Some(animation.frame_rate()), Some(u64::MAX))
        .map_err(|e| Error::InvalidAnimation(format!("the USD layer written does not read back: {e}")))?;
    let same = back.triangles() == animation.triangles()
        && back.positions().len() == animation.positions().len()
        && back.positions().iter().zip(animation.positions()).all(|(a, b)| a.to_bits() == b.to_bits());
    if !same {
        return Err(Error::InvalidAnimation(format!(
            "{}: the USD layer written does not read back as the same positions and triangles",
            name(path)
        )));
    }
    Ok(())
}

/// Extensions read and written as USD text layers.
pub(super) fn is_usd_extension(ext: &str) -> bool {
    matches!(ext, "usda" | "usd" | "usdc" | "usdz")
}

/// A sorted map, so tests can compare sample sets; used by the tests only.
#[cfg(test)]
fn times_of(animation_text: &str) -> std::collections::BTreeMap<String, usize> {
    let mut m = std::collections::BTreeMap::new();
    for line in animation_text.lines() {
        if let Some((t, _)) = line.trim().split_once(": [") {
            *m.entry(t.to_owned()).or_insert(0) += 1;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::{assert_same_geometry, test_animation};

    fn parse(text: &str) -> Result<Animation> {
        parse_usda(text.as_bytes(), "t.usda", None, None)
    }

    #[test]
    fn written_layers_read_back_bit_exact() {
        for (v, f, fps) in [(7, 5, 25.0), (3, 1, 30.0), (40, 3, 29.97)] {
            let anim = test_animation(v, f, fps);
            let bytes = encode_usda(&anim).unwrap();
            let back = parse_usda(&bytes, "rt.usda", None, None).unwrap();
            assert_same_geometry(&anim, &back);
            assert_eq!(back.frame_rate(), fps);
            let text = String::from_utf8(bytes).unwrap();
            // One `extent` and one `points` sample per frame.
            assert!(times_of(&text).values().all(|&n| n == 2), "{:?}", times_of(&text));
        }
    }

    const QUAD: &str = r#"#usda 1.0
(
    timeCodesPerSecond = 48
    framesPerSecond = 24
    doc = """a "quoted" doc
over two lines"""
    customLayerData = {
        string note = "{ [ ( ignored"
        dictionary nested = { int x = 3 }
    }
)

class "Proto" { def Mesh "ignored" { point3f[] points = [(1,2,3)] } }

def Scope "world" (
    prepend apiSchemas = ["SomeAPI"]
)
{
    def Mesh "quad" (kind = "component")
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token orientation = "leftHanded"
        point3f[] points.timeSamples = {
            0: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
            4: [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1e0)],
        }
        color3f[] primvars:displayColor = [(1, 0, 0)] (interpolation = "constant")
        rel material:binding = </world/mat>
    }
    def Mesh "tri" (active = true)
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 2, 1]
        point3f[] points = [(-1.5, 2.25, -0), (3, 4, 5), (6, 7, 8)]
        point3f[] points.timeSamples = {
            0: [(0, 0, 0), (0, 0, 0), (0, 0, 0)],
            8: [(8, 8, 8), (8, 8, 8), (8, 8, 8)],
        }
    }
    def Mesh "off" (active = false) { point3f[] points = [(1,2,3)] }
}
"#;

    #[test]
    fn meshes_samples_polygons_and_rates_are_read_as_usd_plays_them() {
        let a = parse(QUAD).unwrap();
        assert_eq!(a.vertex_count(), 7);
        // Times 0, 4, 8 at 48 codes per second: step 4 → 12 fps.
        assert_eq!(a.frame_count(), 3);
        assert_eq!(a.frame_rate(), 12.0);
        // The quad fanned and flipped (left-handed), the triangle after it, offset by 4.
        assert_eq!(a.triangles(), &[[0, 2, 1], [0, 3, 2], [4, 6, 5]]);
        // The quad holds its last sample at time 8; the triangle is interpolated at time 4.
        assert_eq!(&a.frame(2)[..12], &[0., 0., 1., 1., 0., 1., 1., 1., 1., 0., 1., 1.]);
        assert_eq!(&a.frame(1)[12..15], &[4., 4., 4.]);
        assert_eq!(parse_usda(QUAD.as_bytes(), "t", Some(30.0), None).unwrap().frame_rate(), 30.0);
    }

    #[test]
    fn unsupported_and_malformed_layers_are_named() {
        let cases: &[(&str, &str)] = &[
            ("PXR-USDC\0\0\0\0", "usdcat"),
            ("PK\x03\x04rest", "USDZ"),
            ("hello", "#usda"),
            ("#usda 1.0\n(\n subLayers = [@a.usda@]\n)\n", "subLayers"),
            ("#usda 1.0\ndef Xform \"a\" (references = @b.usda@) {}\n", "references"),
            ("#usda 1.0\ndef Xform \"a\" { double3 xformOp:translate = (1, 2, 3)\n uniform token[] xformOpOrder = [\"xformOp:translate\"]\n def Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] } }\n", "xformOpOrder"),
            ("#usda 1.0\ndef Xform \"a\" {}\n", "no Mesh"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,3] }\n", "out of range"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0)]\n int[] faceVertexCounts = [2]\n int[] faceVertexIndices = [0,1] }\n", "at least 3"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points.timeSamples = { 0: [(0,0,0)], 1: [(0,0,0),(1,1,1)] }\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n", "changing point count"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points.timeSamples = { 0: [(0,0,0)], 1: [(1,0,0)], 3: [(2,0,0)] }\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n", "evenly spaced"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,nan)]\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n", "t.usda"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0)\n", "line"),
            ("#usda 2.0\n", "version"),
        ];
        for (text, needle) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text:?}: {e}");
        }
        let deep =
            format!("#usda 1.0\ndef Mesh \"m\" {{ int[] x = {}{} }}\n", "[".repeat(100_000), "]".repeat(100_000));
        assert!(parse(&deep).unwrap_err().to_string().contains("nested"));
        let deep = format!("#usda 1.0\n{}", "def \"a\" {".repeat(100_000));
        assert!(parse(&deep).unwrap_err().to_string().contains("nested"));
    }

    /// Issue 41 (misc): the nesting error counts levels, not prims; it says so, with both.
    #[test]
    fn the_nesting_error_states_the_levels_and_prims_counted() {
        let mesh = "def Mesh \"m\" { point3f[] points.timeSamples = { 0: [(0,0,0),(1,0,0),(0,1,0)] }\n int[] \
                    faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] }\n";
        let nested = |n: usize| format!("#usda 1.0\n{}{mesh}{}", "def Xform \"x\" {\n".repeat(n), "}\n".repeat(n));
        let e = parse(&nested(254)).unwrap_err().to_string();
        assert!(e.contains("nested 257 levels deep, past the limit of 256 levels (255 of them nested prims"), "{e}");
        // A shallower one reads.
        assert_eq!(parse(&nested(250)).unwrap().vertex_count(), 3);
    }

    /// Issue 41 (usd-deepnames): every prim cloned its whole path, so nested long names cost
    /// the sum of every prefix (2.5 GB for a 20 MB layer). Only a kept mesh's path is held, and
    /// it is counted against the budget.
    #[test]
    fn long_prim_paths_are_counted_once() {
        let name = "n".repeat(10_000);
        let mut text = String::from("#usda 1.0\n");
        for k in 0..50 {
            let _ = writeln!(text, "def Xform \"{name}{k}\" {{");
        }
        text += "def Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] \
                 faceVertexIndices = [0,1,2] }\n";
        text += &"}\n".repeat(50);
        // The mesh path is 500 000 characters: a budget below it refuses, naming it...
        let e = parse_usda(text.as_bytes(), "p.usda", None, Some(400_000)).unwrap_err().to_string();
        assert!(e.contains("prim paths") && e.contains("--max-memory"), "{e}");
        // ... one above it reads (the 50 prefixes alone were 12.75 MB).
        assert_eq!(parse_usda(text.as_bytes(), "p.usda", None, Some(2_000_000)).unwrap().vertex_count(), 3);
        // Messages elide the middle of a long path.
        let e = parse(&text.replace("int[] faceVertexIndices = [0,1,2]", "int[] faceVertexIndices = [0,1,7]"))
            .unwrap_err()
            .to_string();
        assert!(e.len() < 1000 && e.contains("characters)"), "{} bytes: {}", e.len(), &e[..e.len().min(300)]);
    }

    #[test]
    fn the_budget_bounds_the_read() {
        let anim = test_animation(50, 20, 24.0);
        let bytes = encode_usda(&anim).unwrap();
        let e = parse_usda(&bytes, "b.usda", None, Some(10_000)).unwrap_err().to_string();
        assert!(e.contains("total memory"), "{e}");
        // A one-point static mesh beside a long animated one: the cache is frames × all points,
        // counted before it is allocated.
        let mut text = String::from("#usda 1.0\ndef Mesh \"big\" { point3f[] points = [");
        text.push_str(&"(1,2,3),".repeat(20_000));
        text.push_str("]\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\ndef Mesh \"long\" { point3f[] points.timeSamples = {");
        for t in 0..20_000 {
            let _ = write!(text, "{t}: [(0,0,0)],");
        }
        text.push_str("}\n int[] faceVertexCounts = []\n int[] faceVertexIndices = [] }\n");
        let e = parse_usda(text.as_bytes(), "b.usda", None, Some(64 * text.len() as u64)).unwrap_err().to_string();
        assert!(e.contains("positions"), "{e}");
    }
}
