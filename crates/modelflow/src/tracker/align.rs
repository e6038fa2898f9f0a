//! Lining up a roughly placed mesh with one frame (`modelflow align`): the rigid pose, and
//! optionally one uniform scale, that makes all cameras agree about the surface.
//!
//! Multi-view photo-consistency through the tracker's own machinery. Each camera in turn is a
//! *source*: the pixels each triangle owns in it (`patch`, after z-buffering and erosion) are
//! attached to the surface by their barycentric coordinates, exactly as a template frame's are,
//! and warped by the triangle's homography into every *other* camera that sees the triangle,
//! where their colours must match (up to the solver's per-(triangle, camera) brightness gain,
//! since cameras differ in exposure and a glossy surface differs between viewpoints). Unlike a
//! template frame's, these pixels are not glued to the surface: as the mesh moves, the point a
//! pixel sees slides along its own camera's ray, and the solver's derivative says so
//! (`solve::SourceWarp`). The whole mesh moves by one rigid motion
//! ([`Motion::Rigid`], or [`Motion::Similarity`] with a scale), solved by the same
//! Gauss–Newton/Levenberg–Marquardt loop as a tracker frame. Because the attachment is made at
//! the current pose, the problem is re-linearised in *rounds*: the pixels are taken again from
//! the moved mesh until the pose stops changing, coarse to fine over a pyramid deep enough that
//! the mesh's misplacement is a pixel or two at the coarsest level.
//!
//! What the footage cannot tell: photo-consistency fixes where the surface *is*, not which point
//! of the mesh is which (the texture is in the images, not on the mesh). A motion that keeps the
//! surface in place — sliding a flat sheet within its plane, spinning a surface of revolution
//! about its axis — is seen only at the surface's outline and creases, or not at all. Such
//! motions are found from the solve's own normal equations (eigenvectors of the 6×6 pose block,
//! 7×7 with the scale, whose curvature is below `gauge_floor` times the largest): steps leave
//! them out, so the
//! mesh keeps the user's placement along them instead of wandering with noise, and
//! [`Alignment::loose`] names every loosely held one, so the user knows which part of the
//! placement only they can set.
//!
//! Invariant: no I/O; images in, positions out.

use crate::base::camera::{Camera, Projection};
use crate::base::image::RgbImage;
use crate::base::mesh::{centroid, rms_radius, Mesh};
use crate::base::raster::IndexBuffer;
use crate::error::{Error, Result};
use crate::tracker::outline;
use crate::tracker::patch::{CameraPatches, Patch, PatchOptions, PatchSet};
use crate::tracker::pyramid::{camera_level, level_skips, Pyramid};
use crate::tracker::sequence::{level_projection, one_per_camera};
use crate::tracker::solve::{pose_stiffness, Motion, Problem, SolverOptions, StopReason};
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Settings of [`align`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlignOptions {
    /// Also solve for one uniform scale about the mesh's centroid.
    pub scale: bool,
    /// Pyramid levels; 0 chooses them from the mesh's size in the images (the coarsest level
    /// shows it about 24 pixels across).
    pub levels: usize,
    /// Re-linearisations per level at most (the pixels are attached again at the moved mesh).
    pub rounds: usize,
    /// Gaussian smoothing of every level, pixels.
    pub blur: f64,
    /// Pixels this close to a silhouette or occluding edge are left out (as in tracking).
    pub margin: usize,
    /// Triangles seen more obliquely than this cosine are left out.
    pub min_cos: f64,
    /// Whole-mesh motions that the images fix less than this fraction as firmly as the
    /// best-fixed one (sliding a flat sheet in its plane, spinning a surface of revolution) are
    /// not moved along: they keep the user's placement.
    pub gauge_floor: f64,
    /// Fit the mesh's border to the outline the cameras see, along the motions the images
    /// leave free (`outline`): for a sheet whose border is its visible edge against a
    /// background. Off by default (a mesh whose border lies inside a surface has no edge there).
    pub outline: bool,
    /// Also solve a second pass with each patch weighed by how textured its source pixels are
    /// (`weigh_by_texture`), and keep where it ends when the cameras agree there at least
    /// [`TEXTURE_PASS_GAIN`] times better per unit of texture than where the plain pass ends:
    /// with three cameras around an object the plain pass can be drawn partly over a plain
    /// background (docs/tracker.md, "With three cameras"). `placement`, which only asks
    /// whether the mesh is off, runs without it.
    #[serde(default)]
    pub texture_pass: bool,
    /// Also start the weighed pass from [`SEARCH_STARTS`] placements around the one given
    /// (moved by [`SEARCH_SHIFT`] of the mesh's size along each axis, either way, and turned
    /// by [`SEARCH_TURN`] about each axis through its centroid), each end kept by the same rule
    /// against the best so far: a misplacement beyond the plain pass's reach is then often
    /// within one of theirs. With `texture_pass` only; twelve more passes, solved down to the
    /// level at most `SEARCH_WIDTH` pixels wide (one that is kept is then solved on from there
    /// to full resolution).
    #[serde(default)]
    pub search: bool,
    /// Compare the cameras at this many times their images' resolution: each image enlarged
    /// by Catmull–Rom interpolation and its camera with it ([`Camera::enlarged`]), so that the
    /// finest level samples every triangle four times as densely (`align`'s cost is a sum over
    /// pixels, and a glossy near-sphere's spin is held by how finely it is summed:
    /// docs/tracker.md, "Compared at twice the resolution"). 0 chooses: 2 when the cameras'
    /// images have at most [`ENLARGE_MAX_PIXELS`] pixels together, 1 otherwise; 1 and 2 force
    /// it.
    /// Option files written before it existed read 1 (as they were made).
    #[serde(default = "one")]
    pub enlarge: u32,
    /// The solver of each round (with the tracker's robust loss by default).
    pub solver: SolverOptions,
}

impl Default for AlignOptions {
    fn default() -> Self {
        AlignOptions {
            scale: false,
            levels: 0,
            rounds: 12,
            gauge_floor: 1e-6,
            outline: false,
            texture_pass: true,
            search: true,
            enlarge: 0,
            blur: 1.0,
            margin: 1,
            min_cos: 0.1,
            solver: SolverOptions {
                max_iterations: 10,
                // Cameras compared at one instant differ by exposure and by gloss between
                // viewpoints, not by a turn under the lights: the tracker's wider range let
                // the hard sample's highlights pass as gains (from the truth 0.140 → 0.195 %).
                gain_range: 2.0,
                // The patches are weighed as a whole as in the tracker (`patch_scale`): a
                // highlight over a whole facet differs between viewpoints too, and pulled the
                // loosely held rotations of a near-sphere (docs/tracker.md, `align`).
                ..SolverOptions::default()
            },
        }
    }
}

impl AlignOptions {
    pub fn validate(&self) -> Result<()> {
        if self.levels > 8 {
            return Err(Error::option("--levels", self.levels, "0 (auto) to 8"));
        }
        if self.rounds == 0 {
            return Err(Error::option("rounds", self.rounds, "at least 1"));
        }
        if !(0.0..=20.0).contains(&self.blur) {
            return Err(Error::option("blur", self.blur, "0 to 20 pixels"));
        }
        if self.enlarge > 2 {
            return Err(Error::option(
                "--enlarge",
                self.enlarge,
                "0 (chosen from the images' size), 1 or 2",
            ));
        }
        if !(0.0..=1.0).contains(&self.min_cos) {
            return Err(Error::option("min_cos", self.min_cos, "0 to 1"));
        }
        if !(0.0..1e-2).contains(&self.gauge_floor) {
            return Err(Error::option(
                "gauge_floor",
                self.gauge_floor,
                "0 (every motion moves) to below 1e-2",
            ));
        }
        Ok(())
    }
}

/// [`AlignOptions::enlarge`]'s choice: a rig whose images have at most this many pixels
/// together (four cameras of 1 280 × 720, eight of 640 × 480) is compared at twice their
/// resolution. `align` then takes about 1.5–2 times as long and holds about four times the
/// images' memory (the real board's four 1 280 × 720 webcams: 1.2 → 2.7 s, peak resident
/// memory 138 → 519 MB); a larger rig is compared as it is.
pub const ENLARGE_MAX_PIXELS: u64 = 4 * 1280 * 720;

fn one() -> u32 {
    1
}

impl AlignOptions {
    /// The factor [`align`] enlarges `cameras`' images by ([`AlignOptions::enlarge`]).
    pub fn enlargement(&self, cameras: &[Camera]) -> u32 {
        match self.enlarge {
            0 if cameras
                .iter()
                .map(|c| c.width as u64 * c.height as u64)
                .sum::<u64>()
                <= ENLARGE_MAX_PIXELS =>
            {
                2
            }
            0 => 1,
            f => f,
        }
    }
}

/// One pyramid level of an alignment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlignLevel {
    pub level: usize,
    /// Re-linearisations run.
    pub rounds: usize,
    /// Gauss–Newton iterations over all rounds.
    pub iterations: usize,
    /// Cost (mean robust RGB residual) at the level's start and end, with the pixels attached
    /// at the start and at the end respectively.
    pub cost_before: f64,
    pub cost_after: f64,
    /// Pixels compared in the last round (each source pixel once per camera it is warped into).
    /// A coarse level that compares fewer than 200 where it starts is skipped (0 rounds): so
    /// few hold no pose.
    pub pixels: usize,
    /// The largest vertex motion of the last round, in this level's pixels.
    pub last_move_px: f64,
    pub stop: StopReason,
}

