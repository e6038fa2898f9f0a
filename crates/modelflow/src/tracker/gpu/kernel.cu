// The photometric evaluation of `solve::Problem::triangle` on the GPU: one warp per patch
// (triangle, camera). Written by hand: it is the product's inner loop (warp, Catmull-Rom sample
// with exact derivatives, per-patch gain fit, robust loss, the normal equations' 3x3 vertex-pair
// blocks), line by line the CPU's.
//
// The sums are transposed: the warp takes the patch's pixels 32 at a time, each lane computes
// one pixel's intermediate values into shared memory, and then each lane owns a few of the
// patch's sums (the 60 entries of the six pair blocks with their gain couplings, the gradient,
// the cost...) and adds the chunk's pixels to them in pixel order. Every sum is thus formed in
// the CPU's order, operation for operation (no fused multiply-add), so the two paths agree to
// the bit but for `log1p`; each lane holds four accumulators instead of a hundred (registers,
// occupancy); and there are no atomics on floating point, so runs repeat to the bit.
//
// The same source compiles as plain C99 (`emulate.c`, WARP 1) so that the CPU tests run this
// arithmetic against the CPU path without a GPU.

#ifndef WARP
#define WARP 32
#endif
#ifndef PATCHES_PER_BLOCK
#define PATCHES_PER_BLOCK 4
#endif

#define REC 67
#define HIST_BINS 160
// Per-pixel intermediate values in shared memory (pass 2; pass 1 uses the first six).
#define NV 27
// The patch's sums: pass 1 (the gain fit) and pass 2 (at most; see out2).
#define NOUT1 10
#define NOUT2 109
#define OWN1 ((NOUT1 + WARP - 1) / WARP)
#define OWN2 ((NOUT2 + WARP - 1) / WARP)

#define FLAG_TUKEY 1
#define FLAG_CUBIC 2
#define FLAG_SYSTEM 4
#define FLAG_HIST 8
#define FLAG_MOVING 16
#define FLAG_LAG 32
#define GAIN_SHIFT 8

#define GAIN_OFF 0
#define GAIN_CONSTANT 1
#define GAIN_LINEAR 2

#define FIT_NONE 0
#define FIT_CONSTANT 1
#define FIT_LINEAR 2

DEV void project_h(const double* P, const double* p, double* out) {
    for (int r = 0; r < 3; r++) {
        out[r] = P[4 * r] * p[0] + P[4 * r + 1] * p[1] + P[4 * r + 2] * p[2] + P[4 * r + 3];
    }
}

// 3x3 row-major inverse, with nalgebra's formulas in nalgebra's order (`try_inverse`), so that
// the GPU's result is the CPU's to the bit; false only when the determinant is zero (the callers
// check finiteness, as the CPU's do).
DEV bool inverse3(const double* a, double* o) {
    double m11 = a[0], m12 = a[1], m13 = a[2];
    double m21 = a[3], m22 = a[4], m23 = a[5];
    double m31 = a[6], m32 = a[7], m33 = a[8];
    double minor_m12_m23 = m22 * m33 - m32 * m23;
    double minor_m11_m23 = m21 * m33 - m31 * m23;
    double minor_m11_m22 = m21 * m32 - m31 * m22;
    double det = m11 * minor_m12_m23 - m12 * minor_m11_m23 + m13 * minor_m11_m22;
    if (det == 0.0) return false;
    o[0] = minor_m12_m23 / det;
    o[1] = (m13 * m32 - m33 * m12) / det;
    o[2] = (m12 * m23 - m22 * m13) / det;
    o[3] = -minor_m11_m23 / det;
    o[4] = (m11 * m33 - m31 * m13) / det;
    o[5] = (m13 * m21 - m23 * m11) / det;
    o[6] = minor_m11_m22 / det;
    o[7] = (m12 * m31 - m32 * m11) / det;
    o[8] = (m11 * m22 - m21 * m12) / det;
    return true;
}

DEV bool all_finite9(const double* a) {
    for (int i = 0; i < 9; i++)
        if (!isfinite(a[i])) return false;
    return true;
}

// nalgebra's `sum()` of a 3x3 matrix: column by column.
DEV double sum9_colmajor(const double* a) {
    double s = 0.0;
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++) s += a[3 * r + c];
    return s;
}

