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
//! accumulated in place every iteration and the solve is a few dozen preconditioned CG steps; a
//! general sparse format would cost a conversion per iteration for nothing. The preconditioner
//! (block-Jacobi plus coarser levels that move groups of vertices as one, see [`Preconditioner`])
//! is ours too: it is built from the mesh's own graph, which a general-purpose algebraic multigrid
//! would have to rediscover from the matrix at every solve. From `PARALLEL_ROWS` rows on,
//! matrix–vector products, the CG's vector updates and the preconditioner run in parallel over
//! rows (and groups), and dot products are summed in fixed runs of rows, so that results do not
//! depend on the number of threads.

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
        let (a, b) = (self.row_ptr[i], self.row_ptr[i + 1]);
        for (&c, &v) in self.cols[a..b].iter().zip(&self.vals[a..b]) {
            acc += x[c as usize] * v;
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
    /// Each vertex's aggregate for the preconditioner's coarse level (see [`Aggregates`]).
    aggregates: Arc<Aggregates>,
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
            aggregates: Arc::new(Aggregates {
                levels: Vec::new(),
                members: Vec::new(),
            }),
        };
        m.aggregates = Arc::new(Aggregates::of_graph(&m.row_ptr, &m.cols, COARSE_MAX));
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

    /// Stored blocks, and entries of the scalar part.
    pub(crate) fn entries(&self) -> usize {
        self.cols.len() + self.scalar.as_ref().map_or(0, |(k, _)| k.cols.len())
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

    /// `y = A·x`. From `PARALLEL_ROWS` rows on, the rows are split into one contiguous run per
    /// thread: a product of a few thousand blocks takes tens of microseconds, so one task per
    /// thread (not rayon's finer split, whose fork-joins cost more than the product) is what
    /// pays. Below it, waking the other threads for each of the CG's products costs more than
    /// they save (see `PARALLEL_ROWS`). Each row is summed in the same order either way, so the
    /// result does not depend on the thread count.
    pub fn mul(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
        let row = |i: usize| {
            let mut acc = Vector3::zeros();
            let (a, b) = (self.row_ptr[i], self.row_ptr[i + 1]);
            for (block, &c) in self.blocks[a..b].iter().zip(&self.cols[a..b]) {
                acc += block * x[c as usize];
            }
            if let Some((m, s)) = &self.scalar {
                acc += m.row_times(i, x) * *s;
            }
            acc
        };
        let threads = rayon::current_num_threads();
        if y.len() < PARALLEL_ROWS || threads == 1 {
            y.iter_mut().enumerate().for_each(|(i, yi)| *yi = row(i));
        } else {
            let chunk = y.len().div_ceil(threads);
            y.par_chunks_mut(chunk).enumerate().for_each(|(c, ys)| {
                for (k, yi) in ys.iter_mut().enumerate() {
                    *yi = row(c * chunk + k);
                }
            });
        }
    }
}

impl BlockSparse {
    /// Calls `f(j, block)` for every stored block of row `i` and, as `s·K_ij·I₃`, every entry
    /// of the scalar part's row `i`, in a fixed order.
    fn for_each_entry_of_row(&self, i: usize, mut f: impl FnMut(usize, Matrix3<f64>)) {
        for k in self.row_ptr[i]..self.row_ptr[i + 1] {
            f(self.cols[k] as usize, self.blocks[k]);
        }
        if let Some((m, s)) = &self.scalar {
            for e in m.row_ptr[i]..m.row_ptr[i + 1] {
                f(m.cols[e] as usize, Matrix3::identity() * (s * m.vals[e]));
            }
        }
    }
}

/// Systems with fewer rows than this are multiplied on one thread (see [`BlockSparse::mul`]).
/// Measured on two cores (the time `solve_pcg` took in `track`, summed over a run; the meshes
/// are the same to the bit): the bench cloth's 1 681 rows 0.81 s on two threads against 0.67 s
/// on one (20 frames), a 4 096-vertex cloth 0.37 s against 0.38 s, a 10 000-vertex one 0.90 s
/// against 1.07 s.
pub(crate) const PARALLEL_ROWS: usize = 4096;

/// The most groups the coarsest level may have: its matrix (3 unknowns per group) is inverted
/// densely once per solve and applied at every CG iteration. (Where aggregation stops above it,
/// on a mesh of more separate pieces, the last level is block-Jacobi like the others.)
const COARSE_MAX: usize = 64;

/// Nested partitions of the vertices into connected groups, for the preconditioner's coarser
/// levels.
///
/// The regularisers make the normal equations a Laplacian over the mesh (plus the images' local
/// terms); block-Jacobi alone leaves its smooth modes — a region of the mesh moving as one — to
/// the conjugate gradients, which then take about as many iterations as the mesh is wide in
/// edges. Each coarser level moves a group of vertices as one: groups are made by greedy
/// aggregation (a node whose neighbours are all free takes them; the rest join a neighbouring
/// group), repeated on the groups' own graph until at most [`COARSE_MAX`] remain.
/// Deterministic: nodes are visited in index order.
#[derive(Debug)]
struct Aggregates {
    /// For each level from the finest aggregates to the coarsest, the group of every vertex
    /// and how many groups there are.
    levels: Vec<(Vec<u32>, usize)>,
    /// For each level, every group's children in increasing order (CSR: `starts[g]..starts[g + 1]`
    /// of `vertices`): the vertices it holds at the first level, the groups of the level below
    /// it at the others. A group's residual is its children's summed in that order (level by
    /// level, each from the one below), whether the groups are summed one after another or in
    /// parallel, on the CPU or on the GPU.
    members: Vec<Members>,
}

/// The children of each group of one aggregation level (see [`Aggregates::members`]).
#[derive(Debug)]
struct Members {
    starts: Vec<u32>,
    vertices: Vec<u32>,
}

impl Members {
    /// By counting sort of the vertices by group: each group's vertices stay in increasing order.
    fn of(of: &[u32], count: usize) -> Self {
        let mut starts = vec![0u32; count + 1];
        for &g in of {
            starts[g as usize + 1] += 1;
        }
        for g in 0..count {
            starts[g + 1] += starts[g];
        }
        let mut next = starts.clone();
        let mut vertices = vec![0u32; of.len()];
        for (i, &g) in of.iter().enumerate() {
            vertices[next[g as usize] as usize] = i as u32;
            next[g as usize] += 1;
        }
        Members { starts, vertices }
    }

