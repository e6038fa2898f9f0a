//! Video files as input: frames are read frame-accurately from H.264 MP4 and H.265 MOV (with
//! B-frames and several keyframe intervals) in any order, and footage tracked from video matches footage
//! tracked from the same frames as PNG. Needs FFmpeg's `ffmpeg`/`ffprobe` on the PATH (`.ci/run`
//! installs them); without them these tests say so and pass without checking.

mod common;

use common::track_errors;
use modelflow::input::video::{probe, VideoReader};
use modelflow::input::{write_png, Scene, SceneFile};
use modelflow::synth::{SynthOptions, Synthetic};
use modelflow::RgbImage;
use std::path::Path;
use std::process::Command;

fn have_ffmpeg() -> bool {
    let ok = |t: &str| {
        Command::new(t)
            .arg("-version")
            .output()
            .is_ok_and(|o| o.status.success())
    };
    let have = ok("ffmpeg") && ok("ffprobe");
    if !have {
        eprintln!(
            "SKIPPED: ffmpeg/ffprobe not on the PATH (apt-get install ffmpeg; .ci/run installs it)"
        );
    }
    have
}

/// Encodes `dir/{frame:04}.png` into an H.264 MP4 (keyframe every 7 frames, B-frames).
fn encode(dir: &Path, out: &Path, crf: u32) {
    encode_with(dir, out, "libx264", crf);
}

/// Encodes `dir/{frame:04}.png` with `codec` (`libx264`, `libx265`) into `out` (container from
/// its extension), a keyframe every 7 frames and two B-frames between references.
fn encode_with(dir: &Path, out: &Path, codec: &str, crf: u32) {
    let st = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-framerate", "25", "-i"])
        .arg(dir.join("%04d.png"))
        .args(["-c:v", codec, "-g", "7", "-bf", "2", "-pix_fmt", "yuv444p"])
        .args(if codec == "libx265" {
            &[
                "-x265-params",
                "log-level=error:keyint=7:min-keyint=7:bframes=2",
            ][..]
        } else {
            &[][..]
        })
        .arg("-crf")
        .arg(crf.to_string())
        .arg(out)
        .status()
        .unwrap();
    assert!(st.success(), "ffmpeg could not encode {}", dir.display());
}

/// Whether this FFmpeg has `encoder` (to make test footage; reading needs only the decoder).
fn have_encoder(encoder: &str) -> bool {
    let out = Command::new("ffmpeg")
        .args(["-hide_banner", "-encoders"])
        .output()
        .unwrap();
    let have = String::from_utf8_lossy(&out.stdout)
        .lines()
        .any(|l| l.split_whitespace().nth(1) == Some(encoder));
    if !have {
        eprintln!("SKIPPED: this FFmpeg has no {encoder} encoder to make the test footage");
    }
    have
}

#[test]
fn frames_are_read_frame_accurately_in_any_order() {
    if !have_ffmpeg() {
        return;
    }
    frame_accuracy("libx264", "clip.mp4");
}

#[test]
fn h265_mov_frames_are_read_frame_accurately_in_any_order() {
    if !have_ffmpeg() || !have_encoder("libx265") {
        return;
    }
    frame_accuracy("libx265", "clip.mov");
}

/// 40 frames whose red level encodes the frame number, encoded with `codec` into `name`, read
/// in order, backwards, in jumps and repeats: every read gives exactly the frame asked for.
fn frame_accuracy(codec: &str, name: &str) {
    let dir = tempfile::tempdir().unwrap();
    let level = |n: u64| (6 * n) as f32 / 255.0;
    for n in 0..40u64 {
        let img = RgbImage::from_fn(64, 48, |x, _| {
            [level(n), if x < 32 { 0.2 } else { 0.8 }, 0.5]
        });
        write_png(&dir.path().join(format!("{n:04}.png")), &img).unwrap();
    }
    let video = dir.path().join(name);
    encode_with(dir.path(), &video, codec, 10);
    let info = probe(&video).unwrap();
    assert_eq!((info.width, info.height, info.frames), (64, 48, 40));
    let mut r = VideoReader::open(&video).unwrap();
    // In order, then backwards, jumps and repeats.
    let order: Vec<u64> = (0..40).chain([39, 0, 17, 3, 30, 31, 8, 8]).collect();
    for n in order {
        let got = r.frame(n).unwrap().get(10, 20)[0];
        assert!(
            (got - level(n)).abs() < 2.5 / 255.0,
            "frame {n}: red {got}, expected {}",
            level(n)
        );
    }
    let e = r.frame(40).unwrap_err().to_string();
    assert!(e.contains(name) && e.contains("has 40 frames"), "{e}");
    // Not a video.
    std::fs::write(dir.path().join("fake.mp4"), b"not a video").unwrap();
    let e = probe(&dir.path().join("fake.mp4")).unwrap_err().to_string();
    assert!(
        e.contains("fake.mp4") && e.contains("not a readable video"),
        "{e}"
    );
}

