//! mrcal's `.cameramodel` files (one camera each; `mrcal-calibrate-cameras` writes
//! `camera-0.cameramodel`, `camera-1.cameramodel`, ... for a rig, each placed relative to the
//! same reference, camera 0's frame). The format is a Python dict literal: `lensmodel`,
//! `intrinsics` (`fx, fy, cx, cy` and the lens model's distortion), `extrinsics` (`rt_fromref`:
//! a `cv::Rodrigues` vector and a translation taking the reference's coordinates to the
//! camera's), `imagersize` (`[width, height]`); `valid_intrinsics_region`, `icam_intrinsics` and
//! `optimization_inputs` (a bytes literal) are skipped. The literal is read here by hand: no crate
//! reads Python's literal syntax, and the subset mrcal writes is small (dicts, lists, numbers,
//! strings, bytes, comments, trailing commas).
//!
//! Conventions, mrcal's, which are ours: pixel centres at integers, `x_cam = R(r)·x_ref + t`.
//! Lens models: `LENSMODEL_PINHOLE`, `LENSMODEL_OPENCV4`, `5`, `8`, `12` (OpenCV's coefficients in
//! OpenCV's order); mrcal's others (its splined and stereographic models, CAHVOR, CAHVORE,
//! LONLAT, LATLON) have no counterpart in OpenCV's and are refused by name, with mrcal's command
//! that fits one of OpenCV's to them.

use super::{strip_bom, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// The cameras of one `.cameramodel` file, or of every `.cameramodel` file in a folder (in the
/// order of their names, numbers compared as numbers), each named after its file.
pub fn read_mrcal(path: &Path) -> Result<Vec<CalibratedCamera>> {
    let files: Vec<PathBuf> = if path.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)
            .map_err(|e| Error::io(path, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "cameramodel"))
            .collect();
        files.sort_by_key(|p| natural_key(&p.file_stem().unwrap_or_default().to_string_lossy()));
        if files.is_empty() {
            return Err(Error::invalid(
                path,
                "(folder)",
                "no .cameramodel file in it (mrcal-calibrate-cameras writes camera-0.cameramodel, camera-1.cameramodel, ...)",
            ));
        }
        files
    } else {
        vec![path.to_path_buf()]
    };
    files.iter().map(|f| read_one(f)).collect()
}

/// A name split into its text and number runs, so that `camera-10` sorts after `camera-9`.
fn natural_key(s: &str) -> Vec<(String, u64)> {
    let mut out = Vec::new();
    let mut text = String::new();
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        if c.is_ascii_digit() {
            let mut n = c.to_digit(10).unwrap() as u64;
            while let Some(d) = chars.peek().and_then(|d| d.to_digit(10)) {
                n = n.saturating_mul(10).saturating_add(d as u64);
                chars.next();
            }
            out.push((std::mem::take(&mut text), n));
        } else {
            text.push(c);
        }
    }
    out.push((text, 0));
    out
}

