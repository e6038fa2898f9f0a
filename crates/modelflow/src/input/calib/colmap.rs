//! COLMAP sparse models (`cameras.txt` + `images.txt`, or `cameras.bin` + `images.bin`): every
//! registered image becomes one camera of the rig, named after the folder that holds its image
//! (`images/cam0/0000.png` → `cam0`) or, without a folder, its file stem.
//!
//! COLMAP's conventions converted here: its pixel centres sit at half-integers (the top-left
//! pixel's centre is `(0.5, 0.5)`), so `cx`, `cy` lose 0.5; its image poses are world-to-camera
//! `(QW, QX, QY, QZ, TX, TY, TZ)`, quaternion with `w` first, the same direction as ours; its
//! camera models map to OpenCV's distortion (`SIMPLE_RADIAL` `k` → `(k, 0, 0, 0)`, `RADIAL`
//! `k1, k2` → `(k1, k2, 0, 0)`, `OPENCV` → 4, `FULL_OPENCV` → 8 coefficients, `OPENCV_FISHEYE`
//! → fisheye). Other models (FOV, the other fisheyes, ...) are refused by name.

use super::{check_rotation, quaternion_rotation, strip_bom, CalibratedCamera};
use crate::base::lens::Distortion;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use std::collections::BTreeMap;
use std::path::Path;

/// A COLMAP camera: model name, size, parameters; and where it was read (for errors).
struct ColmapCamera {
    model: String,
    width: u64,
    height: u64,
    params: Vec<f64>,
}

struct ColmapImage {
    q: [f64; 4],
    t: [f64; 3],
    camera_id: u64,
    name: String,
    /// "line N" (text) or "image N" (binary), for errors.
    at: String,
}

/// The cameras of the COLMAP model in `dir`: the text files if `cameras.txt` is there, else the
/// binary ones.
pub fn read_colmap(dir: &Path) -> Result<Vec<CalibratedCamera>> {
    if dir.is_file() {
        let parent = dir
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        return Err(Error::invalid(
            dir,
            "(path)",
            format!(
                "is a file, but a COLMAP model is a folder (holding cameras.txt and images.txt, or the .bin files): give the folder, {}",
                parent.display()
            ),
        ));
    }
    let (cams_path, images_path, cams, images) = if dir.join("cameras.txt").is_file() {
        let (c, i) = (dir.join("cameras.txt"), dir.join("images.txt"));
        let cams = read_cameras_text(&c)?;
        let images = read_images_text(&i)?;
        (c, i, cams, images)
    } else if dir.join("cameras.bin").is_file() {
        let (c, i) = (dir.join("cameras.bin"), dir.join("images.bin"));
        let cams = read_cameras_bin(&c)?;
        let images = read_images_bin(&i)?;
        (c, i, cams, images)
    } else {
        return Err(Error::invalid(
            dir,
            "(folder)",
            "no COLMAP model here: expected cameras.txt and images.txt, or cameras.bin and images.bin",
        ));
    };
    if images.is_empty() {
        return Err(Error::invalid(
            &images_path,
            "(file)",
            "no image in the model",
        ));
    }
    let mut out: Vec<CalibratedCamera> = Vec::with_capacity(images.len());
    let mut seen: BTreeMap<String, String> = BTreeMap::new();
    for im in images {
        let cam = cams.get(&im.camera_id).ok_or_else(|| {
            Error::invalid(
                &images_path,
                format!("{}: CAMERA_ID", im.at),
                format!("camera {} is not in {}", im.camera_id, cams_path.display()),
            )
        })?;
        let name = camera_name(&im.name);
        if let Some(other) = seen.insert(name.clone(), im.name.clone()) {
            return Err(Error::invalid(
                &images_path,
                format!("{}: NAME", im.at),
                format!(
                    "images {other:?} and {:?} are both camera {name:?}: import the model of one moment of the rig (one image per camera)",
                    im.name
                ),
            ));
        }
        let (k, distortion) = intrinsics(cam)
            .map_err(|m| Error::invalid(&cams_path, format!("camera {}", im.camera_id), m))?;
        let r = quaternion_rotation(im.q[0], im.q[1], im.q[2], im.q[3])
            .filter(check_rotation)
            .ok_or_else(|| {
                Error::invalid(
                    &images_path,
                    format!("{}: QW QX QY QZ", im.at),
                    format!("{:?} is not a rotation quaternion", im.q),
                )
            })?;
        if !im.t.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid(
                &images_path,
                format!("{}: TX TY TZ", im.at),
                format!("{:?} has a non-finite entry", im.t),
            ));
        }
        let size = |v: u64, what: &str| {
            u32::try_from(v).ok().filter(|&v| v > 0).ok_or_else(|| {
                Error::invalid(
                    &cams_path,
                    format!("camera {}: {what}", im.camera_id),
                    format!("{v} is not an image size"),
                )
            })
        };
        out.push(CalibratedCamera {
            name,
            width: size(cam.width, "WIDTH")?,
            height: size(cam.height, "HEIGHT")?,
            k,
            r,
            t: Vector3::from(im.t),
            distortion,
            note: None,
        });
    }
    Ok(out)
}

