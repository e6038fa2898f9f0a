//! The cameras of a USD file (`.usda`, USD's text layer): what Houdini (Solaris), Maya, Blender,
//! Omniverse and modelflow's own export write. Every `Camera` prim defined on the stage is read
//! with the transform operations of its prim and of the prims above it composed at each frame:
//! one that holds still becomes a static camera, one that moves a pose per frame. Read by hand:
//! no maintained Rust crate parses USD's text format, and the part cameras need (prims,
//! attributes, time samples, `xformOp`s) is small. A binary (`.usdc`) or zipped (`.usdz`) layer,
//! and cameras that need composition (references, payloads, variants, value clips, sublayers),
//! are refused with the command that flattens the stage into one text layer.
//!
//! Conventions (docs/scene-format.md, "Importing a calibration"): USD's matrices map row
//! vectors, translation in the last row; `xformOpOrder` lists the operations outermost first;
//! the camera looks down its −Z with +Y up; focal length, apertures and aperture offsets are in
//! one unit, and Pixar's `GfCamera` maps the aperture onto the image. A film back whose aspect is
//! not the image's is conformed as USD's render settings say (`aspectRatioConformPolicy`, by
//! default `expandAperture`), except in modelflow's own export, whose aperture carries `fx ≠ fy`.

use super::scene3d::{still_or_moving, world_to_camera, SceneCameras, View};
use super::{line_at, pinhole_k};
use crate::base::Units;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Rotation3, Vector3};
use std::path::Path;

/// How far a film back's aspect may differ from the image's before `import` says it was
/// conformed (below it, the rounding of 32-bit apertures: Blender's 0.2025 for 16:9).
const SAY_CONFORMED: f64 = 1e-4;
/// Deeper nesting than any scene has (prims, values): a file that nests further is refused.
const MAX_DEPTH: usize = 200;
/// How to flatten a stage into one text layer, for files this reader cannot take as they are.
const FLATTEN: &str = "flatten the stage into one text layer first: `usdcat --flatten IN -o OUT.usda` (USD's tools), or in Python `from pxr import Usd; Usd.Stage.Open(IN).Export(OUT.usda)`";

/// Reads every camera of the USD text file `path` at frames `frames.0..=frames.1` (frame `F` at
/// time code `F · timeCodesPerSecond / framesPerSecond`, which is `F` when the two rates agree,
/// as the packages write them). `size` is the image size; without it, a camera's image size is
/// modelflow's own `modelflow:imageSize`, else the resolution of the render settings or
/// product that names the camera.
pub fn read_usd(path: &Path, size: Option<(u32, u32)>, frames: (u32, u32)) -> Result<SceneCameras> {
    super::scene3d::check_frames(frames).map_err(|m| Error::invalid(path, "--frames", m))?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_bytes(path, bytes, size, frames)
}

