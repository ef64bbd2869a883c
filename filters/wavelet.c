/* fogpipe stage "wavelet": B-spline wavelet decomposition of the fogmap
 * (seed 000 sec. 3.2, 4.2, 4.4).  See wavelet.h for the conventions. */
#include "wavelet.h"
#include "bspline.h"
#include "fp.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* i mod n in [0, n) for any sign of i. */
static int wrapi(long i, int n)
{
    long r = i % n;
    return (int)(r < 0 ? r + n : r);
}

/* ------------------------------------------------------------------ */
/* 1D lifting (Daubechies & Sweldens 1998; unnormalized, periodic).
 *
 * Even samples e_l = x_{2l} and odd samples o_l = x_{2l+1}, l = 0..n-1,
 * indices taken mod n.  Every "sample" is a vector of m doubles at
 * e + l * es (resp. o + l * es), so one call lifts m signals at once: a
 * row of a 2D array lifts along V with m = the row length, and a single
 * row lifts along U with m = 1, es = 2.  Each step updates e from o or o
 * from e, so the steps run in place.  Forward: e becomes the coarse
 * scaling coefficients s_l, o the details d_l.
 *
 * Synthesis with zero details is the uniform B-spline refinement of
 * degree d (the two-scale relation, seed 000 eq. 7; checked by the
 * tests), with coarse l centered over fine 2l, 2l+1 for even d and on fine
 * 2l for odd d:
 *   d = 0: x_{2l} = x_{2l+1} = s_l
 *   d = 1: x_{2l} = s_l,                     x_{2l+1} = (s_l + s_{l+1})/2
 *   d = 2: x_{2l} = (s_{l-1} + 3 s_l)/4,      x_{2l+1} = (3 s_l + s_{l+1})/4
 *   d = 3: x_{2l} = (s_{l-1} + 6 s_l + s_{l+1})/8, x_{2l+1} = (s_l + s_{l+1})/2
 * and a constant signal analyses to the same constant and zero details. */

#define LIFT_E(l) (e + (size_t)(l) * es)
#define LIFT_O(l) (o + (size_t)(l) * es)
#define LIFT_PREV(l) ((l) > 0 ? (l) - 1 : n - 1)
#define LIFT_NEXT(l) ((l) + 1 < n ? (l) + 1 : 0)

/* o_l += a * (e_l + e_{l+1})  (b = 0) or a * e_l + b * e_{l+1} */
static void lift_o(double *o, const double *e, int n, int m, size_t es, double a, double b)
{
    for (int l = 0; l < n; l++) {
        double *ol = LIFT_O(l);
        const double *e0 = LIFT_E(l), *e1 = LIFT_E(LIFT_NEXT(l));
        for (int x = 0; x < m; x++)
            ol[x] += a * e0[x] + b * e1[x];
    }
}

/* e_l += a * o_{l-1} + b * o_l */
static void lift_e(double *e, const double *o, int n, int m, size_t es, double a, double b)
{
    for (int l = 0; l < n; l++) {
        double *el = LIFT_E(l);
        const double *o0 = LIFT_O(LIFT_PREV(l)), *o1 = LIFT_O(l);
        for (int x = 0; x < m; x++)
            el[x] += a * o0[x] + b * o1[x];
    }
}

static void lift_scale(double *e, int n, int m, size_t es, double a)
{
    for (int l = 0; l < n; l++) {
        double *el = LIFT_E(l);
        for (int x = 0; x < m; x++)
            el[x] *= a;
    }
}

