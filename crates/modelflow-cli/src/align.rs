//! `modelflow align`: refines the pose (and optionally the scale) of a roughly placed mesh at the
//! scene's first frame so that all cameras agree, and writes the lined-up mesh; the work is the
//! library's (`tracker::align`).

use modelflow::base::{rms_distance, Length};
use modelflow::report::{alignment_picture, surface_rms};
use modelflow::tracker::{align, onto_surface, perturb, surface_offset, AlignOptions, MotionKind};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// The scene file (modelflow-scene/1); its mesh (or --mesh) is the rough placement.
    #[arg(long)]
    scene: PathBuf,
    /// Where to write the lined-up mesh (OBJ, with the input's UVs and normals; written under a
    /// temporary name, then renamed). Track from it with `track --mesh FILE`.
    #[arg(long, value_name = "FILE.obj", value_parser = obj_path)]
    out: PathBuf,
    #[command(flatten)]
    select: crate::select::SelectArgs,
    /// Also solve for one uniform scale about the mesh's centroid.
    #[arg(long)]
    scale: bool,
    /// Fit the mesh's border to the outline the cameras see, for what photo-consistency leaves
    /// free (a flat sheet's place in its plane). Only when the border is the object's visible
    /// edge against a background (a cloth, a sheet of paper), not a cut inside a surface.
    #[arg(long)]
    outline: bool,
    /// When the mesh lies off the surface the cameras agree on (the check `track` makes: 1.5
    /// px or more along its normals), first move every vertex along its normal onto it (for a
    /// mesh made from silhouettes, which lies outside it); its triangulation is kept.
    #[arg(long)]
    surface: bool,
    /// Pyramid levels (0 = from the mesh's size in the images: about 24 px across at the
    /// coarsest; 0 to 8).
    #[arg(long, default_value_t = AlignOptions::default().levels)]
    levels: usize,
    /// Solve only from the placement given: leave out the twelve extra starts around it (moved
    /// 2.5 % of the mesh's size along each axis, turned 5° about each), which reach farther
    /// misplacements with few cameras for twelve more passes' time, at most 640 px wide
    /// (docs/tracker.md, "With three cameras").
    #[arg(long)]
    no_search: bool,
    /// Compare the cameras at this many times their images' resolution (1 or 2; 0 = twice
    /// when the images have at most 4 × 1 280 × 720 pixels together): each image enlarged by
    /// Catmull–Rom interpolation, which samples every triangle four times as densely and
    /// holds the pose more finely (docs/tracker.md, "Compared at twice the resolution").
    #[arg(long, default_value_t = AlignOptions::default().enlarge)]
    enlarge: u32,
    /// Before aligning, misplace the mesh on purpose by PCT percent of its size and DEG degrees
    /// about a random axis (seeded by --seed): a check of how far off a placement may be. With
    /// ground truth, the error before and after is printed.
    #[arg(long, value_name = "PCT,DEG", value_parser = parse_perturb)]
    perturb: Option<(f64, f64)>,
    /// Seed of --perturb's direction and axis.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also draw the mesh as placed and as aligned over every camera's frame into this PNG.
    #[arg(long, value_name = "FILE.png", value_parser = png_path)]
    picture: Option<PathBuf>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// An output file path whose extension is `ext` (any case) and that is not a folder: checked
/// when the command line is read, so that nothing is written before a bad path is refused.
fn output_path(s: &str, ext: &str, what: &str) -> Result<PathBuf, String> {
    let p = PathBuf::from(s);
    if p.is_dir() || s.ends_with('/') {
        return Err(format!(
            "{s} is a folder; expected a file path ending in .{ext}"
        ));
    }
    let ok = p
        .extension()
        .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case(ext));
    if !ok {
        return Err(format!(
            "expected a file ending in .{ext} ({what}), got {s:?}"
        ));
    }
    Ok(p)
}

fn obj_path(s: &str) -> Result<PathBuf, String> {
    output_path(s, "obj", "the mesh is written as OBJ")
}

fn png_path(s: &str) -> Result<PathBuf, String> {
    output_path(s, "png", "the picture is written as PNG")
}