fn read_one(path: &Path) -> Result<CalibratedCamera> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut p = Parser {
        s: strip_bom(&text).as_bytes(),
        i: 0,
        depth: 0,
        path,
    };
    p.skip();
    let (lit, line) = p.value()?;
    let Lit::Dict(entries) = lit else {
        return Err(Error::invalid(
            path,
            format!("line {line}"),
            "expected a Python dict literal { 'lensmodel': ..., 'intrinsics': [...], ... }, as mrcal writes a .cameramodel",
        ));
    };
    p.skip();
    if p.i < p.s.len() {
        return Err(p.bad("text after the model's closing }"));
    }
    // As Python reads a dict literal, a key given twice takes its last value; mrcal's reader
    // renames the keys of its older files (`distortion_model`, `lens_model`: `lensmodel`).
    let get = |key: &str| {
        entries.iter().rev().find(|(k, _, _)| {
            k == key || (key == "lensmodel" && (k == "distortion_model" || k == "lens_model"))
        })
    };
    let field = |key: &str| -> Result<(&Lit, usize)> {
        get(key)
            .map(|(_, v, line)| (v, *line))
            .ok_or_else(|| Error::invalid(path, key, "missing"))
    };
    let numbers = |key: &str| -> Result<(Vec<f64>, usize)> {
        let (v, line) = field(key)?;
        let at = format!("line {line}: {key}");
        match v {
            Lit::List(items) => items
                .iter()
                .map(|x| match x {
                    Lit::Num(f) if f.is_finite() => Ok(*f),
                    _ => Err(Error::invalid(path, &at, "expected finite numbers only")),
                })
                .collect::<Result<Vec<f64>>>()
                .map(|v| (v, line)),
            _ => Err(Error::invalid(path, &at, "expected a list of numbers")),
        }
    };
    let (model, mline) = match field("lensmodel")? {
        // mrcal's older files name the models DISTORTION_...
        (Lit::Str(s), line) => (
            match s.strip_prefix("DISTORTION_") {
                Some(rest) => format!("LENSMODEL_{rest}"),
                None => s.clone(),
            },
            line,
        ),
        (_, line) => {
            return Err(Error::invalid(
                path,
                format!("line {line}: lensmodel"),
                "expected a string such as 'LENSMODEL_OPENCV8'",
            ))
        }
    };
    let distortion_count = match model.as_str() {
        "LENSMODEL_PINHOLE" => 0,
        "LENSMODEL_OPENCV4" => 4,
        "LENSMODEL_OPENCV5" => 5,
        "LENSMODEL_OPENCV8" => 8,
        "LENSMODEL_OPENCV12" => 12,
        other => {
            return Err(Error::invalid(
                path,
                format!("line {mline}: lensmodel"),
                format!(
                    "{other} is not read: only LENSMODEL_PINHOLE and LENSMODEL_OPENCV4, 5, 8 or 12 have a counterpart in OpenCV's models; fit one to it with mrcal-convert-lensmodel LENSMODEL_OPENCV8 {} (with --sampled if the file has no optimization_inputs)",
                    path.display()
                ),
            ))
        }
    };
    let (intr, iline) = numbers("intrinsics")?;
    if intr.len() != 4 + distortion_count {
        return Err(Error::invalid(
            path,
            format!("line {iline}: intrinsics"),
            format!(
                "{model} has {} intrinsics (fx, fy, cx, cy and {distortion_count} distortion), found {}",
                4 + distortion_count,
                intr.len()
            ),
        ));
    }
    let k = super::pinhole_k(intr[0], intr[1], intr[2], intr[3]).ok_or_else(|| {
        Error::invalid(
            path,
            format!("line {iline}: intrinsics"),
            "focal lengths must be positive",
        )
    })?;
    let distortion = if distortion_count == 0 {
        None
    } else {
        let d = Distortion::new("opencv", &intr[4..])
            .map_err(|msg| Error::invalid(path, format!("line {iline}: intrinsics"), msg))?;
        Some(d).filter(|d| !d.is_identity())
    };
    let (ext, eline) = numbers("extrinsics")?;
    if ext.len() != 6 {
        return Err(Error::invalid(
            path,
            format!("line {eline}: extrinsics"),
            format!(
                "expected 6 numbers (rt_fromref: a Rodrigues vector, a translation), found {}",
                ext.len()
            ),
        ));
    }
    let r = nalgebra::Rotation3::new(Vector3::new(ext[0], ext[1], ext[2])).into_inner();
    let t = Vector3::new(ext[3], ext[4], ext[5]);
    let (size, sline) = numbers("imagersize")?;
    let (width, height) = (size.len() == 2)
        .then(|| super::whole_size(size[0], size[1]))
        .flatten()
        .ok_or_else(|| {
            Error::invalid(
                path,
                format!("line {sline}: imagersize"),
                "expected [width, height] in whole pixels",
            )
        })?;
    Ok(CalibratedCamera {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        width,
        height,
        k,
        r,
        t,
        distortion,
        note: None,
    })
}

/// A value of the Python literal subset mrcal writes.
enum Lit {
    Dict(Vec<(String, Lit, usize)>),
    List(Vec<Lit>),
    Num(f64),
    Str(String),
    /// A bytes literal (`optimization_inputs`), skipped.
    Bytes,
    Other,
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    /// Lists and dicts open around `i`: bounded, so that a file of brackets is refused, not a
    /// stack overflow.
    depth: usize,
    path: &'a Path,
}

