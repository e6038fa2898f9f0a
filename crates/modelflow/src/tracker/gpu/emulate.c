// `kernel.cu` and `pcg.cu` compiled as plain C for the tests (one lane per warp, one patch or
// row per block, run one after the other): the host side of the GPU path and the kernels'
// arithmetic are checked against the CPU path on machines without a GPU (CI). Not used outside
// the tests.
#include <math.h>
#include <stdbool.h>

#define WARP 1
#define PATCHES_PER_BLOCK 1
#define DEV static inline
#define KERNEL static
#define LDG(p) (*(p))
static int emu_block = 0;
#define BLOCK_X emu_block
#define THREAD_X 0
#define THREAD_Y 0
#define BLOCK_DIM_X 1
#define SHARED
#define SYNCWARP()
#define LAUNCH_BOUNDS
static inline void atomicAdd(unsigned long long* a, unsigned long long v) { *a += v; }

#include "kernel.cu"
#include "pcg.cu"

void modelflow_emu_evaluate_patches(
    const double* x, const double* x0, const double* prev, const double* proj, const double* lag,
    double gap, const unsigned* tris, const unsigned* patches, const float* weights,
    const float* pixels, const float* images, const unsigned long long* img_off,
    const int* img_size, int npatches, double huber, double tukey_px, double patch_scale, double gain_range,
    int flags, const double* edges, double* out, unsigned long long* hist) {
    for (int b = 0; b < npatches; b++) {
        emu_block = b;
        evaluate_patches(x, x0, prev, proj, lag, gap, tris, patches, weights, pixels, images,
                         img_off, img_size, npatches, huber, tukey_px, patch_scale, gain_range, flags, edges,
                         out, hist);
    }
}

void modelflow_emu_sum_triangles(const double* recs, const unsigned* ranges, int ntri,
                                            int system, double* scalars, double* blocks) {
    for (int t = 0; t < ntri; t++) {
        emu_block = t;
        sum_triangles(recs, ranges, ntri, system, scalars, blocks);
    }
}

// The conjugate gradients' kernels (`pcg.cu`), one thread per block, blocks one after the other.
#define EMU_LOOP(count, call)                                                                  \
    for (int b_ = 0; b_ < (count); b_++) {                                                     \
        emu_block = b_;                                                                        \
        call;                                                                                  \
    }

void modelflow_emu_cg_mul(const unsigned* row_ptr, const unsigned* cols, const double* blocks,
                          const unsigned* k_ptr, const unsigned* k_cols, const double* k_vals,
                          double s, int has_scalar, const double* x, double* y, int n) {
    EMU_LOOP(n, cg_mul(row_ptr, cols, blocks, k_ptr, k_cols, k_vals, s, has_scalar, x, y, n))
}

void modelflow_emu_cg_dot_runs(const double* a, const double* b, int n, int run, int runs,
                               double* out) {
    EMU_LOOP(runs, cg_dot_runs(a, b, n, run, runs, out))
}

void modelflow_emu_cg_step(double* x, double* r, const double* p, const double* ap, double alpha,
                           int n3) {
    EMU_LOOP(n3, cg_step(x, r, p, ap, alpha, n3))
}

void modelflow_emu_cg_update_p(double* p, const double* z, double beta, int n3) {
    EMU_LOOP(n3, cg_update_p(p, z, beta, n3))
}

void modelflow_emu_cg_gather(const unsigned* starts, const unsigned* children, const double* src,
                             double* dst, int groups) {
    EMU_LOOP(groups, cg_gather(starts, children, src, dst, groups))
}

void modelflow_emu_cg_level(const double* inv, const double* gathered, double* rl, int groups) {
    EMU_LOOP(groups, cg_level(inv, gathered, rl, groups))
}

void modelflow_emu_cg_coarse(const double* inv, int m, const double* gathered, double* r0) {
    EMU_LOOP(m, cg_coarse(inv, m, gathered, r0))
}

void modelflow_emu_cg_precondition(const double* fine, const double* r, const unsigned* of,
                                   const double* rl, const unsigned long long* rl_off, int levels,
                                   int has_coarse, const double* r0, double* z, int n) {
    EMU_LOOP(n, cg_precondition(fine, r, of, rl, rl_off, levels, has_coarse, r0, z, n))
}
