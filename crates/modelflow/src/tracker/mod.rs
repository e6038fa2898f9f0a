//! The Model Flow tracker. Per frame: image pyramids (`pyramid`), template patches of the known
//! frames (`patch`, on `base::raster`'s index buffers), the per-triangle homography warp and its
//! analytic Jacobian (`warp`), the regularisers (`regularise`), the block-sparse normal equations
//! and their conjugate-gradient solver (`sparse`), and the Gauss–Newton/Levenberg–Marquardt
//! solve (`solve`). Before a shot, `align` lines a roughly placed mesh up with its first frame
//! by the same warps between cameras, and `axes` asks whether the mesh was written with another
//! up axis than the cameras'. Over a shot: [`Tracker`] in memory (`sequence`: images in, positions out)
//! and [`track_scene`] from a scene on disk into a run folder (`shot`). Only `shot` touches
//! files, through `run`; everything else takes and returns memory.

pub(crate) mod align;
mod axes;
mod balance;
pub(crate) mod consensus;
mod coverage;
pub(crate) mod fold;
mod gpu;
pub(crate) mod health;
mod occluder;
mod occlusion;
mod offset;
mod options;
pub(crate) mod outline;
pub(crate) mod patch;
pub(crate) mod pyramid;
pub(crate) mod regularise;
pub(crate) mod rim;
pub(crate) mod sequence;
mod shift;
mod shot;
pub(crate) mod smear;
pub(crate) mod solve;
pub(crate) mod sparse;
pub(crate) mod steady;
pub(crate) mod warp;

#[cfg(test)]
mod tests;

pub use align::{
    align, first_mesh_check, perturb, placement, Agreement, AlignLevel, AlignOptions, Alignment,
    FirstMeshCheck, LooseMotion, MotionKind, OutlineSummary, Placement, LOOSE, PLACEMENT_MIN_GAIN,
    PLACEMENT_WARN, TEXTURE_PASS_GAIN,
};
pub use align::{PassSummary, ENLARGE_MAX_PIXELS, SEARCH_SHIFT, SEARCH_STARTS, SEARCH_TURN};
pub use axes::{axes_swapped, AxesSwapped, AXES_GAIN};
pub use coverage::{coverage, Coverage};
pub use gpu::{Gpu, GpuStats};
pub use health::{
    check_reports, Checks, Concern, FrameCheck, DISAGREE_FRAMES, DISAGREE_RISE, INFORMATION_FLOOR,
    SUSPECT_RISE,
};
pub use offset::{
    moved_onto_surface, onto_surface, surface_offset, view_agreement, PairAgreement, SurfaceMove,
    SurfaceOffset, ViewAgreement, AGREE_CONTRAST, MIN_PX as SURFACE_MIN_PX,
    RANGE_PX as SURFACE_RANGE_PX,
};
pub use options::{OptionsUsed, TrackOptions};
pub use regularise::Regularisation;
pub use sequence::{
    prepare, FrameReport, Prepared, SecondStart, StepTiming, Tracker, SECOND_START_GAIN,
    SECOND_START_PX,
};
pub use shift::{
    camera_shifts, CameraShifts, MAX_SHIFT_PX as MAX_CAMERA_SHIFT_PX,
    MIN_GAIN as MIN_CAMERA_SHIFT_GAIN,
};
pub use shot::{median, track_scene, TrackSummary};
pub use solve::{
    GainModel, Interpolation, IterationSummary, Loss, SolveSummary, SolverOptions, StopReason,
    VertexConfidence,
};