static void lift_forward(int d, double *e, double *o, int n, int m, size_t es)
{
    switch (d) {
    case 0:     /* Haar: d = x_{2l+1} - x_{2l}; s = x_{2l} + d/2 */
        lift_o(o, e, n, m, es, -1, 0);
        lift_e(e, o, n, m, es, 0, 0.5);
        break;
    case 1:     /* CDF (2,2): d = o - (e_l + e_{l+1})/2; s = e + (d_{l-1} + d_l)/4 */
        lift_o(o, e, n, m, es, -0.5, -0.5);
        lift_e(e, o, n, m, es, 0.25, 0.25);
        break;
    case 2:     /* CDF (3,1), Daubechies & Sweldens 1998 sec. 7 */
        lift_e(e, o, n, m, es, -1.0 / 3, 0);        /* e -= o_{l-1}/3 */
        lift_o(o, e, n, m, es, -9.0 / 8, -3.0 / 8); /* d = o - (9 e_l + 3 e_{l+1})/8 */
        lift_e(e, o, n, m, es, 0, 4.0 / 9);         /* e += 4/9 d_l */
        lift_scale(e, n, m, es, 1.5);                /* s = 3/2 e */
        break;
    default:    /* 3: CDF (4,2) */
        lift_e(e, o, n, m, es, -0.25, -0.25);       /* e -= (o_{l-1} + o_l)/4 */
        lift_o(o, e, n, m, es, -1, -1);             /* d = o - (e_l + e_{l+1}) */
        lift_e(e, o, n, m, es, 3.0 / 16, 3.0 / 16); /* e += 3/16 (d_{l-1} + d_l) */
        lift_scale(e, n, m, es, 2);                  /* s = 2 e */
        break;
    }
}

/* The forward steps undone in reverse order. */
static void lift_inverse(int d, double *e, double *o, int n, int m, size_t es)
{
    switch (d) {
    case 0:
        lift_e(e, o, n, m, es, 0, -0.5);
        lift_o(o, e, n, m, es, 1, 0);
        break;
    case 1:
        lift_e(e, o, n, m, es, -0.25, -0.25);
        lift_o(o, e, n, m, es, 0.5, 0.5);
        break;
    case 2:
        lift_scale(e, n, m, es, 2.0 / 3);
        lift_e(e, o, n, m, es, 0, -4.0 / 9);
        lift_o(o, e, n, m, es, 9.0 / 8, 3.0 / 8);
        lift_e(e, o, n, m, es, 1.0 / 3, 0);
        break;
    default:
        lift_scale(e, n, m, es, 0.5);
        lift_e(e, o, n, m, es, -3.0 / 16, -3.0 / 16);
        lift_o(o, e, n, m, es, 1, 1);
        lift_e(e, o, n, m, es, 0.25, 0.25);
        break;
    }
}

/* ------------------------------------------------------------------ */
/* 2D, Mallat's nonstandard decomposition (seed 000 sec. 3.2): one level
 * lifts every row (along U), then every column (along V), in place on an
 * nx x ny array.  Afterwards the array is interleaved:
 *     a[2j][2i] = LL_ij    a[2j][2i+1] = HL_ij (high along U)
 *     a[2j+1][2i] = LH_ij  a[2j+1][2i+1] = HH_ij */
static void forward_2d(int d, double *a, int nx, int ny)
{
    for (int y = 0; y < ny; y++)
        lift_forward(d, a + (size_t)y * nx, a + (size_t)y * nx + 1, nx / 2, 1, 2);
    lift_forward(d, a, a + nx, ny / 2, nx, 2 * (size_t)nx);
}

static void inverse_2d(int d, double *a, int nx, int ny)
{
    lift_inverse(d, a, a + nx, ny / 2, nx, 2 * (size_t)nx);
    for (int y = 0; y < ny; y++)
        lift_inverse(d, a + (size_t)y * nx, a + (size_t)y * nx + 1, nx / 2, 1, 2);
}

/* Position of band b's coefficient (i,j) in the interleaved array. */
static size_t band_index(int b, int i, int j, int nx)
{
    int di = b == FP_BAND_LH ? 0 : 1, dj = b == FP_BAND_HL ? 0 : 1;
    return (size_t)(2 * j + dj) * nx + 2 * i + di;
}

/* ------------------------------------------------------------------ */
/* Layout shared by the C and OpenCL paths. */

static void level_geometry(fp_fog_level_t *lv, int degree, int dom_w, int dom_h, int shift)
{
    double cell = (double)(1 << shift);
    lv->nx = dom_w >> shift;
    lv->ny = dom_h >> shift;
    lv->cell = cell;
    /* Even degree: centered on the cell (covers the 2x2 finer cells under
     * it); odd degree: on the fine centers of even index. */
    lv->origin_u = lv->origin_v = (degree & 1) ? 0.5 : 0.5 * cell;
}

/* Impulse responses of one synthesis step (fp_wavelet_filter_t), from the
 * lifting steps themselves. */