/// A 10-bit video (a cinema camera's or a phone's HDR mode) keeps its precision: a grey ramp
/// from 0.3 to 0.7 over 512 pixels, from 16-bit PNGs encoded as `yuv444p10le`, reads back with
/// far more than the 103 levels 8 bits would leave, each within 2 of its 1 023 levels; the
/// same ramp in 8-bit video reads back in steps of 1/255.
#[test]
fn a_10_bit_video_is_read_with_its_precision_kept() {
    if !have_ffmpeg() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let ramp = |x: usize| 0.3 + 0.4 * x as f32 / 511.0;
    for n in 0..3 {
        let img = RgbImage::from_fn(512, 16, |x, _| [ramp(x); 3]);
        modelflow::input::write_png16(&dir.path().join(format!("{n:04}.png")), &img).unwrap();
    }
    let levels = |video: &Path| {
        let mut r = VideoReader::open(video).unwrap();
        let img = r.frame(1).unwrap();
        let mut worst = 0.0f32;
        let mut values: Vec<u32> = (0..512)
            .map(|x| {
                let v = img.get(x, 8)[1];
                worst = worst.max((v - ramp(x)).abs());
                (v * 65535.0).round() as u32
            })
            .collect();
        values.sort_unstable();
        values.dedup();
        (r.info().deep, values.len(), worst, img.get(200, 8)[1])
    };
    for (pix_fmt, name) in [("yuv444p10le", "deep.mp4"), ("yuv444p", "eight.mp4")] {
        let st = Command::new("ffmpeg")
            .args(["-v", "error", "-y", "-framerate", "25", "-i"])
            .arg(dir.path().join("%04d.png"))
            .args(["-c:v", "libx264", "-qp", "0", "-pix_fmt", pix_fmt])
            .arg(dir.path().join(name))
            .status()
            .unwrap();
        if !st.success() {
            eprintln!("SKIPPED: this FFmpeg's libx264 cannot encode {pix_fmt}");
            return;
        }
    }
    let (deep, distinct, worst, _) = levels(&dir.path().join("deep.mp4"));
    assert!(deep, "yuv444p10le is deeper than 8 bits");
    assert!(distinct > 300, "{distinct} levels over the ramp");
    assert!(worst < 2.0 / 1023.0, "off by {worst}");
    let (deep, distinct, worst, v) = levels(&dir.path().join("eight.mp4"));
    assert!(!deep);
    assert!(distinct <= 110, "{distinct} levels from 8-bit video");
    assert!(worst < 2.0 / 255.0, "off by {worst}");
    assert!(
        ((v * 255.0).round() - v * 255.0).abs() < 1e-4,
        "{v} is not a step of 1/255"
    );
}

