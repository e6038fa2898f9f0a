//! The cameras of an Alembic file (`.abc`, Ogawa): what a matchmove or layout department hands
//! over from Maya, Houdini, Blender, 3DEqualizer or SynthEyes, and what modelflow's own export
//! writes. Every `Camera` object is read with the transforms above it composed at each frame:
//! one that holds still becomes a static camera, one that moves a pose per frame. Read by hand:
//! no maintained Rust crate reads Alembic (`ogawa-rs` reads the container and no schema), and the
//! part cameras need is small; every offset is checked, so a damaged file is an error naming the
//! file and the object, never a panic.
//!
//! Conventions (docs/scene-format.md, "Importing a calibration"): an Alembic transform maps row
//! vectors, its translation in the last row, the camera looking down its −Z with +Y up; the
//! film back (`CameraSample`) gives the focal length in mm and the apertures and film offsets in
//! cm, and Alembic's screen window (`CameraSample::getScreenWindow`) maps the aperture onto the
//! image. Where the aperture's aspect is not the image's (by more than 2 %), the film's width is fitted to the
//! image's width with square pixels, as Blender (sensor fit Auto, a landscape image), Houdini
//! and Maya's horizontal fit do, and the import says so.

use super::pinhole_k;
use super::scene3d::{still_or_moving, world_to_camera, SceneCameras};
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Rotation3, Unit, Vector3};
use std::path::Path;

/// Ogawa's marker of a data child in a group's list of positions.
const DATA: u64 = 1 << 63;
/// Alembic's time per cycle of an acyclic sampling (`f64::MAX / 32`), compared loosely.
const ACYCLIC: f64 = f64::MAX / 64.0;
/// How far a film back's aspect may differ from the image's and still be taken as it (pixels
/// not square) rather than fitted by its width.
const FIT_ASPECT: f64 = 0.02;
/// Deeper object nesting than any scene has: a file that loops is refused, not followed.
const MAX_DEPTH: usize = 256;
/// Alembic's plain data types read here.
const POD_BOOL: u32 = 0;
const POD_UINT8: u32 = 1;
const POD_INT32: u32 = 6;
const POD_FLOAT32: u32 = 10;
const POD_FLOAT64: u32 = 11;
const POD_STRING: u32 = 12;