static int synth_filters(int d, fp_wavelet_filter_t f[2])
{
    enum { N = 16, L0 = 8 };
    for (int which = 0; which < 2; which++) {
        double e[N] = { 0 }, o[N] = { 0 }, x[2 * N];
        fp_wavelet_filter_t *t = &f[which];
        memset(t, 0, sizeof *t);
        (which ? o : e)[L0] = 1;
        lift_inverse(d, e, o, N, 1, 1);
        int lo = INT_MAX, hi = INT_MIN;
        for (int l = 0; l < N; l++) {
            x[2 * l] = e[l];
            x[2 * l + 1] = o[l];
        }
        for (int k = -2 * L0; k < 2 * (N - L0); k++)
            if (x[2 * L0 + k] != 0) {
                lo = k < lo ? k : lo;
                hi = k > hi ? k : hi;
            }
        if (lo == INT_MAX || hi - lo + 1 > FP_FILTER_MAX_TAPS || lo <= -2 * L0 + 2 ||
            hi >= 2 * (N - L0) - 2)
            return fp_error("wavelet: internal error: synthesis filter of degree %d out of range",
                            d);
        t->lo = lo;
        t->hi = hi;
        for (int k = lo; k <= hi; k++)
            t->tap[k - lo] = x[2 * L0 + k];
        for (int p = 0; p < 2; p++) {
            /* k = 2m + p with lo <= k <= hi */
            int mlo = (lo - p + 2 * L0) / 2 - L0 + ((lo - p) & 1);
            int mhi = (hi - p + 2 * L0) / 2 - L0;
            t->phase_lo[p] = mlo;
            t->phase_n[p] = mhi >= mlo ? mhi - mlo + 1 : 0;
            for (int mm = mlo; mm <= mhi; mm++)
                t->phase[p][mm - mlo] = x[2 * L0 + 2 * mm + p];
        }
    }
    return FP_OK;
}

/* Validate, choose the domain and the levels, fill the geometry and the
 * filters, allocate every coefficient array (zeroed). */
static int fogmap_setup(const float *img, int w, int h, int degree, int levels, int wrap,
                        fp_fogmap_t *out)
{
    memset(out, 0, sizeof *out);
    if (!img || w < 1 || h < 1)
        return fp_usage_error("wavelet: empty fogmap (%d x %d)", w, h);
    if (degree < 0 || degree > FP_MAX_DEGREE)
        return fp_usage_error("wavelet: degree %d out of range (0..%d)", degree, FP_MAX_DEGREE);
    if (levels < 0 || levels > FP_MAX_LEVELS)
        return fp_usage_error("--levels: %d out of range (0..%d)", levels, FP_MAX_LEVELS);
    if (wrap < FP_WRAP_ZERO || wrap > FP_WRAP_REPEAT)
        return fp_usage_error("wavelet: unknown wrap mode %d", wrap);
    int L = levels;
    long W, H, x0 = 0, y0 = 0;
    if (wrap == FP_WRAP_REPEAT) {
        /* Never padded: the fogmap is the period; 2^L must divide it. */
        while (L > 0 && ((w & ((1 << L) - 1)) || (h & ((1 << L) - 1))))
            L--;
        W = w;
        H = h;
    } else {
        /* Margin beyond the basis support (d+1)/2; for CLAMP twice that so
         * the periodic wrap never reaches the replicated edge's support. */
        long margin = wrap == FP_WRAP_ZERO ? degree + 2 : 2 * (degree + 2);
        long step = 1L << L;
        W = ((long)w + 2 * margin + step - 1) / step * step;
        H = ((long)h + 2 * margin + step - 1) / step * step;
        x0 = (W - w) / 2;
        y0 = (H - h) / 2;
    }
    if (W > INT_MAX / 4 || H > INT_MAX / 4 || (double)W * (double)H > (double)(SIZE_MAX / 16))
        return fp_error("wavelet: fogmap %d x %d too large", w, h);
    for (size_t i = 0, n = (size_t)w * h; i < n; i++)
        if (!isfinite(img[i]))
            return fp_error("wavelet: fogmap pixel (%zu, %zu) is not finite (%g)", i % (size_t)w,
                            i / (size_t)w, (double)img[i]);
    out->degree = degree;
    out->wrap = wrap;
    out->levels = L;
    out->width = w;
    out->height = h;
    out->dom_w = (int)W;
    out->dom_h = (int)H;
    out->pad_x0 = (int)x0;
    out->pad_y0 = (int)y0;
    out->num_levels = L + 1;
    if (synth_filters(degree, out->synth))
        return FP_ERR;
    for (int l = 0; l <= L; l++) {
        fp_fog_level_t *lv = &out->level[l];
        level_geometry(lv, degree, out->dom_w, out->dom_h, L - l);
        lv->coef = calloc((size_t)lv->nx * lv->ny, sizeof(float));
        if (!lv->coef)
            goto nomem;
        for (int b = 0; l > 0 && b < 3; b++) {
            fp_fog_level_t *bd = &out->band[l][b];
            level_geometry(bd, degree, out->dom_w, out->dom_h, L - l + 1);
            bd->coef = calloc((size_t)bd->nx * bd->ny, sizeof(float));
            if (!bd->coef)
                goto nomem;
        }
    }
    return FP_OK;
nomem:
    fp_fogmap_free(out);
    return fp_error("wavelet: out of memory for a %d x %d domain", (int)W, (int)H);
}

