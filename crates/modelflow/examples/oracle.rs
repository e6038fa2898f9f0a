use modelflow::scene::Scene;
use modelflow::track::{TrackOptions, Tracker};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene = Scene::load(std::path::Path::new(&args[1])).unwrap();
    let oracle = args.get(2).is_some_and(|a| a == "oracle");
    let mut opts = TrackOptions::default();
    if let Ok(v) = std::env::var("MEMB") {
        opts.solver.springs.membrane = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("ANCH") {
        opts.anchor_weight = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("BLUR") {
        opts.blur = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("MARGIN") {
        opts.margin = v.parse().unwrap();
    }
    let mut tr = Tracker::new(
        &scene.mesh,
        scene.cameras.clone(),
        scene.first,
        &scene.load_images(scene.first).unwrap(),
        opts,
    )
    .unwrap();
    let diag = scene.mesh.bbox_diagonal();
    let mut sum = 0.0;
    let mut n = 0;
    for f in scene.first + 1..=scene.last {
        if oracle {
            tr.set_positions(scene.ground_truth(f - 1).unwrap().unwrap().positions)
                .unwrap();
        }
        tr.step(f, &scene.load_images(f).unwrap()).unwrap();
        let t = scene.ground_truth(f).unwrap().unwrap().positions;
        let e = (tr
            .positions()
            .iter()
            .zip(&t)
            .map(|(a, b)| (a - b).norm_squared())
            .sum::<f64>()
            / t.len() as f64)
            .sqrt();
        sum += e;
        n += 1;
        println!("frame {f}: {:.4}% ({:.2} mm)", 100.0 * e / diag, e * 1e3);
    }
    println!(
        "mean over solved frames {:.4}%",
        100.0 * sum / n as f64 / diag
    );
}
