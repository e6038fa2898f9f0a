"""Type stubs of the `modelflow` extension module (Model Flow: markerless capture of deforming
geometry from calibrated multi-view footage). Lengths are in the scene's unit; images are
(height, width, 3) arrays, float32 in 0..1 or uint8; positions are (V, 3) float64 arrays."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike]
_Image = Union[npt.NDArray[np.float32], npt.NDArray[np.uint8]]

class ModelflowError(Exception):
    """A bad file or value (the message names the file and field, or the option), or a failed run."""

class Scene:
    """A scene: calibrated cameras, footage and the mesh lined up with the first frame."""

    @staticmethod
    def load(
        path: _Path,
        cameras: Optional[Sequence[str]] = None,
        frames: Optional[Tuple[int, int]] = None,
    ) -> "Scene":
        """Loads and checks a scene file (modelflow-scene/1); `cameras` and `frames` load only
        that part, whose images alone are checked (track --cameras, --frames)."""
    def with_frames(self, first: int, last: int) -> "Scene":
        """The same scene restricted to frames first..=last (the mesh lined up with `first`)."""
    @property
    def first(self) -> int: ...
    @property
    def last(self) -> int: ...
    @property
    def cameras(self) -> List[str]:
        """The cameras' names, in the scene's order."""
    @property
    def units(self) -> Optional[str]:
        """The scene's length unit ("m", "cm", "mm") or None."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """The mesh's vertex positions at the first frame, (V, 3)."""
    @property
    def triangles(self) -> npt.NDArray[np.uint32]:
        """The mesh's triangles, (T, 3) vertex indices."""
    def load_images(self, frame: int) -> List[npt.NDArray[np.float32]]:
        """Every camera's image of `frame` as the tracker sees it (undistorted), (H, W, 3) in 0..1."""
    def ground_truth(self, frame: int) -> Optional[npt.NDArray[np.float64]]:
        """The ground-truth positions at `frame`, (V, 3), or None without ground truth."""

