//! USD in and out: time-sampled `UsdGeomMesh` prims of text layers (`.usda`), crate files
//! (`.usdc`, [`super::usdc`]) and usdz packages (read only; their root layer). A `.usd` file
//! may hold either a text layer or a crate file: the reader goes by the first bytes (`#usda`,
//! `PXR-USDC`, a zip's `PK`), never by the extension.
//!
//! **Read** ([`parse_usd`]): both the text parser here and the crate reader fill one layer
//! model (`usd_layer`), and one assembly (`usd_assemble`) makes the animation. Every `def Mesh` of the layer (depth-first, in authored order, as
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
//! The `xformOp`s of each mesh and of its ancestors (`xformOpOrder`, `usd_xform`) are applied
//! to its points at every frame; ops sampled at other times than the points add those frames.
//! Meshes bound to a `UsdSkel` skeleton or blend shapes are evaluated as UsdSkel plays them
//! (`usd_skel`: blend shapes, then linear blend skinning into the Skeleton's space, placed by
//! the Skeleton's transforms); the animation's samples add frames too.
//!
//! What is refused by name rather than read wrongly: composition arcs (`subLayers`,
//! `references`, `payload`, `inherits`, `specializes`, variant sets: flatten the stage first,
//! with usd-core's `Usd.Stage.Open(IN).Export(OUT)`), the UsdSkel features not evaluated
//! (inbetween shapes, dual-quaternion skinning, indexed skinning primvars, bindings without
//! `SkelBindingAPI` or outside a `SkelRoot`), a time-sampled topology, points whose count
//! changes over time, value clips, spline-valued points and ops.
//!
//! The input is untrusted: nesting is bounded ([`MAX_DEPTH`]), every array is counted against
//! the read's memory budget before it is kept, the cache's size is checked against
//! [`reader_limits`](super::reader_limits) and the budget before it is allocated, and every
//! coordinate must be finite.
//!
//! **Write** ([`encode_usda`]; [`super::usdc::encode_usdc`] writes the same scene as a crate
//! file): one `Mesh` prim `/animcodec/mesh` under an `Xform`, triangles as
//! `faceVertexCounts` of 3, `points.timeSamples`, per-frame `extent` and `defaultPrim`, so
//! Pixar's compliance checker passes it. The stage metadata is the source's when the animation
//! carries it ([`codec_core::SceneMetadata`]: `upAxis`, `metersPerUnit`, `timeCodesPerSecond`,
//! the time code of frame 0), else a vertex cache's conventions: `upAxis = "Y"`,
//! `metersPerUnit = 1`, time codes 0, 1, … at `timeCodesPerSecond` = the frame rate;
//! `framesPerSecond` is always the frame rate. The reader fills the same metadata, so a layer
//! read and written again keeps it. Coordinates are written in the shortest decimal form that reads back as the same `f32`,
//! so a round trip is exact.

use std::fmt::Write as _;
use std::path::Path;

use codec_core::{Animation, Error, Result};

use super::gltf_buffers::Budget;
use super::usd_assemble::assemble;
pub use super::usd_layer::USD_DEFAULT_TIME_CODES_PER_SECOND;
use super::usd_layer::{
    is_kept_attribute, is_kept_relationship, shown, unsupported, Attribute, Layer, Prim, Relationship, StageTimeLine,
    Value, FLATTEN_ADVICE,
};
use super::{name, read_file};

pub use super::usd_layer::MAX_DEPTH;

/// The USDA header every text layer starts with.
const USDA_MAGIC: &[u8] = b"#usda ";
/// The first bytes of a binary crate file.
pub(super) const USDC_MAGIC: &[u8] = b"PXR-USDC";
/// The first bytes of a zip archive (a `.usdz` package).
const ZIP_MAGIC: &[u8] = b"PK\x03\x04";

/// Reads a USD file — a text layer, a crate file or a `.usdz` package, told apart by their
/// first bytes, whatever the extension (see the module documentation); `frame_rate` overrides
/// the layer's rate.
pub fn read_usd(path: &Path, frame_rate: Option<f32>) -> Result<Animation> {
    let bytes = read_file(path)?;
    let budget = Budget::new(&name(path), None);
    parse_usd_with(&bytes, &name(path), frame_rate, budget)
}

/// Parses a USD layer held in memory: a text layer (`#usda`), a crate file (`PXR-USDC`) or a
/// `.usdz` package (a zip). `file` names the source in errors; `frame_rate` overrides the
/// layer's; `memory_budget` bounds what the read holds beyond the input (default: the
/// process's read budget, 1 GiB unless `--max-memory` set it).
pub fn parse_usd(bytes: &[u8], file: &str, frame_rate: Option<f32>, memory_budget: Option<u64>) -> Result<Animation> {
    parse_usd_with(bytes, file, frame_rate, Budget::new(file, memory_budget))
}

