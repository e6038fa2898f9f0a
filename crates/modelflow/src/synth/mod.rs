//! Synthetic footage with exact ground truth: the software renderer (`render`, which knows only
//! meshes, cameras and a [`Material`] to colour them; the report draws with it too), procedural
//! textures (`texture`, materials for the renderer), an irregular triangulation of the sphere
//! (`remesh`) and the presets that move a surface and write
//! a scene (`presets`).

mod presets;
mod remesh;
pub(crate) mod render;
pub(crate) mod texture;

pub use presets::{
    icosphere, write_dataset, Bump, MotionStats, Preset, SynthOptions, Synthetic, FPS,
};
pub use render::{depth_map, render, vertex_normals, Light, Material, RenderOptions, Surface};
pub use texture::{CubeTexture, PlaneTexture, Texture};
