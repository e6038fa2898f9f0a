//! Turning runs into figures: scoring against ground truth (`eval`), colours (`colormap`), 2-D
//! drawing and text (`draw`), line plots (`plot`), mesh pictures (`overlay`, filled meshes
//! through `synth::render`), the photometric quality measure for footage without ground truth
//! (`photometric`), the photometric residual image of one frame (`residual`), the scrubbable flipbook of every frame's overlays (`flipbook`) and the
//! HTML page that ties them together (`page`, `html`); and the picture of an alignment
//! (`alignment`, for `modelflow align --picture`).
//! It reads run folders through `run`; it never runs a tracker.

mod alignment;
pub(crate) mod colormap;
pub(crate) mod draw;
mod eval;
mod flipbook;
mod html;
pub(crate) mod overlay;
mod page;
pub(crate) mod photometric;
pub(crate) mod plot;
mod residual;

pub use alignment::alignment_picture;
pub use eval::{evaluate, surface_rms, EvalReport, FrameError, ViewsError, ViewsSummary};
pub use page::{
    seconds_per_frame, write_report, ReportOptions, ReportSummary, ResidualRow, RunSummary,
};
