#include "fogmap.h"
#include "animate.h"
#include "fogmap_cache.h"
#include "fp.h"
#include "oiio_bridge.h"
#include "options.h"
#include "seq.h"
#include "textfile.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "../kernels/fog_core.h"

#define FM(f) offsetof(fp_params_t, fogmap.f)
const fp_option_t fp_fogmap_options[] = {
    { "fogmap", 0, FP_OPT_STRING, FM(fogmap), 0, 0, NULL, 0, 0, NULL, "FILE",
      "greyscale fogmap (any image OpenImageIO reads; values are data, integers map to 0..1): "
      "the fog seen from above, scaling --density", NULL, 0 },
    { "fogmap-channel", 0, FP_OPT_STRING, FM(channel), 0, 0, NULL, 0, 0, NULL, "NAME",
      "channel of the fogmap to use (default: the first)", NULL, 0 },
    { "fog-rect", 0, FP_OPT_VEC, FM(rect), 4, 4, "-50,-50,50,50", -1e9, 1e9, NULL, "A0,B0,A1,B1",
      "world rectangle the fogmap covers on the horizontal axes: X0,Z0,X1,Z1 (--up y, row 0 "
      "at Z0) or X0,Y0,X1,Y1 (--up z, row 0 at Y1)", NULL, 0 },
    { "basis", 0, FP_OPT_ENUM, FM(basis), 0, 0, "linear", 0, 0, "haar|linear|quadratic|cubic",
      NULL, "B-spline basis of the fogmap (degree 0..3; linear = bilinear between pixel "
      "centers)", NULL, 0 },
    { "fog-wrap", 0, FP_OPT_ENUM, FM(wrap), 0, 0, "zero", 0, 0, "zero|clamp|repeat", NULL,
      "the fogmap outside its rectangle: no fog, its edge extended, or tiled", NULL, 0 },
    { "levels", 0, FP_OPT_INT, FM(levels), 0, 0, "3", 0, 12, NULL, "N",
      "wavelet detail levels over the coarse approximation", NULL, 0 },
    { "lod-mu", 0, FP_OPT_REAL, FM(lod_mu), 0, 0, "1", 0, 1, NULL, "MU",
      "level of detail: level l is integrated only up to |OP| MU^l (seed 000 eq. 12; 1 = all)",
      NULL, 0 },
    { "lod-footprint", 0, FP_OPT_REAL, FM(lod_footprint), 0, 0, "0", 0, 1e4, NULL, "PX",
      "drop a detail level where its cells project below PX pixels (0 = off)", NULL, 0 },
    { "lod-bound", 0, FP_OPT_REAL, FM(lod_bound), 0, 0, "0", 0, 1, NULL, "DTAU",
      "walk a coarser sum of levels wherever the finer levels cannot change a ray's "
      "transmittance by more than DTAU in all (each cell bounds them: exactly for the linear "
      "basis, by their largest coefficients reaching it otherwise; weighted by the height "
      "profile and the transmittance so far; 0 = exact)", NULL, 0 },
    { "min-transmittance", 0, FP_OPT_REAL, FM(min_transmittance), 0, 0, "0", 0, 1, NULL, "T",
      "stop integrating a ray once its transmittance is below T (0 = never)", NULL, 0 },
    { "integrator", 0, FP_OPT_ENUM, FM(integrator), 0, 0, "exact", 0, 0,
      "exact|march|reference", NULL,
      "exact cell-by-cell integration, the uniform raymarching baseline (seed 002 sec. 4.2), "
      "or the Monte Carlo reference of the light in the fog (--spp, --seed, --bounces; slow)",
      NULL, 0 },
    { "steps", 0, FP_OPT_INT, FM(steps), 0, 0, "64", 1, 1 << 20, NULL, "N",
      "raymarching steps per ray (--integrator march)", NULL, 0 },
    { "jitter", 0, FP_OPT_FLAG, FM(jitter), 0, 0, NULL, 0, 1, NULL, NULL,
      "offset the march samples per pixel (the same pattern every frame)", NULL, 0 },
    { "sparse", 0, FP_OPT_ENUM, FM(sparse), 0, 0, "on", 0, 0, "off|on", NULL,
      "skip blocks of zero coefficients while walking each level's grid (exact; the "
      "level-by-level walk of --deconstruct off)", NULL, 0 },
    { "deconstruct", 0, FP_OPT_ENUM, FM(deconstruct), 0, 0, "on", 0, 0, "off|on", NULL,
      "turn detail bands back into one B-spline surface per level (seed 000 sec. 4.4); off "
      "expands the raw bands on the fly (slower, for comparison)", NULL, 0 },
    { "fogmap-preview", 0, FP_OPT_STRING, FM(preview), 0, 0, NULL, 0, 0, NULL, "DIR",
      "write one PNG per wavelet level and the reconstructed fogmap into DIR, then exit", NULL,
      FP_OPTF_CLI_ONLY },
    { "fogmap-cache", 0, FP_OPT_STRING, FM(cache), 0, 0, NULL, 0, 0, NULL, "DIR|off",
      "keep a big still fogmap's decomposition in DIR, keyed by its content, for later runs "
      "(default: fogmaps/ in the OpenCL program cache directory; off: never)", NULL, 0 },
    FP_OPT_END
};

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

/* Largest of 8, 4, 2, 1 dividing both sizes: occupancy blocks must tile the
 * periodic grid. */
static int block_size(int nx, int ny)
{
    int b = 8;
    while (b > 1 && (nx % b || ny % b))
        b /= 2;
    return b;
}

/* A block of cells is empty when every coefficient whose support reaches
 * it is zero: cells K use coefficients K - d/2 .. K - d/2 + d. */
static void occupancy(const fp_fog_level_t *lv, int d, int block, unsigned char *occ)
{
    int bx = lv->nx / block, by = lv->ny / block, half = d / 2;
    for (int j = 0; j < by; j++)
        for (int i = 0; i < bx; i++) {
            int any = 0;
            for (int m = j * block - half; m <= j * block + block - 1 - half + d && !any; m++)
                for (int k = i * block - half; k <= i * block + block - 1 - half + d && !any; k++) {
                    int kw = ((k % lv->nx) + lv->nx) % lv->nx, mw = ((m % lv->ny) + lv->ny) % lv->ny;
                    any = lv->coef[(size_t)mw * lv->nx + kw] != 0;
                }
            occ[j * bx + i] = (unsigned char)any;
        }
}

