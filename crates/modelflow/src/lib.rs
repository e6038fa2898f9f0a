//! modelflow: markerless capture of deforming geometry from calibrated, synchronised multi-view
//! footage, after "Model Flowing" (Reuterswärd, 2005). See `ARCHITECTURE.md` for the map.

pub mod camera;
pub mod colormap;
pub mod draw;
pub mod error;
pub mod eval;
pub mod fsutil;
pub mod image;
pub mod imageio;
pub mod mesh;
pub mod meshio;
pub mod overlay;
pub mod plot;
pub mod render;
pub mod report;
pub mod scene;
pub mod texture;

pub use error::{Error, Result};