class Tracker:
    """The Model Flow tracker in memory: images in, positions out, one frame at a time."""

    def __init__(
        self,
        scene: Scene,
        images: Optional[Sequence[_Image]] = None,
        options: Optional[Dict[str, Any]] = None,
    ) -> None:
        """A tracker at the scene's first frame. `images`: that frame's images (default: read
        from the scene). `options`: tracker options by their JSON names, over the defaults."""
    def step(self, frame: int, images: Sequence[_Image]) -> Dict[str, Any]:
        """Solves `frame` from its images (one per camera, in the scene's order). Returns the
        frame's report (the fields of a `log.jsonl` line: "stalled", "suspect",
        "contradicted_share", ...), with the per-vertex confidence as arrays "information",
        "residual", "sigma"."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """The current vertex positions, (V, 3)."""
    @property
    def first_mesh_moved(self) -> Optional[Dict[str, Any]]:
        """When the scene's mesh lay off the surface the cameras agree on and was moved onto
        it before tracking (option "onto_surface", on by default): {"found": {"pixels",
        "length", "ratio", "at_limit", "closed", "compared", "texture_kept"}, "median",
        "max"}, as run.json's
        `first_mesh_moved`; else None."""
    @property
    def camera_shifts(self) -> Optional[Dict[str, Any]]:
        """The shifts of the cameras' images at which they agree best about the first mesh
        (option "shift_cameras", on by default): {"shifts": [[dx, dy], ...] (pixels, one per
        camera), "pairs", "cost_before", "cost_after", "applied"}, as run.json's
        `camera_shifts`; the tracker sees every camera shifted by them when "applied". None
        when not measured or no two cameras compare the mesh."""

def track_scene(
    scene: Scene,
    out: _Path,
    options: Optional[Dict[str, Any]] = None,
    force: bool = False,
    device: str = "cpu",
) -> Dict[str, Any]:
    """Tracks the whole scene into the run folder `out`, as `modelflow track` does. `device`:
    "cpu", or "gpu" for the solver's per-pixel work on an NVIDIA GPU (raises ModelflowError
    saying what is missing where there is none). Returns the
    summary: "frames", "solved", "resumed_from", "total_seconds", "median_frame_seconds",
    "median_iterations", "stalled_frames" (the mesh could not move), "suspect_frames" (the
    cameras contradicted where the frame left the surface, the frame started from such a
    solution, the mesh saw next to none of its texture, folded over itself or leapt away, or a
    camera's image was blank or repeated the frame before) and "checks": every frame to look at, as {"frame": N, "concerns": [{"kind":
    "stalled" | "contradicted" | "started_contradicted" | "little_texture" | "folded" |
    "blank" | "repeated" | "late" | "early" | "ahead" | "rejoined" | "moved" | "disagree" | "jumped", ...their figures}]}."""

def evaluate(scene: Scene, run: _Path) -> Dict[str, Any]:
    """Scores a run folder against the scene's ground truth: per-frame and mean RMS error, over
    all vertices, the seen ones, by how many cameras see them (`by_views`), and of the shape alone
    after the best rigid fit (`shape_rms`, `pose_turn_deg`, `pose_shift`); docs/scene-format.md."""

def frames_to_check(scene: Scene, run: _Path) -> Optional[List[Dict[str, Any]]]:
    """The frames of the scene's range that the tracker's own checks flag in the run folder, and
    why: [{"frame": N, "concerns": [{"kind": "stalled" | "contradicted" |
    "started_contradicted" | "little_texture" | "folded" | "blank" | "repeated" | "late" | "early" | "ahead" | "rejoined" | "moved" | "disagree" | "jumped", ...their figures}]}], as
    `track` warned and the
    report lists them; [] when none is; None when the folder has no tracker log (the
    baseline's)."""

def export(run: _Path, out: _Path, fps: float = 24.0) -> List[str]:
    """Writes a run folder as .usda, .glb, .pc2 or .mdd (from `out`'s extension); warns
    (UserWarning) when a USD export cannot carry the scene's cameras."""

def synth(
    out: _Path,
    preset: str = "cloth",
    cameras: Optional[int] = None,
    width: int = 640,
    height: int = 480,
    frames: int = 120,
    noise: float = 0.0,
    seed: int = 1,
    light: bool = True,
    supersample: Optional[int] = None,
    shake: float = 0.0,
    distortion: Optional[str] = None,
    cloth_grid: Optional[int] = None,
    sync_error: float = 0.0,
    motion_blur: float = 0.0,
    rolling_shutter: float = 0.0,
    turn: float = 0.0,
    backdrop: bool = False,
    bump: Optional[str] = None,
) -> PathLike:
    """Synthetic multi-view footage with ground truth written into `out`, as `modelflow synth`
    writes it (presets "cloth", "blob", "irregular", "limb", "crossing"); returns the scene
    file's path. `None` keeps the preset's default."""

def baseline(scene: Scene, out: _Path, force: bool = False) -> Dict[str, Any]:
    """The optical-flow baseline (Lucas–Kanade per camera, then triangulation) over the whole
    scene into the run folder `out`, as `modelflow baseline` with its defaults; returns
    {"solved", "median_frame_seconds"}."""

def report(
    scene: Scene,
    runs: Dict[str, _Path],
    out: _Path,
    frames: Optional[Sequence[int]] = None,
    flipbook: bool = True,
    shared_scale: bool = False,
    residual_frame: Optional[int] = None,
) -> Dict[str, Any]:
    """The HTML report comparing runs ({name: folder}, in the page's order), as `modelflow
    report` writes it into `out`; returns {"index": the page, "files", "frames": drawn}."""

def import_calibration(
    format: str,
    input: _Path,
    out: Optional[_Path] = None,
    mesh: str = "mesh/initial.obj",
    images: str = "images/{camera}/{frame:04}.png",
    frames: Tuple[int, int] = (0, 0),
    size: Optional[Tuple[int, int]] = None,
    chunk: Optional[str] = None,
    units: Optional[str] = None,
    before_applied_transform: bool = False,
    force: bool = False,
) -> Dict[str, Any]:
    """A scene file from another tool's calibration, as `modelflow import` does: `format` is
    "colmap", "opencv", "metashape" or "nerfstudio" (transforms.json). With `out` it is written
    there (replacing a file only with `force`). Returns {"scene": the scene file as a dict,
    "notes": [what to know about the file], "written": the path or None}."""

def read_run(run: _Path) -> Dict[int, npt.NDArray[np.float64]]:
    """A run folder's frame meshes: {frame: (V, 3) positions}."""

def first_mesh_check(
    scene: Scene, positions: Optional[npt.NDArray[np.float64]] = None
) -> Dict[str, Any]:
    """What `modelflow track` checks before tracking, at the first frame, for the scene's mesh
    (or the same triangles at `positions`, (V, 3)): {"surface": how far along its normals the
    cameras agree best (or None), "placement": how far `align` would move the mesh (or None;
    only for a mesh on the surface, off it by more than a quarter of its size, or off it by
    less where `align`'s rigid move makes the cameras agree better than the move along the
    normals does: misplaced, not off the surface), "surface_off": bool, "misplaced": bool,
    "calibration_explains": bool, "views": {"pairs": [{"a": int, "b": int, "contrast": float,
    "compared": float}], "disagreeing": [camera names], "none_agree": bool} (each pair of cameras'
    agreement about the mesh: a camera that agrees with no other, contrast under 1.4, where another
    pair does, has images that are another camera's or from another frame, or a calibration far
    off),
    "axes_swapped": None or {"swap": "y_up_to_z_up" | "z_up_to_y_up", "gain": float, "message":
    str} when the cameras agree at least 1.25 times better about the mesh with its axes swapped}.
    `track` moves the mesh onto the surface when "surface_off" holds within a quarter of its
    size and "placement" is None. Both findings
    carry "compared" (pixels the cameras compare where the mesh is) and "texture_kept" (their
    texture where the finding would put the mesh, over that where it is), the placement also
    "agreement_gain" (the cameras' cost where the mesh is over that where `align` ends), and
    both "disparity" when two cameras see a vertex well (how many pixels of the frames the move
    shifts where one camera's view of the surface lands in another's); a finding from fewer than
    200 pixels, or one that keeps less than a quarter of the texture (the pixels moved onto a
    plain background), or a placement where the cameras agree less than 1.05 times better, or
    an offset along the normals whose disparity is under 1.5 px (a calibration that far off
    explains it as well), is not off; "calibration_explains" is True for such an offset and for
    a misplacement named whose disparity is that small (a camera's calibration may be off)."""

def coverage(scene: Scene, options: Optional[Dict[str, Any]] = None) -> Dict[str, float]:
    """How much of the mesh's surface (by area, at the first frame) is seen by two or more
    cameras ("two_or_more"), by one only ("one"), by none ("none")."""

def blind_cameras(scene: Scene) -> List[Dict[str, Any]]:
    """The cameras that see none of the mesh at the first frame: [{"camera": name, "index":
    int, "why": "behind" | "outside_image", "message": str}] (the message names the likely
    mistake in the camera's calibration, as `track` prints it). Empty when all see some of it."""

def off_centre_principal_points(scene: Scene) -> List[Dict[str, Any]]:
    """The cameras whose principal point lies more than a fifth of the image from its centre:
    [{"camera": name, "index": int, "cx": float, "cy": float, "message": str}] (the message names
    the likely cause, a K made at another resolution, and the scale to apply)."""

def turned_images(scene: Scene) -> List[Dict[str, Any]]:
    """The cameras whose image file at the first frame asks viewers to turn or mirror it (its EXIF
    orientation: a phone's JPEG shot upright): [{"camera": name, "index": int, "file": str,
    "turn": str, "message": str}]. modelflow reads the pixels as stored (as PIL does), so a
    calibration made on the images as shown does not fit them. Empty when none does."""

def mesh_out_of_scale(scene: Scene) -> Optional[Dict[str, Any]]:
    """The mesh's size in the images at the first frame when it is under 8 px or over 10 times
    the images' diagonal: {"pixels": float, "image": float, "message": str}; None otherwise.
    Almost always a mesh in another unit than the calibration."""

def align(
    scene: Scene,
    positions: Optional[npt.NDArray[np.float64]] = None,
    scale: bool = False,
    outline: bool = False,
    search: bool = True,
) -> Dict[str, Any]:
    """Lines up a roughly placed mesh (`positions`, (V, 3); default: the scene's) with the
    scene's first frame, as `modelflow align` does. Returns "positions", "rotation", "translation",
    "scale", "angle_deg", "levels", "loose" (motions the images hold loosely; those with
    stiffness below 1e-6 were kept as placed) and "outline" (with `outline=True`: those motions
    set from the contrast across the mesh's border, for a sheet whose border is its visible
    edge) and "agreement" ({"before", "after": the cameras' mean cost compared with each other
    as placed and where the solve ended; "pixels_before", "texture_before", "texture_after": the
    pixels compared as placed and their texture there and where it ended; "kept_given": where it
    ended they agree no better, so the placement given was returned}, or None), "passes" (the
    coarse-to-fine passes solved: [{"shift", "turn": where each started, moved by fractions of
    the mesh's size or turned by degrees about each axis from the placement given; "weighed":
    its patches weighed by their texture; "per_texture": the cameras' cost per unit of texture
    where its result is, None where it compares no texture; "kept_given"}]: the plain pass, the weighed one and, with `search`,
    twelve more from around the placement given) and "kept_pass" (the index of the one
    returned: a later pass is kept only where the cameras agree at least twice as well)."""