/* The fogmap on the padded domain, for the marching baseline: zeros or the
 * edge repeated around it, as the decomposition padded it. */
static float *padded_fine(const float *img, const fp_fogmap_t *m)
{
    float *g = calloc((size_t)m->dom_w * m->dom_h, sizeof *g);
    if (!g)
        return NULL;
    for (int y = 0; y < m->dom_h; y++)
        for (int x = 0; x < m->dom_w; x++) {
            int i = x - m->pad_x0, j = y - m->pad_y0;
            if (m->wrap == FP_WRAP_CLAMP) {
                i = i < 0 ? 0 : i >= m->width ? m->width - 1 : i;
                j = j < 0 ? 0 : j >= m->height ? m->height - 1 : j;
            } else if (i < 0 || j < 0 || i >= m->width || j >= m->height) {
                continue;
            }
            g[(size_t)y * m->dom_w + x] = img[(size_t)j * m->width + i];
        }
    return g;
}

/* Levels 1.. as raw bands (LH, HL, HH at half resolution, one after the
 * other) instead of deconstructed surfaces. */
static size_t band_size(const fp_fogmap_t *m, int l)
{
    return (size_t)m->band[l][0].nx * m->band[l][0].ny;
}

/* A coarse level's surface refined onto the grid twice as fine, added to
 * `out` (nx x ny = 2 cnx x 2 cny, periodic): coarse basis i is
 * sum_k tap[k - lo] f_{2i+k} (filters/wavelet.h), along U then V. */
static int refine_add(const double *coarse, int cnx, int cny, const fp_wavelet_filter_t *f,
                      double *out)
{
    int nx = 2 * cnx, ny = 2 * cny;
    double *tmp = calloc((size_t)nx * cny, sizeof *tmp);
    if (!tmp)
        return fp_error("fogmap: out of memory");
    for (int j = 0; j < cny; j++)
        for (int i = 0; i < cnx; i++) {
            double c = coarse[(size_t)j * cnx + i];
            if (c == 0)
                continue;
            for (int k = f->lo; k <= f->hi; k++)
                tmp[(size_t)j * nx + ((2 * i + k) % nx + nx) % nx] += c * f->tap[k - f->lo];
        }
    for (int j = 0; j < cny; j++)
        for (int k = f->lo; k <= f->hi; k++) {
            double w = f->tap[k - f->lo];
            double *o = out + (size_t)(((2 * j + k) % ny + ny) % ny) * nx;
            const double *r = tmp + (size_t)j * nx;
            for (int i = 0; i < nx; i++)
                o[i] += w * r[i];
        }
    free(tmp);
    return FP_OK;
}

/* The sums A_l = S_0 + ... + S_l, each on level l's grid, for the walk of
 * kernels/fog_core.h (fp_grid_walk): *a holds A_1 .. A_{nl-2} one after
 * another (A_0 is level 0, A_{nl-1} the padded fogmap itself); tail[l]
 * the sum of max |coef| of the levels finer than l. */
static int approx_levels(const fp_fogmap_t *m, float **a, size_t *na, double *tail)
{
    int nl = m->num_levels;
    *a = NULL;
    *na = 0;
    tail[nl - 1] = 0;
    for (int l = nl - 2; l >= 0; l--) {
        double amax = 0;
        const fp_fog_level_t *lv = &m->level[l + 1];
        for (size_t i = 0; i < (size_t)lv->nx * lv->ny; i++)
            amax = fmax(amax, fabs(lv->coef[i]));
        tail[l] = tail[l + 1] + amax;
    }
    for (int l = 1; l + 1 < nl; l++)
        *na += (size_t)m->level[l].nx * m->level[l].ny;
    if (*na == 0)
        return FP_OK;
    *a = malloc(*na * sizeof **a);
    const fp_fog_level_t *l0 = &m->level[0];
    double *prev = malloc((size_t)l0->nx * l0->ny * sizeof *prev);
    if (!*a || !prev) {
        free(prev);
        free(*a);
        *a = NULL;
        return fp_error("fogmap: out of memory");
    }
    for (size_t i = 0; i < (size_t)l0->nx * l0->ny; i++)
        prev[i] = l0->coef[i];
    size_t at = 0;
    for (int l = 1; l + 1 < nl; l++) {
        const fp_fog_level_t *lv = &m->level[l], *up = &m->level[l - 1];
        size_t n = (size_t)lv->nx * lv->ny;
        double *cur = calloc(n, sizeof *cur);
        if (!cur || lv->nx != 2 * up->nx || lv->ny != 2 * up->ny ||
            refine_add(prev, up->nx, up->ny, &m->synth[0], cur)) {
            free(cur);
            free(prev);
            free(*a);
            *a = NULL;
            return fp_error("fogmap: cannot sum the levels (%dx%d under %dx%d)", lv->nx, lv->ny,
                            up->nx, up->ny);
        }
        for (size_t i = 0; i < n; i++) {
            cur[i] += lv->coef[i];
            (*a)[at + i] = (float)cur[i];
        }
        at += n;
        free(prev);
        prev = cur;
    }
    free(prev);
    return FP_OK;
}

/* For --lod-bound: per cell of level l's grid, l = 0..nl-2, a bound of
 * |F - A_l| there: t_l(cell) = max over the 4 cells under it of
 * (max |coef| of level l+1 reaching that cell + t_{l+1}), t_{nl-1} = 0.
 * *tm holds t_0 .. t_{nl-2} one after another. */