DEV void mul3(const double* a, const double* b, double* o) {
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            o[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
}

DEV void catmull_rom(float t, float* w, float* dw) {
    float t2 = t * t;
    float t3 = t2 * t;
    w[0] = 0.5f * (-t3 + 2.0f * t2 - t);
    w[1] = 0.5f * (3.0f * t3 - 5.0f * t2 + 2.0f);
    w[2] = 0.5f * (-3.0f * t3 + 4.0f * t2 + t);
    w[3] = 0.5f * (t3 - t2);
    dw[0] = 0.5f * (-3.0f * t2 + 4.0f * t - 1.0f);
    dw[1] = 0.5f * (9.0f * t2 - 10.0f * t);
    dw[2] = 0.5f * (-9.0f * t2 + 8.0f * t + 1.0f);
    dw[3] = 0.5f * (3.0f * t2 - 2.0f * t);
}

// `RgbImage::sample_cubic` / `sample_exact`: colour and its derivatives in x and y (9 values).
DEV bool sample(const float* img, long w, long h, double u, double v, bool cubic,
                              float* out) {
    if (!(u >= 0.0 && v >= 0.0 && u <= (double)(w - 1) && v <= (double)(h - 1))) return false;
    long x0 = (long)u;
    long y0 = (long)v;
    long wm = w >= 2 ? w - 2 : 0;
    long hm = h >= 2 ? h - 2 : 0;
    if (x0 > wm) x0 = wm;
    if (y0 > hm) y0 = hm;
    if (cubic) {
        float wx[4], dwx[4], wy[4], dwy[4];
        catmull_rom((float)(u - (double)x0), wx, dwx);
        catmull_rom((float)(v - (double)y0), wy, dwy);
        float col[4][3], coldv[4][3];
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) {
                col[i][k] = 0.0f;
                coldv[i][k] = 0.0f;
            }
        for (int j = 0; j < 4; j++) {
            long y = y0 + j - 1;
            if (y < 0) y = 0;
            if (y > h - 1) y = h - 1;
            for (int i = 0; i < 4; i++) {
                long x = x0 + i - 1;
                if (x < 0) x = 0;
                if (x > w - 1) x = w - 1;
                const float* px = img + 3 * (y * w + x);
                for (int k = 0; k < 3; k++) {
                    float p = LDG(px + k);
                    col[i][k] += wy[j] * p;
                    coldv[i][k] += dwy[j] * p;
                }
            }
        }
        for (int k = 0; k < 9; k++) out[k] = 0.0f;
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) {
                out[k] += wx[i] * col[i][k];
                out[3 + k] += dwx[i] * col[i][k];
                out[6 + k] += wx[i] * coldv[i][k];
            }
        return true;
    }
    float fx = (float)(u - (double)x0);
    float fy = (float)(v - (double)y0);
    long x1 = x0 + 1 < w - 1 ? x0 + 1 : w - 1;
    long y1 = y0 + 1 < h - 1 ? y0 + 1 : h - 1;
    const float* a = img + 3 * (y0 * w + x0);
    const float* b = img + 3 * (y0 * w + x1);
    const float* c = img + 3 * (y1 * w + x0);
    const float* d = img + 3 * (y1 * w + x1);
    for (int k = 0; k < 3; k++) {
        float ak = LDG(a + k), bk = LDG(b + k), ck = LDG(c + k), dk = LDG(d + k);
        float top = ak + (bk - ak) * fx;
        float bottom = ck + (dk - ck) * fx;
        out[k] = top + (bottom - top) * fy;
        out[3 + k] = (1.0f - fy) * (bk - ak) + fy * (dk - ck);
        out[6 + k] = bottom - top;
    }
    return true;
}

// The bin of a squared residual norm: how many edges are <= e2 (NaN: 0).
DEV int hist_bin(const double* edges, double e2) {
    int lo = 0, hi = HIST_BINS - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (edges[mid] <= e2) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}


// Pass 1's sums: gm's six distinct entries (a <= b), gr, the count, each as
// (V[ia] * V[ib]) * V[ic] over the valid pixels, V = {1, l0, l1, l2, |c|^2, s.c}.
DEV void out1(int o, int* ia, int* ib, int* ic) {
    const int A[6] = {0, 0, 0, 1, 1, 2};
    const int B[6] = {0, 1, 2, 1, 2, 2};
    if (o < 6) {
        *ia = 1 + A[o];
        *ib = 1 + B[o];
        *ic = 4;
    } else if (o < 9) {
        *ia = 1 + (o - 6);
        *ib = 5;
        *ic = 0;
    } else {
        *ia = 0;
        *ib = 0;
        *ic = 0;
    }
}