/// The result of [`align`]: the moved positions and the similarity that moved them,
/// `X' = scale·R·X + t` (world coordinates).
#[derive(Clone, Debug, PartialEq)]
pub struct Alignment {
    pub positions: Vec<Point3<f64>>,
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
    pub scale: f64,
    pub levels: Vec<AlignLevel>,
    /// The whole-mesh motions the images hold loosely at the solution (relative stiffness
    /// below [`LOOSE`]), loosest first; those below the options' `gauge_floor` were not moved
    /// along at all and keep the input's placement.
    pub loose: Vec<LooseMotion>,
    /// With `AlignOptions::outline` (and a mesh with a border and free motions): how the border
    /// was fitted to the outline.
    pub outline: Option<OutlineSummary>,
    /// The loose motions' pose eigenvectors `(ω·r, v, σ·r)` about the solution's centroid, in
    /// `loose`'s order ([`placement`] leaves them out).
    pub(crate) loose_twists: Vec<[f64; 7]>,
    /// How the cameras agree where the solve started and where it ended; `None` when that
    /// could not be compared.
    pub agreement: Option<Agreement>,
    /// The coarse-to-fine passes solved, in order: the plain one from the placement given,
    /// then with [`AlignOptions::texture_pass`] the weighed one, and with
    /// [`AlignOptions::search`] the weighed ones from the placements around it; those that
    /// could not be compared (a start the cameras do not see) are left out.
    pub passes: Vec<PassSummary>,
    /// Which of `passes` the result is from (0, the plain pass, also when `passes` is empty:
    /// the cameras could not be compared).
    pub kept_pass: usize,
    /// How many times the images' resolution the cameras were compared at
    /// ([`AlignOptions::enlarge`]): `levels`' level 0, their pixel counts and moves are of the
    /// images enlarged so.
    pub enlarged: u32,
}

/// One coarse-to-fine pass of [`align`], by how well the cameras agree per unit of texture where
/// its result is ([`Agreement::kept_per_texture`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PassSummary {
    /// Where it started: the placement given moved by this fraction of the mesh's size along
    /// each axis (world) ...
    pub shift: [f64; 3],
    /// ... or turned about each axis through its centroid by these degrees (all 0: the
    /// placement given).
    pub turn: [f64; 3],
    /// Its patches were weighed by their texture.
    pub weighed: bool,
    /// The cameras' cost per unit of texture where its result is (at full resolution; for a
    /// search start not kept, where its solve at the reduced level ended). Infinite where its
    /// result compares no texture (`null` in JSON).
    pub per_texture: f64,
    /// Its end was no better than the placement given (its result is the placement given).
    pub kept_given: bool,
}

/// The cameras' comparison with each other where [`align`] started and where it ended: each
/// camera's pixels of the mesh warped into every other camera that sees the triangle, at full
/// resolution, up to the gains, with the convex loss (Huber), the pixels attached where the
/// mesh is in each case.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Agreement {
    /// The mean cost per pixel compared at the placement given.
    pub before: f64,
    /// The same where the solve ended.
    pub after: f64,
    /// The placement given was kept: the cameras agree no better where the solve ended.
    pub kept_given: bool,
    /// The pixels compared at the placement given.
    pub pixels_before: f64,
    /// Their texture (per patch, the mean squared deviation of its source colours from their
    /// mean, averaged over the pixels: what a plain background lacks) at the placement given
    /// and where the solve ended.
    pub texture_before: f64,
    pub texture_after: f64,
}

impl Agreement {
    /// [`Agreement::after_per_texture`] where the solve's end is kept, and the same at the
    /// placement given where that is kept instead.
    pub fn kept_per_texture(&self) -> f64 {
        if !self.kept_given {
            return self.after_per_texture();
        }
        if self.texture_before > 0.0 {
            self.before / self.texture_before
        } else {
            f64::INFINITY
        }
    }
    /// The cameras' mean cost where the solve ended per unit of the texture compared there:
    /// how well they agree relative to what there is to agree on (a plain background, which
    /// every camera sees alike, has a low cost and no texture). Infinite without texture.
    pub fn after_per_texture(&self) -> f64 {
        if self.texture_after > 0.0 {
            self.after / self.texture_after
        } else {
            f64::INFINITY
        }
    }
}

/// How many times better per unit of texture ([`Agreement::after_per_texture`]) the cameras
/// must agree where [`AlignOptions::texture_pass`]'s pass ends than where the plain pass ends
/// for it to be kept. Where both passes come back to the surface they end within a few per
/// cent of each other on that measure (the hard sample's fourteen: 1.58–1.63); the plain pass drawn
/// over a plain background by three cameras ends 4–11 times worse than the truth (blob 1.24
/// against 0.11, irregular 0.99–1.85 against 0.28).
pub const TEXTURE_PASS_GAIN: f64 = 2.0;

/// [`AlignOptions::search`]'s starts: [`SEARCH_SHIFT`] either way along each axis, then
/// [`SEARCH_TURN`] either way about each.
pub const SEARCH_STARTS: usize = 12;
/// How far [`AlignOptions::search`] moves its starts, as a fraction of the mesh's size (its
/// bounding-box diagonal): about the reach of one pass with three cameras around an object.
pub const SEARCH_SHIFT: f64 = 0.025;
/// How far [`AlignOptions::search`] turns its starts, degrees.
pub const SEARCH_TURN: f64 = 5.0;
/// The widest pyramid level [`AlignOptions::search`]'s starts are solved at, by the widest
/// camera (the coarsest level where none is that narrow; the one they keep is then solved on
/// from there to full resolution): on an 8-camera 1080p rig `align` takes 10 s with the
/// search instead of 34 s at full resolution (2.5 s without it); a 1280×960 three-camera blob
/// comes back from every misplacement it came back from at full resolution.
const SEARCH_WIDTH: u32 = 640;

/// One coarse-to-fine pass of [`align`]: where it ended (the motions the images leave free
/// undone), each level's summary, and the pose's stiffness at the finest level.
struct Pass {
    x: Vec<Point3<f64>>,
    levels: Vec<AlignLevel>,
    stiffness: Vec<(f64, [f64; 7])>,
    free: Vec<[f64; 7]>,
}

/// What the outline fit did (see [`AlignOptions::outline`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutlineSummary {
    /// Mean squared contrast across the border (RGB, per pixel²) before and after the fit.
    pub contrast_before: f64,
    pub contrast_after: f64,
    /// The largest image motion of a vertex it made, full-resolution pixels.
    pub moved_px: f64,
}