static int tail_maps(const fp_fogmap_t *m, float **tm, size_t *ntm)
{
    int nl = m->num_levels, d = m->degree, first = d / 2;
    *tm = NULL;
    *ntm = 0;
    for (int l = 0; l + 1 < nl; l++)
        *ntm += (size_t)m->level[l].nx * m->level[l].ny;
    if (*ntm == 0)
        return FP_OK;
    *tm = calloc(*ntm, sizeof **tm);
    float *a = NULL;
    if (*tm)
        a = malloc((size_t)m->level[nl - 1].nx * m->level[nl - 1].ny * sizeof *a);
    if (!*tm || !a) {
        free(*tm);
        *tm = NULL;
        return fp_error("fogmap: out of memory");
    }
    size_t off[FP_MAX_LEVELS + 1], at = 0;
    for (int l = 0; l + 1 < nl; l++) {
        off[l] = at;
        at += (size_t)m->level[l].nx * m->level[l].ny;
    }
    for (int l = nl - 2; l >= 0; l--) {
        const fp_fog_level_t *fine = &m->level[l + 1];
        int fx = fine->nx, fy = fine->ny;
        /* a: level l+1's largest |coef| over each of its cells, plus t_{l+1}. */
        for (int mm = 0; mm < fy; mm++)
            for (int k = 0; k < fx; k++) {
                float v = 0;
                for (int j = 0; j <= d; j++)
                    for (int i = 0; i <= d; i++) {
                        int kw = ((k - first + i) % fx + fx) % fx;
                        int mw = ((mm - first + j) % fy + fy) % fy;
                        v = fmaxf(v, fabsf(fine->coef[(size_t)mw * fx + kw]));
                    }
                if (l + 2 < nl)
                    v += (*tm)[off[l + 1] + (size_t)mm * fx + k];
                a[(size_t)mm * fx + k] = v;
            }
        int cx = m->level[l].nx, cy = m->level[l].ny;
        float *out = *tm + off[l];
        for (int mm = 0; mm < cy; mm++)
            for (int k = 0; k < cx; k++) {
                float v = 0;
                for (int j = 0; j < 2; j++)
                    for (int i = 0; i < 2; i++)
                        v = fmaxf(v, a[(size_t)(2 * mm + j) * fx + 2 * k + i]);
                /* Rounded up past float's rounding of the sums. */
                out[(size_t)mm * cx + k] = v * (1 + 1e-5f);
            }
    }
    free(a);
    return FP_OK;
}

/* The same bound, exact for the linear basis: F - A_l is bilinear on every
 * finest cell (the knots of every A_l are finest-grid nodes), so its
 * largest |.| over a level-l cell is the largest at the finest nodes in
 * the cell and on its edges, where F is the fine grid's value and A_l the
 * bilinear interpolation of its coefficients as the walk reads them
 * (float).  0 where A_l = F over the whole cell: the walk stays coarse
 * there at no cost.  `fine`: the padded fogmap (A_{nl-1}); `approx`:
 * A_1 .. A_{nl-2} (approx_levels).  *tm as tail_maps'. */
static int tail_maps_linear(const fp_fogmap_t *m, const float *fine, const float *approx,
                            float **tm, size_t *ntm)
{
    int nl = m->num_levels, nf = m->dom_w, mf = m->dom_h;
    *tm = NULL;
    *ntm = 0;
    for (int l = 0; l + 1 < nl; l++)
        *ntm += (size_t)m->level[l].nx * m->level[l].ny;
    if (*ntm == 0)
        return FP_OK;
    *tm = calloc(*ntm, sizeof **tm);
    double *r0 = malloc((size_t)nf * sizeof *r0), *r1 = malloc((size_t)nf * sizeof *r1);
    float *rowmax = malloc((size_t)nf * sizeof *rowmax);
    if (!*tm || !r0 || !r1 || !rowmax) {
        free(*tm);
        *tm = NULL;
        free(r0);
        free(r1);
        free(rowmax);
        return fp_error("fogmap: out of memory");
    }
    size_t at = 0, ao = 0;
    for (int l = 0; l + 1 < nl; l++) {
        const fp_fog_level_t *lv = &m->level[l];
        int cx = lv->nx, cy = lv->ny, s = 1 << (nl - 1 - l);
        const float *a = l == 0 ? lv->coef : approx + ao;
        float *out = *tm + at;
        if (cx * s != nf || cy * s != mf) {
            free(*tm);
            *tm = NULL;
            free(r0);
            free(r1);
            free(rowmax);
            return fp_error("fogmap: level %d (%dx%d) does not tile the %dx%d domain", l, cx, cy,
                            nf, mf);
        }
        for (int j = 0; j < mf; j++) {
            /* A_l along fine row j: rows m0, m0 + 1 of its coefficients
             * interpolated along U at every fine node, then along V. */
            int m0 = j / s, m1 = (m0 + 1) % cy;
            double fy = (double)(j % s) / s;
            for (int i = 0; i < nf; i++) {
                int k0 = i / s, k1 = (k0 + 1) % cx;
                double fx = (double)(i % s) / s;
                r0[i] = (1 - fx) * a[(size_t)m0 * cx + k0] + fx * a[(size_t)m0 * cx + k1];
                r1[i] = (1 - fx) * a[(size_t)m1 * cx + k0] + fx * a[(size_t)m1 * cx + k1];
            }
            /* |F - A_l| at the nodes, then its max over each cell's span of
             * nodes along U (s + 1 of them, both ends). */
            for (int i = 0; i < nf; i++)
                rowmax[i] = (float)fabs((double)fine[(size_t)j * nf + i] -
                                        ((1 - fy) * r0[i] + fy * r1[i]));
            /* (Comparisons rather than fmaxf: gcc calls libm for fmaxf.) */
            for (int k = 0; k < cx; k++) {
                float v = rowmax[(size_t)((k + 1) * s) % nf];
                for (int i = k * s; i < (k + 1) * s; i++)
                    v = rowmax[i] > v ? rowmax[i] : v;
                /* Fine row j lies in cell row j / s, and on the edge of the
                 * row below when it is a multiple of s. */
                float *o = out + (size_t)m0 * cx + k;
                *o = v > *o ? v : *o;
                if (j % s == 0) {
                    o = out + (size_t)((m0 + cy - 1) % cy) * cx + k;
                    *o = v > *o ? v : *o;
                }
            }
        }
        /* Rounded up past the rounding of the differences above. */
        for (size_t i = 0; i < (size_t)cx * cy; i++)
            out[i] *= 1 + 1e-5f;
        at += (size_t)cx * cy;
        if (l > 0)
            ao += (size_t)cx * cy;
    }
    free(r0);
    free(r1);
    free(rowmax);
    return FP_OK;
}