// Pass 2's sums, each (V[ia] * V[ib]) * V[ic] over the valid pixels, with V = {1, rho, d2,
// rejected, wl[3], l[3], gt[10], r3[3], mu[3], w.|c|^2}: the CPU's products in its order.
//   0 cost, 1 Tukey's thresholds, 2 pixels, 3 rejected,
//   4.. 63 hp[k][e] = (wl[i] * l[j]) * gt[e]     (k: the pair (i, j))
//  64.. 72 gp[a][k] = (wl[a] * r3[k]) * 1
//  73.. 99 coupling[a][b][e] = (wl[a] * mu[b]) * t[e]   (a free gain not on the template)
// 100..108 gram[a][b] = ((w |c|^2) * mu[a]) * mu[b]
DEV void out2(int o, int* ia, int* ib, int* ic) {
    const int PI[6] = {0, 1, 2, 0, 0, 1};
    const int PJ[6] = {0, 1, 2, 1, 2, 2};
    if (o < 4) {
        *ia = o == 0 ? 1 : (o == 1 ? 2 : (o == 2 ? 0 : 3));
        *ib = 0;
        *ic = 0;
    } else if (o < 64) {
        int k = (o - 4) / 10, e = (o - 4) % 10;
        *ia = 4 + PI[k];
        *ib = 7 + PJ[k];
        *ic = 10 + e;
    } else if (o < 73) {
        *ia = 4 + (o - 64) / 3;
        *ib = 20 + (o - 64) % 3;
        *ic = 0;
    } else if (o < 100) {
        int q = o - 73;
        *ia = 4 + q / 9;
        *ib = 23 + (q / 3) % 3;
        *ic = 16 + q % 3;
    } else {
        int q = o - 100;
        *ia = 26;
        *ib = 23 + q / 3;
        *ic = 23 + q % 3;
    }
}

// The patch's warp: where its pixel with stored barycentrics l lands (u, v, 1/h_z); false when
// behind the camera.
DEV bool warp_pixel(const double* y, const double* l, double* u, double* v, double* inv) {
    double hx = y[0] * l[0] + y[3] * l[1] + y[6] * l[2];
    double hy = y[1] * l[0] + y[4] * l[1] + y[7] * l[2];
    double hz = y[2] * l[0] + y[5] * l[1] + y[8] * l[2];
    if (!(hz > 0.0)) return false;
    *inv = 1.0 / hz;
    *u = hx * *inv;
    *v = hy * *inv;
    return true;
}