    fn of_group(&self, g: usize) -> &[u32] {
        &self.vertices[self.starts[g] as usize..self.starts[g + 1] as usize]
    }
}

impl Aggregates {
    /// The levels of the graph whose adjacency (self loops allowed) is the CSR `row_ptr`/`cols`.
    fn of_graph(row_ptr: &[usize], cols: &[u32], max: usize) -> Self {
        let n = row_ptr.len() - 1;
        let mut of: Vec<u32> = (0..n as u32).collect();
        let mut count = n;
        let mut adj: Vec<Vec<u32>> = (0..n)
            .map(|i| cols[row_ptr[i]..row_ptr[i + 1]].to_vec())
            .collect();
        let mut levels = Vec::new();
        while count > max {
            let (step, c) = Self::once(&adj);
            if c == count {
                break;
            }
            for a in of.iter_mut() {
                *a = step[*a as usize];
            }
            let mut next: Vec<Vec<u32>> = vec![Vec::new(); c];
            for (i, row) in adj.iter().enumerate() {
                let a = step[i];
                next[a as usize].extend(row.iter().map(|&j| step[j as usize]));
            }
            for row in next.iter_mut() {
                row.sort_unstable();
                row.dedup();
            }
            adj = next;
            count = c;
            levels.push((of.clone(), c));
        }
        // Each level's groups as groups of the level below's (nested by construction).
        let members = (0..levels.len())
            .map(|l| {
                let (of, c) = &levels[l];
                if l == 0 {
                    return Members::of(of, *c);
                }
                let (below, nb) = &levels[l - 1];
                let mut parent = vec![0u32; *nb];
                for (&h, &g) in below.iter().zip(of) {
                    parent[h as usize] = g;
                }
                Members::of(&parent, *c)
            })
            .collect();
        Aggregates { levels, members }
    }

    /// One pass of greedy aggregation: each node's group and how many there are.
    fn once(adj: &[Vec<u32>]) -> (Vec<u32>, usize) {
        const FREE: u32 = u32::MAX;
        let n = adj.len();
        let mut of = vec![FREE; n];
        let mut count = 0u32;
        for i in 0..n {
            if of[i] == FREE && adj[i].iter().all(|&j| of[j as usize] == FREE) {
                of[i] = count;
                for &j in &adj[i] {
                    of[j as usize] = count;
                }
                count += 1;
            }
        }
        // Every node left has a neighbour in a group (else it would have started one).
        let first = of.clone();
        for i in 0..n {
            if of[i] == FREE {
                of[i] = adj[i]
                    .iter()
                    .map(|&j| first[j as usize])
                    .find(|&a| a != FREE)
                    .unwrap_or_else(|| {
                        count += 1;
                        count - 1
                    });
            }
        }
        (of, count as usize)
    }
}

/// The preconditioner: block-Jacobi on the vertices, plus on every coarser level of
/// [`Aggregates`] the same for the groups moved as one (`P_lᵀ·A·P_l`'s diagonal blocks), plus the
/// coarsest level solved exactly (its dense inverse) — an additive multilevel preconditioner in the
/// manner of BPX, symmetric positive definite whenever `A` is.
struct Preconditioner<'a> {
    fine: Vec<Matrix3<f64>>,
    /// Each intermediate level: the inverses of its groups' diagonal blocks.
    levels: Vec<Grouped<'a, Vec<Matrix3<f64>>>>,
    /// The coarsest level: the inverse of its whole matrix (by Cholesky, symmetrised), applied
    /// by [`dense_apply`]: a product, which the GPU runs one row per thread, where two
    /// substitutions would be a chain of `2m` dependent steps.
    coarsest: Option<Grouped<'a, nalgebra::DMatrix<f64>>>,
}

/// One aggregation level of the [`Preconditioner`]: each vertex's group, each group's vertices,
/// and what the level solves with.
struct Grouped<'a, T> {
    of: &'a [u32],
    members: &'a Members,
    solve: T,
}

/// Groups from which a [`GroupMatrix`]'s rows are built on several threads.
const GROUP_ROWS_PARALLEL: usize = 512;

/// A matrix over one aggregation level's groups, `P_lᵀ·A·P_l`: each group's row holds its
/// blocks with the groups it touches, in the order they were first met.
struct GroupMatrix {
    rows: Vec<Vec<(u32, Matrix3<f64>)>>,
}

impl GroupMatrix {
    /// `count` rows over `count` groups, row `g` from `fill(g, add)`, which calls `add(h, b)`
    /// for each block `b` at (g, h) in its fixed order. Each row is summed on its own (the same
    /// sums on one thread or several), with a sparse accumulator: `at[h]` remembers where the
    /// row being filled keeps `h`, so there is no search.
    fn build(count: usize, fill: impl Fn(usize, &mut dyn FnMut(u32, Matrix3<f64>)) + Sync) -> Self {
        let row = |at: &mut Vec<(u32, u32)>, g: usize| {
            let mut row: Vec<(u32, Matrix3<f64>)> = Vec::new();
            fill(g, &mut |h, b| {
                let (r, k) = at[h as usize];
                if r == g as u32 {
                    row[k as usize].1 += b;
                } else {
                    at[h as usize] = (g as u32, row.len() as u32);
                    row.push((h, b));
                }
            });
            row
        };
        let fresh = || vec![(u32::MAX, 0u32); count];
        let rows = if count >= GROUP_ROWS_PARALLEL && rayon::current_num_threads() > 1 {
            (0..count).into_par_iter().map_init(fresh, row).collect()
        } else {
            let mut at = fresh();
            (0..count).map(|g| row(&mut at, g)).collect()
        };
        GroupMatrix { rows }
    }

    /// The first level's, from `A`'s entries: each group's vertices' rows in increasing order.
    fn of(a: &BlockSparse, of: &[u32], members: &Members, count: usize) -> Self {
        Self::build(count, |g, add| {
            for &i in members.of_group(g) {
                a.for_each_entry_of_row(i as usize, |j, b| add(of[j], b));
            }
        })
    }

    /// The next level's: each of its groups' children's rows, children in increasing order.
    fn coarser(&self, children: &Members, count: usize) -> Self {
        let mut parent = vec![0u32; self.rows.len()];
        for g in 0..count {
            for &c in children.of_group(g) {
                parent[c as usize] = g as u32;
            }
        }
        Self::build(count, |g, add| {
            for &c in children.of_group(g) {
                for &(h, b) in &self.rows[c as usize] {
                    add(parent[h as usize], b);
                }
            }
        })
    }

