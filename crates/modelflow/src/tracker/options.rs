//! The tracker's options: [`TrackOptions`] as given (what `modelflow track`'s flags set), and
//! [`OptionsUsed`], the same resolved and with what they imply, which the tracker runs with and
//! a run's manifest records (like Ceres' summary, which reports options as given and as used).

use crate::tracker::pyramid::auto_levels;
use crate::tracker::regularise::{self, Regularisation};
use crate::tracker::solve::{Interpolation, SolverOptions};
use serde::{Deserialize, Serialize};

/// Tracker settings. `Default` is what `modelflow track` uses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackOptions {
    pub solver: SolverOptions,
    /// The regularisers' weights.
    pub regularisation: Regularisation,
    /// Pyramid levels solved, coarse to fine (1 = full resolution only; 0 = chosen from the
    /// image size, see `pyramid::auto_levels`).
    pub levels: usize,
    /// Gaussian smoothing (pixels, at each level's own scale) before gradients are taken.
    pub blur: f64,
    /// Weight of the first-frame template relative to the previous-frame one (0 = thesis only).
    pub anchor_weight: f64,
    /// Silhouette margin in pixels.
    pub margin: usize,
    /// Grazing-angle cut-off (cosine between normal and view direction).
    pub min_cos: f64,
    /// Try a constant-velocity prediction as the starting guess.
    pub predict: bool,
    /// At full resolution, compare every other pixel of the previous frame (a checkerboard, at
    /// twice the weight) instead of all of them. Neighbouring pixels of a smoothed image carry
    /// nearly the same information, so this halves the finest level's work for no measurable
    /// loss of accuracy (the first-frame anchor is always a checkerboard).
    pub checkerboard: bool,
    /// Solve each pyramid level for one rigid motion of the whole mesh first, then per vertex
    /// (a hierarchy of motion models: large motion is caught by six unknowns that every
    /// triangle's pixels constrain together).
    #[serde(default = "yes")]
    pub rigid_first: bool,
}

fn yes() -> bool {
    true
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            solver: SolverOptions::default(),
            regularisation: Regularisation::default(),
            levels: 0,
            blur: 1.0,
            anchor_weight: 2.0,
            margin: 1,
            min_cos: 0.1,
            predict: true,
            checkerboard: true,
            rigid_first: true,
        }
    }
}

/// The options a tracker runs with: the given ones resolved, and what they imply.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptionsUsed {
    /// The options after resolution (`levels` at least 1).
    pub options: TrackOptions,
    /// How the next frame is sampled at each pyramid level, finest (level 0) first: the chosen
    /// interpolation at full resolution, bilinear at the coarser levels (they only bring the
    /// mesh near the solution; the finest level decides it).
    pub interpolation_per_level: Vec<Interpolation>,
    /// The regularisers in the cost, in the order the solver adds them.
    pub regularisers: Vec<String>,
}

impl TrackOptions {
    /// These options with `levels = 0` (automatic) resolved for images of the given sizes
    /// (width, height): the smallest image decides.
    pub fn resolved_for(&self, sizes: impl IntoIterator<Item = (u32, u32)>) -> TrackOptions {
        if self.levels > 0 {
            return *self;
        }
        let short = sizes.into_iter().map(|(w, h)| w.min(h)).min().unwrap_or(0);
        TrackOptions {
            levels: auto_levels(short),
            ..*self
        }
    }

    /// These options as a tracker uses them (automatic levels must be resolved first with
    /// [`TrackOptions::resolved_for`]; left at 0 they count as 1).
    pub fn used(&self) -> OptionsUsed {
        let options = TrackOptions {
            levels: self.levels.max(1),
            ..*self
        };
        let interpolation_per_level = (0..options.levels)
            .map(|l| {
                if l == 0 {
                    options.solver.interpolation
                } else {
                    Interpolation::Linear
                }
            })
            .collect();
        let regularisers = regularise::names(&options.regularisation)
            .into_iter()
            .map(String::from)
            .collect();
        OptionsUsed {
            options,
            interpolation_per_level,
            regularisers,
        }
    }
}