fn camera_name(image: &str) -> String {
    let p = Path::new(image);
    match p.parent().and_then(|d| d.file_name()) {
        Some(dir) => dir.to_string_lossy().into_owned(),
        None => p
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| image.to_string()),
    }
}

/// Our `K` (pixel centres at integers) and distortion from a COLMAP camera.
fn intrinsics(c: &ColmapCamera) -> std::result::Result<(Matrix3<f64>, Option<Distortion>), String> {
    let need = match c.model.as_str() {
        "SIMPLE_PINHOLE" => 3,
        "PINHOLE" | "SIMPLE_RADIAL" => 4,
        "RADIAL" => 5,
        "OPENCV" | "OPENCV_FISHEYE" => 8,
        "FULL_OPENCV" => 12,
        other => {
            return Err(format!(
                "model {other} has no equivalent here (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV, OPENCV_FISHEYE)"
            ))
        }
    };
    let p = &c.params;
    if p.len() != need {
        return Err(format!(
            "model {} has {need} parameters, found {}",
            c.model,
            p.len()
        ));
    }
    if let Some(v) = p.iter().find(|v| !v.is_finite()) {
        return Err(format!("parameter {v} is not finite"));
    }
    let (fx, fy, cx, cy, rest) = match c.model.as_str() {
        "SIMPLE_PINHOLE" | "SIMPLE_RADIAL" | "RADIAL" => (p[0], p[0], p[1], p[2], &p[3..]),
        _ => (p[0], p[1], p[2], p[3], &p[4..]),
    };
    if fx <= 0.0 || fy <= 0.0 {
        return Err(format!("focal lengths {fx}, {fy} must be positive"));
    }
    let k = Matrix3::new(fx, 0.0, cx - 0.5, 0.0, fy, cy - 0.5, 0.0, 0.0, 1.0);
    let d = match c.model.as_str() {
        "SIMPLE_PINHOLE" | "PINHOLE" => None,
        "SIMPLE_RADIAL" => Some(Distortion::new("opencv", &[rest[0], 0.0, 0.0, 0.0])?),
        "RADIAL" => Some(Distortion::new("opencv", &[rest[0], rest[1], 0.0, 0.0])?),
        "OPENCV" | "FULL_OPENCV" => Some(Distortion::new("opencv", rest)?),
        _ => Some(Distortion::new("fisheye", rest)?),
    };
    Ok((k, d.filter(|d| !d.is_identity())))
}

/// The file's lines with their numbers from 1 (a byte-order mark at its start dropped).
fn data_lines(path: &Path) -> Result<Vec<(usize, String)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    Ok(strip_bom(&text)
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.to_string()))
        .collect())
}

fn number<T: std::str::FromStr>(
    path: &Path,
    line: usize,
    field: &str,
    s: Option<&str>,
) -> Result<T> {
    let s = s.ok_or_else(|| Error::invalid(path, format!("line {line}: {field}"), "missing"))?;
    s.parse::<T>().map_err(|_| {
        Error::invalid(
            path,
            format!("line {line}: {field}"),
            format!("{s:?} is not a number"),
        )
    })
}

fn read_cameras_text(path: &Path) -> Result<BTreeMap<u64, ColmapCamera>> {
    let mut out = BTreeMap::new();
    for (n, line) in data_lines(path)? {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let mut it = l.split_whitespace();
        let id: u64 = number(path, n, "CAMERA_ID", it.next())?;
        let model = it
            .next()
            .ok_or_else(|| Error::invalid(path, format!("line {n}: MODEL"), "missing"))?
            .to_string();
        let width = number(path, n, "WIDTH", it.next())?;
        let height = number(path, n, "HEIGHT", it.next())?;
        let params = it
            .enumerate()
            .map(|(i, s)| number(path, n, &format!("PARAMS[{i}]"), Some(s)))
            .collect::<Result<Vec<f64>>>()?;
        if out
            .insert(
                id,
                ColmapCamera {
                    model,
                    width,
                    height,
                    params,
                },
            )
            .is_some()
        {
            return Err(Error::invalid(
                path,
                format!("line {n}: CAMERA_ID"),
                format!("camera {id} is given twice"),
            ));
        }
    }
    Ok(out)
}

