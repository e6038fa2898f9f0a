//! Core values every stage shares: the camera model (`camera`) and its lens distortion
//! (`lens`), in-memory images and their
//! samplers (`image`), triangle meshes and their topology (`mesh`), and z-buffered visibility of a
//! mesh in a camera (`raster`, used by the tracker and the baseline alike, so both agree on what
//! a camera sees), and the scene's length unit (`units`). Nothing here reads or writes files or knows about tracking, footage or
//! reports.

pub(crate) mod camera;
pub(crate) mod image;
pub(crate) mod lens;
pub(crate) mod mesh;
pub(crate) mod raster;
pub(crate) mod units;

pub use camera::{is_rotation, look_at, Camera, Projection, ProjectionError};
pub use image::{blank_images, comparable, mixes_grey_and_colour, BlockMeans, RgbImage};
pub use lens::{DistortMap, Distortion, Lens, UndistortMap};
pub use mesh::{
    centroid, grid, rms_distance, rms_radius, AxisSwap, CornerNormals, CornerTable, Mesh,
};
pub use units::{Length, Units};