/* The tensor grid of the linear basis (kernels/fog_core.h, fp_tensor_walk)
 * over the padded fogmap F (nx x ny, periodic as the walk reads it): *bx,
 * *by the break nodes per axis, *val F at them (rows along V), *eps the
 * exact max |F - G| over the plane, G bilinear on the rectangles between
 * consecutive breaks.  A node is a break where the largest |second
 * difference| of F across it (over every line of the other axis) passes
 * FP_TENSOR_TOL of F's largest |value|, a few times float's rounding of
 * the values (the rest of F's rounding lands in eps, measured).  None
 * (*nbx = 0) unless both axes have at most 1/FP_TENSOR_SPARSE of their
 * nodes as breaks: a map with fine detail keeps the dyadic levels alone. */
_Static_assert(FP_TG_ROW > FP_MAX_LEVELS + 1 && FP_TG_ROW < FP_LEVEL_TABLE,
               "the tensor grid's row follows the levels' and the fine grid's");
#define FP_TENSOR_TOL 1e-6
#define FP_TENSOR_SPARSE 8
static int tensor_grid(const float *F, int nx, int ny, float **bx, int *nbx, float **by,
                       int *nby, float **val, double *eps)
{
    *bx = *by = *val = NULL;
    *nbx = *nby = 0;
    *eps = 0;
    float *cx = calloc((size_t)nx, sizeof *cx), *cy = calloc((size_t)ny, sizeof *cy);
    int *rx = malloc((size_t)nx * sizeof *rx), *ry = malloc((size_t)ny * sizeof *ry);
    double *g0 = malloc((size_t)nx * sizeof *g0), *g1 = malloc((size_t)nx * sizeof *g1);
    int rc = FP_OK;
    if (!cx || !cy || !rx || !ry || !g0 || !g1) {
        rc = fp_error("fogmap: out of memory");
        goto done;
    }
    float fmax_abs = 0;
    for (size_t i = 0; i < (size_t)nx * ny; i++) {
        float a = fabsf(F[i]);
        fmax_abs = a > fmax_abs ? a : fmax_abs;
    }
    float tol = (float)(FP_TENSOR_TOL * fmax_abs);
    /* Second differences along U (their largest per column into cx) and V
     * (per row into cy), the breaks counted as they appear: a map with fine
     * detail stops within its first rows. */
    int kx = 0, ky = 0;
    for (int j = 0; j < ny && kx <= nx / FP_TENSOR_SPARSE && ky <= ny / FP_TENSOR_SPARSE; j++) {
        const float *row = F + (size_t)j * nx;
        const float *up = F + (size_t)(j ? j - 1 : ny - 1) * nx;
        const float *dn = F + (size_t)(j + 1 < ny ? j + 1 : 0) * nx;
        float vmax = 0;
        for (int i = 0; i < nx; i++) {
            float l = row[i ? i - 1 : nx - 1], r = row[i + 1 < nx ? i + 1 : 0];
            float du = fabsf(l - 2 * row[i] + r), dv = fabsf(up[i] - 2 * row[i] + dn[i]);
            kx += du > tol && !(cx[i] > tol);
            cx[i] = du > cx[i] ? du : cx[i];
            vmax = dv > vmax ? dv : vmax;
        }
        cy[j] = vmax;
        ky += vmax > tol;
    }
    if (kx > nx / FP_TENSOR_SPARSE || ky > ny / FP_TENSOR_SPARSE)
        goto done;
    /* At least one break per axis: one rectangle a period wide. */
    kx = kx ? kx : 1;
    ky = ky ? ky : 1;
    *bx = malloc(2 * (size_t)kx * sizeof **bx);
    *by = malloc(2 * (size_t)ky * sizeof **by);
    *val = malloc((size_t)kx * ky * sizeof **val);
    if (!*bx || !*by || !*val) {
        rc = fp_error("fogmap: out of memory");
        goto done;
    }
    int n = 0;
    for (int i = 0; i < nx; i++)
        if (cx[i] > tol)
            rx[n++] = i;
    if (n == 0)
        rx[n++] = 0;
    n = 0;
    for (int j = 0; j < ny; j++)
        if (cy[j] > tol)
            ry[n++] = j;
    if (n == 0)
        ry[n++] = 0;
    for (int q = 0; q < ky; q++)
        for (int r = 0; r < kx; r++)
            (*val)[(size_t)q * kx + r] = F[(size_t)ry[q] * nx + rx[r]];
    for (int r = 0; r < kx; r++) {
        int w = (r + 1 < kx ? rx[r + 1] : rx[0] + nx) - rx[r];
        (*bx)[r] = (float)rx[r];
        (*bx)[kx + r] = 1.0f / w;
    }
    for (int q = 0; q < ky; q++) {
        int w = (q + 1 < ky ? ry[q + 1] : ry[0] + ny) - ry[q];
        (*by)[q] = (float)ry[q];
        (*by)[ky + q] = 1.0f / w;
    }
    /* Each node's rectangle: that of the last break at or before it, the
     * last rectangle (wrapping) before the first break. */
    for (int i = 0, r = kx - 1, next = 0; i < nx; i++) {
        if (next < kx && (int)(*bx)[next] == i)
            r = next++;
        rx[i] = r;
    }
    for (int j = 0, q = ky - 1, next = 0; j < ny; j++) {
        if (next < ky && (int)(*by)[next] == j)
            q = next++;
        ry[j] = q;
    }
    /* eps: F - G is bilinear on every finest cell, so its largest |.| is at
     * the nodes.  G as the walk forms it from the stored values: along U on
     * the rectangle's two rows, then along V. */
    double e = 0;
    int qrow = -1;
    for (int j = 0; j < ny; j++) {
        int q = ry[j], q1 = q + 1 < ky ? q + 1 : 0;
        double fy = (double)(((j - (int)(*by)[q]) % ny + ny) % ny) * (*by)[ky + q];
        if (q != qrow) {
            for (int i = 0; i < nx; i++) {
                int r = rx[i], r1 = r + 1 < kx ? r + 1 : 0;
                double fx = (double)(((i - (int)(*bx)[r]) % nx + nx) % nx) * (*bx)[kx + r];
                const float *v0 = *val + (size_t)q * kx, *v1 = *val + (size_t)q1 * kx;
                g0[i] = (1 - fx) * v0[r] + fx * v0[r1];
                g1[i] = (1 - fx) * v1[r] + fx * v1[r1];
            }
            qrow = q;
        }
        const float *row = F + (size_t)j * nx;
        for (int i = 0; i < nx; i++) {
            double dd = fabs((double)row[i] - ((1 - fy) * g0[i] + fy * g1[i]));
            e = dd > e ? dd : e;
        }
    }
    /* Rounded up past the rounding of the differences above, and past the
     * walk's reading of G on a rectangle's far sides (nodes of the next
     * rectangle, left out above) through the rounded 1 / widths: there G
     * differs from the corner's value by at most |c1 - c0| <= max F
     * (F >= 0) times float's rounding (6e-8) per axis. */
    *eps = e * (1 + 1e-6) + 1.2e-7 * fmax_abs;
    *nbx = kx;
    *nby = ky;
done:
    free(cx);
    free(cy);
    free(rx);
    free(ry);
    free(g0);
    free(g1);
    if (rc || !*nbx) {
        free(*bx);
        free(*by);
        free(*val);
        *bx = *by = *val = NULL;
    }
    return rc;
}