fn parse_perturb(s: &str) -> Result<(f64, f64), String> {
    let bad = || {
        format!("expected PCT,DEG with 0 <= PCT <= 100 and 0 <= DEG <= 90 (e.g. 5,10), got {s:?}")
    };
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    let (a, b) = (
        a.trim().parse::<f64>().map_err(|_| bad())?,
        b.trim().parse::<f64>().map_err(|_| bad())?,
    );
    if !((0.0..=100.0).contains(&a) && (0.0..=90.0).contains(&b)) {
        return Err(bad());
    }
    Ok((a, b))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = args.select.load(&args.scene)?;
    crate::select::warn_calibration(&scene);
    let frame = scene.first;
    let mut mesh = scene.mesh.clone();
    if let Some((pct, deg)) = args.perturb {
        mesh = mesh.with_positions(perturb(&mesh, pct / 100.0, deg, args.seed));
    }
    let opts = AlignOptions {
        scale: args.scale,
        levels: args.levels,
        outline: args.outline,
        search: !args.no_search,
        enlarge: args.enlarge,
        ..AlignOptions::default()
    };
    opts.validate()?;
    let shown = scene.load_images(frame)?;
    // Colour and monochrome cameras together are compared in luminance (as `track` does); the
    // picture shows the frames as they are.
    let images = modelflow::base::comparable(&shown);
    if matches!(images, std::borrow::Cow::Owned(_)) {
        eprintln!("note: some cameras record no colour: every camera is compared in luminance");
    }
    let t = std::time::Instant::now();
    // With --surface, a mesh off the surface has its shape moved first (it pulls the pose the
    // cameras agree on: docs/tracker.md, "The first mesh must lie on the surface"), then its
    // pose aligned, then its shape refined once more from there.
    let off = if args.surface {
        surface_offset(&mesh, &scene.cameras, frame, &images)
    } else {
        None
    };
    // Asked for, the move is made also where a calibration's error would explain it.
    let reshape = off.is_some_and(|o| o.is_off_by_images());
    if args.surface && !reshape {
        eprintln!(
            "the mesh lies on the surface the cameras agree on (within {} px along its normals): its shape is left as it is",
            modelflow::tracker::SURFACE_MIN_PX
        );
    }
    let start = if reshape {
        mesh.with_positions(onto_surface(
            &mesh,
            &scene.cameras,
            frame,
            &images,
            3,
            off.as_ref(),
        ))
    } else {
        mesh.clone()
    };
    let mut a = align(&start, &scene.cameras, frame, &images, &opts)?;
    if reshape {
        a.positions = onto_surface(
            &mesh.with_positions(a.positions.clone()),
            &scene.cameras,
            frame,
            &images,
            1,
            None,
        );
        let o = off.expect("reshape implies an offset");
        eprintln!(
            "the mesh lay {}{:.1} px off the surface the cameras agree on (along its normals); every vertex was moved onto it",
            if o.at_limit { "at least " } else { "" },
            o.pixels.abs()
        );
    }
    let seconds = t.elapsed().as_secs_f64();
    let out = mesh.with_positions(a.positions.clone());
    modelflow::input::write_obj(&args.out, &out)?;
    if let Some(p) = &args.picture {
        let pic = alignment_picture(&scene.cameras, frame, &shown, &mesh, &out)?;
        modelflow::input::write_png(p, &pic)?;
    }

    let size = scene.mesh.bbox_diagonal();
    let truth = match scene.ground_truth(frame) {
        Some(t) => Some(t?),
        None => None,
    };
    // Vertex error (which point is which) and surface error (where the surface is).
    let errors = truth.as_ref().map(|t| {
        (
            100.0 * rms_distance(&mesh.positions, &t.positions) / size,
            100.0 * rms_distance(&a.positions, &t.positions) / size,
            surface_rms(&mesh.positions, t).map(|r| 100.0 * r.0 / size),
            surface_rms(&a.positions, t).map(|r| 100.0 * r.0 / size),
        )
    });
    let len = Length::of(scene.units);
    if args.json {
        let v = serde_json::json!({
            "frame": frame,
            "seconds": seconds,
            "rotation_deg": a.angle_deg(),
            "centroid_shift": a.centroid_shift(&mesh.positions),
            "scale": a.scale,
            "levels": a.levels,
            "loose": a.loose,
            "outline": a.outline,
            "agreement": a.agreement,
            "passes": a.passes,
            "kept_pass": a.kept_pass,
            "enlarged": a.enlarged,
            "error_before_pct": errors.map(|e| e.0),
            "error_after_pct": errors.map(|e| e.1),
            "surface_error_before_pct": errors.and_then(|e| e.2),
            "surface_error_after_pct": errors.and_then(|e| e.3),
            "units": scene.units.map(|u| u.name()),
            "out": args.out,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        if a.enlarged > 1 {
            eprintln!(
                "compared at {} times the images' resolution (level 0: the enlarged images; --enlarge 1 compares them as they are)",
                a.enlarged
            );
        }
        eprintln!("level  rounds  iterations  cost before → after    pixels  last move (px)");
        for l in &a.levels {
            if l.rounds == 0 {
                eprintln!(
                    "{:>5}  skipped: the cameras compare {} pixels here, too few to hold a pose",
                    l.level, l.pixels
                );
                continue;
            }
            eprintln!(
                "{:>5}  {:>6}  {:>10}  {:>10.3e} → {:<10.3e} {:>8}  {:>8.3}  ({:?})",
                l.level,
                l.rounds,
                l.iterations,
                l.cost_before,
                l.cost_after,
                l.pixels,
                l.last_move_px,
                l.stop
            );
        }
        eprintln!(
            "moved by {:.2}° and {:.3} {} (centroid){} in {:.1} s",
            a.angle_deg(),
            len.value(a.centroid_shift(&mesh.positions)),
            len.unit(),
            if args.scale {
                format!(", scaled by {:.4}", a.scale)
            } else {
                String::new()
            },
            seconds
        );
        match a.agreement {
            Some(g) if g.kept_given => eprintln!(
                "kept as placed: where the solve ended the cameras agree no better with each other \
                 (mean cost {:.3e} there, {:.3e} as placed)",
                g.after, g.before
            ),
            Some(g) => eprintln!(
                "the cameras agree {:.2} times better with each other as aligned (mean cost {:.3e}, \
                 {:.3e} as placed)",
                g.before / g.after,
                g.after,
                g.before
            ),
            None => {}
        }
        if a.kept_pass > 0 {
            let (p, plain) = (a.passes[a.kept_pass], a.passes[0]);
            let from = if p.shift.iter().any(|v| *v != 0.0) {
                let k = p.shift.iter().position(|v| *v != 0.0).unwrap_or(0);
                format!(
                    " started {:+.1} % of its size along {} from the placement given",
                    100.0 * p.shift[k],
                    ["x", "y", "z"][k]
                )
            } else if p.turn.iter().any(|v| *v != 0.0) {
                let k = p.turn.iter().position(|v| *v != 0.0).unwrap_or(0);
                format!(
                    " started turned {:+.0}° about {} from the placement given",
                    p.turn[k],
                    ["x", "y", "z"][k]
                )
            } else {
                String::new()
            };
            let ratio = plain.per_texture / p.per_texture;
            let how = if ratio.is_finite() {
                format!("{ratio:.1} times better")
            } else {
                "better".to_string()
            };
            let than = if plain.kept_given {
                "at the placement given"
            } else {
                "where the plain pass left the mesh, which a plain background can draw in"
            };
            eprintln!(
                "kept the pass{from} that weighs each patch by its texture: there the cameras agree {how} per unit of texture than {than} (docs/tracker.md, \"With three cameras\")"
            );
        }
        if let Some(o) = &a.outline {
            eprintln!(
                "outline: the border moved by up to {:.2} px along the free motions; contrast across it {:.3e} → {:.3e}",
                o.moved_px, o.contrast_before, o.contrast_after
            );
        }
        for m in &a.loose {
            let what = match m.kind {
                MotionKind::Rotation => "rotation about",
                MotionKind::Translation => "translation along",
                MotionKind::Scale => "scale",
            };
            let axis = if m.kind == MotionKind::Scale {
                String::new()
            } else {
                format!(" ({:.2}, {:.2}, {:.2})", m.axis[0], m.axis[1], m.axis[2])
            };
            if m.stiffness < opts.gauge_floor && a.outline.is_some() {
                eprintln!("not fixed by the images: {what}{axis}: set from the outline");
            } else if m.stiffness < opts.gauge_floor {
                eprintln!(
                    "not fixed by the images: {what}{axis}: kept as placed (set it by hand if it matters)"
                );
            } else {
                eprintln!(
                    "loosely held by the images: {what}{axis} ({:.1e} of the firmest motion's stiffness)",
                    m.stiffness
                );
            }
        }
        if a.outline.is_none() && a.loose.iter().any(|m| m.stiffness < opts.gauge_floor) {
            eprintln!(
                "hint: if the mesh's border is the object's visible edge against the background (a cloth, a sheet, a flag), --outline sets the motions the images leave free from it (docs/tracker.md, \"--outline\")"
            );
        }
        if let Some((b, after, sb, sa)) = errors {
            let pct = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.3}"));
            let (sb, sa) = (pct(sb), pct(sa));
            eprintln!(
                "error against the ground truth of frame {frame}, % of size: vertices {b:.3} before, \
                 {after:.3} after; surface (where the mesh is over it) {sb} before, {sa} after"
            );
        }
        println!("{}", args.out.display());
    }
    Ok(())
}
