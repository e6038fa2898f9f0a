//! `modelflow import`: writes a scene file from a calibration made by another tool (a COLMAP
//! sparse model, an OpenCV `FileStorage` file, a Metashape camera XML, a nerfstudio / instant-ngp /
//! NeRF `transforms.json`, an anipose / Pose2Sim / FreeMoCap / caliscope TOML file, a Kalibr
//! `camchain.yaml`, mrcal `.cameramodel` files, the cameras of an Alembic or USD file), with the
//! user's mesh, image pattern and frames.
//! The readers, the conversion of conventions and the checks are the library's
//! (`input::calib::import_calibration`); this parses the options, writes and reports.

use modelflow::input::calib::{import_calibration, CalibrationFormat, ImportOptions, Imported};
use modelflow::input::Scene;
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Format {
    /// Whichever of the formats below the input is, told from its files or its first bytes.
    Auto,
    /// A COLMAP sparse model folder (cameras.txt + images.txt, or the .bin files).
    Colmap,
    /// An OpenCV FileStorage file (.yml, .yaml or .json) from camera or stereo calibration.
    Opencv,
    /// An Agisoft Metashape camera XML file (aligned frame cameras).
    Metashape,
    /// A transforms.json file (nerfstudio, instant-ngp, NeRF synthetic): one frame per camera.
    Nerfstudio,
    /// A TOML rig calibration: anipose's, Pose2Sim's or FreeMoCap's calibration.toml, caliscope's
    /// camera_array.toml (or its older config.toml).
    #[value(
        alias = "anipose",
        alias = "pose2sim",
        alias = "freemocap",
        alias = "caliscope"
    )]
    Toml,
    /// A Kalibr camera chain: camchain.yaml (or camchain-imucam.yaml), cam0's frame the world.
    Kalibr,
    /// An mrcal .cameramodel file, or a folder of them (mrcal-calibrate-cameras' camera-N files).
    Mrcal,
    /// The cameras of an Alembic file (.abc, Ogawa): Maya's, Houdini's, Blender's, a matchmove
    /// package's or modelflow's own export; a moving camera gets a pose per frame.
    Alembic,
    /// The cameras of a USD text file (.usda): Houdini's, Maya's, Blender's, Omniverse's or
    /// modelflow's own export; a moving camera gets a pose per frame.
    Usd,
    /// An AliceVision (Meshroom) SfM file in JSON: StructureFromMotion's cameras.sfm, or an
    /// sfm.json; one camera per reconstructed view.
    #[value(alias = "meshroom")]
    Alicevision,
}

#[derive(clap::Args)]
pub struct Args {
    /// What the calibration is.
    #[arg(value_enum)]
    format: Format,
    /// The calibration: a COLMAP model folder, an OpenCV file, a Metashape XML file, a
    /// transforms.json file, a TOML file, a Kalibr camchain.yaml, an mrcal .cameramodel (or a
    /// folder of them), an Alembic file or a USD text file.
    input: PathBuf,
    /// The scene file to write.
    #[arg(long)]
    out: PathBuf,
    /// The mesh lined up with the first frame, as the scene file will name it (relative to the
    /// scene file's folder).
    #[arg(long, default_value = "mesh/initial.obj")]
    mesh: String,
    /// Each camera's images: {camera} becomes the camera's name, {frame} or {frame:0N} the frame
    /// number zero-padded to N digits (relative to the scene file's folder); or each camera's
    /// video file (videos/{camera}.mp4).
    #[arg(long, default_value = "images/{camera}/{frame:04}.png")]
    images: String,
    /// The frames, A..B inclusive (Alembic: frame F at F/fps seconds, the file's fps; USD: at
    /// time code F).
    #[arg(long, value_name = "A..B", default_value = "0..0", value_parser = crate::select::parse_frames)]
    frames: (u32, u32),
    /// The image size of cameras whose calibration gives none (OpenCV files without
    /// image_width/image_height, NeRF synthetic transforms.json files without w/h, TOML cameras
    /// without size, Alembic cameras from other packages than Blender, USD cameras without render
    /// settings), as WxH.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Metashape: the chunk to import, by its label or id (needed when several enabled chunks
    /// have aligned cameras).
    #[arg(long, value_name = "LABEL_OR_ID")]
    chunk: Option<String>,
    /// nerfstudio: place the cameras in the world before the file's applied_transform (the
    /// original reconstruction's, e.g. COLMAP's, where a mesh made from it lies) instead of the
    /// file's own.
    #[arg(long)]
    before_applied_transform: bool,
    /// The unit of the calibration's world coordinates (m, cm or mm), written into the scene so
    /// that errors are shown in mm; without it they are shown in scene units.
    #[arg(long)]
    units: Option<modelflow::base::Units>,
    /// Replace an existing scene file.
    #[arg(long)]
    force: bool,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected WxH with positive integers (e.g. 1920x1080), got {s:?}");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    match (w.trim().parse::<u32>(), h.trim().parse::<u32>()) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => Err(bad()),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.out.exists() && !args.force {
        anyhow::bail!("{} exists; give --force to replace it", args.out.display());
    }
    let format = match args.format {
        Format::Auto => {
            let f = CalibrationFormat::detect(&args.input)?;
            eprintln!("read as the {} format", f.name());
            f
        }
        Format::Colmap => CalibrationFormat::Colmap,
        Format::Opencv => CalibrationFormat::Opencv,
        Format::Metashape => CalibrationFormat::Metashape,
        Format::Nerfstudio => CalibrationFormat::Nerfstudio,
        Format::Toml => CalibrationFormat::Toml,
        Format::Kalibr => CalibrationFormat::Kalibr,
        Format::Mrcal => CalibrationFormat::Mrcal,
        Format::Alembic => CalibrationFormat::Alembic,
        Format::Usd => CalibrationFormat::Usd,
        Format::Alicevision => CalibrationFormat::AliceVision,
    };
    let opts = ImportOptions {
        mesh: args.mesh,
        images: args.images,
        frames: args.frames,
        size: args.size,
        chunk: args.chunk,
        units: args.units,
        before_applied_transform: args.before_applied_transform,
    };
    let Imported {
        cameras,
        notes,
        file,
    } = import_calibration(format, &args.input, &opts)?;
    file.write(&args.out)?;
    let (first, last) = opts.frames;
    for c in &cameras {
        let lens = match &c.distortion {
            Some(d) => format!("{} {:?}", d.model(), d.coefficients()),
            None => "pinhole".into(),
        };
        let note = c
            .note
            .as_ref()
            .map_or(String::new(), |n| format!("  ({n})"));
        eprintln!(
            "  {:<12} {}x{}  f {:.2}, {:.2}  c {:.2}, {:.2}  {lens}{note}",
            c.name,
            c.width,
            c.height,
            c.k[(0, 0)],
            c.k[(1, 1)],
            c.k[(0, 2)],
            c.k[(1, 2)]
        );
    }
    for n in &notes {
        eprintln!("note: {n}");
    }
    eprintln!(
        "wrote {} ({} cameras, frames {first}..={last})",
        args.out.display(),
        cameras.len()
    );
    // The scene is complete only with its mesh and images in place: say what is missing.
    match Scene::load(&args.out) {
        Ok(scene) => crate::select::warn_calibration(&scene),
        Err(e) => eprintln!("note: the scene does not load yet: {e}"),
    }
    println!("{}", args.out.display());
    Ok(())
}
