// The conjugate gradients' operations (`sparse::CgOps`) on the GPU: the block-sparse product,
// the dot products' runs, the vector updates and the multilevel preconditioner. Written by
// hand (the solver's inner loop, as `kernel.cu` is the evaluation's), each one row, group or
// run per thread, operation for operation the CPU's (`sparse.rs`): a 3x3 block times a vector
// as nalgebra's gemv forms it (column by column), rows and groups summed in the CPU's order,
// dot products in the CPU's runs. No atomics: runs repeat to the bit and equal the CPU's.
//
// 3x3 blocks are nine doubles, column-major (nalgebra's storage); vectors three per vertex.

// y = m * x, as nalgebra's `Matrix3 * Vector3` (gemv: the first column times x0, then each
// further column times its entry added to it).
DEV void gemv3(const double* m, double x0, double x1, double x2, double* y) {
    double y0 = m[0] * x0, y1 = m[1] * x0, y2 = m[2] * x0;
    y0 = m[3] * x1 + y0;
    y1 = m[4] * x1 + y1;
    y2 = m[5] * x1 + y2;
    y0 = m[6] * x2 + y0;
    y1 = m[7] * x2 + y1;
    y2 = m[8] * x2 + y2;
    y[0] = y0;
    y[1] = y1;
    y[2] = y2;
}

DEV int global_index(void) { return (int)(BLOCK_X * BLOCK_DIM_X + THREAD_X); }

// y = A x: every row's blocks in column order, then the scalar part s * (K row . x).
KERNEL void cg_mul(const unsigned* row_ptr, const unsigned* cols, const double* blocks,
                   const unsigned* k_ptr, const unsigned* k_cols, const double* k_vals, double s,
                   int has_scalar, const double* x, double* y, int n) {
    int i = global_index();
    if (i >= n) return;
    double a0 = 0.0, a1 = 0.0, a2 = 0.0;
    for (unsigned k = row_ptr[i]; k < row_ptr[i + 1]; k++) {
        const double* xc = x + 3 * (long)cols[k];
        double b[3];
        gemv3(blocks + 9 * (long)k, xc[0], xc[1], xc[2], b);
        a0 = a0 + b[0];
        a1 = a1 + b[1];
        a2 = a2 + b[2];
    }
    if (has_scalar) {
        double t0 = 0.0, t1 = 0.0, t2 = 0.0;
        for (unsigned e = k_ptr[i]; e < k_ptr[i + 1]; e++) {
            const double* xc = x + 3 * (long)k_cols[e];
            double v = k_vals[e];
            t0 = t0 + xc[0] * v;
            t1 = t1 + xc[1] * v;
            t2 = t2 + xc[2] * v;
        }
        a0 = a0 + t0 * s;
        a1 = a1 + t1 * s;
        a2 = a2 + t2 * s;
    }
    y[3 * i] = a0;
    y[3 * i + 1] = a1;
    y[3 * i + 2] = a2;
}

// One run of a dot product: rows [t*run, min(n, (t+1)*run)) summed in order (each row's
// x0*y0 + x1*y1 + x2*y2 as nalgebra's 3-vector dot), from -0.0 as Rust's `sum` starts.
KERNEL void cg_dot_runs(const double* a, const double* b, int n, int run, int runs, double* out) {
    int t = global_index();
    if (t >= runs) return;
    long lo = (long)t * run, hi = lo + run < n ? lo + run : n;
    double s = -0.0;
    for (long i = lo; i < hi; i++) {
        double d = a[3 * i] * b[3 * i] + a[3 * i + 1] * b[3 * i + 1];
        d = d + a[3 * i + 2] * b[3 * i + 2];
        s = s + d;
    }
    out[t] = s;
}

// x += p * alpha, r -= ap * alpha.
KERNEL void cg_step(double* x, double* r, const double* p, const double* ap, double alpha, int n3) {
    int i = global_index();
    if (i >= n3) return;
    x[i] = x[i] + p[i] * alpha;
    r[i] = r[i] - ap[i] * alpha;
}

// p = z + p * beta.
KERNEL void cg_update_p(double* p, const double* z, double beta, int n3) {
    int i = global_index();
    if (i >= n3) return;
    p[i] = z[i] + p[i] * beta;
}

// A level's groups' residuals: each group's children (vertices at the first level, the level
// below's groups at the others) summed in increasing order, from zero.
KERNEL void cg_gather(const unsigned* starts, const unsigned* children, const double* src,
                      double* dst, int groups) {
    int g = global_index();
    if (g >= groups) return;
    double a0 = 0.0, a1 = 0.0, a2 = 0.0;
    for (unsigned k = starts[g]; k < starts[g + 1]; k++) {
        const double* c = src + 3 * (long)children[k];
        a0 = a0 + c[0];
        a1 = a1 + c[1];
        a2 = a2 + c[2];
    }
    dst[3 * g] = a0;
    dst[3 * g + 1] = a1;
    dst[3 * g + 2] = a2;
}

// An intermediate level's corrections: each group's inverse times its residual.
KERNEL void cg_level(const double* inv, const double* gathered, double* rl, int groups) {
    int g = global_index();
    if (g >= groups) return;
    const double* v = gathered + 3 * (long)g;
    gemv3(inv + 9 * (long)g, v[0], v[1], v[2], rl + 3 * (long)g);
}

// The coarsest level's correction: its dense inverse times its groups' residuals, one row per
// thread, the columns summed in order from zero (`sparse::dense_apply`).
KERNEL void cg_coarse(const double* inv, int m, const double* gathered, double* r0) {
    int k = global_index();
    if (k >= m) return;
    double acc = 0.0;
    for (int j = 0; j < m; j++) acc = acc + inv[k + (long)j * m] * gathered[j];
    r0[k] = acc;
}

// z = M^-1 r: block-Jacobi, then each level's group correction in level order, then the
// coarsest's. `of` holds every level's vertex-to-group map (levels + 1 of them, the coarsest
// last), `rl` the levels' corrections at `rl_off[level]` doubles.
KERNEL void cg_precondition(const double* fine, const double* r, const unsigned* of,
                            const double* rl, const unsigned long long* rl_off, int levels,
                            int has_coarse, const double* r0, double* z, int n) {
    int i = global_index();
    if (i >= n) return;
    double zi[3];
    gemv3(fine + 9 * (long)i, r[3 * i], r[3 * i + 1], r[3 * i + 2], zi);
    for (int lv = 0; lv < levels; lv++) {
        const double* c = rl + rl_off[lv] + 3 * (long)of[(long)lv * n + i];
        zi[0] = zi[0] + c[0];
        zi[1] = zi[1] + c[1];
        zi[2] = zi[2] + c[2];
    }
    if (has_coarse) {
        const double* c = r0 + 3 * (long)of[(long)levels * n + i];
        zi[0] = zi[0] + c[0];
        zi[1] = zi[1] + c[1];
        zi[2] = zi[2] + c[2];
    }
    z[3 * i] = zi[0];
    z[3 * i + 1] = zi[1];
    z[3 * i + 2] = zi[2];
}
