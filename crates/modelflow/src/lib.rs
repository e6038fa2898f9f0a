//! modelflow: markerless capture of deforming geometry from calibrated, synchronised multi-view
//! footage, after "Model Flowing" (Reuterswärd, 2005). See `ARCHITECTURE.md` for the map.

pub mod baseline;
pub mod bending;
pub mod camera;
pub mod colormap;
pub mod draw;
pub mod error;
pub mod eval;
pub mod fsutil;
pub mod image;
pub mod imageio;
pub mod lk;
pub mod mesh;
pub mod meshio;
pub mod overlay;
pub mod patch;
pub mod plot;
pub mod pyramid;
pub mod raster;
pub mod render;
pub mod report;
pub mod scene;
pub mod solve;
pub mod sparse;
pub mod springs;
pub mod synth;
pub mod texture;
pub mod track;
pub mod triangulate;
pub mod visibility;
pub mod warp;

pub use error::{Error, Result};
