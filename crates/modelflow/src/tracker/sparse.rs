//! The normal equations `JᵀJ·δ = −Jᵀr` as a block-sparse symmetric matrix with one 3×3 block per
//! pair of mesh-adjacent vertices (thesis §6.4, Fig. 6.2), and a preconditioned conjugate-gradient
//! solver for it.
//!
//! A term whose Jacobian is the same for x, y and z and does not depend on the positions (the
//! bending term's Laplacian `L`) contributes `s·K ⊗ I₃` with a constant scalar matrix `K = LᵀL`.
//! That part is kept as one shared [`ScalarSparse`] and a weight instead of being accumulated
//! into 3×3 blocks: `K` couples vertices two rings apart, and storing it as blocks would triple
//! the matrix and the cost of every CG step.
//!
//! Hand-written rather than taken from `faer`: the structure is fixed by the mesh once, blocks are
//! accumulated in place every iteration and the solve is a few dozen block-Jacobi-preconditioned CG
//! steps; a general sparse format would cost a conversion per iteration for nothing. Matrix–vector
//! products run in parallel over block rows; dot products are summed sequentially so that results
//! do not depend on the number of threads.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use std::sync::Arc;

/// A symmetric sparse matrix of scalars `K` (CSR, both triangles stored), applied to
/// 3-vectors per vertex as `K ⊗ I₃`.
#[derive(Clone, Debug)]
pub struct ScalarSparse {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    vals: Vec<f64>,
    diag: Vec<f64>,
}

impl ScalarSparse {
    /// The Gram matrix `LᵀL` of a sparse `L` with `n` columns, given as its rows (each a list of
    /// `(column, value)`; a column may appear once per row).
    pub fn gram<'a>(n: usize, rows: impl IntoIterator<Item = &'a [(u32, f64)]>) -> Self {
        let mut triplets: Vec<(u32, u32, f64)> = Vec::new();
        for row in rows {
            for &(i, a) in row {
                for &(j, b) in row {
                    triplets.push((i, j, a * b));
                }
            }
        }
        // Sum duplicates in a fixed order (sorted by position, stable within a position).
        triplets.sort_by_key(|&(i, j, _)| (i, j));
        let mut row_ptr = vec![0usize; n + 1];
        let mut cols = Vec::new();
        let mut vals: Vec<f64> = Vec::new();
        let mut diag = vec![0.0; n];
        let mut last = None;
        for (i, j, v) in triplets {
            if last == Some((i, j)) {
                *vals.last_mut().expect("a value was pushed") += v;
            } else {
                cols.push(j);
                vals.push(v);
                row_ptr[i as usize + 1] += 1;
                last = Some((i, j));
            }
        }
        for i in 0..n {
            row_ptr[i + 1] += row_ptr[i];
        }
        for i in 0..n {
            for k in row_ptr[i]..row_ptr[i + 1] {
                if cols[k] as usize == i {
                    diag[i] = vals[k];
                }
            }
        }
        ScalarSparse {
            row_ptr,
            cols,
            vals,
            diag,
        }
    }

    pub fn dim(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// `K_ii`.
    pub fn diagonal(&self, i: usize) -> f64 {
        self.diag[i]
    }

    /// `Σ_j K_ij·x_j` for row `i`.
    #[inline]
    fn row_times(&self, i: usize, x: &[Vector3<f64>]) -> Vector3<f64> {
        let mut acc = Vector3::zeros();
        for k in self.row_ptr[i]..self.row_ptr[i + 1] {
            acc += x[self.cols[k] as usize] * self.vals[k];
        }
        acc
    }
}

/// Symmetric block-sparse matrix, both triangles stored (CSR over 3×3 blocks), plus at most one
/// shared scalar part `s·K ⊗ I₃` (see the module documentation).
#[derive(Clone, Debug)]
pub struct BlockSparse {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    blocks: Vec<Matrix3<f64>>,
    diag: Vec<usize>,
    /// For each pattern edge `[a, b]` given to [`BlockSparse::new`], the positions of its blocks
    /// (a, b) and (b, a): edge terms are added without a search (shared by clones).
    edge_slots: Arc<[[u32; 2]]>,
    scalar: Option<(Arc<ScalarSparse>, f64)>,
}