static unsigned long next_serial(void)
{
    static _Atomic unsigned long serial;
    return ++serial;
}

static int build_tables(const fp_fogmap_t *m, const float *img, double cell_to_fog,
                        int deconstruct, fp_fog_tables_t *t)
{
    memset(t, 0, sizeof *t);
    int nl = m->num_levels;
    fp_fog_level_t fine = { m->dom_w, m->dom_h, 1, 0.5, 0.5, 0, NULL };
    size_t ncoef = (size_t)m->dom_w * m->dom_h, nocc = 0;
    for (int l = 0; l < nl; l++) {
        const fp_fog_level_t *lv = &m->level[l];
        int b = block_size(lv->nx, lv->ny);
        ncoef += !deconstruct && l > 0 ? 3 * band_size(m, l) : (size_t)lv->nx * lv->ny;
        nocc += (size_t)(lv->nx / b) * (lv->ny / b);
    }
    float *approx = NULL;
    size_t napprox = 0;
    double tail[FP_LEVEL_TABLE] = { 0 };
    float *tmaps = NULL;
    size_t ntmaps = 0;
    fine.coef = padded_fine(img, m);
    if (!fine.coef)
        return fp_error("fogmap: out of memory");
    if (deconstruct && approx_levels(m, &approx, &napprox, tail)) {
        free(fine.coef);
        return FP_ERR;
    }
    if (deconstruct && (m->degree == 1 ? tail_maps_linear(m, fine.coef, approx, &tmaps, &ntmaps)
                                       : tail_maps(m, &tmaps, &ntmaps))) {
        free(fine.coef);
        free(approx);
        return FP_ERR;
    }
    float *tbx = NULL, *tby = NULL, *tval = NULL;
    int tnx = 0, tny = 0;
    double teps = 0;
    if (deconstruct && m->degree == 1 &&
        tensor_grid(fine.coef, m->dom_w, m->dom_h, &tbx, &tnx, &tby, &tny, &tval, &teps)) {
        free(fine.coef);
        free(approx);
        free(tmaps);
        return FP_ERR;
    }
    size_t ntensor = tnx ? (size_t)tnx * tny + 2 * (size_t)tnx + 2 * (size_t)tny : 0;
    t->coef = fp_fog_tables_alloc((ncoef + napprox + ntmaps + ntensor) * sizeof(float));
    t->occ = fp_fog_tables_alloc(nocc + 1);
    if (!t->coef || !t->occ) {
        free(fine.coef);
        free(approx);
        free(tmaps);
        free(tbx);
        free(tby);
        free(tval);
        return fp_error("fogmap: out of memory");
    }
    size_t co = 0, oo = 0;
    for (int l = 0; l <= nl; l++) {
        const fp_fog_level_t *lv = l < nl ? &m->level[l] : &fine;
        int b = block_size(lv->nx, lv->ny);
        int *li = t->lvi + l * FP_LI_STRIDE;
        double *lr = t->lvf + l * FP_LR_STRIDE;
        li[FP_LI_NX] = lv->nx;
        li[FP_LI_NY] = lv->ny;
        li[FP_LI_COEF] = (int)co;
        li[FP_LI_OCC] = (int)oo;
        li[FP_LI_BLOCK] = b;
        lr[FP_LR_CELL] = lv->cell;
        lr[FP_LR_ORIGIN_U] = lv->origin_u;
        lr[FP_LR_ORIGIN_V] = lv->origin_v;
        lr[FP_LR_LOD_DIST] = lv->cell * cell_to_fog;
        if (!deconstruct && l > 0 && l < nl) {
            li[FP_LI_BANDS] = 1;
            for (int band = 0; band < 3; band++) {
                memcpy(t->coef + co, m->band[l][band].coef, band_size(m, l) * sizeof(float));
                co += band_size(m, l);
            }
        } else {
            memcpy(t->coef + co, lv->coef, (size_t)lv->nx * lv->ny * sizeof(float));
            co += (size_t)lv->nx * lv->ny;
        }
        if (l < nl) {
            occupancy(lv, m->degree, b, t->occ + oo);
            oo += (size_t)(lv->nx / b) * (lv->ny / b);
        }
    }
    free(fine.coef);
    /* The walk's surfaces: A_0 = level 0, A_{nl-1} = the fine grid (row nl),
     * the others after every level's coefficients; none with raw bands. */
    size_t ao = co, to = co + napprox;
    for (int l = 0; l < nl; l++) {
        int *li = t->lvi + l * FP_LI_STRIDE;
        t->lvf[l * FP_LR_STRIDE + FP_LR_TAIL] = tail[l] * (1 + 1e-6);
        li[FP_LI_TMAP] = -1;
        if (deconstruct && l + 1 < nl) {
            li[FP_LI_TMAP] = (int)to;
            to += (size_t)li[FP_LI_NX] * li[FP_LI_NY];
        }
        if (!deconstruct) {
            li[FP_LI_APPROX] = -1;
        } else if (l == 0) {
            li[FP_LI_APPROX] = li[FP_LI_COEF];
        } else if (l == nl - 1) {
            li[FP_LI_APPROX] = t->lvi[nl * FP_LI_STRIDE + FP_LI_COEF];
        } else {
            li[FP_LI_APPROX] = (int)ao;
            ao += (size_t)li[FP_LI_NX] * li[FP_LI_NY];
        }
    }
    if (napprox)
        memcpy(t->coef + co, approx, napprox * sizeof(float));
    if (ntmaps)
        memcpy(t->coef + co + napprox, tmaps, ntmaps * sizeof(float));
    free(approx);
    free(tmaps);
    ncoef += napprox + ntmaps;
    /* The tensor grid after them: G, then the breaks and 1 / widths along
     * U, then along V. */
    if (tnx) {
        int *ti = t->lvi + FP_TG_ROW * FP_LI_STRIDE;
        ti[FP_TI_NX] = tnx;
        ti[FP_TI_NY] = tny;
        ti[FP_TI_VAL] = (int)ncoef;
        memcpy(t->coef + ncoef, tval, (size_t)tnx * tny * sizeof(float));
        ncoef += (size_t)tnx * tny;
        ti[FP_TI_BX] = (int)ncoef;
        memcpy(t->coef + ncoef, tbx, 2 * (size_t)tnx * sizeof(float));
        ncoef += 2 * (size_t)tnx;
        ti[FP_TI_BY] = (int)ncoef;
        memcpy(t->coef + ncoef, tby, 2 * (size_t)tny * sizeof(float));
        ncoef += 2 * (size_t)tny;
        /* Up to a float, as the device reads it. */
        t->lvf[FP_TG_ROW * FP_LR_STRIDE + FP_TR_EPS] = nextafterf((float)teps, INFINITY);
    }
    free(tbx);
    free(tby);
    free(tval);
    t->serial = next_serial();
    t->nlevels = nl;
    t->ncoef = ncoef;
    t->nocc = nocc + 1;
    return FP_OK;
}