// One record of REC doubles per patch: cost (weighted, after the patch loss), pixels, the
// patch's weight per pixel (or, with rejected = -1, its whole weight at once: an edge-on
// source), rejected, the six vertex-pair blocks (PAIRS order, row-major 3x3, weighted), the
// three vertices' gradient vectors (weighted).
DEV void evaluate_patch(
    const double* x, const double* x0, const double* prev, const double* proj,
    const double* lag, double gap, const unsigned* tris, const unsigned* patches,
    const float* weights, const float* pixels, const float* images, const unsigned long long* img_off,
    const int* img_size, int npatches, double huber, double tukey_px, double patch_scale, double gain_range,
    int flags, const double* edges, double* out, unsigned long long* hist) {
    SHARED double sv[PATCHES_PER_BLOCK][WARP][NV];
    SHARED int svalid[PATCHES_PER_BLOCK][WARP];
    SHARED double sout[PATCHES_PER_BLOCK][NOUT2];
    // The patch's warp, the same for every lane: y (where barycentric e_k lands, homogeneous;
    // y[k][r] at 3k + r), the derivative's matrix m (row-major, at 9) and a moving source's
    // stored-to-current barycentrics (at 18).
    SHARED double shead[PATCHES_PER_BLOCK][27];
    int p = BLOCK_X * PATCHES_PER_BLOCK + THREAD_Y;
    int lane = THREAD_X;
    if (p >= npatches) return;
    double (*V)[NV] = sv[THREAD_Y];
    int* valid = svalid[THREAD_Y];
    double* so = sout[THREAD_Y];
    double* H = shead[THREAD_Y];
    const int pairs_i[6] = {0, 1, 2, 0, 0, 1};
    const int pairs_j[6] = {0, 1, 2, 1, 2, 2};
    const bool tukey = (flags & FLAG_TUKEY) != 0;
    const bool cubic = (flags & FLAG_CUBIC) != 0;
    const bool system = (flags & FLAG_SYSTEM) != 0;
    const bool want_hist = (flags & FLAG_HIST) != 0;
    const int gain_model = (flags >> GAIN_SHIFT) & 3;
    unsigned tri = patches[4 * p];
    unsigned cams = patches[4 * p + 1];
    unsigned start = patches[4 * p + 2];
    unsigned end = patches[4 * p + 3];
    int cam = (int)(cams & 0xffffu);
    int src = (int)(cams >> 16);
    double pw = (double)weights[p];
    double* rec = out + (unsigned long long)REC * (unsigned long long)p;
    unsigned vs[3] = {tris[3 * tri], tris[3 * tri + 1], tris[3 * tri + 2]};
    double xs[3][3];
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++) xs[k][a] = x[3 * (unsigned long long)vs[k] + a];
    bool moving = (flags & FLAG_MOVING) != 0 && src != cam;
    {
        const double* P = proj + 12 * cam;
        double m[9];
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) m[3 * r + c] = P[4 * r + c];
        double y[3][3];  // y[k]: where barycentric e_k lands (homogeneous)
        double d = (flags & FLAG_LAG) ? lag[cam] : 0.0;
        if (d != 0.0) {
            double s = 1.0 + d / gap;
            for (int i = 0; i < 9; i++) m[i] *= s;
            for (int k = 0; k < 3; k++) {
                double q[3];
                for (int a = 0; a < 3; a++) {
                    double pa = xs[k][a];
                    double qa = prev[3 * (unsigned long long)vs[k] + a];
                    q[a] = pa + (pa - qa) * (d / gap);
                }
                project_h(P, q, y[k]);
            }
        } else {
            for (int k = 0; k < 3; k++) project_h(P, xs[k], y[k]);
        }
        // A moving source (`align`, the stereo term): `SourceWarp`.
        double tcur[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
        if (moving) {
            const double* Ps = proj + 12 * src;
            double si[9], sj[9], s0[9], si_inv[9], hm[9], t[9], am[9];
            // Each camera sees the triangle at its own instant (`Lag`): the source where its
            // pixels were taken, the target where it looks for them; `ai`, `aj` their scales.
            double ds = (flags & FLAG_LAG) ? lag[src] : 0.0;
            double ai = ds != 0.0 ? 1.0 + ds / gap : 1.0;
            double aj = d != 0.0 ? 1.0 + d / gap : 1.0;
            for (int k = 0; k < 3; k++) {
                double a[3], b[3], c[3], q0[3], qi[3], qj[3];
                for (int e = 0; e < 3; e++) {
                    double pa = xs[k][e];
                    double qa = (ds != 0.0 || d != 0.0) ? prev[3 * (unsigned long long)vs[k] + e] : 0.0;
                    q0[e] = x0[3 * (unsigned long long)vs[k] + e];
                    qi[e] = ds != 0.0 ? pa + (pa - qa) * (ds / gap) : pa;
                    qj[e] = d != 0.0 ? pa + (pa - qa) * (d / gap) : pa;
                }
                project_h(Ps, qi, a);
                project_h(P, qj, b);
                project_h(Ps, q0, c);
                for (int r = 0; r < 3; r++) {
                    si[3 * r + k] = a[r];
                    sj[3 * r + k] = b[r];
                    s0[3 * r + k] = c[r];
                }
            }
            bool ok = inverse3(si, si_inv);
            if (ok) {
                mul3(sj, si_inv, hm);
                mul3(si_inv, s0, t);
                mul3(hm, s0, am);
                double mi[9], mj[9], hmi[9];
                for (int r = 0; r < 3; r++)
                    for (int c = 0; c < 3; c++) {
                        mi[3 * r + c] = Ps[4 * r + c] * ai;
                        mj[3 * r + c] = P[4 * r + c] * aj;
                    }
                mul3(hm, mi, hmi);
                for (int i = 0; i < 9; i++) {
                    m[i] = mj[i] - hmi[i];
                    tcur[i] = t[i];
                }
                ok = all_finite9(m) && all_finite9(tcur);
                for (int k = 0; k < 3; k++)
                    for (int r = 0; r < 3; r++) y[k][r] = am[3 * r + k];
            }
            if (!ok) {
                // Edge-on source triangle: its pixels count at the loss's cap.
                if (lane == 0) {
                    double n = (double)(end - start);
                    double hub2 = huber * huber;
                    double cap = tukey ? hub2 / 3.0 : hub2;
                    for (int i = 0; i < REC; i++) rec[i] = 0.0;
                    rec[0] = pw * n * cap;
                    rec[1] = n;
                    rec[2] = pw * n;
                    rec[3] = -1.0;
                }
                return;
            }
        }
        if (lane == 0) {
            for (int k = 0; k < 3; k++)
                for (int r = 0; r < 3; r++) H[3 * k + r] = y[k][r];
            for (int i = 0; i < 9; i++) {
                H[9 + i] = m[i];
                H[18 + i] = tcur[i];
            }
        }
        SYNCWARP();
    }
    const float* pix = pixels + 6 * (unsigned long long)start;
    unsigned n = end - start;
    const float* img = images + 3 * img_off[cam];
    long iw = img_size[2 * cam], ih = img_size[2 * cam + 1];

    // Pass 1: the gain fit's normal equations.
    double gm[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    double gr[3] = {0, 0, 0};
    double count = 0.0;
    if (gain_model != GAIN_OFF) {
        double acc[OWN1];
        int ia[OWN1], ib[OWN1], ic[OWN1];
        for (int r = 0; r < OWN1; r++) {
            acc[r] = 0.0;
            int o = lane + WARP * r;
            out1(o < NOUT1 ? o : 0, &ia[r], &ib[r], &ic[r]);
        }
        for (unsigned base = 0; base < n; base += WARP) {
            unsigned i = base + lane;
            int ok = 0;
            if (i < n) {
                const float* px = pix + 6 * i;
                double l[3] = {(double)px[0], (double)px[1], (double)px[2]};
                double u, v, inv;
                float s[9];
                if (warp_pixel(H, l, &u, &v, &inv) && sample(img, iw, ih, u, v, cubic, s)) {
                    double sc = 0.0, cc = 0.0;
                    for (int k = 0; k < 3; k++) {
                        sc += (double)(s[k] * px[3 + k]);
                        cc += (double)(px[3 + k] * px[3 + k]);
                    }
                    V[lane][0] = 1.0;
                    V[lane][1] = l[0];
                    V[lane][2] = l[1];
                    V[lane][3] = l[2];
                    V[lane][4] = cc;
                    V[lane][5] = sc;
                    ok = 1;
                }
            }
            valid[lane] = ok;
            SYNCWARP();
            unsigned cnt = n - base < WARP ? n - base : WARP;
            for (unsigned q = 0; q < cnt; q++) {
                if (!valid[q]) continue;
                for (int r = 0; r < OWN1; r++)
                    acc[r] += (V[q][ia[r]] * V[q][ib[r]]) * V[q][ic[r]];
            }
            SYNCWARP();
        }
        for (int r = 0; r < OWN1; r++) {
            int o = lane + WARP * r;
            if (o < NOUT1) so[o] = acc[r];
        }
        SYNCWARP();
        const int A[6] = {0, 0, 0, 1, 1, 2};
        const int B[6] = {0, 1, 2, 1, 2, 2};
        for (int k = 0; k < 6; k++) {
            gm[3 * A[k] + B[k]] = so[k];
            gm[3 * B[k] + A[k]] = so[k];
        }
        for (int a = 0; a < 3; a++) gr[a] = so[6 + a];
        count = so[9];
        SYNCWARP();
    }
    float gains[3] = {1.0f, 1.0f, 1.0f};
    int fitted = FIT_NONE;
    double trace = gm[0] + gm[4] + gm[8];
    if (gain_model != GAIN_OFF && trace > 0.0) {
        // The gains are kept within [1 / gain_range, gain_range] (`SolverOptions::gain_range`).
        const double lo = 1.0 / gain_range;
        bool done = false;
        if (gain_model == GAIN_LINEAR && count >= 12.0) {
            double inv[9];
            if (inverse3(gm, inv)) {
                double chk[9];
                mul3(inv, gm, chk);
                if (all_finite9(chk)) {
                    bool same = true;
                    for (int r = 0; r < 3; r++) {
                        double g = inv[3 * r] * gr[0] + inv[3 * r + 1] * gr[1] + inv[3 * r + 2] * gr[2];
                        double c = g < lo ? lo : (g > gain_range ? gain_range : g);
                        if (!(c == g)) same = false;
                        gains[r] = (float)c;
                    }
                    fitted = same ? FIT_LINEAR : FIT_NONE;
                    done = true;
                }
            }
        }
        if (!done) {
            double gs = gr[0] + gr[1] + gr[2];
            double g = gs / sum9_colmajor(gm);
            double c = g < lo ? lo : (g > gain_range ? gain_range : g);
            gains[0] = gains[1] = gains[2] = (float)c;
            fitted = (c == g) ? FIT_CONSTANT : FIT_NONE;
        }
    }
    bool on_template = system && fitted != FIT_NONE && !moving;
    bool free_gain = system && fitted != FIT_NONE && !on_template;
    int nout = free_gain ? NOUT2 : (system ? 73 : 4);

    // Pass 2: residuals, loss, normal equations.
    double hub2 = huber * huber;
    double tol2 = tukey_px * tukey_px;
    double acc[OWN2];
    int ia[OWN2], ib[OWN2], ic[OWN2];
    for (int r = 0; r < OWN2; r++) {
        acc[r] = 0.0;
        int o = lane + WARP * r;
        out2(o < nout ? o : 0, &ia[r], &ib[r], &ic[r]);
    }
    for (unsigned base = 0; base < n; base += WARP) {
        unsigned i = base + lane;
        int ok = 0;
        if (i < n) {
            const float* px = pix + 6 * i;
            double l[3] = {(double)px[0], (double)px[1], (double)px[2]};
            double u, v, inv;
            float s[9];
            if (warp_pixel(H, l, &u, &v, &inv) && sample(img, iw, ih, u, v, cubic, s)) {
                ok = 1;
                double* W = V[lane];
                if (moving) {
                    const double* t = H + 18;
                    double c0 = t[0] * l[0] + t[1] * l[1] + t[2] * l[2];
                    double c1 = t[3] * l[0] + t[4] * l[1] + t[5] * l[2];
                    double c2 = t[6] * l[0] + t[7] * l[1] + t[8] * l[2];
                    l[0] = c0;
                    l[1] = c1;
                    l[2] = c2;
                }
                float gain = px[0] * gains[0] + px[1] * gains[1] + px[2] * gains[2];
                double r[3];
                for (int k = 0; k < 3; k++) r[k] = (double)(s[k] - gain * px[3 + k]);
                double e2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                if (want_hist) {
                    double wgt = round(pw * 1024.0);
                    if (wgt < 1.0) wgt = 1.0;
                    atomicAdd(&hist[hist_bin(edges, e2)], (unsigned long long)wgt);
                }
                double rho, w, d2 = 0.0, rej = 0.0;
                if (!tukey) {
                    if (e2 <= hub2) {
                        rho = e2;
                        w = 1.0;
                    } else {
                        double e = sqrt(e2);
                        rho = 2.0 * huber * e - hub2;
                        w = huber / e;
                    }
                } else {
                    double g2 = 0.0;
                    for (int k = 3; k < 9; k++) g2 += (double)(s[k] * s[k]);
                    d2 = hub2 + tol2 * g2;
                    if (e2 >= d2) {
                        rej = 1.0;
                        rho = d2 / 3.0;
                        w = 0.0;
                    } else {
                        double t = 1.0 - e2 / d2;
                        rho = d2 / 3.0 * (1.0 - t * t * t);
                        w = t * t;
                    }
                }
                W[0] = 1.0;
                W[1] = rho;
                W[2] = d2;
                W[3] = rej;
                if (system) {
                    double gx[3] = {(double)s[3], (double)s[4], (double)s[5]};
                    double gy[3] = {(double)s[6], (double)s[7], (double)s[8]};
                    double aa = gx[0] * gx[0] + gx[1] * gx[1] + gx[2] * gx[2];
                    double ab = gx[0] * gy[0] + gx[1] * gy[1] + gx[2] * gy[2];
                    double bb = gy[0] * gy[0] + gy[1] * gy[1] + gy[2] * gy[2];
                    double ra = gx[0] * r[0] + gx[1] * r[1] + gx[2] * r[2];
                    double rb = gy[0] * r[0] + gy[1] * r[1] + gy[2] * r[2];
                    const double* m = H + 9;
                    double da[3], db[3];
                    for (int k = 0; k < 3; k++) {
                        da[k] = (m[k] - u * m[6 + k]) * inv;
                        db[k] = (m[3 + k] - v * m[6 + k]) * inv;
                    }
                    double pp[3], qq[3];
                    for (int k = 0; k < 3; k++) {
                        pp[k] = aa * da[k] + ab * db[k];
                        qq[k] = ab * da[k] + bb * db[k];
                    }
                    double* gt = W + 10;
                    gt[0] = pp[0] * da[0] + qq[0] * db[0];
                    gt[1] = pp[1] * da[1] + qq[1] * db[1];
                    gt[2] = pp[2] * da[2] + qq[2] * db[2];
                    gt[3] = pp[0] * da[1] + qq[0] * db[1];
                    gt[4] = pp[0] * da[2] + qq[0] * db[2];
                    gt[5] = pp[1] * da[2] + qq[1] * db[2];
                    for (int k = 0; k < 3; k++) W[20 + k] = ra * da[k] + rb * db[k];
                    for (int k = 0; k < 3; k++) {
                        W[4 + k] = w * l[k];
                        W[7 + k] = l[k];
                        W[23 + k] = (double)px[k];
                    }
                    double cc = 0.0;
                    if (fitted != FIT_NONE) {
                        double c[3] = {(double)px[3], (double)px[4], (double)px[5]};
                        double xc = gx[0] * c[0] + gx[1] * c[1] + gx[2] * c[2];
                        double yc = gy[0] * c[0] + gy[1] * c[1] + gy[2] * c[2];
                        for (int k = 0; k < 3; k++) gt[6 + k] = da[k] * xc + db[k] * yc;
                        cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
                    } else {
                        gt[6] = gt[7] = gt[8] = 0.0;
                    }
                    gt[9] = cc;
                    W[26] = w * cc;
                }
            }
        }
        valid[lane] = ok;
        SYNCWARP();
        unsigned cnt = n - base < WARP ? n - base : WARP;
        for (unsigned q = 0; q < cnt; q++) {
            if (!valid[q]) continue;
            for (int r = 0; r < OWN2; r++)
                acc[r] += (V[q][ia[r]] * V[q][ib[r]]) * V[q][ic[r]];
        }
        SYNCWARP();
    }
    for (int r = 0; r < OWN2; r++) {
        int o = lane + WARP * r;
        if (o < nout) so[o] = acc[r];
    }
    SYNCWARP();
    if (lane != 0) return;
    // Lane 0 finishes the patch from the sums in shared memory (few registers: the arrays the
    // CPU names are read where they lie).
    double pcost = so[0], pd2 = so[1], pn = so[2], rejected = so[3];
    // coupling[i][j][a] and gram[i][j]: from the pair blocks' extra entries on a template (the
    // gains' basis is the pixels' own barycentrics), else from their own sums.
    const int PK[9] = {0, 3, 4, 3, 1, 5, 4, 5, 2};
#define CPL(i, j, a) (on_template ? so[4 + 10 * PK[3 * (i) + (j)] + 6 + (a)] : so[73 + 9 * (i) + 3 * (j) + (a)])
#define GRAM(i, j) (on_template ? so[4 + 10 * PK[3 * (i) + (j)] + 9] : so[100 + 3 * (i) + (j)])
    // `gain_schur`: the positions' curvature the fitted gains take away. left[i] and right[i]
    // (3x3 each, row-major) are kept in the now free pixel buffer.
    double* left = &V[0][0];
    double* right = left + 27;
    bool have_schur = false;
    if (system && fitted != FIT_NONE) {
        bool ok = true;
        if (fitted == FIT_LINEAR) {
            double gram[9], ginv[9];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) gram[3 * i + j] = GRAM(i, j);
            ok = inverse3(gram, ginv) && all_finite9(ginv);
            if (ok) {
                for (int i = 0; i < 3; i++) {
                    double q[9];
                    for (int r = 0; r < 3; r++)
                        for (int j = 0; j < 3; j++) q[3 * r + j] = CPL(i, j, r);
                    mul3(q, ginv, left + 9 * i);
                    for (int e = 0; e < 9; e++) right[9 * i + e] = q[e];
                }
            }
        } else {
            double gram[9];
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) gram[3 * i + j] = GRAM(i, j);
            double hs = sum9_colmajor(gram);
            ok = hs == hs && hs > 0.0;
            if (ok) {
                for (int i = 0; i < 3; i++) {
                    for (int e = 0; e < 9; e++) {
                        left[9 * i + e] = 0.0;
                        right[9 * i + e] = 0.0;
                    }
                    for (int r = 0; r < 3; r++) {
                        double cs = CPL(i, 0, r) + CPL(i, 1, r) + CPL(i, 2, r);
                        right[9 * i + 3 * r] = cs;
                        left[9 * i + 3 * r] = cs / hs;
                    }
                }
            }
        }
        have_schur = ok;
    }