/// [`read_usd`] of the file's bytes.
fn read_bytes(
    path: &Path,
    bytes: Vec<u8>,
    size: Option<(u32, u32)>,
    frames: (u32, u32),
) -> Result<SceneCameras> {
    let bad = |field: &str, m: String| Error::invalid(path, field, m);
    if bytes.starts_with(b"PXR-USDC") {
        return Err(bad(
            "(format)",
            format!("a binary USD layer (usdc): not read; {FLATTEN}"),
        ));
    }
    if bytes.starts_with(b"PK\x03\x04") {
        return Err(bad(
            "(format)",
            format!("a zipped USD package (usdz): not read; {FLATTEN}"),
        ));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        bad(
            "(format)",
            format!(
                "not UTF-8 text (byte {}): expected a USD text layer (.usda)",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    let text = super::strip_bom(&text);
    if !text.starts_with("#usda ") {
        return Err(bad(
            "line 1",
            "expected a USD text layer, which starts with `#usda 1.0`".into(),
        ));
    }
    let layer = Parser::parse(path, text)?;
    Reader {
        path,
        layer: &layer,
    }
    .cameras(size, frames)
}

// ---------------------------------------------------------------------------------------------
// The text layer: tokens, then prims with their metadata and attributes.

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    /// An identifier or keyword, namespaces included (`xformOp:translate`).
    Ident(String),
    Num(f64),
    Str(String),
    Asset(String),
    Path(String),
    Punct(u8),
}

/// A value as the text gives it; only what cameras need is kept (a dictionary is skipped).
#[derive(Clone, Debug, PartialEq)]
enum Value {
    Num(f64),
    /// A string, a token, or a bare word (`true`).
    Text(String),
    Asset(String),
    Path(String),
    Tuple(Vec<Value>),
    List(Vec<Value>),
    Dict,
    /// `None`: a blocked value.
    None,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Specifier {
    Def,
    Over,
    Class,
}

#[derive(Debug)]
struct Attr {
    name: String,
    /// Its type as written (`float3`, `matrix4d`, `token[]`, `rel`).
    ty: String,
    default: Option<Value>,
    samples: Option<Vec<(f64, Value)>>,
    /// Animated by a spline (USD 25's `.spline`), not read.
    spline: bool,
    line: usize,
}

#[derive(Debug)]
struct Prim {
    specifier: Specifier,
    ty: String,
    name: String,
    line: usize,
    meta: Vec<(String, Value)>,
    attrs: Vec<Attr>,
    children: Vec<Prim>,
    /// It has variant sets (their contents are not read).
    variants: bool,
}

impl Prim {
    /// A prim that holds what is parsed and not kept (a variant's body, a deleting list edit).
    fn scratch(line: usize) -> Prim {
        Prim {
            specifier: Specifier::Over,
            ty: String::new(),
            name: String::new(),
            line,
            meta: Vec::new(),
            attrs: Vec::new(),
            children: Vec::new(),
            variants: false,
        }
    }

    fn attr(&self, name: &str) -> Option<&Attr> {
        self.attrs.iter().find(|a| a.name == name)
    }
    fn meta(&self, key: &str) -> Option<&Value> {
        self.meta.iter().find(|m| m.0 == key).map(|m| &m.1)
    }
}

struct Layer {
    meta: Vec<(String, Value)>,
    prims: Vec<Prim>,
}

struct Parser<'a> {
    path: &'a Path,
    text: &'a str,
    toks: Vec<(Tok, usize)>,
    at: usize,
    depth: usize,
    /// The byte offset where each line starts.
    line_starts: Vec<usize>,
}

impl<'a> Parser<'a> {
    fn parse(path: &'a Path, text: &'a str) -> Result<Layer> {
        // The first line, `#usda 1.0`, is the header (a comment to the grammar).
        let start = text.find('\n').map_or(text.len(), |n| n + 1);
        let mut p = Parser {
            path,
            text,
            toks: Vec::new(),
            at: 0,
            depth: 0,
            line_starts: std::iter::once(0)
                .chain(text.match_indices('\n').map(|(i, _)| i + 1))
                .collect(),
        };
        p.lex(start)?;
        let mut layer = Layer {
            meta: Vec::new(),
            prims: Vec::new(),
        };
        if p.peek_punct(b'(') {
            layer.meta = p.metadata()?;
        }
        while p.at < p.toks.len() {
            match p.next_ident()?.as_str() {
                "def" => layer.prims.push(p.prim(Specifier::Def)?),
                "over" => layer.prims.push(p.prim(Specifier::Over)?),
                "class" => layer.prims.push(p.prim(Specifier::Class)?),
                "reorder" => {
                    p.next_ident()?;
                    p.expect(b'=')?;
                    p.value()?;
                }
                other => {
                    return Err(p.err_back(format!("expected a prim (`def`), found `{other}`")))
                }
            }
        }
        Ok(layer)
    }

    fn err_at(&self, offset: usize, m: impl Into<String>) -> Error {
        Error::invalid(
            self.path,
            format!("line {}", line_at(self.text.as_bytes(), offset)),
            m,
        )
    }

    /// An error at the token just read.
    fn err_back(&self, m: impl Into<String>) -> Error {
        let off = self
            .toks
            .get(self.at.saturating_sub(1))
            .map_or(self.text.len(), |t| t.1);
        self.err_at(off, m)
    }

    /// The line of the next token, from the table of line starts (not a count per statement:
    /// a flattened stage runs to hundreds of megabytes).
    fn line(&self) -> usize {
        let off = self.toks.get(self.at).map_or(self.text.len(), |t| t.1);
        self.line_starts.partition_point(|&s| s <= off)
    }

    fn lex(&mut self, start: usize) -> Result<()> {
        let b = self.text.as_bytes();
        let mut i = start;
        let ident_start = |c: u8| c.is_ascii_alphabetic() || c == b'_' || c >= 0x80;
        let ident_char = |c: u8| c.is_ascii_alphanumeric() || c == b'_' || c >= 0x80;
        while i < b.len() {
            let c = b[i];
            let at = i;
            if c.is_ascii_whitespace() {
                i += 1;
            } else if c == b'#' || (c == b'/' && b.get(i + 1) == Some(&b'/')) {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
                let end = self.text[i + 2..]
                    .find("*/")
                    .ok_or_else(|| self.err_at(at, "a `/*` comment that is never closed"))?;
                i += 2 + end + 2;
            } else if c == b'"' || c == b'\'' {
                let (s, next) = self.string(i)?;
                self.toks.push((Tok::Str(s), at));
                i = next;
            } else if c == b'@' {
                let (delim, open) = if self.text[i..].starts_with("@@@") {
                    ("@@@", 3)
                } else {
                    ("@", 1)
                };
                let end = self.text[i + open..].find(delim).ok_or_else(|| {
                    self.err_at(at, "an asset path (`@...@`) that is never closed")
                })?;
                let s = self.text[i + open..i + open + end].to_string();
                self.toks.push((Tok::Asset(s), at));
                i += open + end + open;
            } else if c == b'<' {
                let end = self.text[i..]
                    .find('>')
                    .ok_or_else(|| self.err_at(at, "a path (`<...>`) that is never closed"))?;
                self.toks
                    .push((Tok::Path(self.text[i + 1..i + end].to_string()), at));
                i += end + 1;
            } else if c.is_ascii_digit()
                || ((c == b'-' || c == b'+' || c == b'.')
                    && b.get(i + 1)
                        .is_some_and(|d| d.is_ascii_digit() || *d == b'.'))
            {
                let mut j = i + 1;
                while j < b.len()
                    && (b[j].is_ascii_digit()
                        || b[j] == b'.'
                        || ((b[j] == b'e' || b[j] == b'E')
                            && b.get(j + 1)
                                .is_some_and(|d| d.is_ascii_digit() || *d == b'-' || *d == b'+'))
                        || ((b[j] == b'-' || b[j] == b'+')
                            && (b[j - 1] == b'e' || b[j - 1] == b'E')))
                {
                    j += 1;
                }
                let s = &self.text[i..j];
                let x: f64 = s
                    .parse()
                    .map_err(|_| self.err_at(at, format!("`{s}`: not a number")))?;
                self.toks.push((Tok::Num(x), at));
                i = j;
            } else if (c == b'-' || c == b'+') && self.text[i + 1..].starts_with("inf") {
                let x = if c == b'-' {
                    f64::NEG_INFINITY
                } else {
                    f64::INFINITY
                };
                self.toks.push((Tok::Num(x), at));
                i += 4;
            } else if ident_start(c) {
                let mut j = i + 1;
                loop {
                    while j < b.len() && ident_char(b[j]) {
                        j += 1;
                    }
                    // A namespace: `xformOp:translate`, `primvars:st:indices`.
                    if j + 1 < b.len() && b[j] == b':' && ident_start(b[j + 1]) {
                        j += 1;
                    } else {
                        break;
                    }
                }
                let word = &self.text[i..j];
                let tok = match word {
                    "inf" => Tok::Num(f64::INFINITY),
                    "nan" => Tok::Num(f64::NAN),
                    _ => Tok::Ident(word.to_string()),
                };
                self.toks.push((tok, at));
                i = j;
            } else if b"()[]{}=,:;.&".contains(&c) {
                self.toks.push((Tok::Punct(c), at));
                i += 1;
            } else {
                let ch = self.text[i..].chars().next().unwrap_or('?');
                return Err(self.err_at(at, format!("unexpected character {ch:?}")));
            }
        }
        Ok(())
    }

    /// A quoted string starting at `i` (one or three quotes, `"` or `'`), unescaped, and the
    /// offset after it.
    fn string(&self, i: usize) -> Result<(String, usize)> {
        let b = self.text.as_bytes();
        let q = b[i];
        let triple = b.get(i + 1) == Some(&q) && b.get(i + 2) == Some(&q);
        let mut j = i + if triple { 3 } else { 1 };
        let mut out = String::new();
        loop {
            let Some(ch) = self.text[j..].chars().next() else {
                return Err(self.err_at(i, "a string that is never closed"));
            };
            if ch == q as char
                && (!triple || (b.get(j + 1) == Some(&q) && b.get(j + 2) == Some(&q)))
            {
                return Ok((out, j + if triple { 3 } else { 1 }));
            }
            if ch == '\n' && !triple {
                return Err(self.err_at(i, "a string that runs past the end of its line"));
            }
            if ch == '\\' {
                let Some(e) = self.text[j + 1..].chars().next() else {
                    return Err(self.err_at(i, "a string that is never closed"));
                };
                // `\xNN` (two hex digits) and `\NNN` (octal) as USD writes bytes; the rest C's.
                let digits = |radix: u32, most: usize| {
                    let run: String = self.text[j + 2..]
                        .chars()
                        .take(most)
                        .take_while(|c| c.is_digit(radix))
                        .collect();
                    (u32::from_str_radix(&run, radix).ok(), run.len())
                };
                let (ch, used) = match e {
                    'n' => ('\n', 1),
                    't' => ('\t', 1),
                    'r' => ('\r', 1),
                    'x' => match digits(16, 2) {
                        (Some(v), n) => (char::from_u32(v).unwrap_or('?'), 1 + n),
                        (None, _) => ('x', 1),
                    },
                    '0'..='7' => {
                        let run: String = self.text[j + 1..]
                            .chars()
                            .take(3)
                            .take_while(|c| c.is_digit(8))
                            .collect();
                        let v = u32::from_str_radix(&run, 8).unwrap_or(0);
                        (char::from_u32(v).unwrap_or('?'), run.len())
                    }
                    other => (other, 1),
                };
                out.push(ch);
                j += 1 + match e {
                    'x' | '0'..='7' => used,
                    _ => e.len_utf8(),
                };
            } else {
                out.push(ch);
                j += ch.len_utf8();
            }
        }
    }

    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.at).map(|t| &t.0)
    }

    fn peek_punct(&self, c: u8) -> bool {
        self.peek() == Some(&Tok::Punct(c))
    }

    fn next(&mut self) -> Result<Tok> {
        let t = self.toks.get(self.at).map(|t| t.0.clone()).ok_or_else(|| {
            self.err_at(
                self.text.len(),
                "the file ends in the middle of a statement",
            )
        })?;
        self.at += 1;
        Ok(t)
    }

    fn next_ident(&mut self) -> Result<String> {
        match self.next()? {
            Tok::Ident(s) => Ok(s),
            other => Err(self.err_back(format!("expected a name, found {}", show(&other)))),
        }
    }

    fn expect(&mut self, c: u8) -> Result<()> {
        match self.next()? {
            Tok::Punct(p) if p == c => Ok(()),
            other => {
                Err(self.err_back(format!("expected `{}`, found {}", c as char, show(&other))))
            }
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        let yes = self.peek_punct(c);
        if yes {
            self.at += 1;
        }
        yes
    }

    fn deeper(&mut self) -> Result<()> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(self.err_back(format!("nested deeper than {MAX_DEPTH} levels")));
        }
        Ok(())
    }

    /// `( ... )`: a prim's, a property's or the layer's metadata, as key and value.
    fn metadata(&mut self) -> Result<Vec<(String, Value)>> {
        self.expect(b'(')?;
        self.deeper()?;
        let mut out = Vec::new();
        loop {
            match self.next()? {
                Tok::Punct(b')') => break,
                Tok::Punct(b';') => {}
                Tok::Str(doc) => out.push(("doc".to_string(), Value::Text(doc))),
                Tok::Ident(mut key) => {
                    if matches!(
                        key.as_str(),
                        "prepend" | "append" | "add" | "delete" | "reorder"
                    ) {
                        key = self.next_ident()?;
                    }
                    let value = if self.eat(b'=') {
                        // An empty value (`symmetryFunction =`) before the block's end.
                        if self.peek_punct(b')') {
                            out.push((key, Value::None));
                            continue;
                        }
                        let v = self.value()?;
                        // A reference's or sublayer's layer offset: `@a.usd@ (offset = 2)`.
                        if self.peek_punct(b'(') {
                            self.skip_balanced()?;
                        }
                        v
                    } else {
                        Value::None
                    };
                    out.push((key, value));
                }
                other => {
                    return Err(self.err_back(format!(
                        "expected metadata (`name = value`), found {}",
                        show(&other)
                    )))
                }
            }
        }
        self.depth -= 1;
        Ok(out)
    }

    /// Skips a bracketed group `( ... )`, `[ ... ]` or `{ ... }` starting at the next token.
    fn skip_balanced(&mut self) -> Result<()> {
        let mut depth = 0usize;
        loop {
            match self.next()? {
                Tok::Punct(b'(' | b'[' | b'{') => depth += 1,
                Tok::Punct(b')' | b']' | b'}') => {
                    depth = depth.saturating_sub(1);
                    if depth == 0 {
                        return Ok(());
                    }
                }
                _ if depth == 0 => return Err(self.err_back("expected `(`, `[` or `{`")),
                _ => {}
            }
        }
    }

    fn value(&mut self) -> Result<Value> {
        self.deeper()?;
        let v = match self.next()? {
            Tok::Num(x) => Value::Num(x),
            Tok::Str(s) => Value::Text(s),
            Tok::Ident(s) if s == "None" => Value::None,
            Tok::Ident(s) => Value::Text(s),
            Tok::Asset(s) => {
                // A reference's target prim: `@a.usd@</prim>`.
                if matches!(self.peek(), Some(Tok::Path(_))) {
                    self.at += 1;
                }
                Value::Asset(s)
            }
            Tok::Path(s) => Value::Path(s),
            Tok::Punct(b'(') => Value::Tuple(self.items(b')')?),
            Tok::Punct(b'[') => Value::List(self.items(b']')?),
            Tok::Punct(b'{') => {
                self.at -= 1;
                self.skip_balanced()?;
                Value::Dict
            }
            other => return Err(self.err_back(format!("expected a value, found {}", show(&other)))),
        };
        self.depth -= 1;
        Ok(v)
    }

    /// The items of a tuple or list up to `close`, separated by commas (a trailing one allowed).
    fn items(&mut self, close: u8) -> Result<Vec<Value>> {
        let mut out = Vec::new();
        loop {
            if self.eat(close) {
                return Ok(out);
            }
            out.push(self.value()?);
            // A list item's layer offset or metadata: `@a.usd@ (offset = 2)`.
            if close == b']' && self.peek_punct(b'(') {
                self.skip_balanced()?;
            }
            if !self.eat(b',') {
                self.expect(close)?;
                return Ok(out);
            }
        }
    }

    /// A prim after its specifier: `[Type] "name" [( metadata )] { body }`.
    fn prim(&mut self, specifier: Specifier) -> Result<Prim> {
        self.deeper()?;
        let line = self.line();
        let ty = match self.peek() {
            Some(Tok::Ident(_)) => self.next_ident()?,
            _ => String::new(),
        };
        let name = match self.next()? {
            Tok::Str(s) => s,
            other => {
                return Err(self.err_back(format!(
                    "expected the prim's name in quotes, found {}",
                    show(&other)
                )))
            }
        };
        let mut prim = Prim {
            specifier,
            ty,
            name,
            line,
            meta: Vec::new(),
            attrs: Vec::new(),
            children: Vec::new(),
            variants: false,
        };
        if self.peek_punct(b'(') {
            prim.meta = self.metadata()?;
        }
        self.expect(b'{')?;
        self.body(&mut prim)?;
        self.depth -= 1;
        Ok(prim)
    }

    /// A prim's body after `{`, up to and including its `}`.
    fn body(&mut self, prim: &mut Prim) -> Result<()> {
        loop {
            let line = self.line();
            let word = match self.next()? {
                Tok::Punct(b'}') => return Ok(()),
                Tok::Punct(b';') => continue,
                Tok::Ident(w) => w,
                other => {
                    return Err(self.err_back(format!(
                        "expected a property or a prim, found {}",
                        show(&other)
                    )))
                }
            };
            match word.as_str() {
                "def" => prim.children.push(self.prim(Specifier::Def)?),
                "over" => prim.children.push(self.prim(Specifier::Over)?),
                "class" => prim.children.push(self.prim(Specifier::Class)?),
                "variantSet" => {
                    prim.variants = true;
                    self.next()?;
                    self.expect(b'=')?;
                    self.expect(b'{')?;
                    while !self.eat(b'}') {
                        self.next()?;
                        if self.peek_punct(b'(') {
                            self.metadata()?;
                        }
                        self.expect(b'{')?;
                        let mut variant = Prim::scratch(line);
                        self.deeper()?;
                        self.body(&mut variant)?;
                        self.depth -= 1;
                    }
                }
                "reorder" if matches!(self.peek(), Some(Tok::Ident(w)) if w == "nameChildren" || w == "properties") =>
                {
                    self.next()?;
                    self.expect(b'=')?;
                    self.value()?;
                }
                _ => self.property(prim, word, line)?,
            }
        }
    }

    /// A property declaration whose first word is `first`: `[listop] [custom] [uniform] type
    /// name[.timeSamples | .connect | .spline | .default] [= value] [( metadata )]`, or a `rel`.
    fn property(&mut self, prim: &mut Prim, first: String, line: usize) -> Result<()> {
        if first == "delete" {
            // A list edit that removes targets or values: parsed, not applied to the prim.
            let word = self.next_ident()?;
            return self.property(&mut Prim::scratch(line), word, line);
        }
        let mut word = first;
        while matches!(
            word.as_str(),
            "prepend"
                | "append"
                | "add"
                | "delete"
                | "reorder"
                | "custom"
                | "uniform"
                | "varying"
                | "config"
        ) {
            word = self.next_ident()?;
        }
        let mut ty = word;
        if ty != "rel" && self.eat(b'[') {
            self.expect(b']')?;
            ty.push_str("[]");
        }
        let name = self.next_ident()?;
        let mut suffix = String::new();
        if self.eat(b'.') {
            suffix = self.next_ident()?;
        }
        let index = match prim.attrs.iter().position(|a| a.name == name) {
            Some(i) => i,
            None => {
                prim.attrs.push(Attr {
                    name: name.clone(),
                    ty: ty.clone(),
                    default: None,
                    samples: None,
                    spline: false,
                    line,
                });
                prim.attrs.len() - 1
            }
        };
        if self.eat(b'=') {
            match suffix.as_str() {
                "timeSamples" => {
                    self.expect(b'{')?;
                    let mut samples = Vec::new();
                    while !self.eat(b'}') {
                        let t = match self.next()? {
                            Tok::Num(t) if t.is_finite() => t,
                            other => {
                                return Err(self.err_back(format!(
                                    "{name}.timeSamples: expected a time code, found {}",
                                    show(&other)
                                )))
                            }
                        };
                        self.expect(b':')?;
                        samples.push((t, self.value()?));
                        self.eat(b',');
                    }
                    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
                    prim.attrs[index].samples = Some(samples);
                }
                "spline" => {
                    self.skip_balanced()?;
                    prim.attrs[index].spline = true;
                }
                "connect" => {
                    self.value()?;
                }
                // Arrays other than tokens (a mesh's points) are never read: skipped, not kept.
                "" | "default"
                    if ty.ends_with("[]") && ty != "token[]" && self.peek_punct(b'[') =>
                {
                    self.skip_balanced()?;
                }
                "" | "default" => {
                    let v = self.value()?;
                    prim.attrs[index].default = Some(v);
                }
                other => {
                    return Err(
                        self.err_back(format!("{name}.{other}: not a property field USD knows"))
                    )
                }
            }
        }
        if self.peek_punct(b'(') {
            self.metadata()?;
        }
        Ok(())
    }
}

