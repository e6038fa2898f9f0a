//! Video files as a camera's frames (`"images": "cam0.mp4"` in the scene format): H.264/H.265
//! in MP4, MOV, MKV and the like, decoded by the `ffmpeg` program (FFmpeg 5 or later on the PATH;
//! `.ci/run` and `docs/your-footage.md` say how to install it). Running the program rather than
//! binding libav keeps the build free of C libraries and lets any FFmpeg build the user has
//! decode any codec it knows.
//!
//! Frame numbers are *decoded frame indices* counted from 0, never timestamps: frame `n` is the
//! `n`-th frame the decoder outputs (FFmpeg's `select=gte(n,N)` with pass-through timing, so no
//! frame is dropped or duplicated to fit a frame rate). A reader keeps one decoder running and
//! reads frames in order; asking for an earlier frame, or one far ahead, restarts it. Pixels are
//! RGB as FFmpeg converts them: 8-bit, scaled by 1/255 like 8-bit image files, for 8-bit video;
//! 16-bit, scaled by 1/65535, for video with deeper samples (10-, 12-bit: [`VideoInfo::deep`]).
//! A video stored turned (a display rotation) is read turned, as FFmpeg and players show it, at
//! the size it is shown at ([`VideoInfo::rotation`]).

use crate::base::image::RgbImage;
use crate::error::{Error, Result};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

/// File name endings read as video.
pub const VIDEO_EXTENSIONS: [&str; 8] = ["mp4", "mov", "m4v", "mkv", "avi", "webm", "mxf", "mts"];

/// Whether a path names a video file (by its extension).
pub fn is_video(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| VIDEO_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// What [`probe`] finds out about a video.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VideoInfo {
    pub width: u32,
    pub height: u32,
    /// Frames in the first video stream (its packets, counted without decoding).
    pub frames: u64,
    /// Its samples have more than 8 bits (FFmpeg's pixel format, e.g. `yuv420p10le` from a
    /// cinema camera or a phone's HDR mode, `yuv444p12le`, `rgb48le`): its frames are converted
    /// to 16-bit RGB and scaled by 1/65535, so that no precision is rounded away; 8-bit video is
    /// converted to 8-bit RGB and scaled by 1/255.
    pub deep: bool,
    /// The turn its display matrix asks for (0, 90, 180 or 270 degrees, as `ffprobe` reports
    /// it), which FFmpeg applies when it decodes, as players do: `width` and `height` are the
    /// size after it.
    pub rotation: u32,
}

/// Whether FFmpeg's pixel format `name` has more than 8 bits per sample: a bit depth of 9 to 16
/// in its name (`yuv420p10le`, `gray12be`, `gbrp16le`, `p010le`, `y210le`) or one of the packed
/// 16-bit RGB formats (`rgb48le`, `bgra64be`, `x2rgb10le`).
fn deep_pixel_format(name: &str) -> bool {
    let name = name.trim().trim_end_matches("le").trim_end_matches("be");
    if [
        "rgb48", "bgr48", "rgba64", "bgra64", "x2rgb10", "x2bgr10", "p010", "p012", "p016", "p210",
        "p216", "p410", "p416", "y210", "y212", "v210", "nv20",
    ]
    .iter()
    .any(|f| name.ends_with(f))
    {
        return true;
    }
    // A planar or grey format's bits per sample end its name, after a `p` (`yuv420p10`,
    // `gbrap12`) or `gray` / `ya` (`gray10`, `ya16`); other trailing digits are not a depth
    // (`nv12`, `rgb24`, `yuyv422`).
    let digits = name.trim_end_matches(|c: char| c.is_ascii_digit());
    let bits = name[digits.len()..].parse::<u32>().ok();
    let depth_named = digits.ends_with('p') || digits == "gray" || digits == "ya";
    depth_named && bits.is_some_and(|b| (9..=16).contains(&b))
}

fn tool(name: &str, path: &Path) -> Error {
    Error::invalid(
        path,
        "video",
        format!("cannot run `{name}`: reading video needs FFmpeg's `{name}` on the PATH (e.g. `apt-get install ffmpeg`)"),
    )
}

/// Size, frame count and sample depth of a video's first video stream (`ffprobe`). The size is
/// the one the video is shown at, which FFmpeg decodes it to: a phone's video stored sideways with
/// a rotation of ±90° in its display matrix (or an older `rotate` tag) has its stored width and
/// height swapped, so that a camera declared at the stored size is refused rather than read
/// garbled.
pub fn probe(path: &Path) -> Result<VideoInfo> {
    let out = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-count_packets"])
        .args([
            "-show_entries",
            "stream=width,height,pix_fmt,nb_read_packets:stream_tags=rotate:stream_side_data=rotation",
            "-of",
            "json",
        ])
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .map_err(|_| tool("ffprobe", path))?;
    let unreadable = || {
        Error::invalid(
            path,
            "video",
            format!(
                "not a readable video (ffprobe: {})",
                String::from_utf8_lossy(&out.stderr)
                    .trim()
                    .lines()
                    .next()
                    .unwrap_or("no video stream")
            ),
        )
    };
    if !out.status.success() {
        return Err(unreadable());
    }
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).map_err(|_| unreadable())?;
    let stream = &json["streams"][0];
    // ffprobe writes some numbers as JSON numbers and others (the packet count, tags) as strings.
    let number = |v: &serde_json::Value| -> Option<f64> {
        v.as_f64()
            .or_else(|| v.as_str().and_then(|s| s.trim().parse().ok()))
    };
    let whole = |v: &serde_json::Value| {
        number(v).filter(|&x| x >= 1.0 && x <= u32::MAX as f64 && x.fract() == 0.0)
    };
    let (Some(w), Some(h), Some(n)) = (
        whole(&stream["width"]),
        whole(&stream["height"]),
        whole(&stream["nb_read_packets"]),
    ) else {
        return Err(unreadable());
    };
    let rotation = stream["side_data_list"]
        .as_array()
        .and_then(|list| list.iter().find_map(|d| number(&d["rotation"])))
        .or_else(|| number(&stream["tags"]["rotate"]))
        .unwrap_or(0.0);
    let rotation = ((rotation / 90.0).round() as i64).rem_euclid(4) as u32 * 90;
    let sideways = rotation % 180 == 90;
    let (width, height) = if sideways { (h, w) } else { (w, h) };
    Ok(VideoInfo {
        width: width as u32,
        height: height as u32,
        frames: n as u64,
        deep: stream["pix_fmt"].as_str().is_some_and(deep_pixel_format),
        rotation,
    })
}

