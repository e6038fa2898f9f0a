//! Regularisers: the terms of the tracker's cost that do not come from the images and keep the
//! mesh sane where the images say little. Each one is a [`Regulariser`] in a file of its own:
//! the thesis' cubic edge springs (`springs`), the frame-to-frame membrane (`membrane`) and the
//! bending term against the rest shape (`bending`). The solver sees only the trait: it adds each
//! term's cost and normal equations to the photometric ones. A new regulariser is one new file
//! implementing the trait, a weight in [`Regularisation`] and a line in [`build`].
//!
//! Knows the mesh, its rest shape, the previous frames' positions and how much the previous
//! frame's solve was constrained at each vertex (one number per vertex); nothing of images or
//! cameras.

pub(crate) mod bending;
pub(crate) mod membrane;
pub(crate) mod springs;

use crate::base::mesh::Mesh;
use crate::tracker::sparse::BlockSparse;
use nalgebra::{Matrix3, Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Weights and parameters of the regularisers (0 turns a term off). `Default` is what
/// `modelflow track` uses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Regularisation {
    /// Spring constant `k` of the cubic edge springs (thesis Eq. 5.16).
    pub spring_k: f64,
    /// Threshold ratio `T` of Eq. 5.16, as a fraction of the rest length (0.1 = 10 %).
    pub spring_t: f64,
    /// Yield strain of the springs, as a fraction of the rest length: an edge held stretched
    /// (or compressed) beyond it in the previous frame has its spring centred on that length
    /// less the yield, so a surface that really stretches is not pulled back to its first
    /// frame's shape (`springs::spring_centre`). 0 = off: the springs always pull toward the
    /// rest length, as in the thesis (and in runs made before the option existed).
    #[serde(default)]
    pub spring_yield: f64,
    /// Beyond the yield strain, how far the spring's centre stands behind the previous frame's
    /// length, toward the rest length, as a fraction of the yield strain
    /// (`springs::spring_centre`), while the surface shows no stretch (see
    /// `spring_stretch_share`): 1 (the default, and runs made before the option existed) pulls
    /// a strain back by the whole yield every frame; 0 resists only a change from the previous
    /// frame.
    #[serde(default = "one")]
    pub spring_pull_back: f64,
    /// The share of the edges that, strained beyond twice the yield strain in the previous
    /// frame, shows that the surface stretches (`springs::pull_back_for`): the pull-back is
    /// then 0 for the frame, whatever `spring_pull_back` says. 0 = off (runs made before the
    /// option existed).
    #[serde(default)]
    pub spring_stretch_share: f64,
    /// Weight `μ` of the frame-to-frame membrane.
    pub membrane: f64,
    /// Whether the membrane's reference turns with each connected piece of the mesh (the
    /// rotation that best maps its edges onto the current ones), so that a piece turning faster
    /// or slower than predicted is not held back (`membrane::Membrane`). `false`: the reference
    /// keeps its orientation and such a change of rotation rate is resisted (runs made before
    /// the option existed, `--membrane-resists-turns`).
    #[serde(default)]
    pub membrane_turns: bool,
    /// Weight `β` of the bending term against the rest shape.
    pub bending: f64,
    /// Yield of the bending term, as a fraction of the mean rest edge length: a vertex whose
    /// Laplacian coordinates the previous frame left further than this from the rest shape's
    /// (turned by the vertex's rotation) is pulled toward that shape less the yield, not the rest
    /// shape, so a fold or a dent the images held is followed (`bending::yielded_target`). 0 = off:
    /// always the rest shape (as in runs made before the option existed).
    #[serde(default)]
    pub bending_yield: f64,
    /// The bending term's yield (as `bending_yield`) where the previous frame's images pinned
    /// the vertex well: its photometric information (the confidence file's `information`) at
    /// least `bending_seen_share` of the frame's median. There a deviation from the rest shape
    /// is the surface's own (a fold, a dent) and little of it is pulled back; elsewhere
    /// `bending_yield` lets the rest shape pull harder, so a drift the images do not see (a side
    /// turning away, a fold of the mesh over itself) is undone. Used only when
    /// `bending_seen_share` is above 0.
    #[serde(default)]
    pub bending_yield_seen: f64,
    /// Where `bending_yield_seen` applies: vertices whose information in the previous frame was
    /// at least this share of the median over the vertices the images saw. 0 = off: every
    /// vertex has `bending_yield` (runs made before the option existed).
    #[serde(default)]
    pub bending_seen_share: f64,
}

fn one() -> f64 {
    1.0
}

impl Default for Regularisation {
    fn default() -> Self {
        Regularisation {
            spring_k: 1.0,
            spring_t: 0.2,
            spring_yield: 0.065,
            spring_pull_back: 1.0,
            spring_stretch_share: 0.005,
            membrane: 0.002,
            membrane_turns: true,
            bending: 0.03,
            bending_yield: 0.05,
            bending_yield_seen: 0.01,
            bending_seen_share: 0.5,
        }
    }
}