/// A token as an error message shows it.
fn show(t: &Tok) -> String {
    match t {
        Tok::Ident(s) => format!("`{s}`"),
        Tok::Num(x) => format!("the number {x}"),
        Tok::Str(s) => format!("the string {s:?}"),
        Tok::Asset(s) => format!("the asset @{s}@"),
        Tok::Path(s) => format!("the path <{s}>"),
        Tok::Punct(c) => format!("`{}`", *c as char),
    }
}

// ---------------------------------------------------------------------------------------------
// The cameras on the stage.

/// A camera prim found, with the prims above it (from the top).
struct Found<'a> {
    chain: Vec<&'a Prim>,
    path: String,
}

impl Found<'_> {
    fn prim(&self) -> &Prim {
        self.chain[self.chain.len() - 1]
    }
}

/// The render settings that may give a camera its image size and conform policy.
#[derive(Clone)]
struct Render {
    /// A `RenderProduct` (which wins over settings naming the same camera).
    product: bool,
    camera: Option<String>,
    resolution: Option<(u32, u32)>,
    policy: Option<String>,
    pixel_aspect: Option<f64>,
    products: Vec<String>,
    path: String,
}

struct Reader<'a> {
    path: &'a Path,
    layer: &'a Layer,
}

impl<'a> Reader<'a> {
    fn err(&self, field: &str, m: impl Into<String>) -> Error {
        Error::invalid(self.path, field, m)
    }

