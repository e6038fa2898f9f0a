"""A researcher's loop with modelflow: load a scene, track it frame by frame from numpy images,
score every frame against the ground truth, and plot the error and the per-vertex confidence.

    pip install ./python matplotlib
    python python/examples/track_and_plot.py [SCENE] [OUT.png]
"""

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import modelflow  # noqa: E402

root = pathlib.Path(__file__).resolve().parents[2]
scene_path = sys.argv[1] if len(sys.argv) > 1 else root / "fixtures/blender-cloth-sample/scene.json"
out = sys.argv[2] if len(sys.argv) > 2 else "track_and_plot.png"

scene = modelflow.Scene.load(scene_path)
diag = np.linalg.norm(scene.positions.max(0) - scene.positions.min(0))
tracker = modelflow.Tracker(scene)
frames, rms, sigma_median = [scene.first], [0.0], [np.nan]
for f in range(scene.first + 1, scene.last + 1):
    report = tracker.step(f, scene.load_images(f))
    truth = scene.ground_truth(f)
    err = np.linalg.norm(tracker.positions - truth, axis=1) if truth is not None else None
    frames.append(f)
    rms.append(100 * np.sqrt(np.mean(err ** 2)) / diag if err is not None else np.nan)
    sigma_median.append(np.median(report["sigma"][np.isfinite(report["sigma"])]))
    print(f"frame {f}: {report['iterations']} iterations, stop {report['stop']}, "
          f"RMS error {rms[-1]:.3f} % of the bbox diagonal")

fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
a.plot(frames, rms, marker="o")
a.set(xlabel="frame", ylabel="RMS vertex error (% of bbox diagonal)", title="Error against ground truth")
b.plot(frames, sigma_median, marker="o", color="C1")
b.set(xlabel="frame", ylabel=f"median sigma ({scene.units or 'scene units'})",
      title="Per-vertex uncertainty (median)")
fig.tight_layout()
fig.savefig(out, dpi=120)
print(f"wrote {out}")