/// A phone's video stored sideways with a display rotation of 90°: read at the size it is shown
/// at, as FFmpeg and players show it (its pixels the stored frame's turned a quarter, not the
/// stored bytes laid out at the wrong width), and a camera declared at the stored size is
/// refused at load with the turn named.
#[test]
fn a_video_stored_turned_is_read_as_shown_and_a_camera_of_its_stored_size_refused() {
    if !have_ffmpeg() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // 64×48, a different colour in each quadrant.
    let quadrant = |x: usize, y: usize| match (x < 32, y < 24) {
        (true, true) => [0.9, 0.1, 0.1],
        (false, true) => [0.1, 0.9, 0.1],
        (true, false) => [0.1, 0.1, 0.9],
        (false, false) => [0.9, 0.9, 0.1],
    };
    for n in 0..3 {
        let img = RgbImage::from_fn(64, 48, quadrant);
        write_png(&dir.path().join(format!("{n:04}.png")), &img).unwrap();
    }
    let plain = dir.path().join("plain.mp4");
    encode(dir.path(), &plain, 10);
    // FFmpeg 5 writes the turn from a `rotate` tag, FFmpeg 6 and later from -display_rotation.
    let turned = dir.path().join("turned.mp4");
    let tries: [&[&str]; 2] = [
        &[
            "-i",
            "plain.mp4",
            "-c",
            "copy",
            "-metadata:s:v:0",
            "rotate=90",
        ],
        &[
            "-display_rotation:v:0",
            "90",
            "-i",
            "plain.mp4",
            "-c",
            "copy",
        ],
    ];
    let made = tries.iter().any(|args| {
        Command::new("ffmpeg")
            .current_dir(dir.path())
            .args(["-v", "error", "-y"])
            .args(*args)
            .arg(&turned)
            .status()
            .is_ok_and(|s| s.success())
            && probe(&turned).is_ok_and(|i| i.rotation != 0)
    });
    if !made {
        eprintln!("SKIPPED: this FFmpeg cannot write a display rotation to make the test footage");
        return;
    }
    let info = probe(&turned).unwrap();
    assert_eq!((info.width, info.height, info.rotation % 180), (48, 64, 90));
    let img = VideoReader::open(&turned).unwrap().frame(1).unwrap();
    assert_eq!((img.width(), img.height()), (48, 64));
    // Shown turned a quarter either way: each quadrant's colour where the turn takes it.
    let near = |a: [f32; 3], b: [f32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 0.1);
    let clockwise = |x: usize, y: usize| quadrant(y, 47 - x);
    let anticlockwise = |x: usize, y: usize| quadrant(63 - y, x);
    let probes = [(10, 10), (38, 10), (10, 54), (38, 54)];
    let as_turned = |f: &dyn Fn(usize, usize) -> [f32; 3]| {
        probes.iter().all(|&(x, y)| near(img.get(x, y), f(x, y)))
    };
    assert!(
        as_turned(&clockwise) || as_turned(&anticlockwise),
        "not the stored frame turned: {:?}",
        probes.map(|(x, y)| img.get(x, y))
    );
    // A camera declared at the stored 64×48 is refused, naming the turn.
    let (path, mut file) = common::write_scene(dir.path());
    file.cameras[0].width = 64;
    file.cameras[0].height = 48;
    file.cameras[0].images = turned.to_string_lossy().into_owned();
    file.write(&path).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("cameras[0].images") && e.contains("is 48x64") && e.contains("turns it by"),
        "{e}"
    );
}

#[test]
fn footage_from_video_files_is_tracked_like_its_frames() {
    if !have_ffmpeg() {
        return;
    }
    let opts = SynthOptions {
        width: 320,
        height: 240,
        frames: 5,
        ..SynthOptions::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let pngs = Synthetic::generate(&opts)
        .unwrap()
        .write(&dir.path().join("png"), &|_, _| {})
        .unwrap();
    let text = std::fs::read_to_string(&pngs).unwrap();
    let mut file = SceneFile::parse(&pngs, &text).unwrap();
    for c in &mut file.cameras {
        let frames = dir.path().join("png/images").join(&c.name);
        encode(&frames, &dir.path().join(format!("png/{}.mp4", c.name)), 12);
        c.images = format!("{}.mp4", c.name);
    }
    let videos = dir.path().join("png/video.json");
    file.write(&videos).unwrap();
    let from_video = track_errors(&Scene::load(&videos).unwrap());
    let from_png = track_errors(&Scene::load(&pngs).unwrap());
    eprintln!("error per frame (%): video {from_video:.4?}, png {from_png:.4?}");
    for (f, (v, p)) in from_video.iter().zip(&from_png).enumerate() {
        assert!(
            *v < 1.5 * p + 0.05,
            "frame {}: {v:.4} % from video vs {p:.4} % from PNG",
            f + 1
        );
    }
    // A frame range past the video's end is refused at load, naming the camera.
    file.frames.last = 9;
    file.ground_truth = None;
    file.write(&videos).unwrap();
    let e = Scene::load(&videos).unwrap_err().to_string();
    assert!(
        e.contains("cameras[0].images") && e.contains("has 5 frames"),
        "{e}"
    );
}