    fn layer_number(&self, key: &str) -> Option<f64> {
        match self.layer.meta.iter().find(|m| m.0 == key)? {
            (_, Value::Num(x)) => Some(*x),
            _ => None,
        }
    }

    fn cameras(&self, size: Option<(u32, u32)>, (first, last): (u32, u32)) -> Result<SceneCameras> {
        let mut found = Vec::new();
        let mut left_out = Vec::new();
        let mut renders = Vec::new();
        for p in &self.layer.prims {
            walk(
                p,
                &mut Vec::new(),
                "",
                &mut found,
                &mut left_out,
                &mut renders,
            );
        }
        inherit_render_settings(&mut renders);
        let mut notes = Vec::new();
        let up = match self.layer.meta.iter().find(|m| m.0 == "upAxis") {
            Some((_, Value::Text(a))) => a.clone(),
            _ => "Y".into(),
        };
        let metres = self.layer_number("metersPerUnit");
        let unit = match metres {
            Some(m) => format!("{m} m per unit"),
            None => "0.01 m per unit (USD's default: centimetres)".into(),
        };
        let units = match metres.unwrap_or(0.01) {
            1.0 => Some(Units::Metres),
            0.01 => Some(Units::Centimetres),
            0.001 => Some(Units::Millimetres),
            _ => None,
        };
        notes.push(format!(
            "the cameras are in the USD file's world, {up} up, {unit}: give the mesh in the same world (Blender's OBJ export: up Z, forward Y, for its USD export's Z-up world)"
        ));
        if let Some((_, v)) = self.layer.meta.iter().find(|m| m.0 == "subLayers") {
            if !matches!(v, Value::List(l) if l.is_empty()) {
                // A sublayer's `over` may move or zoom a camera defined here.
                return Err(self.err(
                    "subLayers",
                    format!(
                        "the file has sublayers, which this reader does not compose: {FLATTEN}"
                    ),
                ));
            }
        }
        notes.extend(left_out);
        if found.is_empty() {
            return Err(self.err(
                "(prims)",
                "holds no Camera prim defined on the stage: export the cameras with the scene (Blender: File > Export > Universal Scene Description, Cameras ticked; Houdini: a Camera LOP; Maya: Export, USD)",
            ));
        }
        // USD's fallbacks: time codes at the frame rate, the frame rate 24.
        let fps_said = self.layer_number("framesPerSecond");
        let tcps = self
            .layer_number("timeCodesPerSecond")
            .or(fps_said)
            .unwrap_or(24.0);
        let fps = fps_said.unwrap_or(24.0);
        if !(tcps > 0.0 && fps > 0.0 && tcps.is_finite() && fps.is_finite()) {
            return Err(self.err(
                "timeCodesPerSecond",
                format!("{tcps} time codes and {fps} frames per second: expected positive rates"),
            ));
        }
        if tcps != fps {
            notes.push(format!(
                "the file has {tcps} time codes per second and {fps} frames per second: frame F is read at time code F·{tcps}/{fps}"
            ));
        }
        let mut out = SceneCameras {
            cameras: Vec::new(),
            poses: Vec::new(),
            notes,
            units,
        };
        for cam in &found {
            let prim = cam.prim();
            let name = camera_name(cam);
            let field = format!("camera {name:?} ({}, line {})", cam.path, prim.line);
            let err = |m: String| self.err(&field, m);
            if let Some(p) = cam.chain.iter().find(|p| composed(p)) {
                return Err(err(format!(
                    "the prim {:?} (line {}) has references, payloads, inherits, variants or value clips, which this reader does not compose: {FLATTEN}",
                    p.name, p.line
                )));
            }
            let names = |r: &&Render| r.camera.as_deref() == Some(cam.path.as_str());
            let render = (renders.iter().filter(|r| r.product).find(names))
                .or_else(|| renders.iter().find(names));
            let own_size = match prim
                .attr("modelflow:imageSize")
                .and_then(|a| a.default.as_ref())
            {
                Some(v) => Some(int2(v).ok_or_else(|| {
                    err("modelflow:imageSize: expected two whole numbers of pixels".into())
                })?),
                None => None,
            };
            let (width, height) = match size.or(own_size).or(render.and_then(|r| r.resolution)) {
                Some(s) => s,
                None => return Err(err(
                    "the file gives no image size (no render settings name this camera): give it with --size WxH (Python: size=(w, h))".into(),
                )),
            };
            if let Some(r) = render {
                if let Some(a) = r.pixel_aspect.filter(|a| (a - 1.0).abs() > 1e-9) {
                    return Err(err(format!(
                        "its render settings {} give pixels of aspect {a}: only square pixels are read",
                        r.path
                    )));
                }
            }
            let policy = render
                .and_then(|r| r.policy.clone())
                .unwrap_or_else(|| "expandAperture".into());
            let mut views: Vec<View> = Vec::new();
            let mut conformed = false;
            for frame in first..=last {
                let time = frame as f64 * tcps / fps;
                let (k, c) = film_k(prim, time, (width, height), &policy, own_size.is_some())
                    .map_err(&err)?;
                conformed |= c;
                let world = orthonormalized(world_transform(&cam.chain, time).map_err(&err)?)
                    .map_err(&err)?;
                let (r, t) = world_to_camera(&world).map_err(&err)?;
                views.push((frame, k, r, t));
            }
            let (camera, poses) = still_or_moving(name.clone(), (width, height), &views, || {
                format!("moving: a pose per frame (time codes at {tcps} per second)")
            })
            .map_err(&err)?;
            if conformed {
                out.notes.push(format!(
                    "camera {name:?}: its aperture's aspect is not the image's {width}x{height}: conformed by `{policy}` (USD's render settings; square pixels)"
                ));
            }
            if poses.is_some() {
                if let Some((lo, hi)) = sampled_span(&cam.chain) {
                    let (lo, hi) = (lo * fps / tcps, hi * fps / tcps);
                    if (first as f64) < lo - 1e-9 || (last as f64) > hi + 1e-9 {
                        out.notes.push(format!(
                            "camera {name:?} is sampled at frames {lo}..{hi} only: frames outside hold its nearest pose"
                        ));
                    }
                }
            }
            out.cameras.push(camera);
            out.poses.push(poses);
        }
        Ok(out)
    }
}

/// Collects the camera prims defined on the stage below `p` (and `p`), what was left out and
/// why, and the render settings and products.
fn walk<'a>(
    p: &'a Prim,
    chain: &mut Vec<&'a Prim>,
    parent: &str,
    found: &mut Vec<Found<'a>>,
    left_out: &mut Vec<String>,
    renders: &mut Vec<Render>,
) {
    let path = format!("{parent}/{}", p.name);
    chain.push(p);
    let defined = chain
        .iter()
        .all(|q| q.specifier == Specifier::Def && active(q));
    if defined && (p.ty == "RenderSettings" || p.ty == "RenderProduct") {
        let rel = |n: &str| match p.attr(n).and_then(|a| a.default.as_ref()) {
            Some(Value::Path(s)) => vec![s.clone()],
            Some(Value::List(l)) => l
                .iter()
                .filter_map(|v| match v {
                    Value::Path(s) => Some(s.clone()),
                    _ => None,
                })
                .collect(),
            _ => Vec::new(),
        };
        renders.push(Render {
            product: p.ty == "RenderProduct",
            camera: rel("camera").into_iter().next(),
            resolution: p
                .attr("resolution")
                .and_then(|a| a.default.as_ref())
                .and_then(int2),
            policy: match p
                .attr("aspectRatioConformPolicy")
                .and_then(|a| a.default.as_ref())
            {
                Some(Value::Text(s)) => Some(s.clone()),
                _ => None,
            },
            pixel_aspect: match p.attr("pixelAspectRatio").and_then(|a| a.default.as_ref()) {
                Some(Value::Num(x)) => Some(*x),
                _ => None,
            },
            products: rel("products"),
            path: path.clone(),
        });
    }
    if p.ty == "Camera" {
        let active = chain.iter().all(|q| active(q));
        if let Some(q) = chain.iter().find(|q| q.specifier != Specifier::Def) {
            let how = if q.specifier == Specifier::Class {
                "class"
            } else {
                "over"
            };
            left_out.push(format!(
                "camera {path} is below an `{how}` ({}), not defined on the stage: left out",
                q.name
            ));
        } else if !active {
            left_out.push(format!(
                "camera {path} is deactivated (active = false): left out"
            ));
        } else {
            found.push(Found {
                chain: chain.clone(),
                path: path.clone(),
            });
        }
    }
    for c in &p.children {
        walk(c, chain, &path, found, left_out, renders);
    }
    chain.pop();
}