/// Parses a USD layer held in memory; the same as [`parse_usd`] (text layers, crate files and
/// packages are all read), kept under its first name.
pub fn parse_usda(bytes: &[u8], file: &str, frame_rate: Option<f32>, memory_budget: Option<u64>) -> Result<Animation> {
    parse_usd(bytes, file, frame_rate, memory_budget)
}

fn parse_usd_with(bytes: &[u8], file: &str, frame_rate: Option<f32>, mut budget: Budget) -> Result<Animation> {
    let layer = read_layer(bytes, file, &mut budget, true)?;
    assemble(file, layer, frame_rate, &mut budget)
}

/// The layer model of a text layer, a crate file or (when `package` allows it) a package's
/// root layer.
fn read_layer(bytes: &[u8], file: &str, budget: &mut Budget, package: bool) -> Result<Layer> {
    if bytes.starts_with(USDC_MAGIC) {
        return super::usdc::read_layer(bytes, file, budget);
    }
    if bytes.starts_with(ZIP_MAGIC) {
        if !package {
            return Err(unsupported(file, "a USDZ package inside a package (its root layer must be usda or usdc)"));
        }
        let (root, root_name) = super::usdz::root_layer(bytes, file)?;
        let inner = format!("{file}[{}]", super::gltf::printable(&root_name));
        return read_layer(root, &inner, budget, false);
    }
    if !bytes.starts_with(USDA_MAGIC) {
        return Err(Error::malformed(
            file.to_owned(),
            "header",
            "not a USD layer (no `#usda` header, no `PXR-USDC` crate header, not a usdz package)",
        ));
    }
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::malformed(file.to_owned(), "text", format!("not UTF-8 (byte {})", e.valid_up_to())))?;
    let mut parser = Parser { lexer: Lexer { text, pos: 0, file }, peeked: None, budget, prim_depth: 0 };
    parser.layer()
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
enum TextValue<'a> {
    /// A number, identifier or string.
    Atom(Tok<'a>),
    /// `[a, b, …]` of atoms or of tuples, flattened: `arity` is the tuple size (0: atoms).
    Array { items: Vec<Tok<'a>>, arity: usize },
    /// Anything else (dictionaries, tuples, nested lists): parsed and dropped.
    Other,
}

/// Time samples of one attribute: time code (as written) → value (`None` = a blocked sample).
type Samples<'a> = Vec<(f64, Option<TextValue<'a>>)>;

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
            // (254 nested prims reach 257 levels, which "more than 256 prims deep" would hide).
            return Err(self.lexer.error(format!(
                "nested {depth} levels deep, past the limit of {MAX_DEPTH} levels ({} of them nested prims; every \
                 prim, metadata block, property, dictionary, list and tuple is one level)",
                self.prim_depth
            )));
        }
        Ok(())
    }

    fn layer(&mut self) -> Result<Layer> {
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
    fn metadata(&mut self, depth: usize, on_entry: &mut dyn FnMut(&str, &TextValue<'a>) -> Result<()>) -> Result<()> {
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
    fn eat_brackets(&mut self) -> Result<bool> {
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
    fn prim(
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
    fn property(&mut self, depth: usize, path: &str) -> Result<Option<Property>> {
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
    fn converted(&mut self, type_name: &str, value: TextValue<'a>, path: &str, prop: &str) -> Result<Value> {
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
    fn value(&mut self, depth: usize) -> Result<TextValue<'a>> {
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
    fn list(&mut self, depth: usize) -> Result<TextValue<'a>> {
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

/// `x` rounded to the nearest IEEE binary16 value (ties to even), as a `half` attribute holds
/// it: 11 significant bits, subnormals below 2⁻¹⁴, infinity from 65520 up.
fn to_half_precision(x: f32) -> f32 {
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
enum Property {
    Attribute(Attribute),
    Relationship(Relationship),
}

/// A relationship target as an absolute prim path: `<../Skel>` and `<Anim>` are relative to
/// the prim `prim` (`/a/b`) that authors the relationship.
fn absolute_target(prim: &str, target: &str) -> String {
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
fn merge_attribute(attributes: &mut Vec<Attribute>, attribute: Attribute) {
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
    let (v, f) = (animation.vertex_count(), animation.frame_count());
    let tris = animation.triangles();
    // About 3 × 12 characters per vertex and frame.
    let mut s = String::with_capacity(64 + tris.len() * 16 + v * f * 40);
    let stage = StageTimeLine::of(animation);
    let _ = write!(
        s,
        "#usda 1.0\n(\n    defaultPrim = \"animcodec\"\n    doc = \"animcodec vertex cache: {v} vertices, {f} frames\"\n    \
         endTimeCode = {}\n    framesPerSecond = {}\n    metersPerUnit = {}\n    startTimeCode = {}\n    \
         timeCodesPerSecond = {}\n    upAxis = \"{}\"\n)\n\n",
        stage.time_code(f - 1),
        stage.frames_per_second,
        stage.meters_per_unit,
        stage.time_code(0),
        stage.time_codes_per_second,
        stage.up_axis,
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
        let _ = write!(s, "            {}: [(", stage.time_code(t));
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
        let _ = write!(s, "            {}: [", stage.time_code(t));
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
/// the same triangles, every coordinate bit for bit, and the same stage metadata and time
/// codes. A layer that does not is never written.
pub(super) fn check_reads_back(path: &Path, bytes: &[u8], animation: &Animation) -> Result<()> {
    let back = parse_usda(bytes, &name(path), Some(animation.frame_rate()), Some(u64::MAX))
        .map_err(|e| Error::InvalidAnimation(format!("the USD layer written does not read back: {e}")))?;
    let same = back.triangles() == animation.triangles()
        && StageTimeLine::of(&back) == StageTimeLine::of(animation)
        && back.positions().len() == animation.positions().len()
        && back.positions().iter().zip(animation.positions()).all(|(a, b)| a.to_bits() == b.to_bits());
    if !same {
        return Err(Error::InvalidAnimation(format!(
            "{}: the USD layer written does not read back as the same positions, triangles and stage metadata",
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
            ("PXR-USDC\0\0\0\0", "88-byte header"),
            ("PK\x03\x04rest", "end-of-central-directory"),
            ("hello", "#usda"),
            ("#usda 1.0\n(\n subLayers = [@a.usda@]\n)\n", "subLayers"),
            ("#usda 1.0\ndef Xform \"a\" (references = @b.usda@) {}\n", "references"),
            ("#usda 1.0\ndef Xform \"a\" { double3 xformOp:translat = (1, 2, 3)\n uniform token[] xformOpOrder = [\"xformOp:translate\"]\n def Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] } }\n", "/a xformOpOrder"),
            ("#usda 1.0\ndef Xform \"a\" {}\n", "no Mesh"),
            ("#usda 1.0\ndef Mesh \"m\" { point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2]\n int[] primvars:skel:jointIndices = [0, 0, 0] (elementSize = 1 interpolation = \"vertex\") }\n", "UsdSkel"),
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

    /// Transforms of the mesh and its ancestors are applied, sampled ones at every frame; a
    /// `Scope` (not xformable) transforms nothing; `!resetXformStack!` drops the parents'.
    #[test]
    fn xform_ops_of_the_mesh_and_its_ancestors_are_applied() {
        let layer = |reset: &str| {
            format!(
                "#usda 1.0\ndef Xform \"a\" {{ double3 xformOp:translate.timeSamples = {{ 0: (1, 2, 3), 2: (3, 2, 3) }}\n \
                 uniform token[] xformOpOrder = [\"xformOp:translate\"]\n def Scope \"s\" {{ float3 xformOp:scale = (9, 9, 9)\n \
                 uniform token[] xformOpOrder = [\"xformOp:scale\"]\n def Mesh \"m\" {{ float xformOp:rotateZ = 90\n \
                 uniform token[] xformOpOrder = [{reset}\"xformOp:rotateZ\"]\n point3f[] points.timeSamples = {{ 0: [(1,0,0),(0,1,0),(0,0,1)], \
                 1: [(1,0,0),(0,1,0),(0,0,1)] }}\n \
                 int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0,1,2] }} }} }}\n"
            )
        };
        let a = parse(&layer("")).unwrap();
        assert_eq!(a.frame_count(), 3);
        // Frame 1 (time 1): rotated 90° about Z, then translated by the interpolated (2, 2, 3).
        let f = a.frame(1);
        let want = [2., 3., 3., 1., 2., 3., 2., 2., 4.];
        assert!(f.iter().zip(want).all(|(x, y)| (x - y).abs() < 1e-6), "{f:?}");
        let a = parse(&layer("\"!resetXformStack!\", ")).unwrap();
        assert_eq!(a.frame_count(), 2);
        let f = a.frame(0);
        let want = [0., 1., 0., -1., 0., 0., 0., 0., 1.];
        assert!(f.iter().zip(want).all(|(x, y)| (x - y).abs() < 1e-6), "{f:?}");
    }

    /// The nesting error counts levels, not prims, and says so, with both (probe misc).
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

    /// Nested long prim names do not cost the sum of every path prefix (2.5 GB for a 20 MB
    /// layer if every prim kept its whole path): only a kept mesh's path is held, and it is
    /// counted against the budget (probe usd-deepnames).
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