void fp_fogmap_free(fp_fogmap_t *m)
{
    if (!m)
        return;
    for (int l = 0; l <= FP_MAX_LEVELS; l++) {
        free(m->level[l].coef);
        for (int b = 0; b < 3; b++)
            free(m->band[l][b].coef);
    }
    memset(m, 0, sizeof *m);
}

/* Pixel (X,Y) of the padded domain. */
static double padded_pixel(const float *img, const fp_fogmap_t *m, int X, int Y)
{
    int i = X - m->pad_x0, j = Y - m->pad_y0;
    if (m->wrap == FP_WRAP_ZERO) {
        if (i < 0 || j < 0 || i >= m->width || j >= m->height)
            return 0;
    } else {
        i = i < 0 ? 0 : i >= m->width ? m->width - 1 : i;
        j = j < 0 ? 0 : j >= m->height ? m->height - 1 : j;
    }
    return img[(size_t)j * m->width + i];
}

static void store_float(fp_fog_level_t *lv, const double *src, size_t stride, int step,
                        int di, int dj)
{
    float amax = 0;
    for (int j = 0; j < lv->ny; j++)
        for (int i = 0; i < lv->nx; i++) {
            float v = (float)src[(size_t)(step * j + dj) * stride + step * i + di];
            lv->coef[(size_t)j * lv->nx + i] = v;
            amax = fabsf(v) > amax ? fabsf(v) : amax;
        }
    lv->amax = amax;
}

int fp_wavelet_decompose(const float *img, int w, int h, int degree, int levels, int wrap,
                         fp_fogmap_t *out)
{
    int rc = fogmap_setup(img, w, h, degree, levels, wrap, out);
    if (rc)
        return rc;
    int W = out->dom_w, H = out->dom_h, L = out->levels;
    double *a = malloc((size_t)W * H * sizeof *a);
    double *ll = malloc(((size_t)W * H / 4 + 1) * sizeof *ll);
    rc = FP_ERR;
    if (!a || !ll) {
        fp_error("wavelet: out of memory for a %d x %d domain", W, H);
        goto done;
    }
    for (int Y = 0; Y < H; Y++)
        for (int X = 0; X < W; X++)
            a[(size_t)Y * W + X] = padded_pixel(img, out, X, Y);
    int nx = W, ny = H;
    for (int k = 1; k <= L; k++) {
        int l = L - k + 1, cx = nx / 2, cy = ny / 2;
        forward_2d(degree, a, nx, ny);
        for (int j = 0; j < cy; j++)
            for (int i = 0; i < cx; i++) {
                size_t at = (size_t)2 * j * nx + 2 * i;
                ll[(size_t)j * cx + i] = a[at];
                a[at] = 0;
            }
        for (int b = 0; b < 3; b++)
            store_float(&out->band[l][b], a, (size_t)nx, 2, b == FP_BAND_LH ? 0 : 1,
                        b == FP_BAND_HL ? 0 : 1);
        /* Seed 000 sec. 4.4: deconstruct the three detail bands into
         * scaling coefficients of the finer level (inverse step, LL = 0). */
        inverse_2d(degree, a, nx, ny);
        store_float(&out->level[l], a, (size_t)nx, 1, 0, 0);
        memcpy(a, ll, (size_t)cx * cy * sizeof *a);
        nx = cx;
        ny = cy;
    }
    store_float(&out->level[0], a, (size_t)nx, 1, 0, 0);
    rc = FP_OK;
done:
    free(a);
    free(ll);
    if (rc)
        fp_fogmap_free(out);
    return rc;
}

