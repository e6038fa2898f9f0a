//! `--frames A..B`, `--cameras NAME,...` and `--mesh FILE`, shared by the commands that read a scene (`track`,
//! `baseline`, `eval`, `report`): parsing here, the selection itself in the library
//! (`Scene::load_selected`, `Scene::with_mesh`).

use modelflow::input::Scene;

#[derive(clap::Args, Clone, Debug, Default)]
pub struct SelectArgs {
    /// Only frames A..B (inclusive, within the scene's); the scene's mesh is taken as lined up
    /// with frame A.
    #[arg(long, value_name = "A..B", value_parser = parse_frames)]
    pub frames: Option<(u32, u32)>,
    /// Only these cameras (names as in the scene, comma-separated); at least two must see the
    /// mesh at the first frame.
    #[arg(long, value_name = "NAME,...", value_delimiter = ',')]
    pub cameras: Option<Vec<String>>,
    /// The mesh lined up with the first frame, instead of the scene's (OBJ, PLY or glTF; e.g. an
    /// earlier run's last frame, to go on from there with --frames).
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<std::path::PathBuf>,
}

/// `--max-memory`, for the commands that hold every camera's frames (`track`, `baseline`).
#[derive(clap::Args, Clone, Debug)]
pub struct MemoryArgs {
    /// Refuse scenes that would need more memory than this, in GiB, before anything is
    /// allocated (the estimate is 100 bytes per pixel of every camera).
    #[arg(long, value_name = "GIB", default_value_t = 16.0)]
    pub max_memory: f64,
}

impl MemoryArgs {
    pub fn check(&self, scene: &Scene) -> modelflow::Result<()> {
        if !(self.max_memory.is_finite() && self.max_memory > 0.0) {
            return Err(modelflow::Error::option(
                "--max-memory",
                self.max_memory,
                "a positive number of GiB",
            ));
        }
        scene.check_memory(
            (self.max_memory * (1u64 << 30) as f64) as u64,
            "--max-memory",
        )
    }
}

/// Says on stderr which cameras see none of the mesh at the scene's first frame, and why
/// (`Scene::blind_cameras`), when the mesh is far too small or large in the images
/// (`Scene::mesh_out_of_scale`), which cameras' principal points lie far from their images'
/// centres (`Scene::off_centre_principal_points`), and which cameras' image files ask to be
/// shown turned (`Scene::turned_images`): a calibration in another convention, unit,
/// resolution or orientation loads, and would otherwise be tracked past in silence.
pub fn warn_calibration(scene: &Scene) {
    if let Some(m) = scene.mesh_out_of_scale() {
        eprintln!("warning: {m} (docs/scene-format.md, \"Convention\").");
    }
    for b in scene.blind_cameras() {
        eprintln!(
            "warning: {b}. The other cameras are used as they are; if the mesh enters this camera's view only later, ignore this."
        );
    }
    for o in scene.off_centre_principal_points() {
        eprintln!("warning: {o} (docs/scene-format.md, \"Convention\").");
    }
    for t in scene.turned_images() {
        eprintln!("warning: {t} (docs/scene-format.md, \"Files\").");
    }
}

impl SelectArgs {
    /// The scene at `path`, restricted as asked: only the chosen cameras' images over the
    /// chosen frames are checked (`Scene::load_selected`), so a camera with broken footage can
    /// be left out and a shot tracked over the frames that exist.
    pub fn load(&self, path: &std::path::Path) -> modelflow::Result<Scene> {
        let selection = modelflow::input::Selection {
            cameras: self.cameras.clone(),
            frames: self.frames,
        };
        let scene = Scene::load_selected(path, &selection)?;
        match &self.mesh {
            Some(m) => scene.with_mesh(m),
            None => Ok(scene),
        }
    }
}

impl SelectArgs {
    /// Without `--frames` (`--cameras`), the frames (cameras) the `runs` were asked to track, as
    /// their `run.json` records them (an interrupted run's frames up to its last complete one;
    /// the frames all of them have, when they differ), so that `track --frames 10..40` then
    /// `eval` or `report` takes those frames. Runs without a manifest (meshes from elsewhere)
    /// leave the whole scene. Says on stderr, after `doing`, which frames when they are not the
    /// scene's.
    pub fn or_the_runs(
        mut self,
        scene: &modelflow::input::SceneFile,
        runs: &[&std::path::Path],
        doing: &str,
    ) -> anyhow::Result<Self> {
        let mut ranges = Vec::new();
        let mut cameras = Vec::new();
        for dir in runs {
            let path = dir.join(modelflow::run::MANIFEST);
            if !path.is_file() {
                return Ok(self);
            }
            let m = modelflow::run::Manifest::read(&path)?;
            let last = match m.status {
                modelflow::run::Status::Complete => m.scene.last,
                _ => m.last_complete.unwrap_or(m.scene.first).min(m.scene.last),
            };
            ranges.push((m.scene.first, last, last < m.scene.last));
            cameras.push(m.options.given.get("--cameras").cloned());
        }
        let (Some(first), Some(last)) = (
            ranges.iter().map(|r| r.0).max(),
            ranges.iter().map(|r| r.1).min(),
        ) else {
            return Ok(self);
        };
        if self.frames.is_none()
            && first <= last
            && (first, last) != (scene.frames.first, scene.frames.last)
        {
            self.frames = Some((first, last));
            let stopped = ranges.iter().any(|r| r.2);
            eprintln!(
                "{doing} frames {first}..={last}, the frames {} tracked (run.json{}; --frames chooses others)",
                if runs.len() == 1 { "the run" } else { "the runs all" },
                if stopped { ": it stopped there" } else { "" }
            );
        }
        if self.cameras.is_none() && cameras.windows(2).all(|w| w[0] == w[1]) {
            if let Some(Some(names)) = cameras.first() {
                self.cameras = Some(names.split(',').map(str::to_string).collect());
            }
        }
        Ok(self)
    }
}

pub fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected A..B with frame numbers A <= B (e.g. 10..40), got {s:?}");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let b = b.strip_prefix('=').unwrap_or(b);
    let (a, b) = (
        a.trim().parse::<u32>().map_err(|_| bad())?,
        b.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if a > b {
        return Err(bad());
    }
    Ok((a, b))
}

#[cfg(test)]
mod tests {
    use super::parse_frames;

    #[test]
    fn frame_ranges_parse_inclusive_and_refuse_the_rest() {
        assert_eq!(parse_frames("10..40"), Ok((10, 40)));
        assert_eq!(parse_frames("3..=3"), Ok((3, 3)));
        for bad in ["10", "40..10", "a..b", "-1..3", "1...3"] {
            assert!(
                parse_frames(bad).unwrap_err().contains("expected A..B"),
                "{bad}"
            );
        }
    }
}