/// A render product without a camera, size or policy of its own takes its render settings'.
fn inherit_render_settings(renders: &mut [Render]) {
    let settings: Vec<Render> = renders
        .iter()
        .filter(|r| !r.products.is_empty())
        .cloned()
        .collect();
    for s in settings {
        for r in renders.iter_mut().filter(|r| s.products.contains(&r.path)) {
            r.camera = r.camera.take().or(s.camera.clone());
            r.resolution = r.resolution.or(s.resolution);
            r.policy = r.policy.take().or(s.policy.clone());
            r.pixel_aspect = r.pixel_aspect.or(s.pixel_aspect);
        }
    }
}

/// Whether the prim is active (not `active = false`).
fn active(p: &Prim) -> bool {
    !matches!(p.meta("active"), Some(Value::Text(s)) if s == "false" || s == "0")
        && !matches!(p.meta("active"), Some(Value::Num(x)) if *x == 0.0)
}

/// Whether composition would change the prim: references, payloads, inherits, specializes or
/// variants.
fn composed(p: &Prim) -> bool {
    p.variants
        || p.meta.iter().any(|(k, v)| {
            matches!(
                k.as_str(),
                "references"
                    | "payload"
                    | "inherits"
                    | "specializes"
                    | "variants"
                    | "variantSets"
                    | "clips"
                    | "clipSets"
            ) && *v != Value::None
                && !matches!(v, Value::List(l) if l.is_empty())
        })
}

/// The camera's name: modelflow's own (`modelflow:name`); else, for a camera prim without a
/// transform of its own that is its `Xform`'s only child (Blender's object over its camera
/// data, Maya's transform over its shape), the `Xform`'s name; else the prim's.
fn camera_name(cam: &Found) -> String {
    let prim = cam.prim();
    if let Some(Value::Text(s)) = prim.attr("modelflow:name").and_then(|a| a.default.as_ref()) {
        return s.clone();
    }
    if let [.., parent, _] = cam.chain.as_slice() {
        if prim.attr("xformOpOrder").is_none() && parent.ty == "Xform" && parent.children.len() == 1
        {
            return parent.name.clone();
        }
    }
    prim.name.clone()
}

fn int2(v: &Value) -> Option<(u32, u32)> {
    match v {
        Value::Tuple(t) => match t.as_slice() {
            [Value::Num(w), Value::Num(h)] => super::whole_size(*w, *h),
            _ => None,
        },
        _ => None,
    }
}

/// A value's numbers, tuples and matrices flattened (row by row), or `None` when it has others.
fn numbers(v: &Value, out: &mut Vec<f64>) -> Option<()> {
    match v {
        Value::Num(x) => out.push(*x),
        Value::Tuple(t) => {
            for x in t {
                numbers(x, out)?;
            }
        }
        _ => return None,
    }
    Some(())
}

/// The attribute's numbers at time code `time`, interpolated as USD does: linearly between the
/// samples around it (quaternions by slerp), held before the first and after the last; the
/// default when it has no samples. 32-bit types rounded as USD stores them.
fn numbers_at(a: &Attr, time: f64) -> std::result::Result<Option<Vec<f64>>, String> {
    if a.spline {
        return Err(format!(
            "{} (line {}) is animated by a spline, which is not read: bake it to time samples",
            a.name, a.line
        ));
    }
    let get = |v: &Value| -> std::result::Result<Vec<f64>, String> {
        let mut out = Vec::new();
        if *v == Value::None {
            return Err(format!(
                "{} (line {}) is blocked (None) at time code {time}",
                a.name, a.line
            ));
        }
        numbers(v, &mut out)
            .ok_or_else(|| format!("{} (line {}): expected numbers", a.name, a.line))?;
        if a.ty.starts_with("float") || a.ty.starts_with("quatf") {
            for x in &mut out {
                *x = *x as f32 as f64;
            }
        }
        Ok(out)
    };
    let quat = a.ty.starts_with("quat");
    let values = match &a.samples {
        Some(s) if !s.is_empty() => {
            let i = s.partition_point(|x| x.0 <= time);
            if i == 0 && s[0].1 != Value::None {
                get(&s[0].1)?
            } else if s[i.max(1) - 1].1 == Value::None {
                // Blocked from this sample on: the fallback, as USD reads it.
                return Ok(None);
            } else if i == s.len() || s[i - 1].0 == time || s[i].1 == Value::None {
                // After the last sample, or before a blocked one: held.
                get(&s[i - 1].1)?
            } else {
                let (t0, t1) = (s[i - 1].0, s[i].0);
                let (a0, a1) = (get(&s[i - 1].1)?, get(&s[i].1)?);
                let u = (time - t0) / (t1 - t0);
                if a0.len() != a1.len() {
                    return Err(format!(
                        "{} (line {}): samples of different sizes",
                        a.name, a.line
                    ));
                }
                if quat && a0.len() == 4 {
                    slerp(&a0, &a1, u)
                } else {
                    a0.iter().zip(&a1).map(|(x, y)| x + (y - x) * u).collect()
                }
            }
        }
        _ => match &a.default {
            // Blocked (None): the schema's fallback, as when not authored.
            Some(Value::None) | None => return Ok(None),
            Some(v) => get(v)?,
        },
    };
    if values.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "{} (line {}) is not finite at time code {time}",
            a.name, a.line
        ));
    }
    Ok(Some(values))
}

/// Spherical interpolation of quaternions `(w, x, y, z)`, the shorter way round (`GfSlerp`).
fn slerp(a: &[f64], b: &[f64], u: f64) -> Vec<f64> {
    let q = |v: &[f64]| nalgebra::Quaternion::new(v[0], v[1], v[2], v[3]);
    let (qa, qb) = (
        nalgebra::UnitQuaternion::from_quaternion(q(a)),
        nalgebra::UnitQuaternion::from_quaternion(q(b)),
    );
    let qb = if qa.coords.dot(&qb.coords) < 0.0 {
        nalgebra::UnitQuaternion::new_unchecked(-qb.into_inner())
    } else {
        qb
    };
    let r = qa.try_slerp(&qb, u, 1e-12).unwrap_or(qa);
    vec![r.w, r.i, r.j, r.k]
}

/// The camera's world transform at time code `time` (column vectors: `p_world = M·p_camera`):
/// each prim's operations composed from the top, a `!resetXformStack!` dropping those above.
fn world_transform(chain: &[&Prim], time: f64) -> std::result::Result<Matrix4<f64>, String> {
    let mut m = Matrix4::identity();
    // Prims that are not transformable (a Scope, a typeless prim, a material) have no
    // transform, whatever operations they author: USD ignores them.
    let transformable = |p: &&&Prim| {
        !matches!(
            p.ty.as_str(),
            "" | "Scope"
                | "Material"
                | "Shader"
                | "NodeGraph"
                | "RenderSettings"
                | "RenderProduct"
                | "RenderVar"
                | "GeomSubset"
                | "SkelAnimation"
                | "BlendShape"
        )
    };
    for p in chain.iter().filter(transformable) {
        let (local, reset) = local_transform(p, time)?;
        m = if reset { local } else { m * local };
    }
    Ok(m)
}

