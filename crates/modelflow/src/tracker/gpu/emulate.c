// `kernel.cu` compiled as plain C for the tests (one lane per warp, one patch per block, run
// one after the other): the host side of the GPU path and the kernels' arithmetic are checked
// against the CPU path on machines without a GPU (CI). Not used outside the tests.
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

void modelflow_emu_evaluate_patches(
    const double* x, const double* x0, const double* prev, const double* proj, const double* lag,
    double gap, const unsigned* tris, const unsigned* patches, const float* weights,
    const float* pixels, const float* images, const unsigned long long* img_off,
    const int* img_size, int npatches, double huber, double tukey_px, double patch_scale,
    int flags, const double* edges, double* out, unsigned long long* hist) {
    for (int b = 0; b < npatches; b++) {
        emu_block = b;
        evaluate_patches(x, x0, prev, proj, lag, gap, tris, patches, weights, pixels, images,
                         img_off, img_size, npatches, huber, tukey_px, patch_scale, flags, edges,
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