    /// Every group's block with itself.
    fn diagonal(&self) -> Vec<Matrix3<f64>> {
        self.rows
            .iter()
            .enumerate()
            .map(|(g, row)| {
                row.iter()
                    .find(|(h, _)| *h as usize == g)
                    .map_or(Matrix3::zeros(), |&(_, b)| b)
            })
            .collect()
    }
}

fn invert_or_scale(d: Matrix3<f64>) -> Matrix3<f64> {
    d.try_inverse().unwrap_or_else(|| {
        let s = d.trace() / 3.0;
        if s > 0.0 {
            Matrix3::identity() / s
        } else {
            Matrix3::identity()
        }
    })
}

impl<'a> Preconditioner<'a> {
    fn new(a: &'a BlockSparse, multilevel: bool) -> Self {
        let fine = if parallel(a.dim()) {
            (0..a.dim())
                .into_par_iter()
                .map(|i| invert_or_scale(a.diagonal(i)))
                .collect()
        } else {
            (0..a.dim())
                .map(|i| invert_or_scale(a.diagonal(i)))
                .collect()
        };
        let mut out = Preconditioner {
            fine,
            levels: Vec::new(),
            coarsest: None,
        };
        let all = &a.aggregates.levels;
        if !multilevel || all.is_empty() {
            return out;
        }
        let members = &a.aggregates.members;
        // Each level's matrix over its groups, `P_lᵀ·A·P_l`: the first level's from one pass over
        // `A`'s entries, every further level's from the level below's (its groups' children).
        // The last level is solved whole only when it is small: aggregation stops early on a mesh
        // of many separate pieces (each piece ends as one group), and a dense inverse of
        // thousands of unknowns would cost more than the solve. Then every level is block-Jacobi.
        let dense = all[all.len() - 1].1 <= COARSE_MAX;
        let mut groups = GroupMatrix::of(a, &all[0].0, &members[0], all[0].1);
        for l in 0..all.len() {
            if l > 0 {
                groups = groups.coarser(&members[l], all[l].1);
            }
            if l + 1 < all.len() || !dense {
                out.levels.push(Grouped {
                    of: &all[l].0,
                    members: &members[l],
                    solve: groups.diagonal().into_iter().map(invert_or_scale).collect(),
                });
            }
        }
        if !dense {
            return out;
        }
        let (of, m) = (&all[all.len() - 1].0[..], all[all.len() - 1].1);
        let last_members = &members[all.len() - 1];
        let mut a0 = nalgebra::DMatrix::<f64>::zeros(3 * m, 3 * m);
        for (g, row) in groups.rows.iter().enumerate() {
            for &(h, b) in row {
                let mut view = a0.fixed_view_mut::<3, 3>(3 * g, 3 * h as usize);
                view += b;
            }
        }
        out.coarsest = nalgebra::Cholesky::new(a0).map(|c| Grouped {
            of,
            members: last_members,
            solve: spd_inverse(&c.unpack()),
        });
        out
    }

    /// `z = M⁻¹·r`, with `scratch` for the coarser levels' residuals (no allocation per call).
    /// From `PARALLEL_ROWS` rows on, the vertices and the groups are split over the threads;
    /// every group's residual is summed over its children (vertices, or the level below's
    /// groups) in increasing order either way, so the result does not depend on the thread
    /// count.
    fn apply(&self, r: &[Vector3<f64>], z: &mut [Vector3<f64>], scratch: &mut Scratch) {
        let par = parallel(r.len());
        rows_mut(par, z, |k0, zs| {
            for (k, zi) in zs.iter_mut().enumerate() {
                *zi = self.fine[k0 + k] * r[k0 + k];
            }
        });
        // Every level's groups' residuals, each level's from the one below (the first's from
        // the vertices'): a group's children summed in increasing order.
        let members = self
            .levels
            .iter()
            .map(|l| l.members)
            .chain(self.coarsest.as_ref().map(|c| c.members));
        scratch.gathered.resize_with(
            self.levels.len() + usize::from(self.coarsest.is_some()),
            Vec::new,
        );
        for (l, mem) in members.enumerate() {
            let (below, this) = scratch.gathered.split_at_mut(l);
            let src: &[Vector3<f64>] = if l == 0 { r } else { &below[l - 1] };
            let dst = &mut this[0];
            dst.clear();
            dst.resize(mem.starts.len() - 1, Vector3::zeros());
            rows_mut(par, dst, |g0, ds| {
                for (k, d) in ds.iter_mut().enumerate() {
                    let mut acc = Vector3::zeros();
                    for &c in mem.of_group(g0 + k) {
                        acc += src[c as usize];
                    }
                    *d = acc;
                }
            });
        }
        scratch.levels.resize_with(self.levels.len(), Vec::new);
        for ((level, rl), gathered) in self
            .levels
            .iter()
            .zip(&mut scratch.levels)
            .zip(&scratch.gathered)
        {
            let (of, inv) = (level.of, &level.solve);
            rl.clear();
            rl.resize(inv.len(), Vector3::zeros());
            rows_mut(par, rl, |g0, rs| {
                for (k, v) in rs.iter_mut().enumerate() {
                    *v = inv[g0 + k] * gathered[g0 + k];
                }
            });
            let rl = &*rl;
            rows_mut(par, z, |k0, zs| {
                for (k, zi) in zs.iter_mut().enumerate() {
                    *zi += rl[of[k0 + k] as usize];
                }
            });
        }
        if let Some(Grouped { of, solve: inv, .. }) = &self.coarsest {
            let gathered = scratch.gathered.last().expect("gathered above");
            let r0 = &mut scratch.coarsest;
            r0.resize(inv.nrows(), 0.0);
            dense_apply(inv, flat_vectors(gathered), r0);
            let r0 = &*r0;
            rows_mut(par, z, |k0, zs| {
                for (k, zi) in zs.iter_mut().enumerate() {
                    let g = 3 * of[k0 + k] as usize;
                    *zi += Vector3::new(r0[g], r0[g + 1], r0[g + 2]);
                }
            });
        }
    }
}