int fp_wavelet_reconstruct(const fp_fogmap_t *m, float *out)
{
    int W = m->dom_w, H = m->dom_h;
    double *a = malloc((size_t)W * H * sizeof *a);
    double *b = malloc((size_t)W * H * sizeof *b);
    int rc = FP_ERR;
    if (!a || !b) {
        fp_error("wavelet: out of memory for a %d x %d domain", W, H);
        goto done;
    }
    const fp_fog_level_t *c = &m->level[0];
    for (size_t i = 0, n = (size_t)c->nx * c->ny; i < n; i++)
        a[i] = c->coef[i];
    for (int l = 1; l <= m->levels; l++) {
        int cx = m->band[l][0].nx, cy = m->band[l][0].ny, nx = 2 * cx;
        for (int j = 0; j < cy; j++)
            for (int i = 0; i < cx; i++) {
                b[(size_t)2 * j * nx + 2 * i] = a[(size_t)j * cx + i];
                for (int bd = 0; bd < 3; bd++)
                    b[band_index(bd, i, j, nx)] = m->band[l][bd].coef[(size_t)j * cx + i];
            }
        inverse_2d(m->degree, b, nx, 2 * cy);
        double *t = a;
        a = b;
        b = t;
    }
    for (int j = 0; j < m->height; j++)
        for (int i = 0; i < m->width; i++)
            out[(size_t)j * m->width + i] =
                (float)a[(size_t)(j + m->pad_y0) * W + i + m->pad_x0];
    rc = FP_OK;
done:
    free(a);
    free(b);
    return rc;
}

/* ------------------------------------------------------------------ */
/* Evaluation. */

static double surface_eval(const fp_fog_level_t *s, int d, double U, double V)
{
    double wx[4], wy[4], sx, sy;
    int kx, ky, f = FP_BSPLINE_FIRST(d);
    fp_bspline_cell(d, (U - s->origin_u) / s->cell, &kx, &sx);
    fp_bspline_cell(d, (V - s->origin_v) / s->cell, &ky, &sy);
    fp_bspline_weights(d, sx, wx);
    fp_bspline_weights(d, sy, wy);
    double sum = 0;
    for (int jj = 0; jj <= d; jj++) {
        const float *row = s->coef + (size_t)wrapi((long)ky - f + jj, s->ny) * s->nx;
        double r = 0;
        for (int j = 0; j <= d; j++)
            r += wx[j] * row[wrapi((long)kx - f + j, s->nx)];
        sum += wy[jj] * r;
    }
    return sum;
}

double fp_fogmap_eval_level(const fp_fogmap_t *m, int l, double U, double V)
{
    if (l < 0 || l >= m->num_levels)
        return 0;
    return surface_eval(&m->level[l], m->degree, U, V);
}

double fp_fogmap_eval(const fp_fogmap_t *m, double U, double V, int max_level)
{
    double sum = 0;
    for (int l = 0; l <= max_level && l < m->num_levels; l++)
        sum += surface_eval(&m->level[l], m->degree, U, V);
    return sum;
}

/* phi_i(x) and psi_i(x) of a coarse grid (cell, origin) for the i that
 * reach x: i = *i0 + n, n < return value; expanded into the finer grid's
 * B-splines with the synthesis filters. */
