// The photometric evaluation of `solve::Problem::triangle` on the GPU: one warp per patch
// (triangle, camera), its lanes over the patch's pixels. Written by hand: it is the product's
// inner loop (warp, Catmull-Rom sample with exact derivatives, per-patch gain fit, robust loss,
// the normal equations' 3x3 vertex-pair blocks), line by line the CPU's, so that the two agree
// to rounding. Reductions go to lane 0 in a fixed order (no atomics on floating point), so every
// run gives the same bytes.
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

DEV double reduce_sum(double v) {
#if WARP > 1
    for (int off = WARP / 2; off > 0; off >>= 1) v += __shfl_down_sync(0xffffffffu, v, off);
    return __shfl_sync(0xffffffffu, v, 0);
#else
    return v;
#endif
}

DEV unsigned reduce_sum_u(unsigned v) {
#if WARP > 1
    for (int off = WARP / 2; off > 0; off >>= 1) v += __shfl_down_sync(0xffffffffu, v, off);
    return __shfl_sync(0xffffffffu, v, 0);
#else
    return v;
#endif
}

// Lane 0 gets the sum (the others a partial one): for the sums only lane 0 writes.
DEV double reduce_to_lane0(double v) {
#if WARP > 1
    for (int off = WARP / 2; off > 0; off >>= 1) v += __shfl_down_sync(0xffffffffu, v, off);
#endif
    return v;
}

DEV void project_h(const double* P, const double* p, double* out) {
    for (int r = 0; r < 3; r++) {
        out[r] = P[4 * r] * p[0] + P[4 * r + 1] * p[1] + P[4 * r + 2] * p[2] + P[4 * r + 3];
    }
}