/// One image line: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`.
fn image_line(path: &Path, n: usize, l: &str) -> Result<ColmapImage> {
    let mut it = l.split_whitespace();
    let _id: u64 = number(path, n, "IMAGE_ID", it.next())?;
    let mut q = [0.0; 4];
    for (j, name) in ["QW", "QX", "QY", "QZ"].iter().enumerate() {
        q[j] = number(path, n, name, it.next())?;
    }
    let mut t = [0.0; 3];
    for (j, name) in ["TX", "TY", "TZ"].iter().enumerate() {
        t[j] = number(path, n, name, it.next())?;
    }
    let camera_id = number(path, n, "CAMERA_ID", it.next())?;
    let name = it.collect::<Vec<_>>().join(" ");
    if name.is_empty() {
        return Err(Error::invalid(path, format!("line {n}: NAME"), "missing"));
    }
    Ok(ColmapImage {
        q,
        t,
        camera_id,
        name,
        at: format!("line {n}"),
    })
}

/// Whether `l` is a POINTS2D line: `X Y POINT3D_ID` triples (finite numbers, an integer id; -1
/// for a point without a 3D point), or nothing.
fn is_points2d(l: &str) -> bool {
    let v: Vec<&str> = l.split_whitespace().collect();
    let coord = |s: &str| s.parse::<f64>().is_ok_and(|x| x.is_finite());
    v.len() % 3 == 0
        && v.chunks(3)
            .all(|p| coord(p[0]) && coord(p[1]) && p[2].parse::<i64>().is_ok())
}

fn read_images_text(path: &Path) -> Result<Vec<ColmapImage>> {
    let mut out = Vec::new();
    let lines = data_lines(path)?;
    // Two lines per image: the pose line, then the (possibly empty) line of 2D points.
    let mut i = 0;
    while i < lines.len() {
        let (n, line) = &lines[i];
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            i += 1;
            continue;
        }
        out.push(image_line(path, *n, l)?);
        // The file may end without the last image's (empty) POINTS2D line.
        if let Some((m, points)) = lines.get(i + 1) {
            let p = points.trim();
            if !is_points2d(p) {
                if image_line(path, *m, p).is_ok() {
                    return Err(Error::invalid(
                        path,
                        format!("line {m}"),
                        format!(
                            "the (possibly empty) POINTS2D line after image line {n} is missing: line {m} is the next image's line (COLMAP writes two lines per image; were the empty lines removed?)"
                        ),
                    ));
                }
                let shown: String = p.chars().take(60).collect();
                let more = if shown.len() < p.len() { "..." } else { "" };
                return Err(Error::invalid(
                    path,
                    format!("line {m}: POINTS2D"),
                    format!(
                        "{shown:?}{more} is not a list of X Y POINT3D_ID triples (the second line of the image on line {n}; empty when it has none)"
                    ),
                ));
            }
        }
        i += 2;
    }
    Ok(out)
}

/// A little-endian reader over a binary file that names the file and what it was reading when
/// the file ends early.
struct Bin<'a> {
    path: &'a Path,
    data: Vec<u8>,
    pos: usize,
}

impl Bin<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8]> {
        if self.data.len() - self.pos < n {
            return Err(Error::invalid(
                self.path,
                format!("byte {}", self.pos),
                format!("the file ends while reading {what}"),
            ));
        }
        self.pos += n;
        Ok(&self.data[self.pos - n..self.pos])
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().unwrap_or_default(),
        ))
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().unwrap_or_default(),
        ))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(
            self.take(8, what)?.try_into().unwrap_or_default(),
        ))
    }
    fn count(&mut self, what: &str, each: usize) -> Result<usize> {
        let n = self.u64(what)?;
        // Each entry takes at least `each` bytes: a count beyond the file is corrupt, not a
        // reason to allocate.
        if n > ((self.data.len() - self.pos) / each.max(1)) as u64 {
            return Err(Error::invalid(
                self.path,
                format!("byte {}", self.pos - 8),
                format!("{what} {n} is more than the file can hold"),
            ));
        }
        Ok(n as usize)
    }
}

fn open_bin(path: &Path) -> Result<Bin<'_>> {
    Ok(Bin {
        path,
        data: std::fs::read(path).map_err(|e| Error::io(path, e))?,
        pos: 0,
    })
}

/// COLMAP's model ids and their parameter counts.
const MODELS: [(&str, usize); 7] = [
    ("SIMPLE_PINHOLE", 3),
    ("PINHOLE", 4),
    ("SIMPLE_RADIAL", 4),
    ("RADIAL", 5),
    ("OPENCV", 8),
    ("OPENCV_FISHEYE", 8),
    ("FULL_OPENCV", 12),
];