/// Work space for [`Preconditioner::apply`].
#[derive(Default)]
struct Scratch {
    /// Every level's groups' residuals.
    gathered: Vec<Vec<Vector3<f64>>>,
    /// Every intermediate level's corrections.
    levels: Vec<Vec<Vector3<f64>>>,
    coarsest: Vec<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgSummary {
    pub iterations: usize,
    /// `|b − A·x| / |b|` at the end.
    pub relative_residual: f64,
    /// The model decrease of the iterate returned, `2·bᵀx − xᵀA·x` (`Σ α_k·r_kᵀz_k` over the
    /// iterations).
    pub decrease: f64,
    /// Stopped by [`CgStop::unpromising_below`]: the decrease settled below it, so the step
    /// is not worth taking (its iterate is not the solution to `tolerance`).
    pub unpromising: bool,
}

/// When the conjugate gradients stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CgStop {
    /// The relative residual `|b − A·x| / |b|` to reach.
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Stop early, with [`CgSummary::unpromising`], once the iterate's model decrease has
    /// settled below half of this (see [`cg_loop`]): the Gauss–Newton step that only asks
    /// whether the solve has converged (a step promising less than this is not taken) learns
    /// it after a few iterations instead of a full solve. `None`: solve to `tolerance`.
    pub unpromising_below: Option<f64>,
}

impl CgStop {
    /// To the relative residual `tolerance`, at most `max_iterations`.
    pub(crate) fn residual(tolerance: f64, max_iterations: usize) -> Self {
        CgStop {
            tolerance,
            max_iterations,
            unpromising_below: None,
        }
    }
}

/// Nash and Sofer's test of a settled model decrease (as Ceres Solver's conjugate gradients use
/// it): iteration `k`'s own decrease, times `k`, at most this share of the decrease so far.
const SETTLED: f64 = 0.1;

/// Whether vectors of `n` rows are worth splitting over the threads (see `PARALLEL_ROWS`).
fn parallel(n: usize) -> bool {
    n >= PARALLEL_ROWS && rayon::current_num_threads() > 1
}

/// Rows summed together in a parallel dot product: fixed, so that the sum's order (rows in
/// order within a run, runs in order) does not depend on the thread count. Short, so that the
/// GPU (one thread per run) sums even a short vector in many pieces.
pub(crate) const DOT_RUN: usize = 64;

/// `aᵀb`: in runs of `DOT_RUN` rows, each summed in order, and the runs' sums added in order;
/// on one thread below `PARALLEL_ROWS` rows, on several from there on, alike.
fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let run = |(x, y): (&[Vector3<f64>], &[Vector3<f64>])| -> f64 {
        x.iter().zip(y).map(|(x, y)| x.dot(y)).sum()
    };
    if !parallel(a.len()) {
        return a.chunks(DOT_RUN).zip(b.chunks(DOT_RUN)).map(run).sum();
    }
    let runs: Vec<f64> = a
        .par_chunks(DOT_RUN)
        .zip(b.par_chunks(DOT_RUN))
        .map(run)
        .collect();
    runs.iter().sum()
}

/// Vectors as three `f64` each.
pub(crate) fn flat_vectors(v: &[Vector3<f64>]) -> &[f64] {
    const _: () = assert!(std::mem::size_of::<Vector3<f64>>() == 24);
    // SAFETY: `Vector3<f64>` is three contiguous `f64`s (nalgebra's `ArrayStorage`).
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<f64>(), v.len() * 3) }
}

/// Calls `f(first row, rows)` over `v` split into one contiguous run per thread when `par`,
/// else once over all of it (each row is written by one call either way).
fn rows_mut<T: Send>(par: bool, v: &mut [T], f: impl Fn(usize, &mut [T]) + Sync) {
    if par && !v.is_empty() {
        let chunk = v.len().div_ceil(rayon::current_num_threads());
        v.par_chunks_mut(chunk)
            .enumerate()
            .for_each(|(c, vs)| f(c * chunk, vs));
    } else {
        f(0, v);
    }
}

/// Solves `A·x = b` by conjugate gradients with the multilevel preconditioner
/// ([`Preconditioner`]), starting from zero, until the relative residual is below `tol` or after
/// `max_iter` iterations.
#[cfg(test)]
pub fn solve_pcg(
    a: &BlockSparse,
    b: &[Vector3<f64>],
    tol: f64,
    max_iter: usize,
) -> (Vec<Vector3<f64>>, CgSummary) {
    pcg(a, b, CgStop::residual(tol, max_iter), true)
}

/// [`solve_pcg`] until `stop` says.
pub(crate) fn solve_pcg_until(
    a: &BlockSparse,
    b: &[Vector3<f64>],
    stop: CgStop,
) -> (Vec<Vector3<f64>>, CgSummary) {
    pcg(a, b, stop, true)
}

/// [`solve_pcg`], with the coarser levels or with block-Jacobi alone.
fn pcg(
    a: &BlockSparse,
    b: &[Vector3<f64>],
    stop: CgStop,
    multilevel: bool,
) -> (Vec<Vector3<f64>>, CgSummary) {
    let n = a.dim();
    let mut ops = CpuCg {
        a,
        multilevel,
        pre: None,
        scratch: Scratch::default(),
        b,
        x: vec![Vector3::zeros(); n],
        r: Vec::new(),
        z: vec![Vector3::zeros(); n],
        p: Vec::new(),
        ap: vec![Vector3::zeros(); n],
    };
    let summary = match cg_loop(&mut ops, stop) {
        Ok(s) => s,
        Err(never) => match never {},
    };
    (ops.x, summary)
}

/// The vectors of the conjugate gradients, as [`CgOps`] names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CgVec {
    B,
    R,
    Z,
    P,
    Ap,
}

/// The operations of the preconditioned conjugate gradients on `A·x = b`, wherever the vectors
/// live: here on the CPU ([`solve_pcg`]) or on the GPU (`tracker::gpu`). [`cg_loop`] drives
/// them, so both paths take the same decisions in the same order; each operation is specified
/// by the CPU's arithmetic (rows in order; dot products as [`dot`] sums them).
pub(crate) trait CgOps {
    type Error;
    /// `aᵀb`, summed as [`dot`] sums it.
    fn dot(&mut self, a: CgVec, b: CgVec) -> Result<f64, Self::Error>;
    /// `x = 0`, `r = b`, `z = M⁻¹·r`, `p = z`.
    fn start(&mut self) -> Result<(), Self::Error>;
    /// `ap = A·p`.
    fn mul_p(&mut self) -> Result<(), Self::Error>;
    /// `x += p·α`, `r −= ap·α`.
    fn step(&mut self, alpha: f64) -> Result<(), Self::Error>;
    /// `z = M⁻¹·r`.
    fn precondition(&mut self) -> Result<(), Self::Error>;
    /// `p = z + p·β`.
    fn update_p(&mut self, beta: f64) -> Result<(), Self::Error>;
}

