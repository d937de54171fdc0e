//! Tokens of a USD text layer (`.usda`) for the parser in [`super::usd_text`]: punctuation,
//! identifiers, numbers, strings, paths and asset references, with the line and column an
//! error names. Kept apart because it only cuts text: what a token means is the parser's work.

use codec_core::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Tok<'a> {
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

pub(super) struct Lexer<'a> {
    pub(super) text: &'a str,
    pub(super) pos: usize,
    pub(super) file: &'a str,
}

impl<'a> Lexer<'a> {
    pub(super) fn line(&self) -> usize {
        self.text.as_bytes()[..self.pos.min(self.text.len())].iter().filter(|&&b| b == b'\n').count() + 1
    }

    pub(super) fn error(&self, detail: impl Into<String>) -> Error {
        Error::malformed(self.file.to_owned(), format!("line {}", self.line()), detail)
    }

    pub(super) fn next(&mut self) -> Result<Tok<'a>> {
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

    pub(super) fn string(&mut self, quote: u8) -> Result<Tok<'a>> {
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

/// How an error message names `tok`.
pub(super) fn describe(tok: Tok) -> String {
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