#undef CPL
#undef GRAM
    // The patch's Cauchy loss (Tukey's patch scale).
    double nn = pn > 0.0 ? pn : 1.0;
    double patch2 = tukey ? patch_scale * patch_scale : 0.0;
    double s2 = patch2 * pd2 / nn;
    double pf = 1.0;
    if (s2 > 0.0) {
        double mm = pcost / nn;
        pcost = nn * s2 * log1p(mm / s2);
        pf = 1.0 / (1.0 + mm / s2);
    }
    rec[0] = pw * pcost;
    rec[1] = pn;
    rec[2] = pw;
    rec[3] = rejected;
    double pwf = pw * pf;
    const int HB[9] = {0, 3, 4, 3, 1, 5, 4, 5, 2};
    for (int k = 0; k < 6; k++) {
        const double* e = so + 4 + 10 * k;
        const double* L = left + 9 * pairs_i[k];
        const double* R = right + 9 * pairs_j[k];
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) {
                int i = 3 * r + c;
                if (!system) {
                    rec[4 + 9 * k + i] = 0.0;
                    continue;
                }
                double v = e[HB[i]];
                // (L * R^T)[r][c]
                if (have_schur)
                    v -= L[3 * r] * R[3 * c] + L[3 * r + 1] * R[3 * c + 1] + L[3 * r + 2] * R[3 * c + 2];
                rec[4 + 9 * k + i] = v * pwf;
            }
    }
    for (int i = 0; i < 9; i++) rec[58 + i] = system ? so[64 + i] * pwf : 0.0;
}