/// Conjugate gradients from zero until the relative residual is below `stop.tolerance` or after
/// `stop.max_iterations` iterations (the solution is left in the operations' `x`); with
/// `stop.unpromising_below = Some(u)`, also as soon as the model decrease `D_k = Σ α_j·r_jᵀz_j`
/// (which only grows) is at most `u/2` and has settled: `k·α_k·r_kᵀz_k ≤ SETTLED·D_k`. The
/// decrease then ends near `D_k`, below `u`, and the step is not worth solving for; every
/// operation up to that point is the same as without it, so a solve that does not stop early
/// gives the same bits.
pub(crate) fn cg_loop<O: CgOps>(ops: &mut O, stop: CgStop) -> Result<CgSummary, O::Error> {
    let (tol, max_iter) = (stop.tolerance, stop.max_iterations);
    let bnorm = ops.dot(CgVec::B, CgVec::B)?.sqrt();
    if bnorm == 0.0 {
        return Ok(CgSummary {
            iterations: 0,
            relative_residual: 0.0,
            decrease: 0.0,
            unpromising: stop.unpromising_below.is_some(),
        });
    }
    ops.start()?;
    let mut rz = ops.dot(CgVec::R, CgVec::Z)?;
    let mut it = 0;
    let mut rnorm = bnorm;
    let mut decrease = 0.0;
    let mut unpromising = false;
    while it < max_iter {
        ops.mul_p()?;
        let pap = ops.dot(CgVec::P, CgVec::Ap)?;
        if pap.is_nan() || pap <= 0.0 {
            break;
        }
        let alpha = rz / pap;
        ops.step(alpha)?;
        it += 1;
        let own = alpha * rz;
        decrease += own;
        rnorm = ops.dot(CgVec::R, CgVec::R)?.sqrt();
        if rnorm <= tol * bnorm {
            break;
        }
        if let Some(u) = stop.unpromising_below {
            if decrease <= 0.5 * u && it as f64 * own <= SETTLED * decrease {
                unpromising = true;
                break;
            }
        }
        ops.precondition()?;
        let rz_new = ops.dot(CgVec::R, CgVec::Z)?;
        let beta = rz_new / rz;
        rz = rz_new;
        ops.update_p(beta)?;
    }
    Ok(CgSummary {
        iterations: it,
        relative_residual: rnorm / bnorm,
        decrease,
        unpromising,
    })
}

/// [`CgOps`] on the CPU.
struct CpuCg<'a> {
    a: &'a BlockSparse,
    multilevel: bool,
    pre: Option<Preconditioner<'a>>,
    scratch: Scratch,
    b: &'a [Vector3<f64>],
    x: Vec<Vector3<f64>>,
    r: Vec<Vector3<f64>>,
    z: Vec<Vector3<f64>>,
    p: Vec<Vector3<f64>>,
    ap: Vec<Vector3<f64>>,
}

impl CpuCg<'_> {
    fn vec(&self, v: CgVec) -> &[Vector3<f64>] {
        match v {
            CgVec::B => self.b,
            CgVec::R => &self.r,
            CgVec::Z => &self.z,
            CgVec::P => &self.p,
            CgVec::Ap => &self.ap,
        }
    }
}

impl CgOps for CpuCg<'_> {
    type Error = std::convert::Infallible;

    fn dot(&mut self, a: CgVec, b: CgVec) -> Result<f64, Self::Error> {
        Ok(dot(self.vec(a), self.vec(b)))
    }

    fn start(&mut self) -> Result<(), Self::Error> {
        let pre = Preconditioner::new(self.a, self.multilevel);
        self.r = self.b.to_vec();
        pre.apply(&self.r, &mut self.z, &mut self.scratch);
        self.pre = Some(pre);
        self.p = self.z.clone();
        Ok(())
    }

    fn mul_p(&mut self) -> Result<(), Self::Error> {
        self.a.mul(&self.p, &mut self.ap);
        Ok(())
    }

    fn step(&mut self, alpha: f64) -> Result<(), Self::Error> {
        let par = parallel(self.x.len());
        let (p, ap) = (&self.p, &self.ap);
        rows_mut(par, &mut self.x, |k0, xs| {
            for (k, xi) in xs.iter_mut().enumerate() {
                *xi += p[k0 + k] * alpha;
            }
        });
        rows_mut(par, &mut self.r, |k0, rs| {
            for (k, ri) in rs.iter_mut().enumerate() {
                *ri -= ap[k0 + k] * alpha;
            }
        });
        Ok(())
    }

    fn precondition(&mut self) -> Result<(), Self::Error> {
        if let Some(pre) = &self.pre {
            pre.apply(&self.r, &mut self.z, &mut self.scratch);
        }
        Ok(())
    }

    fn update_p(&mut self, beta: f64) -> Result<(), Self::Error> {
        let z = &self.z;
        rows_mut(parallel(z.len()), &mut self.p, |k0, ps| {
            for (k, pi) in ps.iter_mut().enumerate() {
                *pi = z[k0 + k] + *pi * beta;
            }
        });
        Ok(())
    }
}

/// `(L·Lᵀ)⁻¹` from a Cholesky factor `L`: `W = L⁻¹` by forward substitution, then `Wᵀ·W`'s
/// lower triangle, mirrored (so exactly symmetric). About `m³/3` multiply-adds, a third of
/// solving for the identity's columns (nalgebra's `Cholesky::inverse`), and written by hand for
/// that: it runs once per linear solve.
fn spd_inverse(l: &nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    let m = l.nrows();
    let mut w = nalgebra::DMatrix::<f64>::zeros(m, m);
    for j in 0..m {
        w[(j, j)] = 1.0 / l[(j, j)];
        for i in j + 1..m {
            let mut s = 0.0;
            for k in j..i {
                s += l[(i, k)] * w[(k, j)];
            }
            w[(i, j)] = -s / l[(i, i)];
        }
    }
    let mut inv = nalgebra::DMatrix::<f64>::zeros(m, m);
    for j in 0..m {
        for i in j..m {
            let mut s = 0.0;
            for k in i..m {
                s += w[(k, i)] * w[(k, j)];
            }
            inv[(i, j)] = s;
            inv[(j, i)] = s;
        }
    }
    inv
}

