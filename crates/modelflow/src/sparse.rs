//! The normal equations `JᵀJ·δ = −Jᵀr` as a block-sparse symmetric matrix with one 3×3 block per
//! pair of mesh-adjacent vertices (thesis §6.4, Fig. 6.2), and a preconditioned conjugate-gradient
//! solver for it.
//!
//! Hand-written rather than taken from `faer`: the structure is fixed by the mesh once, blocks are
//! accumulated in place every iteration and the solve is a few dozen block-Jacobi-preconditioned CG
//! steps; a general sparse format would cost a conversion per iteration for nothing. Matrix–vector
//! products run in parallel over block rows; dot products are summed sequentially so that results
//! do not depend on the number of threads.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// Symmetric block-sparse matrix, both triangles stored (CSR over 3×3 blocks).
#[derive(Clone, Debug)]
pub struct BlockSparse {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    blocks: Vec<Matrix3<f64>>,
    diag: Vec<usize>,
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
        BlockSparse {
            row_ptr,
            cols,
            blocks,
            diag,
        }
    }

    pub fn dim(&self) -> usize {
        self.row_ptr.len() - 1
    }

    pub fn clear(&mut self) {
        self.blocks.iter_mut().for_each(|b| *b = Matrix3::zeros());
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

    /// The diagonal block of vertex `i`.
    pub fn diagonal(&self, i: usize) -> &Matrix3<f64> {
        &self.blocks[self.diag[i]]
    }

    /// Adds `d` to every diagonal entry, and `lm·diag(A)` (Levenberg–Marquardt damping).
    pub fn damp(&mut self, d: f64, lm: f64) {
        for &k in &self.diag {
            let b = &mut self.blocks[k];
            for c in 0..3 {
                b[(c, c)] += d + lm * b[(c, c)];
            }
        }
    }

    /// `y = A·x`.
    pub fn mul(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
        y.par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .for_each(|(i, yi)| {
                let mut acc = Vector3::zeros();
                for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                    acc += self.blocks[k] * x[self.cols[k] as usize];
                }
                *yi = acc;
            });
    }
}

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
}