/// Reads every camera of the Alembic file `path` at frames `frames.0..=frames.1` (frame `f` at
/// `f / fps` seconds, `fps` the file's own: its first uniform time sampling's, else 24). `size` is the
/// image size, for files that do not give one (Blender writes its render size as the cameras'
/// `resx`, `resy` user properties; other packages write none).
pub fn read_alembic(
    path: &Path,
    size: Option<(u32, u32)>,
    frames: (u32, u32),
) -> Result<SceneCameras> {
    super::scene3d::check_frames(frames).map_err(|m| Error::invalid(path, "--frames", m))?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let a = Archive::open(path, &bytes)?;
    let mut found = Vec::new();
    let top = a.root()?;
    a.walk(top, &[], &mut Vec::new(), "", 0, &mut found)?;
    if found.is_empty() {
        return Err(a.err(
            "(objects)",
            "holds no Camera object: export the cameras with the scene (Maya: AbcExport with the camera's transform as a -root; Blender: File > Export > Alembic, the cameras selected or all objects)",
        ));
    }
    let file_fps = a.fps();
    let fps = file_fps.unwrap_or(24.0);
    let (first, last) = frames;
    let mut out = SceneCameras {
        units: None,
        cameras: Vec::new(),
        poses: Vec::new(),
        notes: vec![
            "the cameras are in the Alembic file's world, Y up (Alembic's convention; Blender's exporter turns its Z-up world): give the mesh in the same world (Blender's OBJ export: up Y, forward -Z)".into(),
        ],
    };
    for cam in &found {
        let name = cam.name.clone();
        let field = format!("camera {:?} ({})", name, cam.path);
        let (width, height) =
            match size.or(cam.size) {
                Some(s) => s,
                None => return Err(a.err(
                    &field,
                    "the file gives no image size: give it with --size WxH (Python: size=(w, h))",
                )),
            };
        let mut views = Vec::new();
        let mut fitted = false;
        for frame in first..=last {
            let time = frame as f64 / fps;
            let core = a.camera_core(cam, time, &field)?;
            let (k, fit) = film_back_k(&core, width, height).map_err(|m| a.err(&field, m))?;
            fitted |= fit;
            let world = a.world(cam, time, &field)?;
            let (r, t) = world_to_camera(&world).map_err(|m| a.err(&field, m))?;
            views.push((frame, k, r, t));
        }
        let (camera, poses) = still_or_moving(name.clone(), (width, height), &views, || {
            format!("moving: a pose per frame at {fps} fps")
        })
        .map_err(|m| a.err(&field, m))?;
        let moving = poses.is_some();
        if fitted {
            out.notes.push(format!(
                "camera {name:?}: its film back's aspect is not the image's {width}x{height}: the film's width is fitted to the image's, square pixels (Blender's sensor fit Auto for a landscape image, Houdini's, Maya's Horizontal fit)"
            ));
        }
        if moving {
            if file_fps.is_none() {
                out.notes.push(format!(
                    "camera {name:?} moves, and the file samples it at times of their own, not at a frame rate: frame F is read at F/24 s"
                ));
            }
            if let Some((lo, hi)) = a.sampled_frames(cam, fps) {
                if first < lo || last > hi {
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

/// The camera matrix of Alembic's 16 film-back values for a `width`×`height` image, and whether
/// the film was fitted by its width (its aspect not the image's); or why it cannot be.
fn film_back_k(
    core: &[f64],
    width: u32,
    height: u32,
) -> std::result::Result<(Matrix3<f64>, bool), String> {
    let (focal, ah, hoff, av, voff, squeeze) =
        (core[0], core[1], core[2], core[3], core[4], core[5]);
    if !core[..6].iter().all(|x| x.is_finite()) || focal <= 0.0 || ah <= 0.0 || av <= 0.0 {
        return Err(format!(
            "a film back with focal length {focal} mm and apertures {ah} x {av} cm: expected positive, finite numbers"
        ));
    }
    if (squeeze - 1.0).abs() > 1e-9 {
        return Err(format!(
            "an anamorphic lens squeeze of {squeeze}: not read (desqueeze the footage and set the squeeze to 1)"
        ));
    }
    if core[6..10].iter().any(|x| *x != 0.0) {
        return Err("overscan on the film back: not read (set it to 0)".into());
    }
    let (w, h) = (width as f64, height as f64);
    // Pixels per cm of film across the image's width.
    let px = w / ah;
    let fx = focal / 10.0 * px;
    let cx = w / 2.0 - hoff * px - 0.5;
    // Within 2 % the film back's aspect is the image's with pixels not quite square (a
    // calibrated webcam's fx and fy, as modelflow's own export writes them); past it, a film
    // back whose height the package ignores (Blender's default 36 x 24 mm on a 16:9 render).
    let fitted = ((ah / av) / (w / h) - 1.0).abs() > FIT_ASPECT;
    // Alembic's screen window: the vertical aperture spans the image's height; fitted by the
    // width, the vertical offset is in the same units as the horizontal one.
    let py = if fitted { px } else { h / av };
    let fy = focal / 10.0 * py;
    let cy = h / 2.0 + voff * py - 0.5;
    let k = pinhole_k(fx, fy, cx, cy).ok_or("a film back that gives no focal length")?;
    Ok((k, fitted))
}

/// An object's child as its parent lists it: name, metadata, group.
type Child = (String, String, u64);

/// A camera found: its name, where it is, the transforms above it, its schema's properties.
struct FoundCamera {
    name: String,
    path: String,
    /// The `.xform` compounds from the top down.
    xforms: Vec<Vec<Prop>>,
    /// The `.geom` compound's properties.
    geom: Vec<Prop>,
    size: Option<(u32, u32)>,
}

#[derive(Clone, Debug)]
struct Prop {
    name: String,
    /// 0 compound, 1 scalar, 2 array.
    kind: u32,
    pod: u32,
    extent: u32,
    samples: u32,
    first_changed: u32,
    last_changed: u32,
    sampling: u32,
    group: u64,
}

impl Prop {
    /// The stored sample holding sample `i` (Ogawa stores sample 0, then those from the first
    /// that changed to the last; the others repeat a neighbour).
    fn stored(&self, i: usize) -> usize {
        let (first, last) = (self.first_changed as usize, self.last_changed as usize);
        if (first == 0 && last == 0) || i < first {
            0
        } else if i > last {
            last - first + 1
        } else {
            i - first + 1
        }
    }
}

/// A time sampling: its time per cycle and stored times.
struct Sampling {
    per_cycle: f64,
    times: Vec<f64>,
}

impl Sampling {
    fn time(&self, i: usize) -> f64 {
        let n = self.times.len().max(1);
        if self.per_cycle >= ACYCLIC {
            self.times[i.min(n - 1)]
        } else {
            self.times[i % n] + (i / n) as f64 * self.per_cycle
        }
    }

    /// The sample of `count` in force at `time` (the last at or before it, the first before
    /// them all), as Alembic's readers take it.
    fn index_at(&self, time: f64, count: u32) -> usize {
        let eps = 1e-9 * (1.0 + time.abs());
        (0..count as usize)
            .take_while(|&i| self.time(i) <= time + eps)
            .last()
            .unwrap_or(0)
    }
}

/// An Ogawa archive in memory, every read checked.
struct Archive<'a> {
    path: &'a Path,
    b: &'a [u8],
    meta: Vec<String>,
    samplings: Vec<Sampling>,
    /// Objects visited: a damaged file whose groups loop would otherwise be walked for ever.
    visits: std::cell::Cell<usize>,
}

impl<'a> Archive<'a> {
    fn open(path: &'a Path, b: &'a [u8]) -> Result<Self> {
        let err = |m: &str| Error::invalid(path, "(header)", m.to_string());
        if b.starts_with(b"\x89HDF") {
            return Err(err(
                "an Alembic file in the older HDF5 container: save it as Ogawa (abcconvert -toOgawa IN OUT, or re-export from the package)",
            ));
        }
        if b.len() < 16 || &b[..5] != b"Ogawa" {
            return Err(err("not an Alembic file: no Ogawa header"));
        }
        if b[5] != 0xff {
            return Err(err(
                "the file was not finished (its writer stopped before closing it): export it again",
            ));
        }
        let mut a = Archive {
            path,
            b,
            meta: vec![String::new()],
            samplings: Vec::new(),
            visits: std::cell::Cell::new(0),
        };
        let root = a.children(a.u64_at(8)?)?;
        if root.len() < 6 {
            return Err(err(
                "an archive without its six parts (version, objects, metadata, time samplings)",
            ));
        }
        a.read_indexed_meta(root[5])?;
        a.read_samplings(root[4])?;
        Ok(a)
    }

    fn err(&self, field: &str, message: impl Into<String>) -> Error {
        Error::invalid(self.path, field, message)
    }

    fn damaged(&self, what: &str) -> Error {
        self.err(
            "(container)",
            format!("damaged or truncated ({what}): export it again"),
        )
    }

    fn u64_at(&self, at: u64) -> Result<u64> {
        let at = usize::try_from(at).map_err(|_| self.damaged("a position past the end"))?;
        let s = self
            .b
            .get(at..at.saturating_add(8))
            .filter(|s| s.len() == 8)
            .ok_or_else(|| self.damaged("a position past the end"))?;
        Ok(u64::from_le_bytes(s.try_into().expect("8 bytes")))
    }

    fn children(&self, group: u64) -> Result<Vec<u64>> {
        if group & DATA != 0 {
            return Err(self.damaged("data where a group belongs"));
        }
        if group == 0 {
            return Ok(Vec::new());
        }
        let n = self.u64_at(group)?;
        if n > (self.b.len() / 8) as u64 {
            return Err(self.damaged("a group larger than the file"));
        }
        (0..n).map(|i| self.u64_at(group + 8 * (i + 1))).collect()
    }

    fn data(&self, child: u64) -> Result<&'a [u8]> {
        if child & DATA == 0 {
            return Err(self.damaged("a group where data belongs"));
        }
        let pos = child & !DATA;
        if pos == 0 {
            return Ok(&[]);
        }
        let n = self.u64_at(pos)?;
        let start = (pos + 8) as usize;
        usize::try_from(n)
            .ok()
            .and_then(|n| self.b.get(start..start.checked_add(n)?))
            .ok_or_else(|| self.damaged("data past the end"))
    }

    fn read_indexed_meta(&mut self, child: u64) -> Result<()> {
        let d = self.data(child)?;
        let mut at = 0;
        while at < d.len() {
            let n = d[at] as usize;
            let s = d
                .get(at + 1..at + 1 + n)
                .ok_or_else(|| self.damaged("the indexed metadata"))?;
            self.meta.push(String::from_utf8_lossy(s).into_owned());
            at += 1 + n;
        }
        Ok(())
    }

    fn read_samplings(&mut self, child: u64) -> Result<()> {
        let d = self.data(child)?;
        let bad = || self.damaged("the time samplings");
        let mut at = 0;
        let mut out = Vec::new();
        let word = |at: usize, n: usize| d.get(at..at + n).ok_or_else(bad);
        while at < d.len() {
            // Most samples (u32), time per cycle (f64), stored times (u32 count, f64 each).
            let per_cycle = f64::from_le_bytes(word(at + 4, 8)?.try_into().expect("8"));
            let n = u32::from_le_bytes(word(at + 12, 4)?.try_into().expect("4")) as usize;
            at += 16;
            if n > d.len() / 8 {
                return Err(bad());
            }
            let mut times = Vec::with_capacity(n);
            for _ in 0..n {
                times.push(f64::from_le_bytes(word(at, 8)?.try_into().expect("8")));
                at += 8;
            }
            if times.is_empty()
                || !times.iter().all(|t| t.is_finite())
                || per_cycle.is_nan()
                || per_cycle <= 0.0
            {
                return Err(bad());
            }
            out.push(Sampling { per_cycle, times });
        }
        if out.is_empty() {
            // Sampling 0 is always the identity: one sample per second from 0.
            out.push(Sampling {
                per_cycle: 1.0,
                times: vec![0.0],
            });
        }
        self.samplings = out;
        Ok(())
    }

    fn sampling(&self, p: &Prop) -> Result<&Sampling> {
        self.samplings
            .get(p.sampling as usize)
            .ok_or_else(|| self.damaged("a property on a time sampling the file lacks"))
    }

    /// The frame rate frames are read at: the first uniform or cyclic time sampling after the
    /// identity's (Blender's and Maya's exporters write the scene's); `None` when every one is
    /// acyclic (samples at times of their own).
    fn fps(&self) -> Option<f64> {
        self.samplings
            .iter()
            .skip(1)
            .find(|s| s.per_cycle < ACYCLIC)
            .map(|s| 1.0 / s.per_cycle)
    }

    fn root(&self) -> Result<u64> {
        Ok(self.children(self.u64_at(8)?)?[2])
    }

    /// An object's property compound and its children (name, metadata, group).
    fn object(&self, group: u64) -> Result<(u64, Vec<Child>)> {
        let ch = self.children(group)?;
        let (Some(props), Some(last)) = (ch.first(), ch.last()) else {
            return Err(self.damaged("an object without properties"));
        };
        if ch.len() < 2 {
            return Ok((*props, Vec::new()));
        }
        let h = self.data(*last)?;
        let h = &h[..h.len().saturating_sub(32)];
        let bad = || self.damaged("an object's list of children");
        let (mut at, mut out) = (0, Vec::new());
        let u32_at = |at: usize| -> Result<usize> {
            Ok(
                u32::from_le_bytes(h.get(at..at + 4).ok_or_else(bad)?.try_into().expect("4"))
                    as usize,
            )
        };
        while at < h.len() {
            let n = u32_at(at)?;
            let name = h.get(at + 4..at + 4 + n).ok_or_else(bad)?;
            at += 4 + n;
            let index = *h.get(at).ok_or_else(bad)? as usize;
            at += 1;
            let meta = if index == 0xff {
                let m = u32_at(at)?;
                let s = h.get(at + 4..at + 4 + m).ok_or_else(bad)?;
                at += 4 + m;
                String::from_utf8_lossy(s).into_owned()
            } else {
                self.meta.get(index).cloned().ok_or_else(bad)?
            };
            let group = *ch
                .get(out.len() + 1)
                .filter(|_| out.len() + 2 < ch.len())
                .ok_or_else(bad)?;
            out.push((String::from_utf8_lossy(name).into_owned(), meta, group));
        }
        Ok((*props, out))
    }

    /// A compound's properties.
    fn props(&self, compound: u64) -> Result<Vec<Prop>> {
        let ch = self.children(compound)?;
        let Some(last) = ch.last() else {
            return Ok(Vec::new());
        };
        let h = self.data(*last)?;
        let bad = || self.damaged("a list of properties");
        let (mut at, mut out) = (0usize, Vec::new());
        while at < h.len() {
            let info =
                u32::from_le_bytes(h.get(at..at + 4).ok_or_else(bad)?.try_into().expect("4"));
            at += 4;
            let hint = (info >> 2) & 3;
            let get = |at: &mut usize| -> Result<u32> {
                let n = match hint {
                    0 => 1,
                    1 => 2,
                    _ => 4,
                };
                let s = h.get(*at..*at + n).ok_or_else(bad)?;
                *at += n;
                Ok(match n {
                    1 => s[0] as u32,
                    2 => u16::from_le_bytes([s[0], s[1]]) as u32,
                    _ => u32::from_le_bytes(s.try_into().expect("4")),
                })
            };
            let kind = info & 3;
            let (mut samples, mut first, mut last, mut sampling) = (0, 0, 0, 0);
            if kind != 0 {
                samples = get(&mut at)?;
                if info & 0x200 != 0 {
                    first = get(&mut at)?;
                    last = get(&mut at)?;
                } else if info & 0x800 == 0 {
                    first = 1;
                    last = samples.saturating_sub(1);
                }
                if info & 0x100 != 0 {
                    sampling = get(&mut at)?;
                }
            }
            let n = get(&mut at)? as usize;
            let name = h.get(at..at + n).ok_or_else(bad)?;
            at += n;
            if (info >> 20) & 0xff == 0xff {
                let m = get(&mut at)? as usize;
                h.get(at..at + m).ok_or_else(bad)?;
                at += m;
            }
            let group = *ch
                .get(out.len())
                .filter(|_| out.len() + 1 < ch.len())
                .ok_or_else(bad)?;
            out.push(Prop {
                name: String::from_utf8_lossy(name).into_owned(),
                kind,
                pod: (info >> 4) & 0xf,
                extent: (info >> 12) & 0xff,
                samples,
                first_changed: first,
                last_changed: last,
                sampling,
                group,
            });
        }
        Ok(out)
    }

    /// The stored bytes of sample `i` of a scalar or array property (an array's data block,
    /// after its dimensions block).
    fn sample_data(&self, p: &Prop, i: usize) -> Result<&[u8]> {
        let ch = self.children(p.group)?;
        let step = if p.kind == 2 { 2 } else { 1 };
        let child = *ch
            .get(step * p.stored(i))
            .ok_or_else(|| self.damaged("a property's sample missing"))?;
        self.data(child)
    }

    /// The values of sample `i` of a scalar or array property of numbers, as `f64`.
    fn numbers(&self, p: &Prop, i: usize) -> Result<Vec<f64>> {
        let d = self.sample_data(p, i)?;
        if d.is_empty() {
            return Ok(Vec::new());
        }
        let v = d
            .get(16..)
            .ok_or_else(|| self.damaged("a sample without its key"))?;
        let (size, read): (usize, fn(&[u8]) -> f64) = match p.pod {
            POD_BOOL | POD_UINT8 => (1, |s| s[0] as f64),
            POD_INT32 => (4, |s| i32::from_le_bytes(s.try_into().expect("4")) as f64),
            POD_FLOAT32 => (4, |s| f32::from_le_bytes(s.try_into().expect("4")) as f64),
            POD_FLOAT64 => (8, |s| f64::from_le_bytes(s.try_into().expect("8"))),
            _ => {
                return Err(self.err(
                    &format!("property {}", p.name),
                    format!("a value type ({}) not read here", p.pod),
                ))
            }
        };
        Ok(v.chunks_exact(size).map(read).collect())
    }

    /// Finds every `Camera` object under `group`, with the `.xform` compounds above it.
    fn walk(
        &self,
        group: u64,
        xforms: &[Vec<Prop>],
        names: &mut Vec<String>,
        parent: &str,
        depth: usize,
        found: &mut Vec<FoundCamera>,
    ) -> Result<()> {
        self.visits.set(self.visits.get() + 1);
        // Every object takes more than 8 bytes of the file.
        if depth > MAX_DEPTH || self.visits.get() > self.b.len() / 8 {
            return Err(self.damaged("objects nested past any scene's depth"));
        }
        let (_, children) = self.object(group)?;
        for (name, meta, child) in children {
            let schema = meta
                .split(';')
                .find_map(|kv| kv.strip_prefix("schema="))
                .unwrap_or("");
            let (props, _) = self.object(child)?;
            names.push(name.clone());
            if schema.starts_with("AbcGeom_Xform") {
                let own = self.schema(props, ".xform")?;
                let mut chain = xforms.to_vec();
                chain.push(own);
                self.walk(child, &chain, names, &name, depth + 1, found)?;
            } else {
                if schema.starts_with("AbcGeom_Camera") {
                    let geom = self.schema(props, ".geom")?;
                    let size = self.user_size(&geom);
                    // The transform's name (Maya's `camera1` over `cameraShape1`; Blender and
                    // modelflow name both alike), else the camera's own.
                    let label = if xforms.is_empty() { &name } else { parent };
                    found.push(FoundCamera {
                        name: label.to_string(),
                        path: format!("/{}", names.join("/")),
                        xforms: xforms.to_vec(),
                        geom,
                        size,
                    });
                }
                self.walk(child, xforms, names, &name, depth + 1, found)?;
            }
            names.pop();
        }
        Ok(())
    }

    /// The properties of the schema compound `name` among an object's properties.
    fn schema(&self, props: u64, name: &str) -> Result<Vec<Prop>> {
        let top = self.props(props)?;
        match top.iter().find(|p| p.name == name && p.kind == 0) {
            Some(p) => self.props(p.group),
            None => Ok(Vec::new()),
        }
    }

    /// Blender's render size, written as the camera's `resx`, `resy` user properties.
    fn user_size(&self, geom: &[Prop]) -> Option<(u32, u32)> {
        let user = geom
            .iter()
            .find(|p| p.name == ".userProperties" && p.kind == 0)?;
        let props = self.props(user.group).ok()?;
        let get = |n: &str| {
            let p = props.iter().find(|p| p.name == n && p.kind == 1)?;
            self.numbers(p, 0).ok()?.first().copied()
        };
        super::whole_size(get("resx")?, get("resy")?)
    }

    fn camera_core(&self, cam: &FoundCamera, time: f64, field: &str) -> Result<Vec<f64>> {
        let core = cam
            .geom
            .iter()
            .find(|p| p.name == ".core" && p.kind == 1 && p.extent == 16)
            .ok_or_else(|| self.err(field, "a Camera without its film back (.core)"))?;
        self.check_film_back_ops(cam, time, field)?;
        let i = self.sampling(core)?.index_at(time, core.samples);
        let v = self.numbers(core, i)?;
        if v.len() != 16 {
            return Err(self.damaged("a film back without its 16 values"));
        }
        Ok(v)
    }

    /// Film-back operations (Maya writes `filmFitOffs`, `preScale`, `filmTranslate`,
    /// `postScale`): each named by its type (`t` translate, two channels; `s` scale, two; `m`
    /// matrix, nine) and a hint, their channels in `.filmBackChannels`. Ones that do nothing
    /// (translate 0, scale 1, the identity) are passed over; any other is refused, since the
    /// screen window it would move is not read.
    fn check_film_back_ops(&self, cam: &FoundCamera, time: f64, field: &str) -> Result<()> {
        let Some(ops) = cam
            .geom
            .iter()
            .find(|p| p.name == ".filmBackOps" && p.samples > 0)
        else {
            return Ok(());
        };
        let names = self.strings(ops, 0)?;
        let channels = match cam
            .geom
            .iter()
            .find(|p| p.name == ".filmBackChannels" && p.samples > 0)
        {
            Some(p) => {
                let i = self.sampling(p)?.index_at(time, p.samples);
                self.numbers(p, i)?
            }
            None => Vec::new(),
        };
        let mut at = 0;
        for name in &names {
            let (n, rest): (usize, &[f64]) = match name.as_bytes().first() {
                Some(b't') => (2, &[0.0, 0.0]),
                Some(b's') => (2, &[1.0, 1.0]),
                Some(b'm') => (9, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
                _ => {
                    return Err(self.err(
                        field,
                        format!("a film-back operation {name:?}: not an Alembic one"),
                    ))
                }
            };
            let values = channels.get(at..at + n).ok_or_else(|| {
                self.err(
                    field,
                    "film-back operations with fewer channels than they take",
                )
            })?;
            at += n;
            if values.iter().zip(rest).any(|(v, r)| (v - r).abs() > 1e-12) {
                return Err(self.err(
                    field,
                    format!(
                        "the film-back operation {:?} moves the film ({values:?}): not read; set the camera's film fit and offsets so that it does nothing (Maya: film fit Horizontal with the film back of the image's aspect, no film translate or scale)",
                        &name[1..]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The strings of sample `i` of a string array or scalar property (each ends in a NUL).
    fn strings(&self, p: &Prop, i: usize) -> Result<Vec<String>> {
        if p.pod != POD_STRING {
            return Err(self.damaged("strings of another type"));
        }
        let d = self.sample_data(p, i)?;
        let v = d.get(16..).unwrap_or(&[]);
        Ok(v.split(|b| *b == 0)
            .take(v.iter().filter(|b| **b == 0).count())
            .map(|s| String::from_utf8_lossy(s).into_owned())
            .collect())
    }

    /// The camera's camera-to-world transform at `time` (column vectors).
    fn world(&self, cam: &FoundCamera, time: f64, field: &str) -> Result<Matrix4<f64>> {
        let mut world = Matrix4::identity();
        for xform in &cam.xforms {
            let by = |n: &str| xform.iter().find(|p| p.name == n);
            let local = self.local(xform, time, field)?;
            let inherits = match by(".inherits") {
                Some(p) if p.samples > 0 => {
                    let i = self.sampling(p)?.index_at(time, p.samples);
                    self.numbers(p, i)?.first().is_none_or(|v| *v != 0.0)
                }
                _ => true,
            };
            world = if inherits { world * local } else { local };
        }
        Ok(world)
    }

    /// One `.xform` compound's transform at `time` (column vectors): its operations composed,
    /// the first outermost (Alembic's `XformSample::getMatrix`).
    fn local(&self, xform: &[Prop], time: f64, field: &str) -> Result<Matrix4<f64>> {
        let by = |n: &str| xform.iter().find(|p| p.name == n);
        let ops: Vec<u8> = match by(".ops") {
            Some(p) if p.samples > 0 => self.numbers(p, 0)?.iter().map(|v| *v as u8).collect(),
            _ => Vec::new(),
        };
        let counts: Vec<usize> = ops
            .iter()
            .map(|op| match op >> 4 {
                0 | 1 => Ok(3),
                2 => Ok(4),
                3 => Ok(16),
                4..=6 => Ok(1),
                t => Err(self.err(
                    field,
                    format!("a transform operation of type {t}: not an Alembic one"),
                )),
            })
            .collect::<Result<_>>()?;
        let total: usize = counts.iter().sum();
        let vals = match by(".vals") {
            Some(p) if p.samples > 0 => {
                let i = self.sampling(p)?.index_at(time, p.samples);
                self.numbers(p, i)?
            }
            _ => Vec::new(),
        };
        if vals.len() != total {
            return Err(self.err(
                field,
                format!(
                    "a transform of {} operations with {} values where they take {total}",
                    ops.len(),
                    vals.len()
                ),
            ));
        }
        let mut m = Matrix4::identity();
        let mut at = 0;
        for (op, n) in ops.iter().zip(counts) {
            let v = &vals[at..at + n];
            at += n;
            let axis_angle = |axis: Vector3<f64>, degrees: f64| {
                Rotation3::from_axis_angle(&Unit::new_normalize(axis), degrees.to_radians())
                    .to_homogeneous()
            };
            let step = match op >> 4 {
                0 => Matrix4::new_nonuniform_scaling(&Vector3::new(v[0], v[1], v[2])),
                1 => Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2])),
                2 => {
                    let axis = Vector3::new(v[0], v[1], v[2]);
                    if axis.norm() < 1e-12 {
                        Matrix4::identity()
                    } else {
                        axis_angle(axis, v[3])
                    }
                }
                // Alembic's matrix maps row vectors: ours is its transpose.
                3 => Matrix4::from_row_slice(v).transpose(),
                4 => axis_angle(Vector3::x(), v[0]),
                5 => axis_angle(Vector3::y(), v[0]),
                _ => axis_angle(Vector3::z(), v[0]),
            };
            m *= step;
        }
        Ok(m)
    }

    /// The frames (at `fps`) a moving camera's transforms are sampled over.
    fn sampled_frames(&self, cam: &FoundCamera, fps: f64) -> Option<(u32, u32)> {
        let mut range: Option<(f64, f64)> = None;
        for p in cam
            .xforms
            .iter()
            .flatten()
            .filter(|p| p.name == ".vals" && p.samples > 1)
        {
            let s = self.sampling(p).ok()?;
            let (a, b) = (s.time(0), s.time(p.samples as usize - 1));
            range = Some(range.map_or((a, b), |(lo, hi)| (lo.min(a), hi.max(b))));
        }
        range.map(|(a, b)| {
            (
                (a * fps).round().max(0.0) as u32,
                (b * fps).round().max(0.0) as u32,
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::has;

    fn fixture() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/alembic")
    }

    /// A fixture's points and its views (camera, frame, the points' pixels in Blender).
    fn expected(file: &str) -> (Vec<Vector3<f64>>, Vec<serde_json::Value>) {
        let text = std::fs::read_to_string(fixture().join(file)).unwrap();
        let want: serde_json::Value = serde_json::from_str(&text).unwrap();
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        let points = want["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| Vector3::new(num(&p[0]), num(&p[1]), num(&p[2])))
            .collect();
        (points, want["views"].as_array().unwrap().clone())
    }

    /// How far `K·[R | t]` puts `p` from Blender's pixel `px`.
    fn miss(
        k: &Matrix3<f64>,
        r: &Matrix3<f64>,
        t: &Vector3<f64>,
        p: &Vector3<f64>,
        px: &serde_json::Value,
    ) -> f64 {
        let x = k * (r * p + t);
        (x.x / x.z - px[0].as_f64().unwrap()).hypot(x.y / x.z - px[1].as_f64().unwrap())
    }

    #[test]
    fn blenders_cameras_project_as_blender_renders_them() {
        // fixtures/alembic/cameras.abc: four cameras as Blender 5.0's exporter writes them (a
        // shifted camera under a moved, turned and scaled empty; Blender's default 36 x 24 mm
        // film back on a 16:9 render; one under a turned empty; one keyed at frames 1, 3, 5),
        // and expected.json: where Blender's own `world_to_camera_view` puts six points at each
        // frame (tools/make_alembic_fixture.py).
        let dir = fixture();
        let (points, views) = expected("expected.json");
        let read = read_alembic(&dir.join("cameras.abc"), None, (1, 5)).unwrap();
        let names: Vec<&str> = read.cameras.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names.len(), 4);
        for n in ["front", "side", "tall", "moving"] {
            assert!(names.contains(&n), "{names:?} lacks {n}");
        }
        for (c, poses) in read.cameras.iter().zip(&read.poses) {
            assert_eq!((c.width, c.height), (1280, 720), "Blender's resx, resy");
            assert_eq!(poses.is_some(), c.name == "moving", "{}", c.name);
        }
        assert!(read
            .notes
            .iter()
            .any(|n| n.contains("\"side\"") && n.contains("fitted")));
        assert!(!read.notes.iter().any(|n| n.contains("\"front\"")));
        let mut worst: f64 = 0.0;
        for view in &views {
            let name = view["camera"].as_str().unwrap();
            let frame = view["frame"].as_u64().unwrap() as u32;
            let i = names.iter().position(|n| *n == name).unwrap();
            let cam = &read.cameras[i];
            let (r, t) = match &read.poses[i] {
                Some(p) => {
                    let (f, r, t) = p[(frame - 1) as usize];
                    assert_eq!(f, frame);
                    (r, t)
                }
                None => (cam.r, cam.t),
            };
            for (p, px) in points.iter().zip(view["pixels"].as_array().unwrap()) {
                let e = miss(&cam.k, &r, &t, p, px);
                worst = worst.max(e);
                assert!(e < 1e-3, "{name} frame {frame}: {e} px from Blender's {px}");
            }
        }
        // Blender stores its matrices in 32-bit floats: about a ten-thousandth of a pixel.
        assert!(worst > 0.0 && worst < 1e-3, "{worst}");
    }

    #[test]
    fn translate_rotate_scale_operations_compose_as_alembics_library_does() {
        // fixtures/alembic/trs.abc: cameras whose transforms are translate, rotate (about an
        // axis), rotateX, rotateY, rotateZ and scale operations, as Maya writes them, one of
        // them not inheriting its parent's; trs-expected.json: where Blender puts six points
        // after its importer (the Alembic library) composed them
        // (tools/make_alembic_trs_fixture.py). No image size in the file: it is given. trs_cam
        // carries Maya's four film-back operations, each doing nothing.
        let dir = fixture();
        let (points, views) = expected("trs-expected.json");
        let read = read_alembic(&dir.join("trs.abc"), Some((1280, 720)), (1, 1)).unwrap();
        assert_eq!(read.cameras.len(), 2);
        for view in &views {
            let name = view["camera"].as_str().unwrap();
            let cam = read.cameras.iter().find(|c| c.name == name).unwrap();
            for (p, px) in points.iter().zip(view["pixels"].as_array().unwrap()) {
                let e = miss(&cam.k, &cam.r, &cam.t, p, px);
                assert!(e < 1e-3, "{name}: {e} px from Blender's {px}");
            }
        }
        // trs_cam carries Maya's four film-back operations, each doing nothing: passed over.
        // Translating the film moves the screen window, which is not read: refused by name.
        let err = read_alembic(&dir.join("film-translate.abc"), Some((1280, 720)), (1, 1))
            .unwrap_err()
            .to_string();
        has(
            &err,
            &[
                "film-translate.abc",
                "trs_cam",
                "\"filmTranslate\"",
                "moves the film",
            ],
        );
    }

    #[test]
    fn the_alembic_export_reads_back_as_the_scenes_cameras() {
        // modelflow's own export: a webcam's K (principal point off centre, fx != fy) still,
        // and the same K moving, given at frames 10 and 12 of 10..13.
        use super::super::scene3d::rig::{self, pose};
        let k = rig::k();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("shot.abc");
        // The two cameras exported at `frames`.
        let export = |frames: &[u32]| rig::export(crate::export::ExportFormat::Abc, &out, frames);
        // The moving camera read back: its first view before frame `second`, its second after.
        let moves_at = |read: &SceneCameras, second: u32| {
            let poses = read.poses[1].as_ref().expect("moving");
            for (f, r, t) in poses {
                let eye = if *f < second {
                    [3.0, 1.0, 3.0]
                } else {
                    [2.0, 2.5, 3.5]
                };
                let (rr, tt) = pose(eye);
                assert!(
                    (r - rr).abs().max() < 1e-12 && (t - tt).norm() < 1e-12,
                    "frame {f}"
                );
            }
            poses.iter().map(|p| p.0).collect::<Vec<u32>>()
        };
        export(&[10, 11, 12, 13]);
        let err = read_alembic(&out, None, (10, 13)).unwrap_err().to_string();
        has(&err, &["shot.abc", "web_cam", "--size"]);
        let read = read_alembic(&out, Some((1280, 720)), (10, 13)).unwrap();
        let names: Vec<&str> = read.cameras.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(
            names,
            ["web_cam", "handheld"],
            "the transforms' names, as the USD export's"
        );
        for c in &read.cameras {
            assert!((c.k - k).abs().max() < 1e-9, "{}: {}", c.name, c.k);
        }
        let (r, t) = pose([0.3, -2.0, 4.0]);
        assert!(
            (read.cameras[0].r - r).abs().max() < 1e-12 && (read.cameras[0].t - t).norm() < 1e-12
        );
        assert!(read.poses[0].is_none());
        assert_eq!(moves_at(&read, 12), [10, 11, 12, 13]);
        // Outside its samples a camera holds its nearest pose, and the import says so.
        let read = read_alembic(&out, Some((1280, 720)), (8, 15)).unwrap();
        assert!(read
            .notes
            .iter()
            .any(|n| n.contains("handheld") && n.contains("10..13")));
        // Frames not evenly spaced: the export samples them at their own times (acyclic), read
        // at 24 fps (the export's default), and the import says so.
        export(&[10, 11, 13]);
        let read = read_alembic(&out, Some((1280, 720)), (10, 13)).unwrap();
        assert!(read
            .notes
            .iter()
            .any(|n| n.contains("handheld") && n.contains("F/24 s")));
        // Frame 12, not in the file, holds frame 11's sample (the first view).
        assert_eq!(moves_at(&read, 13), [10, 11, 12, 13]);
    }

    #[test]
    fn damaged_and_foreign_files_are_refused_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let bytes = std::fs::read(fixture().join("cameras.abc")).unwrap();
        let write = |name: &str, b: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, b).unwrap();
            p
        };
        let msg = |p: &Path| read_alembic(p, None, (1, 5)).unwrap_err().to_string();
        has(
            &msg(&write("hdf5.abc", b"\x89HDF\r\n\x1a\n00000000")),
            &["hdf5.abc", "HDF5", "Ogawa"],
        );
        has(
            &msg(&write("text.abc", b"# not alembic")),
            &["text.abc", "not an Alembic file"],
        );
        let mut open = bytes.clone();
        open[5] = 0;
        has(
            &msg(&write("open.abc", &open)),
            &["open.abc", "not finished"],
        );
        has(
            &msg(&write("cut.abc", &bytes[..bytes.len() / 2])),
            &["cut.abc", "truncated"],
        );
        // Every damage a byte can do is an error or a reading, never a panic.
        for i in 16..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x5a;
            let p = write("flip.abc", &b);
            let _ = read_alembic(&p, None, (1, 5));
        }
    }
}
