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
//! 8-bit RGB as FFmpeg converts them, scaled by 1/255 like 8-bit image files.

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
}

fn tool(name: &str, path: &Path) -> Error {
    Error::invalid(
        path,
        "video",
        format!("cannot run `{name}`: reading video needs FFmpeg's `{name}` on the PATH (e.g. `apt-get install ffmpeg`)"),
    )
}

/// Size and frame count of a video's first video stream (`ffprobe`).
pub fn probe(path: &Path) -> Result<VideoInfo> {
    let out = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-count_packets"])
        .args([
            "-show_entries",
            "stream=width,height,nb_read_packets",
            "-of",
            "csv=p=0",
        ])
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .map_err(|_| tool("ffprobe", path))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let fields: Vec<u64> = text
        .trim()
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    match (out.status.success(), fields.as_slice()) {
        (true, [w, h, n])
            if *w > 0 && *h > 0 && *n > 0 && *w <= u32::MAX as u64 && *h <= u32::MAX as u64 =>
        {
            Ok(VideoInfo {
                width: *w as u32,
                height: *h as u32,
                frames: *n,
            })
        }
        _ => Err(Error::invalid(
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
        )),
    }
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
                "rgb24",
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
        let mut buf = vec![0u8; w * h * 3];
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
        let data = buf
            .chunks_exact(3)
            .map(|p| {
                [
                    p[0] as f32 / 255.0,
                    p[1] as f32 / 255.0,
                    p[2] as f32 / 255.0,
                ]
            })
            .collect();
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
    fn video_files_are_told_by_their_extension() {
        assert!(is_video(Path::new("a/cam0.MP4")) && is_video(Path::new("take.mov")));
        assert!(!is_video(Path::new("cam0/{frame:04}.png")) && !is_video(Path::new("mp4")));
    }
}