/* The fogmap's pixels from its file, negative values clamped (a warning). */
static int read_fogmap(const char *path, const char *channel, float **img, int *w, int *h)
{
    int rc;
    if ((rc = fp_image_file_check(path, "fogmap")) ||
        (rc = fp_oiio_read_channel(path, channel, img, w, h)))
        return rc;
    fp_fogmap_clamp_negative(path, *img, *w, *h);
    return FP_OK;
}

static int setup_stage(const fp_params_t *p, fp_cl_t *cl, float **img, const char *path, int w,
                       int h, fp_fogmap_stage_t *s, fp_integrate_data_t *d);

int fp_fogmap_commit(const fp_params_t *p, fp_cl_t *cl, fp_fogmap_stage_t *s,
                     fp_integrate_data_t *d, int *active)
{
    const fp_fogmap_params_t *fm = &p->fogmap;
    memset(s, 0, sizeof *s);
    *active = 0;
    int rc = fp_animate_check(p);
    if (rc || !fm->fogmap)
        return rc;
    const double *r = fm->rect;
    if (!(r[2] > r[0]) || !(r[3] > r[1]))
        return fp_usage_error("--fog-rect: expected A0 < A1 and B0 < B1, got %g,%g,%g,%g",
                              r[0], r[1], r[2], r[3]);
    /* A sequence is set up from its first key. */
    char first[4096];
    const char *path = fm->fogmap;
    if (fp_seq_has_placeholder(fm->fogmap) == 1) {
        fp_frame_list_t keys = { NULL, 0 };
        if ((rc = fp_frames_scan(fm->fogmap, &keys)))
            return rc;
        rc = fp_seq_format(fm->fogmap, keys.frames[0], first, sizeof first);
        fp_frames_free(&keys);
        if (rc)
            return rc;
        path = first;
    }
    float *img = NULL;
    int w, h;
    if ((rc = read_fogmap(path, fm->channel, &img, &w, &h)))
        return rc;
    rc = setup_stage(p, cl, &img, path, w, h, s, d);
    if (rc == FP_OK && fp_animate_fogmap_animated(p))
        rc = fp_fogmap_animate(p, img, w, h, s, d);
    free(img);
    if (rc == FP_OK)
        *active = 1;
    return rc;
}

int fp_fogmap_animate(const fp_params_t *p, const float *img, int w, int h,
                      fp_fogmap_stage_t *s, const fp_integrate_data_t *d)
{
    return fp_animate_open(p, img, w, h, &s->map, d->fp[FP_F_USCALE], d->fp[FP_F_VSCALE],
                           &s->anim);
}

int fp_fogmap_setup(const fp_params_t *p, fp_cl_t *cl, const float *img, int w, int h,
                    fp_fogmap_stage_t *s, fp_integrate_data_t *d)
{
    float *pixels = (float *)img;   /* only read: no path to read it again from */
    return setup_stage(p, cl, &pixels, NULL, w, h, s, d);
}

/* fp_fogmap_setup from *imgp; with `path` (the file *imgp was read from,
 * the caller's to free) the pixels are freed before a cache hit's tables
 * are read (*imgp NULL then), and read again should the hit fail: the
 * program's heap keeps what it frees (cli/main.c), so a 4096 map's 64 MB
 * of pixels stayed resident beside its 200 MB of tables (issue 26). */