/// What a regulariser may refer to in the frame being solved.
pub(crate) struct FrameContext<'a> {
    /// The positions solved for the previous frame.
    pub previous: &'a [Point3<f64>],
    /// The constant-velocity prediction from the two previous frames (the previous positions
    /// when there is no velocity yet).
    pub predicted: &'a [Point3<f64>],
    /// Each vertex's photometric information in the previous frame's solution
    /// (`VertexConfidence::information`, on the tracker's vertices); `None` before the first
    /// solved frame.
    pub information: Option<&'a [f64]>,
}

/// The normal equations a term adds to: `JᵀJ` and `−Jᵀr`.
pub(crate) type System<'s> = (&'s mut BlockSparse, &'s mut [Vector3<f64>]);

/// One term of the cost, `Σ |r(X)|²` over its residuals, with its Gauss–Newton normal
/// equations. Implementations hold their own weight (normalised so that the weights of
/// [`Regularisation`] need no units and do not depend on the mesh's size).
pub(crate) trait Regulariser: Send + Sync {
    /// Its name in logs and manifests (`snake_case`).
    fn name(&self) -> &'static str;

    /// Called once per frame before it is solved (e.g. to take a reference shape).
    fn begin_frame(&mut self, _frame: &FrameContext<'_>) {}

    /// The term's cost at `x` (returned); with `system`, adds its `JᵀJ` and `−Jᵀr` there, on
    /// the mesh's vertex-pair blocks (or the matrix's shared scalar part).
    fn accumulate(&self, x: &[Point3<f64>], system: Option<System<'_>>) -> f64;
}

/// The edges of a mesh with their rest lengths (taken from the first frame), shared by the edge
/// terms. They are the normal equations' block pattern too (`BlockSparse::new` is given
/// `edges`), so an edge term is added by its index.
#[derive(Clone, Debug)]
pub(crate) struct EdgeSet {
    pub edges: Vec<[u32; 2]>,
    pub rest: Vec<f64>,
    pub mean_length: f64,
    /// Each edge's share of the rest surface's area (a third of each adjacent triangle's),
    /// summing to 1: an edge term weighted by it integrates over the surface, so a densely
    /// triangulated region is no stiffer than a coarse one and refining a mesh does not change
    /// the energy. Uniform (1 / number of edges) when the rest surface has no area.
    pub area_weight: Vec<f64>,
}

impl EdgeSet {
    /// The edges of `mesh` (sorted vertex pairs, as `Mesh::edges`) at its positions as rest shape.
    pub fn new(mesh: &Mesh) -> Self {
        let edges = mesh.edges();
        let rest_positions = &mesh.positions;
        let rest: Vec<f64> = edges
            .iter()
            .map(|[a, b]| (rest_positions[*b as usize] - rest_positions[*a as usize]).norm())
            .collect();
        let mean_length = if rest.is_empty() {
            1.0
        } else {
            rest.iter().sum::<f64>() / rest.len() as f64
        };
        let mut area_weight = vec![0.0; edges.len()];
        for (i, t) in mesh.triangles.iter().enumerate() {
            let third = 0.5 * mesh.triangle_normal(i).norm() / 3.0;
            if !third.is_finite() {
                continue;
            }
            for [a, b] in [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]] {
                let key = if a < b { [a, b] } else { [b, a] };
                if let Ok(e) = edges.binary_search(&key) {
                    area_weight[e] += third;
                }
            }
        }
        let total: f64 = area_weight.iter().sum();
        if total > 0.0 && total.is_finite() {
            area_weight.iter_mut().for_each(|w| *w /= total);
        } else {
            let n = edges.len().max(1) as f64;
            area_weight.iter_mut().for_each(|w| *w = 1.0 / n);
        }
        EdgeSet {
            edges,
            rest,
            mean_length,
            area_weight,
        }
    }

    /// Adds the term of edge `e` = `[a, b]`: symmetric Hessian blocks `h` on (a,a), (b,b) and
    /// `−h` on (a,b), (b,a), and gradient `g_b` with respect to `b` (`−g_b` with respect to `a`).
    pub fn add_edge(
        system: &mut System<'_>,
        e: usize,
        [a, b]: [usize; 2],
        h: &nalgebra::Matrix3<f64>,
        g_b: &Vector3<f64>,
    ) {
        let (m, rhs) = system;
        m.add_edge(e, [a, b], h);
        rhs[b] -= g_b;
        rhs[a] += g_b;
    }
}

/// The rotation closest to `m` (polar decomposition via SVD), with `det = +1`.
pub(crate) fn procrustes(m: &Matrix3<f64>) -> Matrix3<f64> {
    polar(&m.svd(true, true)).unwrap_or_else(Matrix3::identity)
}

/// [`procrustes`], or the identity where `m` fixes no rotation: where its second largest
/// singular value is at most `1e-9` of its largest (the directions it was summed from all lie
/// on one line, or there were none). One SVD for both.
pub(crate) fn procrustes_if_fixed(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let mut s = [
        svd.singular_values[0],
        svd.singular_values[1],
        svd.singular_values[2],
    ];
    s.sort_by(|a, b| b.total_cmp(a));
    if s[0] > 0.0 && s[1] > 1e-9 * s[0] {
        polar(&svd).unwrap_or_else(Matrix3::identity)
    } else {
        Matrix3::identity()
    }
}

/// The rotation factor `U·D·Vᵀ` of an SVD (`D` flipping the last axis where `U·Vᵀ` would
/// reflect), or `None` without its factors or when it is not finite.
fn polar(svd: &nalgebra::SVD<f64, nalgebra::U3, nalgebra::U3>) -> Option<Matrix3<f64>> {
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// The regularisers `reg` asks for on `mesh` (whose positions are the rest shape), in the order
/// the solver adds them.
pub(crate) fn build(
    mesh: &Mesh,
    edges: &Arc<EdgeSet>,
    reg: &Regularisation,
) -> Vec<Box<dyn Regulariser>> {
    let mut out: Vec<Box<dyn Regulariser>> = Vec::new();
    if reg.spring_k > 0.0 {
        out.push(Box::new(springs::CubicSprings::new(
            edges.clone(),
            reg.spring_k,
            reg.spring_t,
            (reg.spring_yield > 0.0).then_some(springs::Yield {
                strain: reg.spring_yield,
                pull_back: reg.spring_pull_back,
                stretch_share: reg.spring_stretch_share,
            }),
        )));
    }
    if reg.membrane > 0.0 {
        out.push(Box::new(if reg.membrane_turns {
            membrane::Membrane::new(edges.clone(), reg.membrane)
        } else {
            membrane::Membrane::fixed(edges.clone(), reg.membrane)
        }));
    }
    if reg.bending > 0.0 {
        let b = bending::Bending::new(&mesh.triangles, &mesh.positions);
        out.push(Box::new(bending::BendingTerm::new(
            b,
            reg.bending,
            bending::Yield {
                fraction: reg.bending_yield,
                seen: (reg.bending_seen_share > 0.0).then_some(bending::SeenYield {
                    fraction: reg.bending_yield_seen,
                    share: reg.bending_seen_share,
                }),
            },
        )));
    }
    debug_assert_eq!(
        out.iter().map(|r| r.name()).collect::<Vec<_>>(),
        names(reg),
        "names() lists what build() builds"
    );
    out
}

/// The names of the regularisers [`build`] builds for `reg`, in order, without building them.
pub(crate) fn names(reg: &Regularisation) -> Vec<&'static str> {
    [
        (reg.spring_k > 0.0, "cubic_springs"),
        (reg.membrane > 0.0, "membrane"),
        (reg.bending > 0.0, "bending"),
    ]
    .into_iter()
    .filter_map(|(on, name)| on.then_some(name))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_recorded_before_the_pull_back_option_resumes_with_the_regularisers_it_had() {
        // run.json of a run made before 2026-11-26 names no `spring_pull_back`: its springs
        // pulled a stretch back by the whole yield, so `--resume` must go on that way.
        let old = r#"{"spring_k": 1.0, "spring_t": 0.2, "spring_yield": 0.065,
                      "membrane": 0.002, "bending": 0.01, "bending_yield": 0.05}"#;
        let r: Regularisation = serde_json::from_str(old).unwrap();
        assert_eq!((r.spring_pull_back, r.spring_stretch_share), (1.0, 0.0));
        // Nor a gated bending yield (before 2026-11-28): its one yield everywhere.
        assert_eq!(r.bending_seen_share, 0.0);
        // Nor a membrane that turns with the mesh (before 2026-12-01).
        assert!(!r.membrane_turns);
        // Runs made on 2026-11-26 before the stretch share: pull-back 0 in every frame.
        let day = r#"{"spring_k": 1.0, "spring_t": 0.2, "spring_yield": 0.065,
                      "spring_pull_back": 0.0, "membrane": 0.002, "bending": 0.01,
                      "bending_yield": 0.05}"#;
        let r: Regularisation = serde_json::from_str(day).unwrap();
        assert_eq!((r.spring_pull_back, r.spring_stretch_share), (0.0, 0.0));
        let d = Regularisation::default();
        assert_eq!((d.spring_pull_back, d.spring_stretch_share), (1.0, 0.005));
        assert!(d.membrane_turns);
        assert_eq!(
            (d.bending, d.bending_yield_seen, d.bending_seen_share),
            (0.03, 0.01, 0.5)
        );
        let new = serde_json::to_string(&Regularisation::default()).unwrap();
        assert_eq!(
            serde_json::from_str::<Regularisation>(&new).unwrap(),
            Regularisation::default()
        );
    }

    #[test]
    fn edge_weights_follow_the_area_so_a_sliver_adds_almost_nothing() {
        // A right triangle of area 0.5 and, on its hypotenuse, a sliver of height 1e-6.
        let mesh = Mesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.5, 0.5 + 1e-6, 0.0),
            ],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        let e = EdgeSet::new(&mesh);
        let w = |a: u32, b: u32| e.area_weight[e.edges.binary_search(&[a, b]).unwrap()];
        assert!((e.area_weight.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            assert!((w(a, b) - 1.0 / 3.0).abs() < 1e-5, "{a}-{b}: {}", w(a, b));
        }
        assert!(w(1, 3) < 1e-5 && w(2, 3) < 1e-5);
    }
}
