//! The optical-flow baseline ("Universal Capture"): pyramidal Lucas–Kanade per camera (`lk`, on
//! `gradient`'s pyramids), per-vertex visibility (`visibility`), multi-view triangulation
//! (`triangulate`), chained over a shot by `pipeline`. It knows nothing of the tracker's solver.

pub(crate) mod gradient;
pub(crate) mod lk;
mod pipeline;
pub(crate) mod triangulate;
pub(crate) mod visibility;

pub use lk::LkOptions;
pub use pipeline::{run, Baseline, BaselineFrame, BaselineOptions, BaselineSummary, Seeding};