fn read_cameras_bin(path: &Path) -> Result<BTreeMap<u64, ColmapCamera>> {
    let mut b = open_bin(path)?;
    let n = b.count("the number of cameras", 24)?;
    let mut out = BTreeMap::new();
    for i in 0..n {
        let at = format!("camera {i}");
        let id = b.u32(&format!("{at}: id"))? as u64;
        let model_id = b.u32(&format!("{at}: model id"))? as usize;
        let (model, count) = MODELS.get(model_id).copied().ok_or_else(|| {
            Error::invalid(
                path,
                format!("camera {id}: model id"),
                format!(
                    "model id {model_id} has no equivalent here (supported: 0-6, SIMPLE_PINHOLE to FULL_OPENCV)"
                ),
            )
        })?;
        let width = b.u64(&format!("{at}: width"))?;
        let height = b.u64(&format!("{at}: height"))?;
        let params = (0..count)
            .map(|_| b.f64(&format!("{at}: parameters")))
            .collect::<Result<Vec<_>>>()?;
        out.insert(
            id,
            ColmapCamera {
                model: model.into(),
                width,
                height,
                params,
            },
        );
    }
    Ok(out)
}

fn read_images_bin(path: &Path) -> Result<Vec<ColmapImage>> {
    let mut b = open_bin(path)?;
    let n = b.count("the number of images", 64)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let at = format!("image {i}");
        let _id = b.u32(&format!("{at}: id"))?;
        let mut q = [0.0; 4];
        for v in &mut q {
            *v = b.f64(&format!("{at}: quaternion"))?;
        }
        let mut t = [0.0; 3];
        for v in &mut t {
            *v = b.f64(&format!("{at}: translation"))?;
        }
        let camera_id = b.u32(&format!("{at}: camera id"))? as u64;
        let end = b.data[b.pos..]
            .iter()
            .position(|&c| c == 0)
            .ok_or_else(|| {
                Error::invalid(path, format!("{at}: name"), "the file ends inside the name")
            })?;
        let name = String::from_utf8_lossy(&b.data[b.pos..b.pos + end]).into_owned();
        b.pos += end + 1;
        let points = b.count(&format!("{at}: number of 2D points"), 24)?;
        b.take(points * 24, &format!("{at}: 2D points"))?;
        out.push(ColmapImage {
            q,
            t,
            camera_id,
            name,
            at,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::calib::testing::{err, has};

    fn fixture(file: &str) -> String {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/colmap/text");
        std::fs::read_to_string(p.join(file)).unwrap()
    }

    /// A text model of the fixture's cameras.txt and `images` as images.txt.
    fn model(images: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cameras.txt"), fixture("cameras.txt")).unwrap();
        std::fs::write(dir.path().join("images.txt"), images).unwrap();
        dir
    }

    #[test]
    fn images_txt_without_its_empty_points2d_lines_is_refused_with_the_line() {
        let images = fixture("images.txt");
        // `grep -v '^$'`: every image line is followed by the next one.
        let stripped: String = images
            .lines()
            .filter(|l| !l.is_empty())
            .map(|l| format!("{l}\n"))
            .collect();
        has(
            &err(read_colmap(model(&stripped).path())),
            &[
                "images.txt",
                "line 6",
                "POINTS2D line after image line 5 is missing",
            ],
        );
    }

    #[test]
    fn points2d_lines_are_triples_of_numbers_or_empty() {
        let images = fixture("images.txt");
        let mut lines: Vec<String> = images.lines().map(String::from).collect();
        assert_eq!(lines[5], "", "the fixture's first POINTS2D line is line 6");
        lines[5] = "100.5 200.5 -1 300.25 400.75 5".into();
        let cams = read_colmap(model(&lines.join("\n")).path()).unwrap();
        assert_eq!(cams.len(), 7);
        for bad in ["hello world", "1 2 3 4", "1 2 3.5"] {
            lines[5] = bad.into();
            has(
                &err(read_colmap(model(&lines.join("\n")).path())),
                &["images.txt", "line 6: POINTS2D", bad, "X Y POINT3D_ID"],
            );
        }
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let dir = tempfile::tempdir().unwrap();
        for f in ["cameras.txt", "images.txt"] {
            std::fs::write(dir.path().join(f), format!("\u{feff}{}", fixture(f))).unwrap();
        }
        let plain = model(&fixture("images.txt"));
        assert_eq!(
            read_colmap(dir.path()).unwrap(),
            read_colmap(plain.path()).unwrap()
        );
    }

    #[test]
    fn a_file_given_for_the_model_folder_names_the_folder() {
        let dir = model(&fixture("images.txt"));
        let file = dir.path().join("cameras.txt");
        has(
            &err(read_colmap(&file)),
            &[
                "cameras.txt",
                "is a file",
                "a COLMAP model is a folder",
                &format!("give the folder, {}", dir.path().display()),
            ],
        );
    }
}