// The kernel, as compiled (the registers it may hold chosen by the compiler)...
KERNEL void evaluate_patches(
    const double* x, const double* x0, const double* prev, const double* proj,
    const double* lag, double gap, const unsigned* tris, const unsigned* patches,
    const float* weights, const float* pixels, const float* images, const unsigned long long* img_off,
    const int* img_size, int npatches, double huber, double tukey_px, double patch_scale, double gain_range,
    int flags, const double* edges, double* out, unsigned long long* hist) {
    evaluate_patch(x, x0, prev, proj, lag, gap, tris, patches, weights, pixels, images, img_off, img_size, npatches, huber, tukey_px, patch_scale, gain_range, flags, edges, out, hist);
}

// ...and held to 128 registers, for four blocks of four warps per SM instead of two, at the
// price of a few hundred bytes of spills (`Gpu` picks one: docs/gpu.md).
KERNEL LAUNCH_BOUNDS void evaluate_patches_bounded(
    const double* x, const double* x0, const double* prev, const double* proj,
    const double* lag, double gap, const unsigned* tris, const unsigned* patches,
    const float* weights, const float* pixels, const float* images, const unsigned long long* img_off,
    const int* img_size, int npatches, double huber, double tukey_px, double patch_scale, double gain_range,
    int flags, const double* edges, double* out, unsigned long long* hist) {
    evaluate_patch(x, x0, prev, proj, lag, gap, tris, patches, weights, pixels, images, img_off, img_size, npatches, huber, tukey_px, patch_scale, gain_range, flags, edges, out, hist);
}

