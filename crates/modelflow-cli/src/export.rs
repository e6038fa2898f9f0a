//! `modelflow export`: one run folder becomes one animated file for a 3D package (USD, Alembic,
//! glTF, PC2 or MDD); the writing is the library's (`export`).

use modelflow::base::Units;
use modelflow::export::{export_run, ExportFormat, ExportOptions};
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Format {
    /// USD text: one Mesh prim, points as time samples, UVs and normals as primvars, the
    /// scene's cameras.
    Usda,
    /// Alembic (Ogawa): one PolyMesh under an Xform, points sampled at every frame, UVs and
    /// normals per face corner, the scene's cameras.
    Abc,
    /// Binary glTF 2.0: the first frame's mesh, one morph target per frame, an animation.
    Glb,
    /// PC2 point cache, with the first frame's mesh as OBJ beside it.
    Pc2,
    /// MDD point cache, with the first frame's mesh as OBJ beside it.
    Mdd,
}

#[derive(clap::Args)]
pub struct Args {
    /// The run folder (one OBJ per frame, as `track` or `baseline` writes it).
    #[arg(long)]
    run: PathBuf,
    /// The file to write (replaced if it exists; written under a temporary name, then renamed).
    #[arg(long)]
    out: PathBuf,
    /// The format (default: from --out's extension: .usda, .abc, .glb, .pc2, .mdd).
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Frames per second of the footage: the animation's time codes (above 0, at most 1000).
    #[arg(long, default_value_t = 24.0, allow_negative_numbers = true)]
    fps: f64,
    /// The unit of the coordinates, for USD's metersPerUnit (m, cm or mm; default: the scene's
    /// `units`, found through the run's run.json).
    #[arg(long)]
    units: Option<Units>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let format = match args.format {
        Some(Format::Usda) => ExportFormat::Usda,
        Some(Format::Abc) => ExportFormat::Abc,
        Some(Format::Glb) => ExportFormat::Glb,
        Some(Format::Pc2) => ExportFormat::Pc2,
        Some(Format::Mdd) => ExportFormat::Mdd,
        None => ExportFormat::from_path(&args.out).ok_or_else(|| {
            anyhow::anyhow!(
                "--out {}: give --format, or a file ending in .usda, .abc, .glb, .pc2 or .mdd",
                args.out.display()
            )
        })?,
    };
    let opts = ExportOptions {
        fps: args.fps,
        units: args.units,
    };
    let s = export_run(&args.run, format, &args.out, &opts)?;
    eprintln!(
        "exported {} frames of {} vertices and {} triangles{}",
        s.frames,
        s.vertices,
        s.triangles,
        match s.cameras {
            0 => String::new(),
            n => format!(", with the scene's {n} cameras"),
        }
    );
    for w in s.warnings() {
        eprintln!("warning: {w}");
    }
    for f in &s.files {
        println!("{}", f.display());
    }
    Ok(())
}