/// `out = inv·r` for a dense square `inv`: each row summed over the columns in order, from
/// zero (the GPU's `cg_coarse` sums each row so, one row per thread).
fn dense_apply(inv: &nalgebra::DMatrix<f64>, r: &[f64], out: &mut [f64]) {
    let m = r.len();
    let a = inv.as_slice();
    for (k, o) in out.iter_mut().enumerate() {
        let mut acc = 0.0;
        for (j, rj) in r.iter().enumerate() {
            acc += a[k + j * m] * rj;
        }
        *o = acc;
    }
}

/// A system and its preconditioner flattened for the GPU path (`tracker::gpu`): what
/// [`CgOps`] reads there, in the layouts the CPU holds them (3×3 blocks column-major).
pub(crate) struct FlatSystem<'a> {
    pub n: usize,
    pub row_ptr: Vec<u32>,
    pub cols: &'a [u32],
    /// Nine per block, column-major.
    pub blocks: &'a [f64],
    /// The scalar part `s·K ⊗ I₃`, if any.
    pub scalar: Option<FlatScalar<'a>>,
    /// Block-Jacobi's inverses, nine per vertex, column-major.
    pub fine: Vec<f64>,
    /// Each intermediate level: every vertex's group, the groups' children (starts, children:
    /// vertices at the first level, the level below's groups at the others), and the groups'
    /// inverses (nine each).
    pub levels: Vec<FlatLevel<'a>>,
    /// The coarsest level and its matrix's inverse (`m × m`, column-major).
    pub coarsest: Option<(FlatLevel<'a>, Vec<f64>, usize)>,
}

/// `K`'s rows (CSR starts), columns and values, and its weight `s`, in [`FlatSystem`].
pub(crate) type FlatScalar<'a> = (Vec<u32>, &'a [u32], &'a [f64], f64);

/// One aggregation level in [`FlatSystem`].
pub(crate) struct FlatLevel<'a> {
    pub of: &'a [u32],
    pub starts: &'a [u32],
    pub vertices: &'a [u32],
    pub groups: usize,
    pub inverses: Vec<f64>,
}

fn flat_blocks(m: &[Matrix3<f64>]) -> &[f64] {
    // SAFETY: `Matrix3<f64>` is nine contiguous `f64`s (nalgebra's `ArrayStorage`, `repr(C)`).
    const _: () = assert!(std::mem::size_of::<Matrix3<f64>>() == 72);
    unsafe { std::slice::from_raw_parts(m.as_ptr().cast::<f64>(), m.len() * 9) }
}

impl BlockSparse {
    /// The system and its multilevel preconditioner (built here, on the CPU, as
    /// [`solve_pcg`] builds it) flattened for the GPU.
    pub(crate) fn flat(&self) -> FlatSystem<'_> {
        let pre = Preconditioner::new(self, true);
        let levels = pre
            .levels
            .iter()
            .map(|g| FlatLevel {
                of: g.of,
                starts: &g.members.starts,
                vertices: &g.members.vertices,
                groups: g.solve.len(),
                inverses: flat_blocks(&g.solve).to_vec(),
            })
            .collect();
        let coarsest = pre.coarsest.as_ref().map(|g| {
            let m = g.solve.nrows();
            (
                FlatLevel {
                    of: g.of,
                    starts: &g.members.starts,
                    vertices: &g.members.vertices,
                    groups: m / 3,
                    inverses: Vec::new(),
                },
                g.solve.as_slice().to_vec(),
                m,
            )
        });
        FlatSystem {
            n: self.dim(),
            row_ptr: self.row_ptr.iter().map(|&k| k as u32).collect(),
            cols: &self.cols,
            blocks: flat_blocks(&self.blocks),
            scalar: self.scalar.as_ref().map(|(k, s)| {
                (
                    k.row_ptr.iter().map(|&e| e as u32).collect(),
                    &k.cols[..],
                    &k.vals[..],
                    *s,
                )
            }),
            fine: flat_blocks(&pre.fine).to_vec(),
            levels,
            coarsest,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
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

    /// The early verdict (`CgStop::unpromising_below`): a step whose model decrease settles
    /// below the bound is known after a few iterations, and its decrease is then within the
    /// bound's half of the full solve's; a bound the step clears changes nothing, to the bit.
    #[test]
    fn an_unpromising_step_is_known_before_the_solve_ends() {
        let (w, h) = (60u32, 50u32);
        let n = (w * h) as usize;
        let edges = grid_edges(w, h);
        let mut a = BlockSparse::new(n, &edges);
        for (e, &[i, j]) in edges.iter().enumerate() {
            let k = 1.0 + 0.5 * (e as f64 * 0.37).sin();
            a.add_edge(e, [i as usize, j as usize], &(Matrix3::identity() * k));
        }
        a.damp(1e-3, 1e-4);
        let b: Vec<Vector3<f64>> = (0..n)
            .map(|i| Vector3::new((i as f64 * 0.01).sin(), (i % 13) as f64 * 0.1, 1.0))
            .collect();
        let (x, full) = solve_pcg(&a, &b, 1e-3, 200);
        assert!(
            !full.unpromising && full.relative_residual <= 1e-3,
            "{full:?}"
        );
        // The decrease the loop sums is the model's: 2·bᵀx − xᵀAx.
        let mut ax = vec![Vector3::zeros(); n];
        a.mul(&x, &mut ax);
        let model: f64 = x
            .iter()
            .zip(&b)
            .zip(&ax)
            .map(|((x, b), ax)| 2.0 * x.dot(b) - x.dot(ax))
            .sum();
        assert!(
            (model - full.decrease).abs() <= 1e-9 * model,
            "{model} against {}",
            full.decrease
        );
        // A bound of three times the decrease: stopped early, below half the bound.
        let bound = 3.0 * full.decrease;
        let (_, early) = solve_pcg_until(
            &a,
            &b,
            CgStop {
                unpromising_below: Some(bound),
                ..CgStop::residual(1e-3, 200)
            },
        );
        assert!(early.unpromising, "{early:?}");
        assert!(
            early.iterations < full.iterations / 2,
            "{} iterations against {}",
            early.iterations,
            full.iterations
        );
        assert!(
            early.decrease <= 0.5 * bound && early.decrease >= 0.9 * full.decrease,
            "{early:?} against {full:?}"
        );
        // A bound the full step clears: the same solve, to the bit.
        let (x2, cleared) = solve_pcg_until(
            &a,
            &b,
            CgStop {
                unpromising_below: Some(0.5 * full.decrease),
                ..CgStop::residual(1e-3, 200)
            },
        );
        assert_eq!(cleared, full);
        assert!(x2.iter().zip(&x).all(|(p, q)| p == q));
        // No right-hand side: nothing to gain, known at once.
        let zero = vec![Vector3::zeros(); n];
        let (_, none) = solve_pcg_until(
            &a,
            &zero,
            CgStop {
                unpromising_below: Some(1e-12),
                ..CgStop::residual(1e-3, 200)
            },
        );
        assert!(none.unpromising && none.iterations == 0);
    }

    #[test]
    fn pcg_on_a_large_mesh_solves_it_and_is_the_same_to_the_bit_on_any_thread_count() {
        // An 80×80 grid Laplacian (6 400 rows, past `PARALLEL_ROWS`: the vector updates, the
        // dot products and the multilevel preconditioner are split over the threads), with
        // damping: solved to 1e-10, and the same iterates on one, two and three threads.
        let (w, h) = (80u32, 80u32);
        let n = (w * h) as usize;
        assert!(n >= PARALLEL_ROWS);
        let edges = grid_edges(w, h);
        let mut a = BlockSparse::new(n, &edges);
        for (e, &[i, j]) in edges.iter().enumerate() {
            let k = 1.0 + 0.5 * (e as f64 * 0.37).sin();
            a.add_edge(e, [i as usize, j as usize], &(Matrix3::identity() * k));
        }
        a.damp(0.01, 0.0);
        let truth: Vec<Vector3<f64>> = (0..n)
            .map(|i| Vector3::new((i as f64 * 0.01).sin(), (i % 13) as f64, 1.0))
            .collect();
        let mut b = vec![Vector3::zeros(); n];
        a.mul(&truth, &mut b);
        let solve = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool")
                .install(|| solve_pcg(&a, &b, 1e-10, 1000))
        };
        let (x, s) = solve(1);
        assert!(s.relative_residual <= 1e-10, "{s:?}");
        let err = x
            .iter()
            .zip(&truth)
            .map(|(x, t)| (x - t).norm())
            .fold(0.0, f64::max);
        assert!(err < 1e-6, "largest error {err:e} after {s:?}");
        for threads in [2, 3] {
            let (y, t) = solve(threads);
            assert_eq!(s, t, "{threads} threads");
            assert!(x == y, "{threads} threads: another solution");
        }
    }