/// How far [`align`] would move a mesh to line it up with a frame: what `track` checks before
/// tracking, since a mesh placed a few per cent off (by hand, by eye) is tracked as placed and
/// stays that far off, every frame, with no frame flagged.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    /// RMS distance the vertices would move, scene units.
    pub rms: f64,
    /// The same as a fraction of the mesh's bounding-box diagonal.
    pub fraction: f64,
    /// The rotation's angle, degrees.
    pub degrees: f64,
    /// The translation of the mesh's centroid, scene units.
    pub translation: f64,
    /// How many whole-mesh motions the images hold loosely ([`LOOSE`]: a nearly round
    /// object's spin, a flat sheet's slide) were left out of the figures above: along those,
    /// where `align` ends is the images' noise, not the user's misplacement.
    pub loose_left_out: usize,
    /// Pixels the cameras compare with each other where the mesh is (at the resolution
    /// compared).
    #[serde(default)]
    pub compared: f64,
    /// The texture of the pixels compared where `align` ends over that where the mesh is
    /// (`offset::texture`'s measure): near 0 when the move only puts the pixels compared on a
    /// plain background, which every camera sees alike.
    #[serde(default)]
    pub texture_kept: f64,
    /// The cameras' mean cost where the mesh is over that where `align` ends (both at the
    /// resolution compared, the convex loss): above 1 where they agree better there. Two noisy
    /// cameras that share only a rim disagree with themselves by a few per cent as the pixels
    /// compared change (`align` from the true placement: 0.97–1.03), a mesh 1.5 % of its size
    /// off by 7 % in 20 % noise and by 20 % to 4× in clean footage.
    #[serde(default = "no_ratio")]
    pub agreement_gain: f64,
    /// How far the move shifts where one camera's view of the surface lands in another's, pixels
    /// of the frames, RMS over the vertices two cameras see (`offset::disparity_of_move`): only
    /// the part of each vertex's move along its normal counts. `None` where no two cameras see
    /// a vertex well (and in a file written before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disparity: Option<f64>,
}

/// [`Placement::agreement_gain`] in a file written before it was recorded: not a reason to
/// call the mesh placed where it is.
fn no_ratio() -> f64 {
    f64::MAX
}

/// The least [`Placement::agreement_gain`] worth a warning.
pub const PLACEMENT_MIN_GAIN: f64 = 1.05;

impl Placement {
    /// Off by enough to matter: [`PLACEMENT_WARN`] of the mesh's size or more (`align` from the
    /// true placement moves our clips by 0.01–0.32 %: its noise, not a misplacement), found
    /// from at least `offset::MIN_COMPARED` pixels compared, where they keep at least
    /// `offset::MIN_TEXTURE_KEPT` of their texture (as the surface check's verdict), where the
    /// cameras agree at least [`PLACEMENT_MIN_GAIN`] times better than where the mesh is.
    pub fn is_off(&self) -> bool {
        self.fraction >= PLACEMENT_WARN
            && self.compared >= crate::tracker::offset::MIN_COMPARED
            && self.texture_kept >= crate::tracker::offset::MIN_TEXTURE_KEPT
            && self.agreement_gain >= PLACEMENT_MIN_GAIN
    }

    /// The move shifts the cameras' views of the surface relative to each other by less than
    /// `offset::MIN_DISPARITY_PX` ([`Placement::disparity`]): a calibration that far off draws
    /// the same verdict, which a warning should say (a flat sheet tilted 6° in front of two
    /// cameras 12° apart shifts them by about a pixel, as camera 0's principal point moved by one
    /// pixel does). Unlike the surface check's offset, which `track` acts on, a placement is
    /// only named, so it is still named.
    pub fn calibration_may_explain(&self) -> bool {
        self.disparity
            .is_some_and(|d| d < crate::tracker::offset::MIN_DISPARITY_PX)
    }
}

/// The fewest pixels a coarse level of [`align`] must compare to be solved at (the finest is
/// always solved); the same bound as the surface check's (`offset::MIN_COMPARED`).
const MIN_LEVEL_PIXELS: f64 = crate::tracker::offset::MIN_COMPARED;

/// The misplacement, as a fraction of the mesh's size, worth a warning.
pub const PLACEMENT_WARN: f64 = 0.01;
/// The widest frame [`placement`] compares at full size.
const PLACEMENT_WIDTH: u32 = 1280;

