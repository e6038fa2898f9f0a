//! The Blender-rendered sample footage (a renderer that is not ours) loads, and its cameras
//! follow the documented convention.

use modelflow::scene::Scene;
use std::path::PathBuf;

fn sample() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/footage/blender-cloth-sample/scene.json"
    ))
}

#[test]
fn blender_sample_loads_with_images_and_truth() {
    let scene = Scene::load(&sample()).unwrap();
    assert_eq!((scene.first, scene.last), (0, 11));
    assert_eq!(scene.mesh.positions.len(), 1681);
    assert_eq!(scene.mesh.triangles.len(), 3200);
    assert_eq!(scene.cameras.len(), 2);
    for f in [0, 11] {
        let imgs = scene.load_images(f).unwrap();
        assert_eq!(imgs.len(), 2);
        for img in &imgs {
            assert_eq!((img.width(), img.height()), (320, 240));
        }
        let gt = scene.ground_truth(f).unwrap().unwrap();
        assert_eq!(gt.triangles, scene.mesh.triangles);
    }
}