    /// The edges of a `w`×`h` grid of vertices (right and down neighbours).
    pub(crate) fn grid_edges(w: u32, h: u32) -> Vec<[u32; 2]> {
        let mut edges = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if x + 1 < w {
                    edges.push([i, i + 1]);
                }
                if y + 1 < h {
                    edges.push([i, i + w]);
                }
            }
        }
        edges
    }

    #[test]
    fn aggregates_are_nested_connected_groups_covering_every_vertex() {
        // Two grids side by side that share no edge, and one vertex with no edge at all.
        let mut edges = grid_edges(30, 20);
        edges.extend(grid_edges(12, 9).iter().map(|e| e.map(|v| v + 600)));
        let n = 600 + 108 + 1;
        let a = BlockSparse::new(n, &edges);
        let levels = &a.aggregates.levels;
        assert!(levels.len() >= 2, "{} levels", levels.len());
        assert!(levels.last().expect("levels").1 <= COARSE_MAX);
        let component = |v: usize| {
            if v < 600 {
                0
            } else if v < 708 {
                1
            } else {
                2
            }
        };
        let mut neighbours = vec![Vec::new(); n];
        for &[i, j] in &edges {
            neighbours[i as usize].push(j as usize);
            neighbours[j as usize].push(i as usize);
        }
        let mut previous: Option<&Vec<u32>> = None;
        for (of, count) in levels {
            assert_eq!(of.len(), n);
            // Every group is used, lies in one component and is connected.
            let mut members = vec![Vec::new(); *count];
            for (v, &g) in of.iter().enumerate() {
                members[g as usize].push(v);
            }
            for m in &members {
                assert!(!m.is_empty(), "a group with no vertex");
                assert!(m.iter().all(|&v| component(v) == component(m[0])));
                let mut seen = vec![m[0]];
                let mut stack = vec![m[0]];
                while let Some(v) = stack.pop() {
                    for &w in &neighbours[v] {
                        if of[w] == of[v] && !seen.contains(&w) {
                            seen.push(w);
                            stack.push(w);
                        }
                    }
                }
                assert_eq!(seen.len(), m.len(), "group {m:?} is not connected");
            }
            // A coarser level only merges the groups of the finer one.
            if let Some(prev) = previous {
                for v in 0..n {
                    for w in 0..n {
                        if prev[v] == prev[w] {
                            assert_eq!(of[v], of[w]);
                        }
                    }
                }
            }
            previous = Some(of);
        }
        // The same graph gives the same groups.
        let b = BlockSparse::new(n, &edges);
        assert_eq!(format!("{:?}", a.aggregates), format!("{:?}", b.aggregates));
    }

    #[test]
    fn the_product_is_the_same_to_the_bit_on_one_thread_and_on_several() {
        // Both sides of `PARALLEL_ROWS`: a small system (one thread whatever the pool) and one
        // large enough to be split across the threads, with a scalar part as the bending
        // term adds.
        for (w, h) in [(20u32, 20u32), (70, 70)] {
            let edges = grid_edges(w, h);
            let n = (w * h) as usize;
            let mut a = BlockSparse::new(n, &edges);
            for (e, &[i, j]) in edges.iter().enumerate() {
                let t = e as f64 * 0.13;
                let m = Matrix3::new(
                    1.0 + t.sin(),
                    0.2,
                    t.cos(),
                    0.2,
                    0.8,
                    0.1,
                    t.cos(),
                    0.1,
                    1.2,
                );
                a.add_edge(e, [i as usize, j as usize], &m);
            }
            let rows: Vec<Vec<(u32, f64)>> = (0..n as u32)
                .map(|i| {
                    vec![
                        (i, 1.0),
                        ((i + 1) % n as u32, -0.5),
                        ((i + 7) % n as u32, -0.5),
                    ]
                })
                .collect();
            a.add_scalar(
                &Arc::new(ScalarSparse::gram(n, rows.iter().map(|r| &r[..]))),
                0.3,
            );
            let x: Vec<Vector3<f64>> = (0..n)
                .map(|i| {
                    Vector3::new(
                        (i as f64 * 0.01).sin(),
                        (i % 7) as f64 / 3.0,
                        1.0 / (1.0 + i as f64),
                    )
                })
                .collect();
            let product = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("a thread pool");
                let mut y = vec![Vector3::zeros(); n];
                pool.install(|| a.mul(&x, &mut y));
                y
            };
            let one = product(1);
            assert_eq!(one, product(2), "{n} rows on two threads");
            assert_eq!(one, product(3), "{n} rows on three threads");
            // And it is the product: row 0 summed by hand.
            let mut row0 = Vector3::zeros();
            for (j, xj) in x.iter().enumerate() {
                row0 += a_entry(&a, 0, j) * xj;
            }
            assert!((row0 - one[0]).norm() <= 1e-12 * (1.0 + row0.norm()));
        }
    }

    /// Block `(i, j)` of `a`, its scalar part included (zero where none is stored).
    fn a_entry(a: &BlockSparse, i: usize, j: usize) -> Matrix3<f64> {
        let mut out = Matrix3::zeros();
        a.for_each_entry_of_row(i, |c, b| {
            if c == j {
                out += b;
            }
        });
        out
    }

    /// Every aggregation level's group matrix, built level by level from the one below, is
    /// `P_lᵀ·A·P_l` summed directly from `A`'s entries (to rounding), with one entry per pair of
    /// groups.
    #[test]
    fn each_levels_group_matrix_is_the_direct_sum_over_its_groups() {
        let (w, h) = (50u32, 40u32);
        let n = (w * h) as usize;
        let edges = grid_edges(w, h);
        let mut a = BlockSparse::new(n, &edges);
        for (e, &[i, j]) in edges.iter().enumerate() {
            let t = e as f64 * 0.7;
            let k = Matrix3::new(
                1.0 + t.sin().abs(),
                0.2,
                0.1,
                0.2,
                0.8,
                t.cos() * 0.3,
                0.1,
                t.cos() * 0.3,
                1.1,
            );
            a.add_edge(e, [i as usize, j as usize], &k);
        }
        let rows: Vec<Vec<(u32, f64)>> = edges
            .iter()
            .map(|&[i, j]| vec![(i, 1.0), (j, -1.0)])
            .collect();
        let k = Arc::new(ScalarSparse::gram(n, rows.iter().map(|r| &r[..])));
        a.add_scalar(&k, 0.4);
        let all = &a.aggregates.levels;
        assert!(all.len() >= 2, "{} levels", all.len());
        let members = &a.aggregates.members;
        let mut groups = GroupMatrix::of(&a, &all[0].0, &members[0], all[0].1);
        for (l, (of, count)) in all.iter().enumerate() {
            if l > 0 {
                groups = groups.coarser(&members[l], *count);
            }
            let mut direct = vec![vec![Matrix3::zeros(); *count]; *count];
            for i in 0..n {
                a.for_each_entry_of_row(i, |j, b| direct[of[i] as usize][of[j] as usize] += b);
            }
            let mut seen = 0;
            for (g, row) in groups.rows.iter().enumerate() {
                let mut hs: Vec<u32> = row.iter().map(|e| e.0).collect();
                hs.sort_unstable();
                hs.dedup();
                assert_eq!(
                    hs.len(),
                    row.len(),
                    "level {l}, group {g}: a pair held twice"
                );
                for &(h, b) in row {
                    let d = direct[g][h as usize];
                    assert!(
                        (b - d).norm() <= 1e-12 * (1.0 + d.norm()),
                        "level {l}, ({g}, {h})"
                    );
                    seen += 1;
                }
            }
            let nonzero = direct.iter().flatten().filter(|m| m.norm() > 0.0).count();
            assert!(
                seen >= nonzero,
                "level {l}: {seen} entries, {nonzero} pairs touch"
            );
        }
    }

    /// The coarsest level's inverse from its Cholesky factor is the inverse (to rounding) and
    /// exactly symmetric.
    #[test]
    fn the_inverse_from_a_cholesky_factor_is_the_inverse() {
        let m = 30;
        let b =
            nalgebra::DMatrix::<f64>::from_fn(m, m, |i, j| ((i * 7 + j * 13) % 11) as f64 - 5.0);
        let a = &b * b.transpose() + nalgebra::DMatrix::<f64>::identity(m, m) * 0.5;
        let l = nalgebra::Cholesky::new(a.clone()).expect("SPD").unpack();
        let inv = spd_inverse(&l);
        assert_eq!(inv, inv.transpose());
        let err = (&a * &inv - nalgebra::DMatrix::<f64>::identity(m, m)).amax();
        assert!(err < 1e-9, "A·A⁻¹ − I: {err:e}");
    }

    #[test]
    fn the_coarse_levels_solve_a_mesh_laplacian_in_far_fewer_iterations() {
        // Springs along a 60×60 grid's edges (a Laplacian, stiffer along x than y for each
        // vertex's own term), weak anisotropic data at every vertex, as the tracker's normal
        // equations look where the images say little.
        let (w, h) = (60u32, 60u32);
        let edges = grid_edges(w, h);
        let n = (w * h) as usize;
        let mut a = BlockSparse::new(n, &edges);
        let spring = Matrix3::new(1.0, 0.2, 0.0, 0.2, 0.8, 0.1, 0.0, 0.1, 1.2);
        for (e, &[i, j]) in edges.iter().enumerate() {
            a.add_edge(e, [i as usize, j as usize], &spring);
        }
        for i in 0..n {
            let t = i as f64 * 0.37;
            let d = Vector3::new(t.cos(), t.sin(), 0.3);
            a.add_pair(i, i, &(d * d.transpose() * 1e-3));
        }
        a.damp(1e-5, 1e-4);
        let truth: Vec<Vector3<f64>> = (0..n)
            .map(|i| Vector3::new((i as f64 * 0.01).sin(), (i % 7) as f64, 1.0))
            .collect();
        let mut b = vec![Vector3::zeros(); n];
        a.mul(&truth, &mut b);
        let (x1, s1) = pcg(&a, &b, CgStop::residual(1e-10, 5000), true);
        let (x0, s0) = pcg(&a, &b, CgStop::residual(1e-10, 5000), false);
        assert!(s1.relative_residual <= 1e-10 && s0.relative_residual <= 1e-10);
        let scale = truth.iter().map(|v| v.norm()).fold(0.0, f64::max);
        for i in 0..n {
            assert!((x1[i] - truth[i]).norm() < 1e-6 * scale, "{i}");
            assert!((x0[i] - truth[i]).norm() < 1e-6 * scale, "{i}");
        }
        assert!(
            s1.iterations * 3 < s0.iterations,
            "multilevel {} iterations, block-Jacobi {}",
            s1.iterations,
            s0.iterations
        );
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