impl BlockSparse {
    /// The pattern of a mesh: a block for every vertex with itself and with every pair in
    /// `edges` (the mesh's edges, and any further coupled pairs such as bending stencils').
    pub fn new(vertex_count: usize, edges: &[[u32; 2]]) -> Self {
        let mut nb: Vec<Vec<u32>> = (0..vertex_count).map(|i| vec![i as u32]).collect();
        for &[a, b] in edges {
            nb[a as usize].push(b);
            nb[b as usize].push(a);
        }
        let mut row_ptr = Vec::with_capacity(vertex_count + 1);
        let mut cols = Vec::new();
        let mut diag = Vec::with_capacity(vertex_count);
        row_ptr.push(0);
        for (i, mut row) in nb.into_iter().enumerate() {
            row.sort_unstable();
            row.dedup();
            let d = row.binary_search(&(i as u32)).expect("diagonal present");
            diag.push(cols.len() + d);
            cols.extend(row);
            row_ptr.push(cols.len());
        }
        let blocks = vec![Matrix3::zeros(); cols.len()];
        let mut m = BlockSparse {
            row_ptr,
            cols,
            blocks,
            diag,
            edge_slots: Arc::new([]),
            scalar: None,
        };
        m.edge_slots = edges
            .iter()
            .map(|&[a, b]| {
                let (a, b) = (a as usize, b as usize);
                [m.find(a, b) as u32, m.find(b, a) as u32]
            })
            .collect();
        m
    }

    pub fn dim(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Sets every block, and the scalar part, to zero.
    pub fn clear(&mut self) {
        self.blocks.iter_mut().for_each(|b| *b = Matrix3::zeros());
        self.scalar = None;
    }

    /// Adds `s·K ⊗ I₃`. Only one `K` can be held: adding another one panics (a programming
    /// error), adding the same one again adds the weights.
    pub fn add_scalar(&mut self, k: &Arc<ScalarSparse>, s: f64) {
        assert_eq!(k.dim(), self.dim(), "scalar part of another size");
        match &mut self.scalar {
            None => self.scalar = Some((Arc::clone(k), s)),
            Some((held, w)) => {
                assert!(Arc::ptr_eq(held, k), "only one scalar part is supported");
                *w += s;
            }
        }
    }

    /// The scalar part's diagonal at vertex `i` (`s·K_ii`, 0 without one).
    fn scalar_diagonal(&self, i: usize) -> f64 {
        self.scalar.as_ref().map_or(0.0, |(k, s)| s * k.diagonal(i))
    }

    fn find(&self, i: usize, j: usize) -> usize {
        let row = &self.cols[self.row_ptr[i]..self.row_ptr[i + 1]];
        self.row_ptr[i]
            + row
                .binary_search(&(j as u32))
                .unwrap_or_else(|_| panic!("block ({i}, {j}) is not in the mesh pattern"))
    }

    /// Adds `b` at block (i, j) and `bᵀ` at (j, i) (once if `i == j`). Vertices `i` and `j` must
    /// be equal or share an edge.
    pub fn add_pair(&mut self, i: usize, j: usize, b: &Matrix3<f64>) {
        if i == j {
            let k = self.diag[i];
            self.blocks[k] += b;
        } else {
            let k = self.find(i, j);
            self.blocks[k] += b;
            let k = self.find(j, i);
            self.blocks[k] += b.transpose();
        }
    }

    /// Adds an edge term for pattern edge `e` = `[a, b]` (the `e`-th edge given to
    /// [`BlockSparse::new`]): the symmetric `h` at (a, a) and (b, b), `−h` at (a, b) and (b, a).
    #[inline]
    pub fn add_edge(&mut self, e: usize, [a, b]: [usize; 2], h: &Matrix3<f64>) {
        let [ab, ba] = self.edge_slots[e].map(|k| k as usize);
        debug_assert_eq!(self.cols[ab] as usize, b, "edge {e} is not [{a}, {b}]");
        debug_assert_eq!(self.cols[ba] as usize, a, "edge {e} is not [{a}, {b}]");
        self.blocks[self.diag[a]] += h;
        self.blocks[self.diag[b]] += h;
        self.blocks[ab] -= h;
        self.blocks[ba] -= h;
    }

    /// The diagonal block of vertex `i` (scalar part included).
    pub fn diagonal(&self, i: usize) -> Matrix3<f64> {
        self.blocks[self.diag[i]] + Matrix3::identity() * self.scalar_diagonal(i)
    }

    /// Adds `d` to every diagonal entry, and `lm·diag(A)` (Levenberg–Marquardt damping).
    pub fn damp(&mut self, d: f64, lm: f64) {
        for i in 0..self.dim() {
            let sd = self.scalar_diagonal(i);
            let b = &mut self.blocks[self.diag[i]];
            for c in 0..3 {
                b[(c, c)] += d + lm * (b[(c, c)] + sd);
            }
        }
    }

    /// `y = A·x`. Rows in parallel on large systems; below `PARALLEL_ROWS` rows one thread
    /// is faster (a product of a few thousand blocks takes tens of microseconds, the order of a
    /// rayon fork-join; CG calls this once per iteration). Each row is summed in the same order
    /// either way, so the result does not depend on the thread count.
    pub fn mul(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
        let row = |i: usize| {
            let mut acc = Vector3::zeros();
            for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                acc += self.blocks[k] * x[self.cols[k] as usize];
            }
            if let Some((m, s)) = &self.scalar {
                acc += m.row_times(i, x) * *s;
            }
            acc
        };
        if y.len() < PARALLEL_ROWS {
            y.iter_mut().enumerate().for_each(|(i, yi)| *yi = row(i));
        } else {
            y.par_iter_mut()
                .enumerate()
                .with_min_len(1024)
                .for_each(|(i, yi)| *yi = row(i));
        }
    }
}