enum { FN_MAX = 32 };
static int coarse_functions(const fp_fogmap_t *m, const fp_fog_level_t *g, double x, int *i0,
                            double phi[FN_MAX], double psi[FN_MAX])
{
    int d = m->degree;
    double fcell = 0.5 * g->cell, forigin = (d & 1) ? 0.5 : 0.5 * fcell;
    double xf = (x - forigin) / fcell, r = 0.5 * (d + 1);
    int lo = m->synth[0].lo < m->synth[1].lo ? m->synth[0].lo : m->synth[1].lo;
    int hi = m->synth[0].hi > m->synth[1].hi ? m->synth[0].hi : m->synth[1].hi;
    int a = (int)floor((xf - hi - r) / 2) - 1, b = (int)ceil((xf - lo + r) / 2) + 1;
    int n = b - a + 1 < FN_MAX ? b - a + 1 : FN_MAX;
    *i0 = a;
    for (int t = 0; t < n; t++) {
        phi[t] = psi[t] = 0;
        for (int which = 0; which < 2; which++) {
            const fp_wavelet_filter_t *f = &m->synth[which];
            double v = 0;
            for (int k = f->lo; k <= f->hi; k++)
                v += f->tap[k - f->lo] * fp_bspline(d, xf - (2.0 * (a + t) + k));
            (which ? psi : phi)[t] = v;
        }
    }
    return n;
}

double fp_fogmap_eval_bands(const fp_fogmap_t *m, double U, double V, int max_level)
{
    double sum = m->num_levels > 0 ? surface_eval(&m->level[0], m->degree, U, V) : 0;
    for (int l = 1; l <= max_level && l < m->num_levels; l++) {
        const fp_fog_level_t *g = &m->band[l][0];
        double pu[FN_MAX], qu[FN_MAX], pv[FN_MAX], qv[FN_MAX];
        int iu, iv;
        int nu = coarse_functions(m, g, U, &iu, pu, qu);
        int nv = coarse_functions(m, g, V, &iv, pv, qv);
        for (int t = 0; t < nv; t++) {
            size_t row = (size_t)wrapi((long)iv + t, g->ny) * g->nx;
            for (int s = 0; s < nu; s++) {
                size_t at = row + wrapi((long)iu + s, g->nx);
                sum += m->band[l][FP_BAND_LH].coef[at] * pu[s] * qv[t] +
                       m->band[l][FP_BAND_HL].coef[at] * qu[s] * pv[t] +
                       m->band[l][FP_BAND_HH].coef[at] * qu[s] * qv[t];
            }
        }
    }
    return sum;
}

double fp_fogmap_eval_direct(const float *img, int w, int h, int degree, int wrap, double u,
                             double v)
{
    double r = 0.5 * (degree + 1), sum = 0;
    long i0 = (long)floor(u - 0.5 - r), i1 = (long)ceil(u - 0.5 + r);
    long j0 = (long)floor(v - 0.5 - r), j1 = (long)ceil(v - 0.5 + r);
    for (long j = j0; j <= j1; j++) {
        double by = fp_bspline(degree, v - j - 0.5);
        long jj = j;
        if (by == 0)
            continue;
        if (wrap == FP_WRAP_REPEAT)
            jj = wrapi(j, h);
        else if (wrap == FP_WRAP_CLAMP)
            jj = j < 0 ? 0 : j >= h ? h - 1 : j;
        else if (j < 0 || j >= h)
            continue;
        for (long i = i0; i <= i1; i++) {
            double bx = fp_bspline(degree, u - i - 0.5);
            long ii = i;
            if (bx == 0)
                continue;
            if (wrap == FP_WRAP_REPEAT)
                ii = wrapi(i, w);
            else if (wrap == FP_WRAP_CLAMP)
                ii = i < 0 ? 0 : i >= w ? w - 1 : i;
            else if (i < 0 || i >= w)
                continue;
            sum += img[(size_t)jj * w + ii] * bx * by;
        }
    }
    return sum;
}

/* ------------------------------------------------------------------ */
/* OpenCL: kernels/wavelet.cl.  The lifting runs out of place (every work
 * item recomputes the few intermediate lifting values it needs), one
 * kernel per direction per level; the deconstruction runs the inverse
 * kernels with LL = 0.  Buffers are reused across levels; the in-order
 * queue orders the non-blocking reads before later kernels overwrite. */

enum { K_PAD, K_FWD_ROWS, K_FWD_COLS, K_INV_COLS, K_INV_ROWS, K_COUNT };
static const char *const kernel_names[K_COUNT] = {
    "wavelet_pad", "wavelet_forward_rows", "wavelet_forward_cols", "wavelet_inverse_cols",
    "wavelet_inverse_rows",
};