/// Frames after the decoder's position that are read through rather than restarting it.
const READ_AHEAD: u64 = 256;

/// Sequential, frame-accurate reading of one video.
pub struct VideoReader {
    path: PathBuf,
    info: VideoInfo,
    decoder: Option<(Child, ChildStdout)>,
    /// The frame the running decoder outputs next.
    next: u64,
}

impl std::fmt::Debug for VideoReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VideoReader")
            .field("path", &self.path)
            .field("info", &self.info)
            .field("next", &self.next)
            .finish()
    }
}

impl VideoReader {
    pub fn open(path: &Path) -> Result<VideoReader> {
        Ok(VideoReader {
            path: path.to_path_buf(),
            info: probe(path)?,
            decoder: None,
            next: 0,
        })
    }

    pub fn info(&self) -> VideoInfo {
        self.info
    }

    fn start(&mut self, from: u64) -> Result<()> {
        self.stop();
        let mut child = Command::new("ffmpeg")
            .args(["-nostdin", "-v", "error", "-i"])
            .arg(&self.path)
            .args(["-map", "0:v:0", "-vf"])
            .arg(format!("select=gte(n\\,{from})"))
            .args([
                "-vsync",
                "passthrough",
                "-f",
                "rawvideo",
                "-pix_fmt",
                if self.info.deep { "rgb48le" } else { "rgb24" },
                "-",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|_| tool("ffmpeg", &self.path))?;
        let out = child
            .stdout
            .take()
            .ok_or_else(|| tool("ffmpeg", &self.path))?;
        self.decoder = Some((child, out));
        self.next = from;
        Ok(())
    }

    fn stop(&mut self) {
        if let Some((mut child, _)) = self.decoder.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }

    /// Frame `n` (counted from 0).
    pub fn frame(&mut self, n: u64) -> Result<RgbImage> {
        if n >= self.info.frames {
            return Err(Error::invalid(
                &self.path,
                "video",
                format!(
                    "frame {n} asked for, but the video has {} frames (0..={})",
                    self.info.frames,
                    self.info.frames - 1
                ),
            ));
        }
        if self.decoder.is_none() || n < self.next || n > self.next + READ_AHEAD {
            self.start(n)?;
        }
        let (w, h) = (self.info.width as usize, self.info.height as usize);
        let bytes = if self.info.deep { 2 } else { 1 };
        let mut buf = vec![0u8; w * h * 3 * bytes];
        while self.next <= n {
            let (_, out) = self
                .decoder
                .as_mut()
                .ok_or_else(|| tool("ffmpeg", &self.path))?;
            if out.read_exact(&mut buf).is_err() {
                self.stop();
                return Err(Error::invalid(
                    &self.path,
                    "video",
                    format!("the decoder stopped before frame {n} (the file may be truncated or still being written)"),
                ));
            }
            self.next += 1;
        }
        let data = if self.info.deep {
            buf.chunks_exact(6)
                .map(|p| {
                    let c =
                        |i: usize| u16::from_le_bytes([p[2 * i], p[2 * i + 1]]) as f32 / 65535.0;
                    [c(0), c(1), c(2)]
                })
                .collect()
        } else {
            buf.chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]].map(|c| c as f32 / 255.0))
                .collect()
        };
        RgbImage::from_pixels(w, h, data)
            .ok_or_else(|| Error::invalid(&self.path, "video", "frame size mismatch"))
    }
}

impl Drop for VideoReader {
    fn drop(&mut self) {
        self.stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_formats_deeper_than_8_bits_are_told_by_their_name() {
        for deep in [
            "yuv420p10le",
            "yuv422p10be",
            "yuv444p12le",
            "yuv420p16le",
            "gray10le",
            "gbrp12le",
            "yuva444p10le",
            "p010le",
            "p016be",
            "y210le",
            "rgb48le",
            "bgra64be",
            "x2rgb10le",
            "yuv420p9le",
        ] {
            assert!(deep_pixel_format(deep), "{deep}");
        }
        for eight in [
            "yuv420p", "yuvj420p", "yuv422p", "yuv444p", "nv12", "nv21", "rgb24", "bgr0", "gray",
            "yuyv422", "uyvy422", "gbrp", "yuva420p", "pal8", "nv16", "nv24", "",
        ] {
            assert!(!deep_pixel_format(eight), "{eight}");
        }
    }

    #[test]
    fn video_files_are_told_by_their_extension() {
        assert!(is_video(Path::new("a/cam0.MP4")) && is_video(Path::new("take.mov")));
        assert!(!is_video(Path::new("cam0/{frame:04}.png")) && !is_video(Path::new("mp4")));
    }
}