/// Systems with fewer rows than this are multiplied on one thread (see [`BlockSparse::mul`]).
const PARALLEL_ROWS: usize = 8192;

/// How a conjugate-gradient solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgSummary {
    pub iterations: usize,
    /// `|b − A·x| / |b|` at the end.
    pub relative_residual: f64,
}

fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
}

/// Solves `A·x = b` by conjugate gradients with a block-Jacobi preconditioner, starting from
/// zero, until the relative residual is below `tol` or after `max_iter` iterations.
pub fn solve_pcg(
    a: &BlockSparse,
    b: &[Vector3<f64>],
    tol: f64,
    max_iter: usize,
) -> (Vec<Vector3<f64>>, CgSummary) {
    let n = a.dim();
    let precond: Vec<Matrix3<f64>> = (0..n)
        .map(|i| {
            let d = a.diagonal(i);
            d.try_inverse().unwrap_or_else(|| {
                let s = d.trace() / 3.0;
                if s > 0.0 {
                    Matrix3::identity() / s
                } else {
                    Matrix3::identity()
                }
            })
        })
        .collect();
    let mut x = vec![Vector3::zeros(); n];
    let bnorm = dot(b, b).sqrt();
    if bnorm == 0.0 {
        return (
            x,
            CgSummary {
                iterations: 0,
                relative_residual: 0.0,
            },
        );
    }
    let mut r = b.to_vec();
    let mut z: Vec<Vector3<f64>> = r.iter().zip(&precond).map(|(r, m)| m * r).collect();
    let mut p = z.clone();
    let mut ap = vec![Vector3::zeros(); n];
    let mut rz = dot(&r, &z);
    let mut it = 0;
    let mut rnorm = bnorm;
    while it < max_iter {
        a.mul(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap.is_nan() || pap <= 0.0 {
            break;
        }
        let alpha = rz / pap;
        for i in 0..n {
            x[i] += p[i] * alpha;
            r[i] -= ap[i] * alpha;
        }
        it += 1;
        rnorm = dot(&r, &r).sqrt();
        if rnorm <= tol * bnorm {
            break;
        }
        for i in 0..n {
            z[i] = precond[i] * r[i];
        }
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + p[i] * beta;
        }
    }
    (
        x,
        CgSummary {
            iterations: it,
            relative_residual: rnorm / bnorm,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg_solves_a_chain_laplacian_system() {
        // 1D chain of 50 vertices: A = L ⊗ I + 0.1·I, SPD.
        let n = 50;
        let edges: Vec<[u32; 2]> = (0..n as u32 - 1).map(|i| [i, i + 1]).collect();
        let mut a = BlockSparse::new(n, &edges);
        for &[i, j] in &edges {
            let (i, j) = (i as usize, j as usize);
            a.add_pair(i, i, &Matrix3::identity());
            a.add_pair(j, j, &Matrix3::identity());
            a.add_pair(i, j, &(-Matrix3::identity()));
        }
        a.damp(0.1, 0.0);
        let truth: Vec<Vector3<f64>> = (0..n)
            .map(|i| Vector3::new(i as f64, (i as f64).sin(), 1.0))
            .collect();
        let mut b = vec![Vector3::zeros(); n];
        a.mul(&truth, &mut b);
        let (x, s) = solve_pcg(&a, &b, 1e-12, 500);
        assert!(s.relative_residual <= 1e-12, "{s:?}");
        for i in 0..n {
            assert!((x[i] - truth[i]).norm() < 1e-8);
        }
    }

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn gram_is_lt_l_and_acts_like_the_same_blocks() {
        // L has rows (1, −½, −½, 0) and (0, 1, 0, −1): LᵀL by hand.
        let rows: [&[(u32, f64)]; 2] = [&[(0, 1.0), (1, -0.5), (2, -0.5)], &[(1, 1.0), (3, -1.0)]];
        let k = Arc::new(ScalarSparse::gram(4, rows));
        let dense = [
            [1.0, -0.5, -0.5, 0.0],
            [-0.5, 1.25, 0.25, -1.0],
            [-0.5, 0.25, 0.25, 0.0],
            [0.0, -1.0, 0.0, 1.0],
        ];
        let x: Vec<Vector3<f64>> = (0..4)
            .map(|i| Vector3::new(i as f64 + 1.0, (i * i) as f64, -2.0 * i as f64))
            .collect();
        for i in 0..4 {
            assert_eq!(k.diagonal(i), dense[i][i]);
            let want: Vector3<f64> = (0..4).map(|j| x[j] * dense[i][j]).sum();
            assert!((k.row_times(i, &x) - want).norm() < 1e-15);
        }
        // The same matrix held as 3×3 blocks, and as a scalar part of weight 2 (split 1.5 + 0.5):
        // products, diagonals and damping agree.
        let pairs: Vec<[u32; 2]> = vec![[0, 1], [0, 2], [1, 2], [1, 3]];
        let mut blocks = BlockSparse::new(4, &pairs);
        for i in 0..4 {
            blocks.add_pair(i, i, &(Matrix3::identity() * 2.0 * dense[i][i]));
            for j in i + 1..4 {
                if dense[i][j] != 0.0 {
                    blocks.add_pair(i, j, &(Matrix3::identity() * 2.0 * dense[i][j]));
                }
            }
        }
        let mut scalar = BlockSparse::new(4, &pairs);
        scalar.add_scalar(&k, 1.5);
        scalar.add_scalar(&k, 0.5);
        blocks.damp(0.3, 0.1);
        scalar.damp(0.3, 0.1);
        let (mut y1, mut y2) = (vec![Vector3::zeros(); 4], vec![Vector3::zeros(); 4]);
        blocks.mul(&x, &mut y1);
        scalar.mul(&x, &mut y2);
        for i in 0..4 {
            assert!(
                (y1[i] - y2[i]).norm() < 1e-12,
                "{i}: {} vs {}",
                y1[i],
                y2[i]
            );
            assert!((blocks.diagonal(i) - scalar.diagonal(i)).norm() < 1e-12);
        }
        scalar.clear();
        scalar.mul(&x, &mut y2);
        assert!(
            y2.iter().all(|v| *v == Vector3::zeros()),
            "clear drops the scalar part"
        );
    }
}