static int setup_stage(const fp_params_t *p, fp_cl_t *cl, float **imgp, const char *path, int w,
                       int h, fp_fogmap_stage_t *s, fp_integrate_data_t *d)
{
    const fp_fogmap_params_t *fm = &p->fogmap;
    const double *r = fm->rect;
    const float *img = *imgp;
    int rc;
    memset(s, 0, sizeof *s);
    if ((rc = fp_fogmap_check_values(fm->fogmap ? fm->fogmap : "fogmap", img, w, h,
                                     fp_fogmap_od_scale(p, w, h))))
        return rc;
    double t0 = now_ms();
    fp_fogmap_cache_t fc;
    if ((rc = fp_fogmap_cache_open(p, cl, img, w, h, &fc)))
        return rc;
    /* A cache file (never for an animated or previewed map) makes the
     * pixels unneeded. */
    if (path && fc.path && access(fc.path, R_OK) == 0) {
        free(*imgp);
        *imgp = NULL;
        img = NULL;
#ifdef __GLIBC__
        /* Its pages (and the image reader's) back to the system: the
         * program's heap is never trimmed otherwise. */
        malloc_trim(0);
#endif
    }
    int cached = fp_fogmap_cache_load(&fc, &s->map, &s->tables);
    int w2 = w, h2 = h;
    if (!cached && !img && (rc = read_fogmap(path, fm->channel, imgp, &w2, &h2)) == FP_OK &&
        (w2 != w || h2 != h))
        rc = fp_error("%s: changed while it was read (%dx%d, then %dx%d)", path, w, h, w2, h2);
    if (rc) {
        fp_fogmap_cache_close(&fc);
        return rc;
    }
    img = *imgp;
    s->used_cl = cached && cl;
    rc = cached ? FP_OK : FP_ERR;
    if (rc && cl) {
        rc = fp_wavelet_decompose_cl(cl, img, w, h, fm->basis, fm->levels, fm->wrap, &s->map);
        if (rc)
            fp_warn("%s: OpenCL decomposition failed; using the C reference", fm->fogmap);
        s->used_cl = rc == FP_OK;
    }
    if (rc)
        rc = fp_wavelet_decompose(img, w, h, fm->basis, fm->levels, fm->wrap, &s->map);
    s->decompose_ms = now_ms() - t0;
    if (rc) {
        fp_fogmap_cache_close(&fc);
        return rc;
    }
    const fp_fogmap_t *m = &s->map;
    const char *name = fm->fogmap ? fm->fogmap : "fogmap";
    if (m->levels < fm->levels)
        fp_warn("%s: %dx%d with --fog-wrap repeat allows %d levels (2^levels must divide the "
                "size), not %d", name, w, h, m->levels, fm->levels);
    fp_info("%s: %dx%d, %d levels, %s in %.1f ms (%s)", name, w, h, m->levels,
            cached ? "loaded from the fogmap cache" : "decomposed", s->decompose_ms,
            s->used_cl ? "OpenCL" : "C");

    /* Fog-space rectangle: with --up z fog z is -world y, so the rows that
     * run from Y1 (row 0) down to Y0 run along +z from -Y1. */
    double a0 = r[0], b0 = r[1], a1 = r[2], b1 = r[3];
    if (p->camera.up == FP_UP_Z) {
        b0 = -r[3];
        b1 = -r[1];
    }
    double *v = d->fp;
    int deg = m->degree;
    v[FP_F_USCALE] = w / (a1 - a0);
    v[FP_F_VSCALE] = h / (b1 - b0);
    v[FP_F_A0] = a0;
    v[FP_F_B0] = b0;
    v[FP_F_PAD_X0] = m->pad_x0;
    v[FP_F_PAD_Y0] = m->pad_y0;
    /* ZERO: F vanishes beyond (d+1)/2 pixels of the edge; CLAMP: F stops
     * changing beyond d/2 pixels (filters/wavelet.h). */
    double reach = m->wrap == FP_WRAP_ZERO ? (deg + 1) / 2.0 : deg / 2.0;
    v[FP_F_CLIP] = m->pad_x0 - reach;
    v[FP_F_CLIP + 1] = m->pad_x0 + w + reach;
    v[FP_F_CLIP + 2] = m->pad_y0 - reach;
    v[FP_F_CLIP + 3] = m->pad_y0 + h + reach;
    v[FP_F_DEGREE] = deg;
    v[FP_F_WRAP] = m->wrap;
    v[FP_F_NLEVELS] = m->num_levels;
    v[FP_F_LOD_MU] = fm->lod_mu;
    v[FP_F_LOD_BOUND] = fm->lod_bound;
    v[FP_F_OD_MAX] = fm->min_transmittance > 0 ? -log(fm->min_transmittance) : INFINITY;
    /* Unbounded rays (clamp, repeat) that never leave the fog: integrate
     * 64 fogmap widths, far past any transmittance that shows. */
    v[FP_F_CAP] = 64 * fmax((a1 - a0), (b1 - b0));
    v[FP_F_MODE] = fm->integrator;
    v[FP_F_STEPS] = fm->steps;
    v[FP_F_JITTER] = fm->jitter;
    v[FP_F_SPARSE] = fm->sparse;
    v[FP_F_HAS_MAP] = 1;
    for (int f = 0; f < 2; f++) {
        const fp_wavelet_filter_t *sf = &m->synth[f];
        v[FP_F_TAPS + 18 * f] = sf->lo;
        v[FP_F_TAPS + 18 * f + 1] = sf->hi;
        for (int k = 0; k <= sf->hi - sf->lo && k < 16; k++)
            v[FP_F_TAPS + 18 * f + 2 + k] = sf->tap[k];
    }
    s->cell_to_fog = 1.0 / fmax(v[FP_F_USCALE], v[FP_F_VSCALE]);
    s->decompositions = 1;
    if (cached) {
        /* What the key leaves out: the cells' size in fog units (the
         * rectangle) and the tables' identity. */
        for (int l = 0; l <= m->num_levels; l++)
            s->tables.lvf[l * FP_LR_STRIDE + FP_LR_LOD_DIST] =
                s->tables.lvf[l * FP_LR_STRIDE + FP_LR_CELL] * s->cell_to_fog;
        s->tables.serial = next_serial();
    } else if ((rc = build_tables(m, img, s->cell_to_fog, fm->deconstruct, &s->tables)) == FP_OK) {
        fp_fogmap_cache_store(&fc, m, &s->tables);
        /* The levels themselves are read only by --fogmap-preview and the
         * animation; the tables hold what the integrator reads (and what a
         * cache hit has): 200 MB less before a 4096 map's upload. */
        if (!fm->preview && !fp_animate_fogmap_animated(p)) {
            fp_fogmap_t keep = s->map;
            fp_fogmap_free(&s->map);
            memset(keep.level, 0, sizeof keep.level);
            memset(keep.band, 0, sizeof keep.band);
            s->map = keep;
        }
    }
    fp_fogmap_cache_close(&fc);
    if (rc)
        return rc;
    d->tables = &s->tables;
    return FP_OK;
}