static int enqueue_2d(fp_cl_t *cl, cl_kernel k, const char *name, int gx, int gy)
{
    size_t local[2] = { 16, 8 };
    size_t global[2] = { fp_cl_round_up((size_t)gx, local[0]),
                         fp_cl_round_up((size_t)gy, local[1]) };
    return fp_cl_check(clEnqueueNDRangeKernel(fp_cl_queue(cl), k, 2, NULL, global, local, 0, NULL,
                                              NULL), name);
}

static int read_level(fp_cl_t *cl, cl_mem buf, fp_fog_level_t *lv, const char *what)
{
    return fp_cl_check(clEnqueueReadBuffer(fp_cl_queue(cl), buf, CL_FALSE, 0,
                                           (size_t)lv->nx * lv->ny * sizeof(float), lv->coef, 0,
                                           NULL, NULL), what);
}

int fp_wavelet_decompose_cl(fp_cl_t *cl, const float *img, int w, int h, int degree,
                            int levels, int wrap, fp_fogmap_t *out)
{
    int rc = fogmap_setup(img, w, h, degree, levels, wrap, out);
    if (rc)
        return rc;
    rc = FP_ERR;
    cl_kernel kern[K_COUNT] = { 0 };
    /* img, approximation ping-pong (2), row halves (2), bands (3), level */
    enum { B_IMG, B_A0, B_A1, B_LO, B_HI, B_LH, B_HL, B_HH, B_LEVEL, B_COUNT };
    cl_mem buf[B_COUNT] = { 0 };
    cl_program prog;
    cl_int err = CL_SUCCESS;
    cl_int W = out->dom_w, H = out->dom_h, L = out->levels, d = degree;
    size_t n = (size_t)W * H;
    size_t sizes[B_COUNT] = { (size_t)w * h, n, n / 4 + 1, n / 2 + 1, n / 2 + 1,
                              n / 4 + 1, n / 4 + 1, n / 4 + 1, n };
    if (n > (size_t)INT_MAX) {      /* the kernels index with int */
        fp_error("wavelet: %d x %d domain too large for the OpenCL path", (int)W, (int)H);
        goto done;
    }
    if (fp_cl_program(cl, "wavelet", "-cl-std=CL1.2", &prog))
        goto done;
    for (int i = 0; i < K_COUNT; i++)
        if (fp_cl_kernel(prog, kernel_names[i], &kern[i]))
            goto done;
    for (int i = 0; i < B_COUNT; i++) {
        buf[i] = clCreateBuffer(fp_cl_context(cl), CL_MEM_READ_WRITE, sizes[i] * sizeof(float),
                                NULL, &err);
        if (fp_cl_check(err, "wavelet: buffer"))
            goto done;
    }
    cl_command_queue q = fp_cl_queue(cl);
    if (fp_cl_check(clEnqueueWriteBuffer(q, buf[B_IMG], CL_FALSE, 0, sizes[B_IMG] * sizeof(float),
                                         img, 0, NULL, NULL), "wavelet: upload fogmap"))
        goto done;
    cl_int cw = w, ch = h, x0 = out->pad_x0, y0 = out->pad_y0, cwrap = wrap;
    cl_kernel k = kern[K_PAD];
    if (FP_CL_ARG(k, 0, buf[B_IMG]) || FP_CL_ARG(k, 1, cw) || FP_CL_ARG(k, 2, ch) ||
        FP_CL_ARG(k, 3, buf[B_A0]) || FP_CL_ARG(k, 4, W) || FP_CL_ARG(k, 5, H) ||
        FP_CL_ARG(k, 6, x0) || FP_CL_ARG(k, 7, y0) || FP_CL_ARG(k, 8, cwrap) ||
        enqueue_2d(cl, k, "wavelet_pad", W, H))
        goto done;
    cl_int nx = W, ny = H, zero_lo = 1, keep_lo = 0;
    int cur = B_A0;
    for (int step = 1; step <= L; step++) {
        int l = L - step + 1, next = cur == B_A0 ? B_A1 : B_A0;
        cl_int cx = nx / 2, cy = ny / 2;
        /* Rows (along U): approximation -> low | high halves, cx x ny. */
        k = kern[K_FWD_ROWS];
        if (FP_CL_ARG(k, 0, buf[cur]) || FP_CL_ARG(k, 1, nx) || FP_CL_ARG(k, 2, ny) ||
            FP_CL_ARG(k, 3, buf[B_LO]) || FP_CL_ARG(k, 4, buf[B_HI]) || FP_CL_ARG(k, 5, d) ||
            enqueue_2d(cl, k, "wavelet_forward_rows", cx, ny))
            goto done;
        /* Columns (along V) of each half: LL, LH and HL, HH, cx x cy. */
        k = kern[K_FWD_COLS];
        if (FP_CL_ARG(k, 0, buf[B_LO]) || FP_CL_ARG(k, 1, cx) || FP_CL_ARG(k, 2, ny) ||
            FP_CL_ARG(k, 3, buf[next]) || FP_CL_ARG(k, 4, buf[B_LH]) || FP_CL_ARG(k, 5, d) ||
            enqueue_2d(cl, k, "wavelet_forward_cols", cx, cy))
            goto done;
        if (FP_CL_ARG(k, 0, buf[B_HI]) || FP_CL_ARG(k, 3, buf[B_HL]) ||
            FP_CL_ARG(k, 4, buf[B_HH]) || enqueue_2d(cl, k, "wavelet_forward_cols", cx, cy))
            goto done;
        if (read_level(cl, buf[B_LH], &out->band[l][FP_BAND_LH], "wavelet: read LH") ||
            read_level(cl, buf[B_HL], &out->band[l][FP_BAND_HL], "wavelet: read HL") ||
            read_level(cl, buf[B_HH], &out->band[l][FP_BAND_HH], "wavelet: read HH"))
            goto done;
        /* Seed 000 sec. 4.4, deconstruction: inverse step with LL = 0.
         * Columns back: (0, LH) -> low half, (HL, HH) -> high half. */
        k = kern[K_INV_COLS];
        if (FP_CL_ARG(k, 0, buf[B_LH]) || FP_CL_ARG(k, 1, buf[B_LH]) || FP_CL_ARG(k, 2, cx) ||
            FP_CL_ARG(k, 3, cy) || FP_CL_ARG(k, 4, zero_lo) || FP_CL_ARG(k, 5, buf[B_LO]) ||
            FP_CL_ARG(k, 6, d) || enqueue_2d(cl, k, "wavelet_inverse_cols", cx, cy))
            goto done;
        if (FP_CL_ARG(k, 0, buf[B_HL]) || FP_CL_ARG(k, 1, buf[B_HH]) ||
            FP_CL_ARG(k, 4, keep_lo) || FP_CL_ARG(k, 5, buf[B_HI]) ||
            enqueue_2d(cl, k, "wavelet_inverse_cols", cx, cy))
            goto done;
        k = kern[K_INV_ROWS];
        if (FP_CL_ARG(k, 0, buf[B_LO]) || FP_CL_ARG(k, 1, buf[B_HI]) || FP_CL_ARG(k, 2, cx) ||
            FP_CL_ARG(k, 3, ny) || FP_CL_ARG(k, 4, buf[B_LEVEL]) || FP_CL_ARG(k, 5, d) ||
            enqueue_2d(cl, k, "wavelet_inverse_rows", cx, ny))
            goto done;
        if (read_level(cl, buf[B_LEVEL], &out->level[l], "wavelet: read level"))
            goto done;
        cur = next;
        nx = cx;
        ny = cy;
    }
    if (read_level(cl, buf[cur], &out->level[0], "wavelet: read level 0") ||
        fp_cl_check(clFinish(q), "wavelet: finish"))
        goto done;
    for (int l = 0; l <= L; l++)
        for (int b = 0; b < (l ? 4 : 1); b++) {
            fp_fog_level_t *lv = b ? &out->band[l][b - 1] : &out->level[l];
            float amax = 0;
            for (size_t i = 0, m = (size_t)lv->nx * lv->ny; i < m; i++)
                amax = fabsf(lv->coef[i]) > amax ? fabsf(lv->coef[i]) : amax;
            lv->amax = amax;
        }
    rc = FP_OK;
done:
    if (rc)
        clFinish(fp_cl_queue(cl));   /* no read may still target out's arrays */
    for (int i = 0; i < B_COUNT; i++)
        if (buf[i])
            clReleaseMemObject(buf[i]);
    for (int i = 0; i < K_COUNT; i++)
        if (kern[i])
            clReleaseKernel(kern[i]);
    if (rc)
        fp_fogmap_free(out);
    return rc;
}