// 3x3 row-major inverse by cofactors; false when singular or not finite.
DEV bool inverse3(const double* a, double* o) {
    double c00 = a[4] * a[8] - a[5] * a[7];
    double c01 = a[5] * a[6] - a[3] * a[8];
    double c02 = a[3] * a[7] - a[4] * a[6];
    double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
    if (det == 0.0 || !(det == det)) return false;
    double id = 1.0 / det;
    o[0] = c00 * id;
    o[1] = (a[2] * a[7] - a[1] * a[8]) * id;
    o[2] = (a[1] * a[5] - a[2] * a[4]) * id;
    o[3] = c01 * id;
    o[4] = (a[0] * a[8] - a[2] * a[6]) * id;
    o[5] = (a[2] * a[3] - a[0] * a[5]) * id;
    o[6] = c02 * id;
    o[7] = (a[1] * a[6] - a[0] * a[7]) * id;
    o[8] = (a[0] * a[4] - a[1] * a[3]) * id;
    for (int i = 0; i < 9; i++)
        if (!isfinite(o[i])) return false;
    return true;
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

// One record of REC doubles per patch: cost (weighted, after the patch loss), pixels, weight,
// rejected, the six vertex-pair blocks (PAIRS order, row-major 3x3, weighted), the three
// vertices' gradient vectors (weighted).
KERNEL void evaluate_patches(
    const double* x, const double* x0, const double* prev, const double* proj,
    const double* lag, double gap, const unsigned* tris, const unsigned* patches,
    const float* weights, const float* pixels, const float* images, const unsigned long long* img_off,
    const int* img_size, int npatches, double huber, double tukey_px, double patch_scale,
    int flags, const double* edges, double* out, unsigned long long* hist) {
    int p = BLOCK_X * PATCHES_PER_BLOCK + THREAD_Y;
    int lane = THREAD_X;
    if (p >= npatches) return;
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
    bool moving = (flags & FLAG_MOVING) != 0 && src != cam;
    double tcur[9];
    if (moving) {
        const double* Ps = proj + 12 * src;
        double si[9], sj[9], s0[9], si_inv[9], hm[9], t[9], am[9];
        for (int k = 0; k < 3; k++) {
            double a[3], b[3], c[3], q0[3];
            for (int e = 0; e < 3; e++) q0[e] = x0[3 * (unsigned long long)vs[k] + e];
            project_h(Ps, xs[k], a);
            project_h(P, xs[k], b);
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
                    mi[3 * r + c] = Ps[4 * r + c];
                    mj[3 * r + c] = P[4 * r + c];
                }
            mul3(hm, mi, hmi);
            for (int i = 0; i < 9; i++) {
                m[i] = mj[i] - hmi[i];
                tcur[i] = t[i];
                if (!isfinite(m[i]) || !isfinite(t[i])) ok = false;
            }
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
            }
            return;
        }
    }
    const float* pix = pixels + 6 * (unsigned long long)start;
    unsigned n = end - start;
    const float* img = images + 3 * img_off[cam];
    long iw = img_size[2 * cam], ih = img_size[2 * cam + 1];

    // Pass 1: the gain fit's normal equations.
    double gm[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    double gr[3] = {0, 0, 0};
    unsigned count = 0;
    if (gain_model != GAIN_OFF) {
        for (unsigned i = lane; i < n; i += WARP) {
            const float* px = pix + 6 * i;
            double l[3] = {(double)px[0], (double)px[1], (double)px[2]};
            double hx = y[0][0] * l[0] + y[1][0] * l[1] + y[2][0] * l[2];
            double hy = y[0][1] * l[0] + y[1][1] * l[1] + y[2][1] * l[2];
            double hz = y[0][2] * l[0] + y[1][2] * l[1] + y[2][2] * l[2];
            if (!(hz > 0.0)) continue;
            double inv = 1.0 / hz;
            float s[9];
            if (!sample(img, iw, ih, hx * inv, hy * inv, cubic, s)) continue;
            double sc = 0.0, cc = 0.0;
            for (int k = 0; k < 3; k++) {
                sc += (double)(s[k] * px[3 + k]);
                cc += (double)(px[3 + k] * px[3 + k]);
            }
            for (int a = 0; a < 3; a++) {
                for (int b = 0; b < 3; b++) gm[3 * a + b] += l[a] * l[b] * cc;
                gr[a] += l[a] * sc;
            }
            count++;
        }
        for (int i = 0; i < 9; i++) gm[i] = reduce_sum(gm[i]);
        for (int i = 0; i < 3; i++) gr[i] = reduce_sum(gr[i]);
        count = reduce_sum_u(count);
    }
    float gains[3] = {1.0f, 1.0f, 1.0f};
    int fitted = FIT_NONE;
    double trace = gm[0] + gm[4] + gm[8];
    if (gain_model != GAIN_OFF && trace > 0.0) {
        bool done = false;
        if (gain_model == GAIN_LINEAR && count >= 12) {
            double inv[9];
            if (inverse3(gm, inv)) {
                double chk[9];
                mul3(inv, gm, chk);
                bool fin = true;
                for (int i = 0; i < 9; i++) fin = fin && isfinite(chk[i]);
                if (fin) {
                    bool same = true;
                    for (int r = 0; r < 3; r++) {
                        double g = inv[3 * r] * gr[0] + inv[3 * r + 1] * gr[1] + inv[3 * r + 2] * gr[2];
                        double c = g < 0.5 ? 0.5 : (g > 2.0 ? 2.0 : g);
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
            double ms = 0.0;
            for (int i = 0; i < 9; i++) ms += gm[i];
            double g = gs / ms;
            double c = g < 0.5 ? 0.5 : (g > 2.0 ? 2.0 : g);
            if (!(g == g)) c = g;  // f64::clamp passes NaN through
            gains[0] = gains[1] = gains[2] = (float)c;
            fitted = (c == g) ? FIT_CONSTANT : FIT_NONE;
        }
    }
    bool on_template = system && fitted != FIT_NONE && !moving;
    bool free_gain = system && fitted != FIT_NONE && !on_template;

    // Pass 2: residuals, loss, normal equations.
    double hub2 = huber * huber;
    double tol2 = tukey_px * tukey_px;
    double hp[6][10];
    for (int k = 0; k < 6; k++)
        for (int e = 0; e < 10; e++) hp[k][e] = 0.0;
    double gp[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
    double coupling[3][3][3];
    double gram[9];
    for (int i = 0; i < 27; i++) (&coupling[0][0][0])[i] = 0.0;
    for (int i = 0; i < 9; i++) gram[i] = 0.0;
    double pcost = 0.0, pd2 = 0.0;
    unsigned pn = 0, rejected = 0;
    for (unsigned i = lane; i < n; i += WARP) {
        const float* px = pix + 6 * i;
        double l[3] = {(double)px[0], (double)px[1], (double)px[2]};
        double hx = y[0][0] * l[0] + y[1][0] * l[1] + y[2][0] * l[2];
        double hy = y[0][1] * l[0] + y[1][1] * l[1] + y[2][1] * l[2];
        double hz = y[0][2] * l[0] + y[1][2] * l[1] + y[2][2] * l[2];
        if (!(hz > 0.0)) continue;
        double inv = 1.0 / hz;
        double u = hx * inv, v = hy * inv;
        float s[9];
        if (!sample(img, iw, ih, u, v, cubic, s)) continue;
        if (moving) {
            double c0 = tcur[0] * l[0] + tcur[1] * l[1] + tcur[2] * l[2];
            double c1 = tcur[3] * l[0] + tcur[4] * l[1] + tcur[5] * l[2];
            double c2 = tcur[6] * l[0] + tcur[7] * l[1] + tcur[8] * l[2];
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
        double rho, w;
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
            double d2 = hub2 + tol2 * g2;
            pd2 += d2;
            if (e2 >= d2) {
                rejected++;
                rho = d2 / 3.0;
                w = 0.0;
            } else {
                double t = 1.0 - e2 / d2;
                rho = d2 / 3.0 * (1.0 - t * t * t);
                w = t * t;
            }
        }
        pcost += rho;
        pn++;
        if (!system) continue;
        double gx[3] = {(double)s[3], (double)s[4], (double)s[5]};
        double gy[3] = {(double)s[6], (double)s[7], (double)s[8]};
        double aa = gx[0] * gx[0] + gx[1] * gx[1] + gx[2] * gx[2];
        double ab = gx[0] * gy[0] + gx[1] * gy[1] + gx[2] * gy[2];
        double bb = gy[0] * gy[0] + gy[1] * gy[1] + gy[2] * gy[2];
        double ra = gx[0] * r[0] + gx[1] * r[1] + gx[2] * r[2];
        double rb = gy[0] * r[0] + gy[1] * r[1] + gy[2] * r[2];
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
        double gt[10];
        gt[0] = pp[0] * da[0] + qq[0] * db[0];
        gt[1] = pp[1] * da[1] + qq[1] * db[1];
        gt[2] = pp[2] * da[2] + qq[2] * db[2];
        gt[3] = pp[0] * da[1] + qq[0] * db[1];
        gt[4] = pp[0] * da[2] + qq[0] * db[2];
        gt[5] = pp[1] * da[2] + qq[1] * db[2];
        double r3[3];
        for (int k = 0; k < 3; k++) r3[k] = ra * da[k] + rb * db[k];
        double wl[3] = {w * l[0], w * l[1], w * l[2]};
        double tt[3] = {0.0, 0.0, 0.0}, cc = 0.0;
        if (fitted != FIT_NONE) {
            double c[3] = {(double)px[3], (double)px[4], (double)px[5]};
            double xc = gx[0] * c[0] + gx[1] * c[1] + gx[2] * c[2];
            double yc = gy[0] * c[0] + gy[1] * c[1] + gy[2] * c[2];
            for (int k = 0; k < 3; k++) tt[k] = da[k] * xc + db[k] * yc;
            cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        }
        gt[6] = tt[0];
        gt[7] = tt[1];
        gt[8] = tt[2];
        gt[9] = cc;
        for (int k = 0; k < 6; k++) {
            double c = wl[pairs_i[k]] * l[pairs_j[k]];
            for (int e = 0; e < 10; e++) hp[k][e] += c * gt[e];
        }
        for (int a = 0; a < 3; a++)
            for (int k = 0; k < 3; k++) gp[a][k] += wl[a] * r3[k];
        if (free_gain) {
            double mu[3] = {(double)px[0], (double)px[1], (double)px[2]};
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) {
                    double f = wl[a] * mu[b];
                    for (int e = 0; e < 3; e++) coupling[a][b][e] += f * tt[e];
                    gram[3 * a + b] += w * cc * mu[a] * mu[b];
                }
        }
    }
    pcost = reduce_to_lane0(pcost);
    pd2 = reduce_to_lane0(pd2);
    pn = reduce_sum_u(pn);
    rejected = reduce_sum_u(rejected);
    if (system) {
        for (int k = 0; k < 6; k++)
            for (int e = 0; e < 10; e++) hp[k][e] = reduce_to_lane0(hp[k][e]);
        for (int a = 0; a < 3; a++)
            for (int k = 0; k < 3; k++) gp[a][k] = reduce_to_lane0(gp[a][k]);
        if (free_gain) {
            for (int i = 0; i < 27; i++)
                (&coupling[0][0][0])[i] = reduce_to_lane0((&coupling[0][0][0])[i]);
            for (int i = 0; i < 9; i++) gram[i] = reduce_to_lane0(gram[i]);
        }
    }
    if (lane != 0) return;
    if (on_template) {
        for (int k = 0; k < 6; k++) {
            int i = pairs_i[k], j = pairs_j[k];
            for (int e = 0; e < 3; e++) {
                coupling[i][j][e] = hp[k][6 + e];
                coupling[j][i][e] = hp[k][6 + e];
            }
            gram[3 * i + j] = hp[k][9];
            gram[3 * j + i] = hp[k][9];
        }
    }
    // `gain_schur`: the positions' curvature the fitted gains take away.
    bool have_schur = false;
    double schur[6][9];
    if (system && fitted != FIT_NONE) {
        // q[i] (3x3, row a, column j) = coupling[i][j][a]
        double left[3][9], right[3][9];
        bool ok = true;
        if (fitted == FIT_LINEAR) {
            double ginv[9];
            ok = inverse3(gram, ginv);
            if (ok) {
                for (int i = 0; i < 3; i++) {
                    double q[9];
                    for (int a = 0; a < 3; a++)
                        for (int j = 0; j < 3; j++) q[3 * a + j] = coupling[i][j][a];
                    mul3(q, ginv, left[i]);
                    for (int e = 0; e < 9; e++) right[i][e] = q[e];
                }
            }
        } else {
            double hs = 0.0;
            for (int e = 0; e < 9; e++) hs += gram[e];
            ok = hs == hs && hs > 0.0;
            if (ok) {
                for (int i = 0; i < 3; i++) {
                    for (int e = 0; e < 9; e++) {
                        left[i][e] = 0.0;
                        right[i][e] = 0.0;
                    }
                    for (int a = 0; a < 3; a++) {
                        double cs = coupling[i][0][a] + coupling[i][1][a] + coupling[i][2][a];
                        right[i][3 * a] = cs;
                        left[i][3 * a] = cs / hs;
                    }
                }
            }
        }
        if (ok) {
            have_schur = true;
            for (int k = 0; k < 6; k++) {
                const double* L = left[pairs_i[k]];
                const double* R = right[pairs_j[k]];
                // L * R^T
                for (int r = 0; r < 3; r++)
                    for (int c = 0; c < 3; c++)
                        schur[k][3 * r + c] =
                            L[3 * r] * R[3 * c] + L[3 * r + 1] * R[3 * c + 1] + L[3 * r + 2] * R[3 * c + 2];
            }
        }
    }
    // The patch's Cauchy loss (Tukey's patch scale).
    double nn = pn > 0 ? (double)pn : 1.0;
    double patch2 = tukey ? patch_scale * patch_scale : 0.0;
    double s2 = patch2 * pd2 / nn;
    double pf = 1.0;
    if (s2 > 0.0) {
        double mm = pcost / nn;
        pcost = nn * s2 * log1p(mm / s2);
        pf = 1.0 / (1.0 + mm / s2);
    }
    rec[0] = pw * pcost;
    rec[1] = (double)pn;
    rec[2] = pw * (double)pn;
    rec[3] = (double)rejected;
    double pwf = pw * pf;
    for (int k = 0; k < 6; k++) {
        const double* e = hp[k];
        double hb[9] = {e[0], e[3], e[4], e[3], e[1], e[5], e[4], e[5], e[2]};
        for (int i = 0; i < 9; i++) {
            double v = hb[i];
            if (have_schur) v -= schur[k][i];
            rec[4 + 9 * k + i] = system ? v * pwf : 0.0;
        }
    }
    for (int a = 0; a < 3; a++)
        for (int k = 0; k < 3; k++) rec[58 + 3 * a + k] = system ? gp[a][k] * pwf : 0.0;
}

// Sums each triangle's patch records in order (one thread per triangle).
KERNEL void sum_triangles(const double* recs, const unsigned* ranges, int ntri, int system,
                          double* scalars, double* blocks) {
    int t = BLOCK_X * BLOCK_DIM_X + THREAD_X;
    if (t >= ntri) return;
    unsigned a = ranges[2 * t], b = ranges[2 * t + 1];
    double s[4] = {0, 0, 0, 0};
    for (unsigned p = a; p < b; p++)
        for (int i = 0; i < 4; i++) s[i] += recs[(unsigned long long)REC * p + i];
    for (int i = 0; i < 4; i++) scalars[4 * (unsigned long long)t + i] = s[i];
    if (!system) return;
    for (int i = 0; i < REC - 4; i++) {
        double v = 0.0;
        for (unsigned p = a; p < b; p++) v += recs[(unsigned long long)REC * p + 4 + i];
        blocks[(unsigned long long)(REC - 4) * t + i] = v;
    }
}