/// Nesting deeper than mrcal ever writes (its deepest is a list of pairs in a dict).
const MAX_DEPTH: usize = 32;

impl Parser<'_> {
    fn line(&self) -> usize {
        super::line_at(self.s, self.i)
    }

    fn bad(&self, msg: impl Into<String>) -> Error {
        Error::invalid(self.path, format!("line {}", self.line()), msg)
    }

    /// Past white space and `#` comments.
    fn skip(&mut self) {
        while self.i < self.s.len() {
            match self.s[self.i] {
                b' ' | b'\t' | b'\r' | b'\n' => self.i += 1,
                b'#' => {
                    while self.i < self.s.len() && self.s[self.i] != b'\n' {
                        self.i += 1;
                    }
                }
                _ => break,
            }
        }
    }

    /// The string literal at `i` (quote `q`); a backslash keeps the character after it (mrcal's
    /// names and models have no escapes that mean more).
    fn string(&mut self, q: u8) -> Result<String> {
        self.i += 1;
        let mut out = Vec::new();
        while self.i < self.s.len() {
            match self.s[self.i] {
                b'\\' if self.i + 1 < self.s.len() => {
                    out.push(self.s[self.i + 1]);
                    self.i += 2;
                }
                c if c == q => {
                    self.i += 1;
                    return Ok(String::from_utf8_lossy(&out).into_owned());
                }
                c => {
                    out.push(c);
                    self.i += 1;
                }
            }
        }
        Err(self.bad("a string that does not end"))
    }

    /// The items of a `[...]` or `{...}` up to `close`, each read by `item`.
    fn items(&mut self, close: u8, mut item: impl FnMut(&mut Self) -> Result<()>) -> Result<()> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(self.bad(format!("lists or dicts nested deeper than {MAX_DEPTH}")));
        }
        self.i += 1;
        loop {
            self.skip();
            match self.s.get(self.i) {
                None => return Err(self.bad(format!("missing a closing {}", close as char))),
                Some(&c) if c == close => {
                    self.i += 1;
                    self.depth -= 1;
                    return Ok(());
                }
                _ => {}
            }
            item(self)?;
            self.skip();
            match self.s.get(self.i) {
                Some(b',') => self.i += 1,
                Some(&c) if c == close => {}
                _ => return Err(self.bad(format!("expected , or {}", close as char))),
            }
        }
    }

    fn value(&mut self) -> Result<(Lit, usize)> {
        self.skip();
        let line = self.line();
        let Some(&c) = self.s.get(self.i) else {
            return Err(self.bad("the file ends where a value was expected"));
        };
        let v = match c {
            b'{' => {
                let mut entries = Vec::new();
                self.items(b'}', |p| {
                    p.skip();
                    let key_line = p.line();
                    let key = match p.s.get(p.i) {
                        Some(&q @ (b'\'' | b'"')) => p.string(q)?,
                        _ => return Err(p.bad("expected a quoted key")),
                    };
                    p.skip();
                    if p.s.get(p.i) != Some(&b':') {
                        return Err(p.bad(format!("expected : after '{key}'")));
                    }
                    p.i += 1;
                    let (v, _) = p.value()?;
                    entries.push((key, v, key_line));
                    Ok(())
                })?;
                Lit::Dict(entries)
            }
            b'[' | b'(' => {
                let close = if c == b'[' { b']' } else { b')' };
                let mut items = Vec::new();
                self.items(close, |p| {
                    items.push(p.value()?.0);
                    Ok(())
                })?;
                Lit::List(items)
            }
            b'\'' | b'"' => Lit::Str(self.string(c)?),
            b'b' if matches!(self.s.get(self.i + 1), Some(b'\'' | b'"')) => {
                self.i += 1;
                let q = self.s[self.i];
                self.string(q)?;
                Lit::Bytes
            }
            _ => {
                let start = self.i;
                while self.i < self.s.len()
                    && !matches!(
                        self.s[self.i],
                        b',' | b']' | b'}' | b')' | b' ' | b'\t' | b'\r' | b'\n' | b'#'
                    )
                {
                    self.i += 1;
                }
                let word = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
                match word {
                    "True" | "False" | "None" => Lit::Other,
                    _ => Lit::Num(word.parse::<f64>().map_err(|_| {
                        self.bad(format!("{word:?} is not a number, string, list or dict"))
                    })?),
                }
            }
        };
        Ok((v, line))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::has;
    use nalgebra::Matrix3;

    fn read(text: &str) -> Result<CalibratedCamera> {
        super::super::testing::read_text("camera-0.cameramodel", text, read_one)
    }

    fn err(text: &str) -> String {
        match read(text) {
            Ok(_) => panic!("should be refused"),
            Err(e) => e.to_string(),
        }
    }

    const MODEL: &str = "# generated by mrcal\n{\n    'lensmodel':  'LENSMODEL_OPENCV4',\n\n    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....\n    'intrinsics': [ 1000, 1001, 640.5, 360.25, -0.2, 0.05, 0.001, -0.0005,],\n\n    'valid_intrinsics_region': [\n    [ 0, 0 ],\n    [ 1279, 0 ],\n    [ 1279, 719 ],\n    [ 0, 0 ],\n],\n\n    # extrinsics are rt_fromref\n    'extrinsics': [ 0, 0, 1.5707963267948966, 1, 2, 3,],\n\n    'imagersize': [ 1280, 720,],\n\n    'icam_intrinsics': 0,\n\n    'optimization_inputs': b'c$}5Y#ab!`~;<=>?@^_{|}',\n\n}\n";

    #[test]
    fn a_model_as_mrcal_writes_it_is_read_with_its_lens_and_pose() {
        let c = read(MODEL).unwrap();
        assert_eq!(
            (c.name.as_str(), c.width, c.height),
            ("camera-0", 1280, 720)
        );
        assert_eq!(
            (c.k[(0, 0)], c.k[(1, 1)], c.k[(0, 2)], c.k[(1, 2)]),
            (1000.0, 1001.0, 640.5, 360.25)
        );
        let d = c.distortion.clone().unwrap();
        assert_eq!(
            (d.model(), d.coefficients()),
            ("opencv", vec![-0.2, 0.05, 0.001, -0.0005])
        );
        let quarter = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        assert!((c.r - quarter).norm() < 1e-15, "{}", c.r);
        assert_eq!(c.t, Vector3::new(1.0, 2.0, 3.0));
        // mrcal's older key and model names, and a key given twice (the last counts, as in Python).
        let old = MODEL
            .replace(
                "'lensmodel':  'LENSMODEL_OPENCV4'",
                "'distortion_model': 'DISTORTION_OPENCV4'",
            )
            .replace(
                "'imagersize': [ 1280, 720,],",
                "'imagersize': [ 1, 1,], 'imagersize': [ 1280, 720,],",
            );
        assert_eq!(read(&old).unwrap(), c);
        assert!(
            natural_key("camera-10") > natural_key("camera-9"),
            "camera-10 comes after camera-9"
        );
    }

    #[test]
    fn models_without_a_counterpart_and_broken_files_are_refused_at_their_line() {
        let splined = MODEL.replace(
            "LENSMODEL_OPENCV4",
            "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=30_Ny=18_fov_x_deg=150",
        );
        has(
            &err(&splined),
            &[
                "camera-0.cameramodel",
                "line 3: lensmodel",
                "SPLINED",
                "mrcal-convert-lensmodel LENSMODEL_OPENCV8",
            ],
        );
        let short = MODEL.replace(" -0.0005,]", "]");
        has(
            &err(&short),
            &["line 6: intrinsics", "has 8 intrinsics", "found 7"],
        );
        let ext = MODEL.replace(" 1, 2, 3,]", " 1, 2,]");
        has(&err(&ext), &["line 16: extrinsics", "expected 6 numbers"]);
        let open = MODEL.replace("'imagersize': [ 1280, 720,],", "'imagersize': [ 1280, 720,");
        has(&err(&open), &["camera-0.cameramodel", "expected , or ]"]);
        has(
            &err("{ 'lensmodel': 'LENSMODEL_PINHOLE' }"),
            &["intrinsics", "missing"],
        );
        has(&err("# a comment\n[1, 2]"), &["line 2", "dict literal"]);
        has(
            &err(&"[".repeat(100_000)),
            &["line 1", "nested deeper than 32"],
        );
    }
}