/// `m` with its axes made orthonormal as Pixar's `GfCamera` makes a camera's
/// (`GfMatrix4d::Orthonormalize`: each axis repeatedly averaged with its part square to the
/// others, then normalised, until they change by less than 10⁻⁶; within 10⁻⁶ rad of Gf's own), so that a scale or shear above the camera
/// drops out and a frame between two matrix samples (interpolated entry by entry) is the turn USD
/// shows. Written out because the result must be USD's, not another orthonormalisation's.
fn orthonormalized(mut m: Matrix4<f64>) -> std::result::Result<Matrix4<f64>, String> {
    let mut axes = [0, 1, 2].map(|j| Vector3::new(m[(0, j)], m[(1, j)], m[(2, j)]));
    for a in &mut axes {
        let n = a.norm();
        if !(n > 1e-12 && n.is_finite()) {
            return Err("a transform that scales an axis to zero".into());
        }
        *a /= n;
    }
    if axes[0].cross(&axes[1]).norm() < 1e-6
        || axes[0].cross(&axes[2]).norm() < 1e-6
        || axes[1].cross(&axes[2]).norm() < 1e-6
    {
        return Err("a transform that folds two of the camera's axes into one".into());
    }
    for _ in 0..20 {
        let [x, y, z] = axes;
        let bx = x - y * y.dot(&x) - z * z.dot(&(x - y * y.dot(&x)));
        let by = y - x * x.dot(&y) - z * z.dot(&(y - x * x.dot(&y)));
        let bz = z - x * x.dot(&z) - y * y.dot(&(z - x * x.dot(&z)));
        let next = [(x + bx) / 2.0, (y + by) / 2.0, (z + bz) / 2.0];
        // The change measured before normalising, as Gf measures it.
        let change: f64 = (0..3).map(|i| (axes[i] - next[i]).norm_squared()).sum();
        axes = next.map(|c| c.normalize());
        if change < 1e-6 {
            break;
        }
    }
    for (j, a) in axes.iter().enumerate() {
        for i in 0..3 {
            m[(i, j)] = a[i];
        }
    }
    Ok(m)
}

/// A prim's own transform at `time` from its `xformOpOrder` (outermost first), and whether it
/// resets the transforms above it.
fn local_transform(p: &Prim, time: f64) -> std::result::Result<(Matrix4<f64>, bool), String> {
    let Some(order) = p.attr("xformOpOrder") else {
        return Ok((Matrix4::identity(), false));
    };
    let ops: Vec<String> = match &order.default {
        Some(Value::List(l)) => l
            .iter()
            .map(|v| match v {
                Value::Text(s) => Ok(s.clone()),
                _ => Err(format!(
                    "{}'s xformOpOrder (line {}): expected tokens",
                    p.name, order.line
                )),
            })
            .collect::<std::result::Result<_, _>>()?,
        None | Some(Value::None) => Vec::new(),
        Some(_) => {
            return Err(format!(
                "{}'s xformOpOrder (line {}): expected a list of tokens",
                p.name, order.line
            ))
        }
    };
    let mut m = Matrix4::identity();
    let mut reset = false;
    for op in &ops {
        if op == "!resetXformStack!" {
            // As USD: the operations before it are dropped with the parents'.
            m = Matrix4::identity();
            reset = true;
            continue;
        }
        let (inverse, attr_name) = match op.strip_prefix("!invert!") {
            Some(rest) => (true, rest),
            None => (false, op.as_str()),
        };
        let a = p.attr(attr_name).ok_or_else(|| {
            format!(
                "{}'s xformOpOrder names {attr_name}, which the prim does not have",
                p.name
            )
        })?;
        let kind = attr_name
            .strip_prefix("xformOp:")
            .and_then(|s| s.split(':').next())
            .ok_or_else(|| {
                format!(
                    "{}'s xformOpOrder names {attr_name}: not a transform operation (xformOp:...)",
                    p.name
                )
            })?;
        let v = numbers_at(a, time)?
            .ok_or_else(|| format!("{} of {} (line {}) has no value", attr_name, p.name, a.line))?;
        let m_op = op_matrix(kind, &v)
            .map_err(|e| format!("{attr_name} of {} (line {}): {e}", p.name, a.line))?;
        let m_op = if inverse {
            m_op.try_inverse().ok_or_else(|| {
                format!(
                    "{attr_name} of {} (line {}) is inverted (!invert!) but cannot be",
                    p.name, a.line
                )
            })?
        } else {
            m_op
        };
        m *= m_op;
    }
    Ok((m, reset))
}

/// The matrix (column vectors) of one operation of kind `kind` with value `v`.
fn op_matrix(kind: &str, v: &[f64]) -> std::result::Result<Matrix4<f64>, String> {
    let need = |n: usize| {
        if v.len() == n {
            Ok(())
        } else {
            Err(format!("expected {n} numbers, found {}", v.len()))
        }
    };
    let axis = |c: u8, deg: f64| -> Matrix3<f64> {
        let a = match c {
            b'X' => Vector3::x_axis(),
            b'Y' => Vector3::y_axis(),
            _ => Vector3::z_axis(),
        };
        Rotation3::from_axis_angle(&a, deg.to_radians()).into_inner()
    };
    let linear = |l: Matrix3<f64>| {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&l);
        m
    };
    Ok(match kind {
        "translate" => {
            need(3)?;
            Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2]))
        }
        "scale" => {
            need(3)?;
            Matrix4::new_nonuniform_scaling(&Vector3::new(v[0], v[1], v[2]))
        }
        "rotateX" | "rotateY" | "rotateZ" => {
            need(1)?;
            linear(axis(kind.as_bytes()[6], v[0]))
        }
        "orient" => {
            need(4)?;
            linear(
                super::quaternion_rotation(v[0], v[1], v[2], v[3])
                    .ok_or("a quaternion of zero length")?,
            )
        }
        "transform" => {
            need(16)?;
            // Rows as written map row vectors; ours map columns.
            Matrix4::from_row_slice(v).transpose()
        }
        _ => match kind.strip_prefix("rotate") {
            // rotateXYZ: the value is (x, y, z) angles; X turns first, then Y, then Z.
            Some(order)
                if order.len() == 3 && {
                    let mut s: Vec<u8> = order.bytes().collect();
                    s.sort_unstable();
                    s == b"XYZ"
                } =>
            {
                need(3)?;
                let angle = |c: u8| v[(c - b'X') as usize];
                let o = order.as_bytes();
                linear(axis(o[2], angle(o[2])) * axis(o[1], angle(o[1])) * axis(o[0], angle(o[0])))
            }
            _ => {
                return Err(format!(
                    "xformOp:{kind}: not a transform operation USD knows"
                ))
            }
        },
    })
}

/// The earliest and latest time codes at which the transforms above and of the camera are
/// sampled, if any are.
fn sampled_span(chain: &[&Prim]) -> Option<(f64, f64)> {
    let times = chain
        .iter()
        .flat_map(|p| p.attrs.iter())
        .filter(|a| a.name.starts_with("xformOp:"))
        .filter_map(|a| a.samples.as_ref())
        .flat_map(|s| s.iter().map(|x| x.0));
    times.fold(None, |acc, t| match acc {
        None => Some((t, t)),
        Some((lo, hi)) => Some((f64::min(lo, t), f64::max(hi, t))),
    })
}