static void free_tables(fp_fog_tables_t *t)
{
    free(t->coef);
    free(t->occ);
    memset(t, 0, sizeof *t);
}

int fp_fogmap_frame(const fp_params_t *p, fp_cl_t *cl, fp_fogmap_stage_t *s, long frame,
                    const fp_view_t *v, fp_integrate_data_t *d)
{
    /* Angle of one pixel at the image center, from the NDC->camera map.  An
     * orthographic pixel does not grow with distance: no level is dropped
     * for its footprint (exact, as --lod-footprint 0). */
    double pixel = v->ortho ? 0 : fabs(v->h[4] * v->ndc_scale[1]);
    d->fp[FP_F_FOOTPRINT] = p->fogmap.lod_footprint * pixel;
    fp_animate_transform(p, frame, d);
    if (!s)
        return FP_OK;
    if (!s->anim) {
        s->decompose_ms = s->animate_ms = 0;   /* nothing done per frame */
        s->decompositions = 0;
        return FP_OK;
    }
    double t0 = now_ms();
    fp_animate_frame_t af;
    int rc = fp_animate_fogmap(s->anim, cl, frame, &af);
    if (rc)
        return rc;
    s->decompose_ms = af.decompose_ms;
    s->decompositions = af.decompositions;
    if (af.decompositions)
        s->used_cl = af.used_cl;
    if (af.changed) {
        fp_fog_tables_t t;
        if ((rc = build_tables(af.map, af.img, s->cell_to_fog, p->fogmap.deconstruct, &t))) {
            free_tables(&t);
            return rc;
        }
        free_tables(&s->prev);
        s->prev = s->tables;
        s->tables = t;
        d->tables = &s->tables;
    }
    s->animate_ms = now_ms() - t0;
    if (af.decompositions)
        fp_info("frame %ld: fogmap decomposed in %.1f ms (%d, %s), %.1f ms for the fogmap in all",
                frame, s->decompose_ms, af.decompositions, af.used_cl ? "OpenCL" : "C",
                s->animate_ms);
    return FP_OK;
}

static int write_grey(const char *dir, const char *name, const float *data, int w, int h,
                      double lo, double hi)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    float *g = malloc((size_t)w * h * sizeof *g);
    if (!g)
        return fp_error("out of memory");
    for (size_t i = 0; i < (size_t)w * h; i++)
        g[i] = hi > lo ? (float)((data[i] - lo) / (hi - lo)) : 0.0f;
    int rc = fp_oiio_write_preview(path, g, w, h, 1, 16, 0);
    free(g);
    return rc;
}

int fp_fogmap_preview(const fp_fogmap_stage_t *s, const char *dir)
{
    const fp_fogmap_t *m = &s->map;
    if (mkdir(dir, 0777) != 0 && errno != EEXIST)
        return fp_error("%s: cannot create directory (%s)", dir, strerror(errno));
    int rc = FP_OK;
    /* Levels: the coarse one from 0 to its maximum, details signed around
     * mid-grey so that positive and negative detail both show. */
    for (int l = 0; l < m->num_levels && rc == FP_OK; l++) {
        const fp_fog_level_t *lv = &m->level[l];
        double amax = 0;
        for (size_t i = 0; i < (size_t)lv->nx * lv->ny; i++)
            amax = fmax(amax, fabs(lv->coef[i]));
        char name[64];
        snprintf(name, sizeof name, "level%02d.png", l);
        rc = l == 0 ? write_grey(dir, name, lv->coef, lv->nx, lv->ny, 0, amax)
                    : write_grey(dir, name, lv->coef, lv->nx, lv->ny, -amax, amax);
        if (rc == FP_OK)
            printf("%s/%s: level %d, %dx%d coefficients, cell %g px, %s\n", dir, name, l, lv->nx,
                   lv->ny, lv->cell, l == 0 ? "coarse approximation (0..max)"
                                            : "details (mid-grey = 0, +-max)");
    }
    if (rc)
        return rc;
    /* The reconstructed fogmap: the sum of all level surfaces at the
     * fogmap's pixel centers. */
    float *rec = malloc((size_t)m->width * m->height * sizeof *rec);
    if (!rec)
        return fp_error("out of memory");
    double hi = 0;
    for (int j = 0; j < m->height; j++)
        for (int i = 0; i < m->width; i++) {
            double f = fp_fogmap_eval(m, m->pad_x0 + i + 0.5, m->pad_y0 + j + 0.5, m->levels);
            rec[(size_t)j * m->width + i] = (float)f;
            hi = fmax(hi, f);
        }
    rc = write_grey(dir, "reconstructed.png", rec, m->width, m->height, 0, hi);
    if (rc == FP_OK)
        printf("%s/reconstructed.png: the sum of all levels at the pixel centers, %dx%d (0..%g)\n",
               dir, m->width, m->height, hi);
    free(rec);
    return rc;
}

void fp_fogmap_release(fp_fogmap_stage_t *s)
{
    fp_fogmap_free(&s->map);
    free_tables(&s->tables);
    free_tables(&s->prev);
    fp_animate_close(s->anim);
    memset(s, 0, sizeof *s);
}