/// What [`align`] with its default options would do to `mesh` at `frame` ([`Placement`]);
/// `None` when it cannot tell (fewer than two cameras, or no two of them see a common
/// triangle). A mesh that lies off the surface (`surface_offset`) pulls the pose: check that
/// first. Frames wider than `PLACEMENT_WIDTH` are compared halved until they are not (a
/// misplacement worth a warning is many pixels there too; an 8-camera 4K rig is checked in
/// about the time a 720p one is).
pub fn placement(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<Placement> {
    let widest = cameras.iter().map(|c| c.width).max().unwrap_or(0);
    let halvings = (0..8)
        .find(|&l| widest >> l <= PLACEMENT_WIDTH)
        .unwrap_or(8);
    let small: Option<(Vec<RgbImage>, Vec<Camera>)> = (halvings > 0).then(|| {
        let small: Vec<RgbImage> = images
            .par_iter()
            .map(|img| {
                let mut s = img.downsample2();
                for _ in 1..halvings {
                    s = s.downsample2();
                }
                s
            })
            .collect();
        let cams: Vec<Camera> = cameras
            .iter()
            .zip(&small)
            .map(|(c, img)| {
                Camera::fixed(
                    c.name.clone(),
                    img.width() as u32,
                    img.height() as u32,
                    c.at(frame).downscaled(1 << halvings),
                )
            })
            .collect();
        (small, cams)
    });
    let (imgs, cams, at) = match &small {
        None => (images, cameras, frame),
        Some((small, cams)) => (&small[..], &cams[..], 0),
    };
    let aligned = |opts: &AlignOptions| align(mesh, cams, at, imgs, opts).ok();
    // What the cameras compare where the mesh is, and how much of its texture is left where
    // `align` ends (`Alignment::agreement`): two cameras that share only a rim over a plain
    // background agree best with the rim moved onto the background (the blob's or the limb's
    // two cameras: "moved by 20–42 % of its size").
    let verdict = |a: &Alignment| {
        let g = a.agreement?;
        let kept = if g.texture_before > 0.0 {
            g.texture_after / g.texture_before
        } else {
            1.0
        };
        let gain = if g.after > 0.0 {
            g.before / g.after
        } else {
            f64::MAX
        };
        let p = placement_of(mesh, a);
        Some(Placement {
            compared: g.pixels_before,
            texture_kept: kept,
            agreement_gain: gain,
            disparity: crate::tracker::offset::disparity_of_move(
                mesh, &p.held, cameras, frame, images,
            ),
            ..p.placement
        })
    };
    // Whether the mesh is off, not where exactly it belongs: the plain pass alone.
    // At the images' own resolution: a check made before every track, on frames already
    // halved to at most `PLACEMENT_WIDTH` for time.
    let check = AlignOptions {
        texture_pass: false,
        search: false,
        enlarge: 1,
        ..AlignOptions::default()
    };
    let a = aligned(&check)?;
    let found = verdict(&a)?;
    // A pose the coarsest level alone draws away is not one the images hold: on a body with an
    // arm crossing in front of it at 480×360, the coarsest level compared 114 pixels of thin
    // limbs, moved the mesh 10 % of its size off its true place, and the finer levels stayed
    // there (with one level fewer, 0.014 %). A move worth a warning is asked again without that
    // level, and the smaller of the two is reported: a real misplacement is found both ways.
    if found.is_off() && a.levels.len() > 1 {
        let fewer = AlignOptions {
            levels: a.levels.len() - 1,
            ..check
        };
        if let Some(again) = aligned(&fewer).as_ref().and_then(verdict) {
            if again.fraction < found.fraction {
                return Some(again);
            }
        }
    }
    Some(found)
}

/// [`placement_of`]'s figures and the positions they measure (`align`'s result with the loose
/// motions undone).
struct Measured {
    placement: Placement,
    held: Vec<Point3<f64>>,
}

/// How far alignment `a` moved `mesh` ([`Placement`]), the motions it holds loosely undone.
fn placement_of(mesh: &Mesh, a: &Alignment) -> Measured {
    // Along the motions the images hold loosely (a capsule's or a squashed sphere's spin about
    // its axis), noisy footage moves `align` by many degrees from a correct placement, and a
    // warning would send the user to apply that noise: the move is measured with them undone.
    let held = if a.loose_twists.is_empty() {
        a.positions.clone()
    } else {
        back_to_placement(&a.positions, &mesh.positions, &a.loose_twists)
    };
    let n = mesh.positions.len().max(1) as f64;
    let rms = (mesh
        .positions
        .iter()
        .zip(&held)
        .map(|(p, q)| (q - p).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let size = mesh.bbox_diagonal();
    let moved_centroid = centroid(&held) - centroid(&mesh.positions);
    let (rotation, _, _) = similarity(&mesh.positions, &held);
    let cos = ((rotation.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    let placement = Placement {
        rms,
        fraction: if size > 0.0 { rms / size } else { 0.0 },
        degrees: cos.acos().to_degrees(),
        translation: moved_centroid.norm(),
        loose_left_out: a.loose_twists.len(),
        compared: 0.0,
        texture_kept: 1.0,
        agreement_gain: f64::MAX,
        disparity: None,
    };
    Measured { placement, held }
}

/// What `track` checks about the first mesh before tracking ([`first_mesh_check`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FirstMeshCheck {
    /// How far along its normals the cameras agree best (`surface_offset`); `None` when no two
    /// cameras see a common triangle.
    pub surface: Option<crate::tracker::SurfaceOffset>,
    /// How far `align` would move the mesh ([`placement`]); only for a mesh on the surface (one
    /// off it pulls the pose), farther off it than `track` would move it onto it
    /// ([`crate::tracker::SurfaceOffset::is_off_within`]: misplaced, not a visual hull), or off
    /// it within that reach where the placement explains the cameras better
    /// (`misplaced_instead`); `None` otherwise or when it cannot tell.
    pub placement: Option<Placement>,
}

/// Whether `mesh` lies on the surface the cameras agree on at `frame`, and, when it does,
/// whether it is placed where the images put it: the two checks `track` runs before tracking
/// (a mesh off the surface is moved onto it unless kept as given; a misplaced one is named).
pub fn first_mesh_check(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> FirstMeshCheck {
    let surface = crate::tracker::surface_offset(mesh, cameras, frame, images);
    let placement = match surface {
        Some(s) if s.is_off_within(mesh.bbox_diagonal()) => {
            misplaced_instead(&s, mesh, cameras, frame, images)
        }
        _ => placement(mesh, cameras, frame, images),
    };
    FirstMeshCheck { surface, placement }
}

impl FirstMeshCheck {
    /// The offset along the normals that `track` moves the mesh by onto the surface
    /// (`offset::moved_onto_surface`): off the surface within its reach
    /// ([`crate::tracker::SurfaceOffset::is_off_within`], `size` the mesh's bounding-box
    /// diagonal) and not rather misplaced as a whole (`misplaced_instead`).
    pub fn off_surface(&self, size: f64) -> Option<&crate::tracker::SurfaceOffset> {
        self.surface
            .as_ref()
            .filter(|s| s.is_off_within(size) && self.placement.is_none())
    }
}

/// For a mesh read off the surface along its normals (`found`, within the reach `track` moves
/// a mesh onto it), `align`'s placement when that names it misplaced ([`Placement::is_off`])
/// and its rigid move makes the cameras agree better than the move along the normals does
/// (`agreement_gain` above `found.ratio`): a mesh misplaced as a whole also reads as off its
/// surface, by the part of its move along its normals, and moved along them it would be
/// reshaped instead of named. Measured on the blob and the limb (640×480, four cameras): turned
/// 5° and moved 3 % of its size in eight directions each, four read within that reach (ratios
/// 1.52–1.77) where `align`'s gains were 6.2–26; moved along their normals by 1–4 % of their
/// size, ratios 8–17 against gains 1.2–3.2 (docs/tracker.md, "Misplaced, not off the surface").
pub(crate) fn misplaced_instead(
    found: &crate::tracker::SurfaceOffset,
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
) -> Option<Placement> {
    placement(mesh, cameras, frame, images).filter(|p| p.is_off() && p.agreement_gain > found.ratio)
}

/// Motions held less than this fraction as firmly as the best-held one are reported as loose.
pub const LOOSE: f64 = 1e-2;

/// What a loosely held motion mostly is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionKind {
    /// A rotation about `axis` through the mesh's centroid.
    Rotation,
    /// A translation along `axis`.
    Translation,
    /// A change of scale about the centroid.
    Scale,
}

/// A whole-mesh motion and how firmly the images hold it (see [`Alignment::loose`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LooseMotion {
    /// Its curvature relative to the best-held motion's (0: the cost does not change at all).
    pub stiffness: f64,
    pub kind: MotionKind,
    /// Unit axis (world coordinates) of the rotation or translation.
    pub axis: [f64; 3],
}

impl LooseMotion {
    fn from_eigen(stiffness: f64, v: &[f64; 7]) -> LooseMotion {
        let w = Vector3::new(v[0], v[1], v[2]);
        let t = Vector3::new(v[3], v[4], v[5]);
        let (kind, axis) = if v[6].abs() > w.norm().max(t.norm()) {
            (MotionKind::Scale, Vector3::zeros())
        } else if w.norm() >= t.norm() {
            (MotionKind::Rotation, w.normalize())
        } else {
            (MotionKind::Translation, t.normalize())
        };
        // Axes have no sign: show them with their largest component positive.
        let big = (0..3)
            .max_by(|&a, &b| axis[a].abs().total_cmp(&axis[b].abs()))
            .unwrap_or(0);
        let axis = if axis[big] < 0.0 { -axis } else { axis };
        LooseMotion {
            stiffness,
            kind,
            axis: [axis.x, axis.y, axis.z],
        }
    }
}

impl Alignment {
    /// The rotation's angle, degrees.
    pub fn angle_deg(&self) -> f64 {
        let c = ((self.rotation.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
        c.acos().to_degrees()
    }

    /// How far the mesh's centroid moved (scene units).
    pub fn centroid_shift(&self, before: &[Point3<f64>]) -> f64 {
        (centroid(&self.positions) - centroid(before)).norm()
    }
}

/// Levels that show the mesh about 24 pixels across at the coarsest (median over the cameras
/// of its projected extent), at most 6 and none smaller than 16 pixels on its short side; a
/// camera smaller than the largest counted at the largest's scale, as it enters the levels
/// late by `skips` (`pyramid::level_skips`).
fn auto_levels(cameras: &[Camera], skips: &[usize], frame: u32, x: &[Point3<f64>]) -> usize {
    let mut extents: Vec<f64> = cameras
        .iter()
        .zip(skips)
        .filter_map(|(c, &k)| {
            let p = c.at(frame);
            let mut lo = [f64::INFINITY; 2];
            let mut hi = [f64::NEG_INFINITY; 2];
            for q in x.iter().filter_map(|v| p.project(v)) {
                lo = [lo[0].min(q.x), lo[1].min(q.y)];
                hi = [hi[0].max(q.x), hi[1].max(q.y)];
            }
            (hi[0] > lo[0]).then(|| (hi[0] - lo[0]).max(hi[1] - lo[1]) * f64::from(1u32 << k))
        })
        .collect();
    if extents.is_empty() {
        return 1;
    }
    extents.sort_by(f64::total_cmp);
    let extent = extents[extents.len() / 2];
    let short = cameras
        .iter()
        .zip(skips)
        .map(|(c, &k)| c.width.min(c.height) << k)
        .min()
        .unwrap_or(1);
    let mut levels = 1;
    while levels < 6 && extent / f64::from(1u32 << levels) >= 24.0 && short >> levels >= 16 {
        levels += 1;
    }
    levels
}

/// The patches of one round: every camera's pixels, warped into every other camera that sees
/// the triangle; with `neighbours` above 0, only into that many of them per camera, those
/// [`neighbour_cameras`] chooses.
pub(crate) fn cross_patches(
    x: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    images: &[&RgbImage],
    popts: &PatchOptions,
    neighbours: usize,
) -> PatchSet {
    cross_patches_in(x, triangles, projections, images, None, popts, neighbours)
}

/// [`cross_patches`], with `buffers` each camera's index buffer of `x` (`rasterize` at
/// `projections[c]` in `images[c]`) when it was rasterised once for other uses of the same view
/// too (the tracker's hidden-surface check); rasterised here otherwise.
pub(crate) fn cross_patches_in(
    x: &[Point3<f64>],
    triangles: &[[u32; 3]],
    projections: &[Projection],
    images: &[&RgbImage],
    buffers: Option<&[IndexBuffer]>,
    popts: &PatchOptions,
    neighbours: usize,
) -> PatchSet {
    let per_cam: Vec<CameraPatches> = (0..projections.len())
        .into_par_iter()
        .map(|c| {
            CameraPatches::new(
                x,
                triangles,
                &projections[c],
                images[c],
                c as u16,
                1.0,
                popts,
                None,
                buffers.map(|b| &b[c]),
            )
        })
        .collect();
    let ncam = projections.len();
    // Every camera's pixels in one allocation; each source patch is then listed once per other
    // camera it is warped into (the same pixel range).
    let sources = PatchSet::from_cameras(&per_cam);
    drop(per_cam);
    let mut seen = vec![vec![false; triangles.len()]; ncam];
    for p in &sources.patches {
        seen[p.camera as usize][p.triangle as usize] = true;
    }
    let compared = neighbour_cameras(x, projections, &seen, neighbours);
    let mut patches = Vec::new();
    for p in &sources.patches {
        let i = p.camera as usize;
        for (j, seen_j) in seen.iter().enumerate() {
            if j != i && compared[i * ncam + j] && seen_j[p.triangle as usize] {
                patches.push(Patch {
                    camera: j as u16,
                    source: i as u16,
                    ..*p
                });
            }
        }
    }
    PatchSet {
        patches,
        pixels: sources.pixels,
    }
}

/// Which cameras each camera is compared with (`[i·n + j]`: camera `i`'s pixels warped into
/// camera `j`): every other one when `neighbours` is 0 or reaches them all; otherwise the
/// `neighbours` cameras with the best score `overlap · sin(angle)` (ties to the lower index):
/// the share of the triangles camera `i` sees (`seen[i]`) that camera `j` sees too, times the
/// sine of the angle between their directions to the mesh's centre (the mean of `x`), so that
/// views of the same surface are preferred, and among them the wider baselines, which fix depth.
pub(crate) fn neighbour_cameras(
    x: &[Point3<f64>],
    projections: &[Projection],
    seen: &[Vec<bool>],
    neighbours: usize,
) -> Vec<bool> {
    let n = projections.len();
    let mut out = vec![true; n * n];
    if neighbours == 0 || neighbours + 1 >= n || x.is_empty() {
        return out;
    }
    let centre = centroid(x);
    let dirs: Vec<Vector3<f64>> = projections
        .iter()
        .map(|p| (centre - p.center()).normalize())
        .collect();
    for i in 0..n {
        let own = seen[i].iter().filter(|&&s| s).count().max(1) as f64;
        let score = |j: usize| {
            let both = seen[i]
                .iter()
                .zip(&seen[j])
                .filter(|(a, b)| **a && **b)
                .count();
            both as f64 / own * dirs[i].cross(&dirs[j]).norm()
        };
        let mut others: Vec<(usize, f64)> = (0..n)
            .filter(|&j| j != i)
            .map(|j| (j, score(j)))
            .filter(|&(_, s)| s > 0.0)
            .collect();
        // Best first; `sort_by` is stable, so equal scores keep the index order.
        others.sort_by(|a, b| b.1.total_cmp(&a.1));
        let row = &mut out[i * n..(i + 1) * n];
        row.fill(false);
        for &(j, _) in others.iter().take(neighbours) {
            row[j] = true;
        }
    }
    out
}

/// The largest image motion (pixels of `projections`' level) of any vertex between `a` and `b`.
fn max_move_px(a: &[Point3<f64>], b: &[Point3<f64>], projections: &[Projection]) -> f64 {
    projections
        .iter()
        .flat_map(|p| {
            a.iter().zip(b).filter_map(move |(u, v)| {
                let (pu, pv) = (p.project(u)?, p.project(v)?);
                Some((pu - pv).norm())
            })
        })
        .fold(0.0, f64::max)
}

/// The similarity that maps `a` onto `b` (`base::mesh::best_motion` with the scale).
fn similarity(a: &[Point3<f64>], b: &[Point3<f64>]) -> (Matrix3<f64>, Vector3<f64>, f64) {
    crate::base::mesh::best_motion(a, b, true)
}

/// The centroid of `x` and its RMS radius (1 for a single point), the frame in which pose
/// eigenvectors `(ω·r, v, σ·r)` (see `solve::pose_stiffness`) are expressed.
fn centre_and_radius(x: &[Point3<f64>]) -> (Vector3<f64>, f64) {
    let c = centroid(x);
    let r = rms_radius(x, &c);
    (c.coords, if r > 0.0 { r } else { 1.0 })
}

/// First-order displacement of point `p` along pose eigenvector `v` about centre `c`, radius `r`.
fn displacement(v: &[f64; 7], p: &Point3<f64>, c: &Vector3<f64>, r: f64) -> Vector3<f64> {
    let d = p.coords - c;
    Vector3::new(v[0], v[1], v[2]).cross(&d) / r + Vector3::new(v[3], v[4], v[5]) + d * (v[6] / r)
}

/// `x` moved by `alpha` along the whole-mesh motions `free` (pose eigenvectors `(ω·r, v, σ·r)`,
/// see `solve::pose_stiffness`), about `x`'s centroid.
pub(crate) fn move_along(x: &[Point3<f64>], free: &[[f64; 7]], alpha: &[f64]) -> Vec<Point3<f64>> {
    let (c, r) = centre_and_radius(x);
    let mut xi = [0.0; 7];
    for (v, a) in free.iter().zip(alpha) {
        for (e, vi) in xi.iter_mut().zip(v) {
            *e += a * vi;
        }
    }
    // The screw motion that the constant twist (ω, v) generates, applied for unit time:
    // X' = c + R(ω)(X − c) + J(ω)·v with J the left Jacobian of SO(3). It keeps a motion the
    // images leave free free at any size (a rotation about an axis away from the centroid plus
    // the matching translation stays on that axis), which "rotate about c, then add v" does only
    // to first order. The scale, when free, is applied about c.
    let w = Vector3::new(xi[0], xi[1], xi[2]) / r;
    let v = Vector3::new(xi[3], xi[4], xi[5]);
    let theta = w.norm();
    let wx = w.cross_matrix();
    let j = if theta < 1e-8 {
        nalgebra::Matrix3::identity() + wx * 0.5
    } else {
        nalgebra::Matrix3::identity()
            + wx * ((1.0 - theta.cos()) / (theta * theta))
            + wx * wx * ((theta - theta.sin()) / (theta * theta * theta))
    };
    let rot = nalgebra::Rotation3::new(w);
    let t = j * v;
    let s = (xi[6] / r).exp();
    x.iter()
        .map(|p| Point3::from(c + rot * (p.coords - c) * s + t))
        .collect()
}

/// The motion within the span of `free` (pose eigenvectors `(ω·r, v, σ·r)`, see
/// `solve::pose_stiffness`) that brings `x` closest to `placed` (least squares over the
/// vertices; three Gauss–Newton steps for the rotation's curvature), applied as exact screw
/// motions ([`move_along`]), which keep a free motion free at any size.
fn back_to_placement(
    x: &[Point3<f64>],
    placed: &[Point3<f64>],
    free: &[[f64; 7]],
) -> Vec<Point3<f64>> {
    let mut x = x.to_vec();
    let k = free.len().min(7);
    for _ in 0..3 {
        let (c, r) = centre_and_radius(&x);
        let mut m = nalgebra::DMatrix::<f64>::zeros(k, k);
        let mut rhs = nalgebra::DVector::<f64>::zeros(k);
        for (p, q) in x.iter().zip(placed) {
            let mut g = [Vector3::zeros(); 7];
            for (gi, v) in g.iter_mut().zip(free) {
                *gi = displacement(v, p, &c, r);
            }
            for a in 0..k {
                rhs[a] += g[a].dot(&(q - p));
                for b in 0..k {
                    m[(a, b)] += g[a].dot(&g[b]);
                }
            }
        }
        let Some(alpha) = m.cholesky().map(|ch| ch.solve(&rhs)) else {
            break;
        };
        x = move_along(&x, free, alpha.as_slice());
    }
    x
}

/// Lines up `mesh` with frame `frame` of `cameras`, whose images (one per camera, pinhole, as
/// `Scene::load_images` gives them) are `images`. See the module's documentation.
pub fn align(
    mesh: &Mesh,
    cameras: &[Camera],
    frame: u32,
    images: &[RgbImage],
    opts: &AlignOptions,
) -> Result<Alignment> {
    opts.validate()?;
    one_per_camera(cameras.len(), images.len())?;
    // Colour and monochrome cameras together are compared in luminance (as the tracker does).
    let compared = crate::base::image::comparable(images);
    let images = &compared[..];
    if let Some(i) = mesh
        .positions
        .iter()
        .position(|p| !p.coords.iter().all(|v| v.is_finite()))
    {
        return Err(Error::mismatch(
            "mesh positions",
            "finite coordinates",
            format!("vertex {i} at {:?}", mesh.positions[i].coords.as_slice()),
        ));
    }
    for (c, (cam, img)) in cameras.iter().zip(images).enumerate() {
        if (img.width(), img.height()) != (cam.width as usize, cam.height as usize) {
            return Err(Error::mismatch(
                format!("image of camera {c} ({})", cam.name),
                format!("{}×{} (the camera's size)", cam.width, cam.height),
                format!("{}×{}", img.width(), img.height()),
            ));
        }
    }
    // A blank image (a black frame, a lens cap: `image::blank_images`) compares alike with
    // nothing: the cameras that show something are aligned with each other.
    let blank = crate::base::image::blank_images(images);
    if blank.iter().any(|&b| b) && cameras.len() >= 2 {
        let shown = blank.iter().filter(|b| !**b).count();
        if shown < 2 {
            return Err(Error::mismatch(
                "cameras",
                "at least 2 whose image of the frame shows something (alignment compares cameras with each other)",
                format!("{shown} (the other images are blank: one colour over the whole frame)"),
            ));
        }
        let (cams, imgs): (Vec<Camera>, Vec<RgbImage>) = cameras
            .iter()
            .zip(images)
            .zip(&blank)
            .filter(|(_, b)| !**b)
            .map(|((c, i), _)| (c.clone(), i.clone()))
            .unzip();
        return align(mesh, &cams, frame, &imgs, opts);
    }
    if cameras.len() < 2 {
        return Err(Error::mismatch(
            "cameras",
            "at least 2 (alignment compares cameras with each other)",
            cameras.len(),
        ));
    }
    // Compared at twice the resolution (`AlignOptions::enlarge`): the same alignment of the
    // enlarged images, whose cameras see the mesh where these do, one level deeper.
    if opts.enlargement(cameras) == 2 {
        let cams: Vec<Camera> = cameras.iter().map(|c| c.enlarged(2)).collect();
        let imgs: Vec<RgbImage> = images.par_iter().map(RgbImage::enlarged2).collect();
        // A level count given keeps its coarsest level's scale (one more level, within the 8
        // that `validate` allows: given 8, the coarsest is then twice as fine).
        let inner = AlignOptions {
            enlarge: 1,
            levels: match opts.levels {
                0 => 0,
                l => (l + 1).min(8),
            },
            ..*opts
        };
        let mut a = align(mesh, &cams, frame, &imgs, &inner)?;
        a.enlarged = 2;
        return Ok(a);
    }
    let start = mesh.positions.clone();
    // Wound as the tracker winds them (`Mesh::facing_outward`): the facing test needs it.
    let triangles = mesh.facing_outward().0;
    // A camera smaller than the largest enters the levels late (`pyramid::level_skips`), as
    // in tracking.
    let skips = level_skips(cameras.iter().map(|c| (c.width, c.height)));
    let levels = if opts.levels == 0 {
        auto_levels(cameras, &skips, frame, &start)
    } else {
        opts.levels
    };
    let pyramids: Vec<Pyramid> = images
        .par_iter()
        .zip(&skips)
        .map(|(img, &k)| Pyramid::with_skip(img, levels, opts.blur, k))
        .collect();
    let popts = PatchOptions {
        margin: opts.margin,
        min_cos: opts.min_cos,
        two_sided: !mesh.is_closed(),
        checkerboard: false,
        stride: 1,
    };
    let motion = if opts.scale {
        Motion::Similarity
    } else {
        Motion::Rigid
    };
    let pattern = mesh.edges();
    // One coarse to fine pass from the placement given, its patches weighed by their texture or
    // not (`weigh_by_texture`); the motions the images leave free undone at its end.
    // Each vertex's triangles, for `weigh_by_texture`'s neighbourhoods.
    let mut ring: Vec<Vec<u32>> = vec![Vec::new(); start.len()];
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            ring[v as usize].push(t as u32);
        }
    }
    // Levels `coarsest` down to `finest` are solved (0: full resolution).
    let solve_pass =
        |weigh: bool, from: &[Point3<f64>], finest: usize, coarsest: usize| -> Result<Pass> {
            let mut x = from.to_vec();
            let mut out_levels = Vec::with_capacity(levels);
            let mut last = None;
            for level in (finest..=coarsest).rev() {
                let projections: Vec<Projection> = cameras
                    .iter()
                    .zip(&skips)
                    .map(|(c, &k)| level_projection(c.at(frame), camera_level(level, k)))
                    .collect();
                let targets: Vec<&RgbImage> = pyramids
                    .iter()
                    .zip(&skips)
                    .map(|(p, &k)| p.at(level, k))
                    .collect();
                // At coarse levels a triangle may be smaller than a pixel, and the margin test (a
                // pixel's neighbours must belong to its triangle or one sharing a vertex) would then
                // drop every pixel: there the pixels are kept up to the outline, and the finest level
                // drops what mixes two surfaces.
                let popts = PatchOptions {
                    margin: if level == 0 { popts.margin } else { 0 },
                    ..popts
                };
                let mut summary = AlignLevel {
                    level,
                    rounds: 0,
                    iterations: 0,
                    cost_before: f64::NAN,
                    cost_after: f64::NAN,
                    pixels: 0,
                    last_move_px: 0.0,
                    stop: StopReason::NoData,
                };
                for round in 0..opts.rounds {
                    let x0 = x.clone();
                    let mut set = cross_patches(&x0, &triangles, &projections, &targets, &popts, 0);
                    // A coarse level that compares only a few pixels (two cameras that share only a
                    // rim: 0–33 at the coarser levels of the limb's two cameras at 480×360) holds no
                    // pose; followed, it turned the limb 142°. The finer levels start where it began.
                    if level > finest
                        && round == 0
                        && (set.compared_pixels() as f64) < MIN_LEVEL_PIXELS
                    {
                        summary.pixels = set.compared_pixels();
                        summary.stop = StopReason::NoData;
                        break;
                    }
                    if weigh {
                        weigh_by_texture(&mut set, &triangles, &ring, projections.len());
                    }
                    let by_triangle = set.by_triangle();
                    let problem = Problem {
                        moving_source: Some(&x0),
                        gauge_floor: opts.gauge_floor,
                        ..Problem::photometric(
                            &triangles,
                            &set,
                            &by_triangle,
                            targets.clone(),
                            projections.clone(),
                            &pattern,
                        )
                    };
                    // The chosen robust loss from the first round: an occluder in front of the surface
                    // (a rod, a hand) or a highlight is seen differently by every camera, and with a
                    // convex loss it pulls the loosely held motions (a nearly round object's spin: the
                    // Blender hard sample drifted 0.51 % from its true placement with Huber until the
                    // last rounds, 0.18 % with Tukey throughout). Tukey's threshold follows the
                    // residuals and the image gradient (`SolverOptions::tukey_px`), so a misplaced
                    // mesh's pixels on edges are kept while it comes in.
                    let sopts = opts.solver;
                    let (sol, s, lin) = problem.solve_motion(&x, None, &sopts, motion);
                    summary.rounds += 1;
                    summary.iterations += s.iterations.len();
                    if round == 0 {
                        summary.cost_before = s.initial_cost;
                    }
                    summary.cost_after = s.final_cost;
                    summary.pixels = s.pixels;
                    summary.stop = s.stop;
                    let moved = max_move_px(&x, &sol, &projections);
                    summary.last_move_px = moved;
                    x = sol;
                    if level == 0 {
                        last = Some((lin, x.clone()));
                    }
                    if s.stop == StopReason::NoData || s.stop == StopReason::NonFinite {
                        break;
                    }
                    // Converged when a round moves nothing by more than a twentieth of a pixel.
                    if moved < 0.05 {
                        break;
                    }
                }
                if summary.stop == StopReason::NoData && level == finest {
                    return Err(Error::mismatch(
                        "cameras seeing the mesh",
                        format!("at least 2 that see a common triangle at frame {frame}"),
                        "none: the mesh is outside the images, seen by one camera only, or only \
                     edge-on (triangles more oblique than min_cos) or in slivers thinner than \
                     the margin",
                    ));
                }
                out_levels.push(summary);
            }
            let stiffness = last
                .map(|(lin, xs)| pose_stiffness(&lin, &xs, opts.scale))
                .unwrap_or_default();
            // Steps leave out the motions the images do not fix, but those are the current pose's: a
            // sheet tilted on the way in slides in its own plane while the tilt is taken out. The
            // motions free at the solution are undone here, as far as they bring the mesh back to
            // where the user put it (they cost nothing: the images cannot tell).
            let free: Vec<[f64; 7]> = stiffness
                .iter()
                .filter(|(s, _)| *s < opts.gauge_floor)
                .map(|(_, v)| *v)
                .collect();
            if !free.is_empty() {
                x = back_to_placement(&x, &start, &free);
            }
            Ok(Pass {
                x,
                levels: out_levels,
                stiffness,
                free,
            })
        };
    // The verdict on the whole solve: the cameras compared with each other where it ends and
    // where it started, each with its pixels attached where the mesh is (what the rounds solve
    // is always the pixels of the round's start, so no round sees this). Where it ends no
    // better, the placement given is kept: two noisy cameras that share only a rim drew the
    // limb 2 % of its size off its true place to where they agree 45 % worse.
    let compared_at = |x: &[Point3<f64>]| {
        crate::tracker::offset::compared_texture(
            &mesh.with_positions(x.to_vec()),
            cameras,
            frame,
            images,
        )
        .filter(|c| c.cost.is_finite())
    };
    let given = compared_at(&start);
    let judge = |end: &[Point3<f64>]| {
        let before = given.as_ref()?;
        compared_at(end).map(|after| agreement(before, &after))
    };
    let top = levels - 1;
    let plain = solve_pass(false, &start, 0, top)?;
    let mut found = judge(&plain.x);
    let mut chosen = plain;
    let summary = |weighed: bool, shift: [f64; 3], turn: [f64; 3], g: &Agreement| PassSummary {
        shift,
        turn,
        weighed,
        per_texture: g.kept_per_texture(),
        kept_given: g.kept_given,
    };
    let mut passes: Vec<PassSummary> = found
        .iter()
        .map(|g| summary(false, [0.0; 3], [0.0; 3], g))
        .collect();
    let mut kept_pass = 0;
    // A second pass with the patches weighed by their texture, kept where it ends with the
    // cameras agreeing at least `TEXTURE_PASS_GAIN` times better per unit of texture: with
    // three cameras around an object the plain pass can be drawn partly over a plain
    // background, where the bands two cameras share compare background with background
    // (docs/tracker.md, "With three cameras"); the weighed pass, which gives those patches
    // no say, comes back from there more often, but where both come back the plain one is the
    // closer (the glossy hard sample: 0.145–0.150 % against 0.19–0.25 %). With `search`, the
    // weighed pass again from placements around the one given, each judged the same way
    // against the best so far. A start that no two cameras see is passed over.
    let mut starts: Vec<([f64; 3], [f64; 3])> = Vec::new();
    if opts.texture_pass && found.is_some() {
        starts.push(([0.0; 3], [0.0; 3]));
        if opts.search {
            for k in 0..SEARCH_STARTS {
                let (axis, sign) = ((k / 2) % 3, if k % 2 == 0 { 1.0 } else { -1.0 });
                let mut v = [0.0; 3];
                if k < 6 {
                    v[axis] = sign * SEARCH_SHIFT;
                    starts.push((v, [0.0; 3]));
                } else {
                    v[axis] = sign * SEARCH_TURN;
                    starts.push(([0.0; 3], v));
                }
            }
        }
    }
    let size = crate::base::mesh::bbox_diagonal(&start);
    let centre = centroid(&start);
    let widest = cameras.iter().map(|c| c.width).max().unwrap_or(0);
    let search_finest = (0..levels)
        .find(|&l| widest >> l <= SEARCH_WIDTH)
        .unwrap_or(top);
    for (shift, turn) in starts {
        let turned =
            nalgebra::Rotation3::from_scaled_axis(Vector3::from(turn).map(f64::to_radians));
        let moved = Vector3::from(shift) * size;
        let from: Vec<Point3<f64>> = start
            .iter()
            .map(|p| centre + turned * (p - centre) + moved)
            .collect();
        // The starts around the placement given stop at the level at most `SEARCH_WIDTH`
        // pixels wide (they only have to find the right valley); one kept is then solved again
        // from where it ended down to full resolution and judged again.
        let search_start = shift != [0.0; 3] || turn != [0.0; 3];
        let finest = if search_start { search_finest } else { 0 };
        // (A pass whose result compares no texture is never kept: that is the pose these
        // passes are there to avoid.)
        let better = |g: &Agreement, best: Option<Agreement>| {
            !g.kept_given
                && g.after_per_texture().is_finite()
                && g.after_per_texture() * TEXTURE_PASS_GAIN
                    <= best.map_or(f64::INFINITY, |b| b.kept_per_texture())
        };
        let Ok(mut pass) = solve_pass(true, &from, finest, top) else {
            continue;
        };
        let Some(mut g) = judge(&pass.x) else {
            continue;
        };
        if finest > 0 && better(&g, found) {
            let Ok(full) = solve_pass(true, &pass.x, 0, finest - 1) else {
                continue;
            };
            let Some(h) = judge(&full.x) else {
                continue;
            };
            (pass, g) = (full, h);
        }
        passes.push(summary(true, shift, turn, &g));
        if better(&g, found) {
            found = Some(g);
            chosen = pass;
            kept_pass = passes.len() - 1;
        }
    }
    let agreement = found;
    let Pass {
        mut x,
        levels: out_levels,
        stiffness,
        free,
    } = chosen;
    if let Some(a) = &agreement {
        if a.kept_given {
            x = start.clone();
        }
    }
    let mut outline_fit = None;
    if opts.outline && !free.is_empty() {
        if let Some(border) = outline::Border::of(mesh) {
            let views: Vec<Vec<outline::EdgeView>> = (0..levels)
                .map(|l| {
                    cameras
                        .iter()
                        .zip(&pyramids)
                        .map(|(c, p)| {
                            outline::EdgeView::new(level_projection(c.at(frame), l), &p.levels[l])
                        })
                        .collect()
                })
                .collect();
            let px = outline::pixels_per_unit(cameras, frame, &x);
            let size = crate::base::mesh::bbox_diagonal(&x);
            let fit = outline::fit(&border, &x, &free, &views, px, size);
            let moved = max_move_px(
                &x,
                &fit.positions,
                &cameras
                    .iter()
                    .map(|c| c.at(frame).clone())
                    .collect::<Vec<_>>(),
            );
            outline_fit = Some(OutlineSummary {
                contrast_before: fit.before,
                contrast_after: fit.after,
                moved_px: moved,
            });
            x = fit.positions;
        }
    }
    let (rotation, translation, scale) = similarity(&start, &x);
    let loose_twists: Vec<[f64; 7]> = stiffness
        .iter()
        .filter(|(s, _)| *s < LOOSE)
        .map(|(_, v)| *v)
        .collect();
    let loose = stiffness
        .into_iter()
        .filter(|(s, _)| *s < LOOSE)
        .map(|(s, v)| LooseMotion::from_eigen(s, &v))
        .collect();
    Ok(Alignment {
        positions: x,
        rotation,
        translation,
        scale,
        levels: out_levels,
        loose,
        outline: outline_fit,
        loose_twists,
        agreement,
        passes,
        kept_pass,
        enlarged: 1,
    })
}

/// Of each patch's weight, the share its texture earns: `t / (t + TEXTURE_SCALE·median t)`, with
/// `t` the colour variance (summed over R, G, B) of its source camera's pixels over the
/// triangle and every triangle sharing a vertex with it (at the coarse levels a triangle owns a
/// pixel or two, too few for a variance of its own), the median over the patches compared. A
/// patch over a plain background (which every camera sees alike, so comparing it rewards a pose
/// that puts the mesh there) gets almost none; a textured one keeps nearly all of its weight.
fn weigh_by_texture(set: &mut PatchSet, triangles: &[[u32; 3]], ring: &[Vec<u32>], cameras: usize) {
    let nt = triangles.len();
    // Per (source camera, triangle): the count, sum and sum of squares of its pixels' colours.
    // A source patch is listed once per camera it is warped into; it is counted once.
    let mut sums = vec![[0.0f64; 7]; cameras * nt];
    let mut counted = vec![false; cameras * nt];
    for p in &set.patches {
        let k = p.source as usize * nt + p.triangle as usize;
        if std::mem::replace(&mut counted[k], true) {
            continue;
        }
        let a = &mut sums[k];
        for px in &set.pixels[p.start as usize..p.end as usize] {
            a[0] += 1.0;
            for (c, &v) in px.color.iter().enumerate() {
                a[1 + c] += f64::from(v);
                a[4 + c] += f64::from(v) * f64::from(v);
            }
        }
    }
    let mut texture = vec![0.0f64; cameras * nt];
    let mut near: Vec<u32> = Vec::new();
    for c in 0..cameras {
        for t in 0..nt {
            if !counted[c * nt + t] {
                continue;
            }
            near.clear();
            for &v in &triangles[t] {
                near.extend_from_slice(&ring[v as usize]);
            }
            near.sort_unstable();
            near.dedup();
            let mut a = [0.0f64; 7];
            for &u in &near {
                for (s, b) in a.iter_mut().zip(&sums[c * nt + u as usize]) {
                    *s += b;
                }
            }
            if a[0] > 0.0 {
                texture[c * nt + t] = (0..3)
                    .map(|i| (a[4 + i] / a[0] - (a[1 + i] / a[0]).powi(2)).max(0.0))
                    .sum();
            }
        }
    }
    let of = |p: &Patch| texture[p.source as usize * nt + p.triangle as usize];
    let mut sorted: Vec<f64> = set.patches.iter().map(of).collect();
    sorted.sort_by(f64::total_cmp);
    let scale = TEXTURE_SCALE * sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    if scale <= 0.0 {
        return;
    }
    let shares: Vec<f32> = set
        .patches
        .iter()
        .map(|p| (of(p) / (of(p) + scale)) as f32)
        .collect();
    for (p, w) in set.patches.iter_mut().zip(shares) {
        p.weight *= w;
    }
}

/// The texture, as a fraction of the median patch's, at which [`weigh_by_texture`] halves a
/// patch's weight.
const TEXTURE_SCALE: f64 = 0.25;

/// How the cameras agree with each other at the placement given and where [`align`] ended,
/// from their comparisons there (`offset::compared_texture`).
fn agreement(
    before: &crate::tracker::offset::Compared,
    after: &crate::tracker::offset::Compared,
) -> Agreement {
    Agreement {
        before: before.cost,
        after: after.cost,
        kept_given: after.cost >= before.cost,
        pixels_before: before.pixels,
        texture_before: before.texture,
        texture_after: after.texture,
    }
}

/// `mesh` moved by a rotation of `degrees` about a random axis through its centroid and a
/// translation of `fraction` of its bounding-box diagonal in a random direction (seeded): the
/// misplacement [`align`] is tested and measured against (`modelflow align --perturb`).
pub fn perturb(mesh: &Mesh, fraction: f64, degrees: f64, seed: u64) -> Vec<Point3<f64>> {
    let unit = |k: u64| {
        // Uniform on the sphere from two hashed uniforms.
        let h = |i: u64| {
            (crate::synth::texture::mix64(seed.wrapping_mul(0x9E37_79B9).wrapping_add(i + 16 * k))
                >> 11) as f64
                / (1u64 << 53) as f64
        };
        let z = 2.0 * h(0) - 1.0;
        let phi = std::f64::consts::TAU * h(1);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vector3::new(r * phi.cos(), r * phi.sin(), z)
    };
    let axis = nalgebra::Unit::new_normalize(unit(0));
    let dir = unit(1);
    let r = nalgebra::Rotation3::from_axis_angle(&axis, degrees.to_radians());
    let c = centroid(&mesh.positions).coords;
    let t = dir * fraction * mesh.bbox_diagonal();
    mesh.positions
        .iter()
        .map(|p| Point3::from(c + r * (p.coords - c) + t))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_camera_is_compared_with_the_wide_views_of_what_it_sees() {
        // Cameras looking at the origin from directions `deg` degrees about the vertical; camera
        // `i` sees the triangles `seen[i]`.
        let rig = |deg: &[f64]| -> Vec<Projection> {
            let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
            deg.iter()
                .map(|d| {
                    let a = d.to_radians();
                    let eye = Point3::new(3.0 * a.sin(), -3.0 * a.cos(), 0.0);
                    let (r, t) = crate::base::camera::look_at(
                        &eye,
                        &Point3::origin(),
                        &Vector3::new(0.0, 0.0, 1.0),
                    );
                    Projection::from_krt(&k, &r, &t).expect("a camera")
                })
                .collect()
        };
        let x = [Point3::new(0.1, 0.0, 0.0), Point3::new(-0.1, 0.0, 0.0)];
        let chosen = |c: &[bool], n: usize, i: usize| -> Vec<usize> {
            (0..n).filter(|&j| c[i * n + j]).collect()
        };
        // A row of six cameras 8° apart, all seeing every triangle: camera 0 is compared with
        // the three widest baselines, camera 2 with those on its far side first.
        let row = rig(&[-20.0, -12.0, -4.0, 4.0, 12.0, 20.0]);
        let all = vec![vec![true; 10]; 6];
        let c = neighbour_cameras(&x, &row, &all, 3);
        assert_eq!(chosen(&c, 6, 0), vec![3, 4, 5]);
        assert_eq!(chosen(&c, 6, 2), vec![0, 4, 5]);
        assert!((0..6).all(|i| !c[i * 6 + i]));
        // A ring of eight 45° apart around a closed surface: each sees the half facing it
        // (triangles 0..16 by direction), so the opposite camera, which shares none, is never
        // chosen, and the two beside it (most shared) come before those at 90°.
        let ring = rig(&[0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0]);
        let half = |i: usize| -> Vec<bool> { (0..16).map(|t| (t + 16 - 2 * i) % 16 < 8).collect() };
        let seen: Vec<Vec<bool>> = (0..8).map(half).collect();
        let c = neighbour_cameras(&x, &ring, &seen, 3);
        for i in 0..8 {
            let got = chosen(&c, 8, i);
            assert!(
                got.contains(&((i + 1) % 8)) && got.contains(&((i + 7) % 8)),
                "{i}: {got:?}"
            );
            assert!(!got.contains(&((i + 4) % 8)), "{i}: {got:?}");
            assert_eq!(got.len(), 3);
        }
        // Four cameras or fewer with three neighbours, or neighbours 0: every other camera.
        let c = neighbour_cameras(&x, &row[..4], &all[..4], 3);
        assert!(c.iter().all(|&b| b));
        let c = neighbour_cameras(&x, &row, &all, 0);
        assert!(c.iter().all(|&b| b));
    }

    #[test]
    fn similarity_recovers_a_known_motion() {
        let a: Vec<Point3<f64>> = (0..20)
            .map(|i| {
                let f = i as f64;
                Point3::new(f.sin(), (1.3 * f).cos(), 0.1 * f)
            })
            .collect();
        let r = nalgebra::Rotation3::from_euler_angles(0.1, -0.2, 0.3);
        let t = Vector3::new(0.5, -1.0, 2.0);
        let b: Vec<Point3<f64>> = a
            .iter()
            .map(|p| Point3::from(r * p.coords * 1.1 + t))
            .collect();
        let (rr, tt, s) = similarity(&a, &b);
        assert!((rr - r.matrix()).norm() < 1e-12);
        assert!((tt - t).norm() < 1e-12);
        assert!((s - 1.1).abs() < 1e-12);
    }
}