/// The camera matrix of a USD camera at `time` for a `width`×`height` image, and whether its
/// aperture was conformed to the image's aspect by `policy`; or why it cannot be. Pixar's
/// `GfCamera` maps the aperture (offset by the aperture offsets) onto the image: with pixel
/// centres at integers, `fx = f·W/A_h`, `cx = W/2 − o_h·W/A_h − 0.5`, `fy = f·H/A_v`,
/// `cy = H/2 + o_v·H/A_v − 0.5`.
fn film_k(
    cam: &Prim,
    time: f64,
    (width, height): (u32, u32),
    policy: &str,
    own: bool,
) -> std::result::Result<(Matrix3<f64>, bool), String> {
    // Omniverse's lens models replace the pinhole; no other package reads them.
    if let Some(a) = cam.attrs.iter().find(|a| {
        a.name.starts_with("omni:lensdistortion:")
            || (a.name == "cameraProjectionType"
                && !matches!(&a.default, Some(Value::Text(t)) if t == "pinhole"))
    }) {
        return Err(format!(
            "{} (line {}): an Omniverse lens model, not read: only pinhole cameras are (calibrate the lens, e.g. with COLMAP or OpenCV, and import that)",
            a.name, a.line
        ));
    }
    if let Some(Value::Text(p)) = cam.attr("projection").and_then(|a| a.default.as_ref()) {
        if p != "perspective" {
            return Err(format!(
                "a {p} projection: only perspective cameras are read"
            ));
        }
    }
    let get = |name: &str, fallback: f64| -> std::result::Result<f64, String> {
        match cam.attr(name) {
            Some(a) => match numbers_at(a, time)? {
                Some(v) if v.len() == 1 => Ok(v[0]),
                Some(_) => Err(format!("{name} (line {}): expected one number", a.line)),
                None => Ok(fallback),
            },
            None => Ok(fallback),
        }
    };
    // UsdGeomCamera's fallbacks (a 35 mm film back's aperture, in mm).
    let focal = get("focalLength", 50.0)?;
    let (mut ah, mut av) = (
        get("horizontalAperture", 20.955)?,
        get("verticalAperture", 15.2908)?,
    );
    let (oh, ov) = (
        get("horizontalApertureOffset", 0.0)?,
        get("verticalApertureOffset", 0.0)?,
    );
    if !(focal > 0.0 && ah > 0.0 && av > 0.0) {
        return Err(format!(
            "focal length {focal} and apertures {ah} x {av}: expected positive numbers"
        ));
    }
    let (w, h) = (width as f64, height as f64);
    let aspect = w / h;
    let mismatch = ((ah / av) / aspect - 1.0).abs();
    // modelflow's own export writes a camera whose fx and fy differ as an aperture of another
    // aspect than the image's (marked by its modelflow:imageSize): taken as it is.
    let conformed = mismatch > SAY_CONFORMED && !own;
    if mismatch > 0.0 && !own {
        // CameraUtilConformWindow: one aperture changed to the image's aspect, the offsets kept.
        let widen = match policy {
            "expandAperture" => ah / av < aspect,
            "cropAperture" => ah / av > aspect,
            "adjustApertureWidth" => true,
            "adjustApertureHeight" => false,
            "adjustPixelAspectRatio" => {
                return Err(format!(
                    "its aperture's aspect {:.4} is not the image's {aspect:.4}, and its render settings' policy adjustPixelAspectRatio would make pixels that are not square: not read",
                    ah / av
                ))
            }
            other => return Err(format!("aspectRatioConformPolicy {other:?}: not a policy USD knows")),
        };
        if widen {
            ah = av * aspect;
        } else {
            av = ah / aspect;
        }
    }
    let k = pinhole_k(
        focal * w / ah,
        focal * h / av,
        w / 2.0 - oh * w / ah - 0.5,
        h / 2.0 + ov * h / av - 0.5,
    )
    .ok_or("a film back that gives no focal length")?;
    Ok((k, conformed))
}

#[cfg(test)]
mod tests {
    use super::super::scene3d::worst_miss;
    use super::*;
    use crate::input::calib::testing::has;

