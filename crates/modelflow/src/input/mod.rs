//! Everything that enters from disk: the scene format (`scene`), mesh files (`meshio`: OBJ, PLY)
//! image files (`imageio`: PNG, JPEG, TIFF, OpenEXR), video files (`video`, through FFmpeg) and
//! calibrations made by other tools
//! (`calib`: COLMAP, OpenCV `FileStorage`, Metashape XML, nerfstudio `transforms.json`). Each reader validates what it reads and
//! names the file and the field or line at fault. Nothing here tracks, renders or scores.

pub mod calib;
pub(crate) mod dpx;
pub(crate) mod gltfmesh;
pub(crate) mod imageio;
pub(crate) mod meshio;
pub(crate) mod scene;
pub mod transfer;
pub mod video;

pub use imageio::{image_orientation, image_size, read_rgb, write_jpeg, write_png, write_png16};
pub use meshio::{parse_obj, parse_ply, read_mesh, read_mesh_with, validate, write_obj, Checks};
pub use scene::{
    blind_cameras, mesh_out_of_scale, off_centre_principal_points, visible_share, Blind,
    BlindCamera, CameraEntry, DistortionEntry, FramePattern, FrameRange, MeshOutOfScale, OffCentre,
    PoseEntry, Scene, SceneFile, Selection, TurnedImages, BYTES_PER_PIXEL, FORMAT,
    HUGE_MESH_IMAGES, LENS_BYTES_PER_PIXEL, MIN_VISIBLE_SHARE, PRINCIPAL_POINT_OFF,
    ROTATION_TOLERANCE, TINY_MESH_PX,
};