// Sums each triangle's patch records in order (one thread per triangle), as the CPU's
// `TriAccum` does: the cost and the blocks per patch, the weight per pixel.
KERNEL void sum_triangles(const double* recs, const unsigned* ranges, int ntri, int system,
                          double* scalars, double* blocks) {
    int t = BLOCK_X * BLOCK_DIM_X + THREAD_X;
    if (t >= ntri) return;
    unsigned a = ranges[2 * t], b = ranges[2 * t + 1];
    double cost = 0.0, pixels = 0.0, weight = 0.0, rejected = 0.0;
    for (unsigned p = a; p < b; p++) {
        const double* r = recs + (unsigned long long)REC * p;
        cost += r[0];
        pixels += r[1];
        if (r[3] < 0.0) {
            weight += r[2];
        } else {
            for (long i = 0; i < (long)r[1]; i++) weight += r[2];
            rejected += r[3];
        }
    }
    scalars[4 * (unsigned long long)t] = cost;
    scalars[4 * (unsigned long long)t + 1] = pixels;
    scalars[4 * (unsigned long long)t + 2] = weight;
    scalars[4 * (unsigned long long)t + 3] = rejected;
    if (!system) return;
    for (int i = 0; i < REC - 4; i++) {
        double v = 0.0;
        for (unsigned p = a; p < b; p++) v += recs[(unsigned long long)REC * p + 4 + i];
        blocks[(unsigned long long)(REC - 4) * t + i] = v;
    }
}