    fn fixture() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/usd")
    }

    fn names(read: &SceneCameras) -> Vec<&str> {
        read.cameras.iter().map(|c| c.name.as_str()).collect()
    }

    #[test]
    fn blenders_cameras_project_as_blender_renders_them() {
        // fixtures/usd/blender.usda: the four cameras of the Alembic fixture as Blender 5.0's
        // USD exporter writes them (a shifted camera under a moved, turned and twice-scaled
        // empty; Blender's default film back on a 16:9 render; one under a turned empty; one
        // keyed at frames 1, 3, 5, sampled at every frame), each an Xform holding its camera
        // data; blender-expected.json: where Blender's own `world_to_camera_view` puts six
        // points at each frame (tools/make_alembic_fixture.py). Blender writes no image size.
        let path = fixture().join("blender.usda");
        let e = read_usd(&path, None, (1, 5)).unwrap_err().to_string();
        has(&e, &["blender.usda", "no image size", "--size"]);
        let read = read_usd(&path, Some((1280, 720)), (1, 5)).unwrap();
        let mut n = names(&read);
        n.sort_unstable();
        assert_eq!(n, ["front", "moving", "side", "tall"], "the objects' names");
        for (c, poses) in read.cameras.iter().zip(&read.poses) {
            assert_eq!(poses.is_some(), c.name == "moving", "{}", c.name);
        }
        assert!(read.notes[0].contains("Z up"), "{:?}", read.notes);
        let worst = worst_miss(&read, &fixture().join("blender-expected.json"), 1);
        // Blender's 32-bit floats: about a ten-thousandth of a pixel.
        assert!(worst < 1e-3, "{worst} px from Blender's pixels");
    }

    #[test]
    fn pixars_cameras_project_as_pixars_camera_model_does() {
        // fixtures/usd/cameras.usda, written by Pixar's library (tools/make_usd_fixture.py):
        // translate, rotateZXY, rotateX/Z, scale, orient, a pivot and its !invert!, a 4x4
        // transform with !resetXformStack! under a moved and scaled prim, time samples that
        // USD interpolates (linearly, and by slerp for the orientation), apertures conformed to
        // the image by the render settings' policies, image sizes from render settings and a
        // render product, a matrix sampled at frames 1 and 5 (interpolated entry by entry, then
        // orthonormalised as Gf.Camera does); cameras-expected.json: where Pixar's `Gf.Camera` puts six points.
        let path = fixture().join("cameras.usda");
        let read = read_usd(&path, None, (1, 5)).unwrap();
        assert_eq!(
            names(&read),
            ["front", "orbit", "matrixcam", "tumble", "moving"]
        );
        for (c, poses) in read.cameras.iter().zip(&read.poses) {
            assert_eq!(
                (c.width, c.height),
                (1280, 720),
                "the render settings' size"
            );
            let moves = c.name == "moving" || c.name == "tumble";
            assert_eq!(poses.is_some(), moves, "{}", c.name);
        }
        let notes = read.notes.join("\n");
        for want in [
            "Y up, 1 m per unit",
            "camera /_template/cam is below a",
            "camera /ghost/cam is below an `over`",
            "camera /off is deactivated",
            "\"orbit\": its aperture's aspect is not the image's 1280x720: conformed by `expandAperture`",
            "\"matrixcam\": its aperture's aspect is not the image's 1280x720: conformed by `cropAperture`",
        ] {
            assert!(notes.contains(want), "{notes}\nlacks {want:?}");
        }
        let worst = worst_miss(&read, &fixture().join("cameras-expected.json"), 1);
        assert!(worst < 1e-3, "{worst} px from Pixar's pixels");
        // The operations composed the other way round miss by far: the test can fail.
        let text = std::fs::read_to_string(&path).unwrap().replace(
            "[\"xformOp:translate\", \"xformOp:rotateZXY\", \"xformOp:scale\"]",
            "[\"xformOp:scale\", \"xformOp:rotateZXY\", \"xformOp:translate\"]",
        );
        let dir = tempfile::tempdir().unwrap();
        let reversed = dir.path().join("reversed.usda");
        std::fs::write(&reversed, text).unwrap();
        let read = read_usd(&reversed, None, (1, 5)).unwrap();
        let worst = worst_miss(&read, &fixture().join("cameras-expected.json"), 1);
        assert!(worst > 10.0, "{worst}");
    }

    #[test]
    fn the_usd_export_reads_back_as_the_scenes_cameras() {
        // modelflow's own export: a webcam's K (principal point off centre, fx != fy) still,
        // and the same K moving, given at frames 10 and 12 of 10..13; the image size and the
        // scene's own names (not USD identifiers) carried in modelflow's attributes.
        use super::super::scene3d::rig::{self, pose};
        let k = rig::k();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("shot.usda");
        rig::export(crate::export::ExportFormat::Usda, &out, &[10, 11, 12, 13]);
        let read = read_usd(&out, None, (10, 13)).unwrap();
        assert_eq!(names(&read), ["web cam", "handheld"]);
        for c in &read.cameras {
            assert_eq!((c.width, c.height), (1280, 720));
            // The apertures are 32-bit floats.
            assert!((c.k - k).abs().max() < 1e-3, "{}: {}", c.name, c.k);
        }
        let (r, t) = pose([0.3, -2.0, 4.0]);
        assert!(
            (read.cameras[0].r - r).abs().max() < 1e-12 && (read.cameras[0].t - t).norm() < 1e-12
        );
        assert!(read.poses[0].is_none());
        let poses = read.poses[1].as_ref().expect("moving");
        assert_eq!(
            poses.iter().map(|p| p.0).collect::<Vec<_>>(),
            [10, 11, 12, 13]
        );
        // Frames 10, 12 and 13 (held after the last sample) are the views given; frame 11, between
        // two samples, is USD's interpolation: a turn between them, not either.
        for (f, eye) in [
            (0, [3.0, 1.0, 3.0]),
            (2, [2.0, 2.5, 3.5]),
            (3, [2.0, 2.5, 3.5]),
        ] {
            let (rr, tt) = pose(eye);
            assert!(
                (poses[f].1 - rr).abs().max() < 1e-12 && (poses[f].2 - tt).norm() < 1e-12,
                "{f}"
            );
        }
        let (r10, r12) = (pose([3.0, 1.0, 3.0]).0, pose([2.0, 2.5, 3.5]).0);
        let between = poses[1].1;
        assert!(crate::base::camera::is_rotation(&between, 1e-9));
        let angle = |a: &Matrix3<f64>, b: &Matrix3<f64>| {
            Rotation3::from_matrix_unchecked(a * b.transpose()).angle()
        };
        let whole = angle(&r12, &r10);
        assert!(whole > 0.1, "{whole}");
        assert!((angle(&between, &r10) - whole / 2.0).abs() < 0.05 * whole);
    }

    /// Writes `text` as a USD file and reads it at frames 1..2, 640x480.
    fn read_text(text: &str) -> Result<SceneCameras> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shot.usda");
        std::fs::write(&path, text).unwrap();
        read_usd(&path, Some((640, 480)), (1, 2))
    }

    fn refused(text: &str, parts: &[&str]) {
        match read_text(text) {
            Ok(c) => panic!("should be refused, read {} cameras", c.cameras.len()),
            Err(e) => has(&e.to_string(), &[&["shot.usda"], parts].concat()),
        }
    }

    const CAMERA: &str = "#usda 1.0\ndef Xform \"rig\" (\n    kind = \"group\"\n)\n{\n    def Camera \"cam\"\n    {\n        float focalLength = 30\n        float horizontalAperture = 36\n        float verticalAperture = 27\n        double3 xformOp:translate = (0, 0, 5)\n        uniform token[] xformOpOrder = [\"xformOp:translate\"]\n    }\n}\n";

    #[test]
    fn what_usd_ignores_or_falls_back_on_is_ignored_and_fallen_back_on() {
        // A Scope's and a typeless prim's operations move nothing; !resetXformStack! after
        // operations drops them with the parents'; a blocked focal length is the fallback, 50;
        // a list edit that deletes a relationship's target names nothing.
        let text = CAMERA
            .replace("def Xform \"rig\"", "def Scope \"rig\"")
            .replace(
                "    def Camera \"cam\"\n    {",
                "    double3 xformOp:translate = (10, 0, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n    def Camera \"cam\"\n    {",
            )
            .replace("float focalLength = 30", "float focalLength = None");
        let read = read_text(&text).unwrap();
        let c = &read.cameras[0];
        assert!((c.k[(0, 0)] - 50.0 * 640.0 / 36.0).abs() < 1e-9, "{}", c.k);
        assert!(
            (c.t - Vector3::new(0.0, 0.0, 5.0)).norm() < 1e-12,
            "{}",
            c.t
        );
        let text = CAMERA.replace(
            "[\"xformOp:translate\"]",
            "[\"xformOp:rotateX\", \"!resetXformStack!\", \"xformOp:translate\"]\n        float xformOp:rotateX = 90",
        );
        let c = &read_text(&text).unwrap().cameras[0];
        assert!(
            (c.t - Vector3::new(0.0, 0.0, 5.0)).norm() < 1e-12
                && (c.r - Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)))
                    .abs()
                    .max()
                    < 1e-12
        );
        let render = "def RenderSettings \"r\"\n{\n    delete rel camera = </rig/cam>\n    uniform int2 resolution = (10, 10)\n}\n";
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shot.usda");
        std::fs::write(&path, format!("{CAMERA}{render}")).unwrap();
        let e = read_usd(&path, None, (1, 1)).unwrap_err().to_string();
        has(&e, &["no image size"]);
    }

    #[test]
    fn cameras_it_cannot_read_as_usd_shows_them_are_refused_by_name() {
        let read = read_text(CAMERA).unwrap();
        assert_eq!(names(&read), ["cam"]);
        assert!((read.cameras[0].k[(0, 0)] - 30.0 * 640.0 / 36.0).abs() < 1e-9);
        let with = |from: &str, to: &str| {
            assert!(CAMERA.contains(from), "{from}");
            CAMERA.replace(from, to)
        };
        // Composition this reader does not do.
        refused(
            &with(
                "kind = \"group\"",
                "prepend references = @./rig.usda@</rig> (offset = 2)",
            ),
            &[
                "camera \"cam\" (/rig/cam",
                "\"rig\" (line 2) has references",
                "usdcat --flatten",
            ],
        );
        refused(
            &with(
                "float focalLength = 30",
                "token projection = \"orthographic\"",
            ),
            &["orthographic projection", "only perspective"],
        );
        refused(
            &with(
                "float focalLength = 30",
                "float focalLength.timeSamples = { 1: 30, 2: 35 }",
            ),
            &["changes over the frames", "keep one K"],
        );
        refused(
            &with(
                "double3 xformOp:translate = (0, 0, 5)",
                "double3 xformOp:translate.spline = { 1: 0 }",
            ),
            &[
                "xformOp:translate (line",
                "spline",
                "bake it to time samples",
            ],
        );
        refused(
            &with("[\"xformOp:translate\"]", "[\"xformOp:translate\", \"xformOp:scale\"]\n        float3 xformOp:scale = (1, -1, 1)"),
            &["mirrors the camera"],
        );
        refused(
            &with(
                "[\"xformOp:translate\"]",
                "[\"xformOp:translate\", \"xformOp:rotateXYW\"]",
            ),
            &["names xformOp:rotateXYW, which the prim does not have"],
        );
        refused(
            &with(
                "[\"xformOp:translate\"]",
                "[\"xformOp:translate\", \"xformOp:skew\"]\n        float xformOp:skew = 3",
            ),
            &["xformOp:skew: not a transform operation USD knows"],
        );
        refused(
            &with("(0, 0, 5)", "(0, 0)"),
            &[
                "xformOp:translate of cam (line 11)",
                "expected 3 numbers, found 2",
            ],
        );
        refused(&with("Camera", "Mesh"), &["holds no Camera prim"]);
        refused(
            &with(
                "#usda 1.0\n",
                "#usda 1.0\n(\n    subLayers = [@./anim.usda@]\n)\n",
            ),
            &["subLayers", "usdcat --flatten"],
        );
        refused(
            &with(
                "kind = \"group\"",
                "clips = { dictionary default = { asset[] assetPaths = [@a.usd@] } }",
            ),
            &["value clips", "usdcat --flatten"],
        );
        refused(
            &with(
                "float focalLength = 30",
                "token cameraProjectionType = \"fisheyePolynomial\"",
            ),
            &["cameraProjectionType (line 8)", "Omniverse lens model"],
        );
        match read_usd(Path::new("x.usda"), None, (2, 1)) {
            Err(e) => has(&e.to_string(), &["--frames", "2..1", "A <= B"]),
            Ok(_) => panic!("a reversed range read"),
        }
        // Broken text: the line named.
        refused(
            &with(
                "float verticalAperture = 27",
                "float verticalAperture = \"27",
            ),
            &["line 10", "string"],
        );
        refused(&with("    }\n}\n", "    }\n"), &["ends in the middle"]);
        refused(
            &with("= 27", "= 27 27"),
            &[
                "line 10",
                "expected a property or a prim, found the number 27",
            ],
        );
        refused("#usdc 1.0\n", &["line 1", "#usda 1.0"]);
        refused(
            "PXR-USDC\0\0\0\0",
            &["binary USD layer", "usdcat --flatten"],
        );
        refused("PK\x03\x04rest", &["usdz", "usdcat --flatten"]);
        // Every damage of a real file is an error or a reading, never a panic.
        let real = std::fs::read_to_string(fixture().join("cameras.usda")).unwrap();
        let path = Path::new("damaged.usda");
        for cut in 0..real.len() {
            let _ = read_bytes(path, real.as_bytes()[..cut].to_vec(), None, (1, 2));
        }
        let bytes = real.as_bytes();
        for i in 0..bytes.len() {
            for b in [b'(', b'}', b'"', b'@', b'<', b'0', b'\n', b'#', 0xff] {
                let mut damaged = bytes.to_vec();
                damaged[i] = b;
                let _ = read_bytes(path, damaged, None, (1, 2));
            }
        }
    }
}
