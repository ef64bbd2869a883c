#include "reference.h"
#include "fp.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The estimator in double precision. */
#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/reference_core.h"

_Static_assert(FP_RP_COUNT == FP_RP_COUNT_, "reference parameter count");
_Static_assert(FP_LT_COUNT == FP_LT_COUNT_, "light parameter count");

#define RF(f) offsetof(fp_params_t, reference.f)
const fp_option_t fp_reference_options[] = {
    { "spp", 0, FP_OPT_INT, RF(spp), 0, 0, "64", 1, 16777216, NULL, "N",
      "--integrator reference: Monte Carlo samples per pixel (the noise falls as 1/sqrt(N); "
      "--seed picks the random numbers, the same seed gives the same frame)", NULL, 0 },
    { "bounces", 0, FP_OPT_INT, RF(bounces), 0, 0, "0", 0, 64, NULL, "N",
      "--integrator reference: scattering events inside the fog after the first, each with "
      "the sun, the lights and the ambient light (0: single scattering, the model the "
      "deterministic integrator computes)", NULL, 0 },
    { "ref-geometry", 0, FP_OPT_INT, RF(geometry), 0, 0, "1", 0, 1, NULL, "0|1",
      "--integrator reference with --bounces: 1: a scattered path ends (black) where it "
      "enters what both the sun's shadow map and the depth buffer hide (the ground, a "
      "caster's inside; needs a shadow map); 0: scattered paths cross all geometry",
      NULL, 0 },
    FP_OPT_END
};

/* Samples per launch (pixels times samples, divided by 1 + bounces), so
 * that one launch stays well under a second on a two-core CPU device and
 * far under any GPU watchdog; fixed, so that the batches, and the bits, do
 * not depend on timing. */
#define FP_REF_LAUNCH (1 << 16)
/* At most this many samples per pixel and launch: the kernel sums them in
 * float. */
#define FP_REF_BATCH 256

static const float no_map[1] = { INFINITY };
static const float no_grid[2] = { 0, 0 };
static const double no_lights[FP_LL_STRIDE];

#define TABLES(t) FP_TABLES3(fp_fog_tables_or_empty(t))

/* ------------------------------------------------------------ the grid */

/* Max and min (both clamped at 0) of the fine-grid coefficients whose
 * B-spline support reaches the domain rectangle [u0,u1] x [v0,v1]: F there
 * is a convex combination of them (non-negative weights summing to 1). */
static void coef_range(const fp_integrate_data_t *fog, double u0, double u1, double v0, double v1,
                       double *fmx, double *fmn)
{
    const double *fp = fog->fp;
    const fp_fog_tables_t *t = fog->tables;
    int l = (int)fp[FP_F_NLEVELS], d = (int)fp[FP_F_DEGREE];
    const int *li = t->lvi + l * FP_LI_STRIDE;
    const double *lr = t->lvf + l * FP_LR_STRIDE;
    int nx = li[FP_LI_NX], ny = li[FP_LI_NY], first = d / 2;
    const float *cf = t->coef + li[FP_LI_COEF];
    double cell = lr[FP_LR_CELL], kappa = (d & 1) ? 0 : 0.5, eps = 1e-4;
    double k0 = floor((u0 - lr[FP_LR_ORIGIN_U]) / cell + kappa - eps) - first;
    double k1 = floor((u1 - lr[FP_LR_ORIGIN_U]) / cell + kappa + eps) - first + d;
    double m0 = floor((v0 - lr[FP_LR_ORIGIN_V]) / cell + kappa - eps) - first;
    double m1 = floor((v1 - lr[FP_LR_ORIGIN_V]) / cell + kappa + eps) - first + d;
    int kc = k1 - k0 + 1 >= nx ? nx : (int)(k1 - k0 + 1);
    int mc = m1 - m0 + 1 >= ny ? ny : (int)(m1 - m0 + 1);
    int kb = (int)(k0 - nx * floor(k0 / nx)), mb = (int)(m0 - ny * floor(m0 / ny));
    double hi = 0, lo = INFINITY;
    for (int j = 0; j < mc; j++) {
        const float *row = cf + (size_t)((mb + j) % ny) * nx;
        for (int i = 0; i < kc; i++) {
            double c = row[(kb + i) % nx];
            hi = fmax(hi, c);
            lo = fmin(lo, c);
        }
    }
    *fmx = hi;
    *fmn = fmax(lo, 0);
}

/* The fine grid's global max and min, clamped at 0. */
static void coef_global(const fp_integrate_data_t *fog, double *fmx, double *fmn)
{
    const fp_fog_tables_t *t = fog->tables;
    int l = (int)fog->fp[FP_F_NLEVELS];
    const int *li = t->lvi + l * FP_LI_STRIDE;
    size_t n = (size_t)li[FP_LI_NX] * li[FP_LI_NY];
    const float *cf = t->coef + li[FP_LI_COEF];
    double hi = 0, lo = INFINITY;
    for (size_t i = 0; i < n; i++) {
        hi = fmax(hi, cf[i]);
        lo = fmin(lo, cf[i]);
    }
    *fmx = hi;
    *fmn = n ? fmax(lo, 0) : 0;
}

/* The bounds of F over the fogmap footprint of the world rectangle
 * [x0,x1] x [z0,z1] (a grid column), within the fog box and the clip
 * rectangle; 0 when the main fog does not reach it. */
static void column_bounds(const fp_integrate_data_t *fog, double x0, double x1, double z0,
                          double z1, double *fmx, double *fmn)
{
    const double *fp = fog->fp;
    *fmx = *fmn = 0;
    double c = fp[FP_F_COS], s = fp[FP_F_SIN];
    double qx0 = INFINITY, qx1 = -INFINITY, qz0 = INFINITY, qz1 = -INFINITY;
    for (int k = 0; k < 4; k++) {
        double px = ((k & 1) ? x1 : x0) - fp[FP_F_OFF], pz = ((k & 2) ? z1 : z0) - fp[FP_F_OFF + 2];
        double qx = c * px - s * pz, qz = s * px + c * pz;
        qx0 = fmin(qx0, qx);
        qx1 = fmax(qx1, qx);
        qz0 = fmin(qz0, qz);
        qz1 = fmax(qz1, qz);
    }
    const double *box = fp + FP_F_BOX;
    double ix0 = fmax(qx0, box[0]), ix1 = fmin(qx1, box[3]);
    double iz0 = fmax(qz0, box[2]), iz1 = fmin(qz1, box[5]);
    if (ix0 > ix1 || iz0 > iz1)
        return;
    double u0 = (ix0 - fp[FP_F_A0]) * fp[FP_F_USCALE] + fp[FP_F_PAD_X0];
    double u1 = (ix1 - fp[FP_F_A0]) * fp[FP_F_USCALE] + fp[FP_F_PAD_X0];
    double v0 = (iz0 - fp[FP_F_B0]) * fp[FP_F_VSCALE] + fp[FP_F_PAD_Y0];
    double v1 = (iz1 - fp[FP_F_B0]) * fp[FP_F_VSCALE] + fp[FP_F_PAD_Y0];
    const double *clip = fp + FP_F_CLIP;
    int wrap = (int)fp[FP_F_WRAP];
    if (wrap == 0) {
        if (u1 < clip[0] || u0 > clip[1] || v1 < clip[2] || v0 > clip[3])
            return;
        u0 = fmax(u0, clip[0]);
        u1 = fmin(u1, clip[1]);
        v0 = fmax(v0, clip[2]);
        v1 = fmin(v1, clip[3]);
    } else if (wrap == 1) {
        u0 = fmin(fmax(u0, clip[0]), clip[1]);
        u1 = fmin(fmax(u1, clip[0]), clip[1]);
        v0 = fmin(fmax(v0, clip[2]), clip[3]);
        v1 = fmin(fmax(v1, clip[2]), clip[3]);
    }
    coef_range(fog, u0, u1, v0, v1, fmx, fmn);
}

int fp_reference_grid_fill(const fp_integrate_data_t *fog, const double lo[3], const double hi[3],
                           const int n[3], fp_reference_grid_t *g)
{
    memset(g, 0, sizeof *g);
    const double *fp = fog->fp;
    g->rp[FP_RP_CONTROL] = 1;
    g->rp[FP_RP_STRATIFY] = 1;
    g->rp[FP_RP_FMAX] = g->rp[FP_RP_FMIN] = 1;
    /* Without a fogmap F = 1 everywhere: no grid (the walk's height
     * segments are exact). */
    if (fp[FP_F_HAS_MAP] == 0 || !fog->tables)
        return FP_OK;
    size_t ncell = (size_t)n[0] * n[1] * n[2];
    g->cells = malloc(2 * ncell * sizeof *g->cells);
    if (!g->cells)
        return fp_error("reference: majorant grid: out of memory");
    /* Margins: float rounding of F on the device must not step over the
     * bounds. */
    const double up = 1 + 1e-6, down = 1 - 1e-6;
    double fmx, fmn;
    coef_global(fog, &fmx, &fmn);
    g->rp[FP_RP_FMAX] = fmx * up;
    g->rp[FP_RP_FMIN] = fmn * down;
    for (int i = 0; i < 3; i++) {
        g->n[i] = n[i];
        g->rp[FP_RP_LO + i] = lo[i];
        g->rp[FP_RP_CELL + i] = (hi[i] - lo[i]) / n[i];
        g->rp[FP_RP_N + i] = n[i];
    }
    /* F does not depend on y: one column's bounds serve its cells.  Each
     * holds over the cell grown by a thousandth of its size, so that a
     * point rounded across a face still lies within. */
    const double grow = 1e-3, *cell = g->rp + FP_RP_CELL;
    for (int k = 0; k < n[2]; k++)
        for (int i = 0; i < n[0]; i++) {
            column_bounds(fog, lo[0] + (i - grow) * cell[0], lo[0] + (i + 1 + grow) * cell[0],
                          lo[2] + (k - grow) * cell[2], lo[2] + (k + 1 + grow) * cell[2], &fmx,
                          &fmn);
            for (int j = 0; j < n[1]; j++) {
                size_t at = 2 * (((size_t)k * n[1] + j) * n[0] + i);
                g->cells[at] = (float)(fmx * up);
                g->cells[at + 1] = (float)(fmn * down);
            }
        }
    return FP_OK;
}

static void grow_box(double lo[3], double hi[3], const double o[3], const double d[3], double t)
{
    for (int i = 0; i < 3; i++) {
        double q = o[i] + t * d[i];
        lo[i] = fmin(lo[i], q);
        hi[i] = fmax(hi[i], q);
    }
}

int fp_reference_grid_build(const fp_integrate_data_t *fog, const fp_scatter_data_t *sd,
                            const fp_view_t *v, const float *depth, int cells,
                            fp_reference_grid_t *g)
{
    const double *o = v->origin, *fp = fog->fp;
    double lo[3], hi[3], reach = 0;
    for (int i = 0; i < 3; i++) {
        lo[i] = o[i];
        hi[i] = o[i] + 1;
    }
    if (fp[FP_F_HAS_MAP] == 0 || !fog->tables) {
        const int none[3] = { 1, 1, 1 };
        return fp_reference_grid_fill(fog, lo, hi, none, g);
    }
    for (int i = 0; i < 3; i++)
        hi[i] = o[i];
    /* Surfaces: the view rays' stretch in the fog. */
    for (int y = 0; y < v->height; y++)
        for (int x = 0; x < v->width; x++) {
            double dir[3], len, po[3];
            fp_view_ray(v, x, y, depth[(size_t)y * v->width + x], dir, &len);
            if (!isfinite(len))
                continue;
            fp_view_origin_at(v, x, y, po);
            double te = fp_ref_fog_end(fp, po[0], po[1], po[2], dir[0], dir[1], dir[2], len);
            if (te > 0) {
                grow_box(lo, hi, po, dir, te);
                reach = fmax(reach, te);
            }
        }
    int nl = sd && sd->lights ? (int)sd->lt[FP_LT_NLIGHTS] : 0;
    for (int k = 0; k < nl; k++) {
        const double *pos = sd->lights + (size_t)k * FP_LL_STRIDE + FP_LL_POS;
        double zero[3] = { 0, 0, 0 };
        grow_box(lo, hi, pos, zero, 0);
        reach = fmax(reach, sqrt((pos[0] - o[0]) * (pos[0] - o[0]) +
                                 (pos[1] - o[1]) * (pos[1] - o[1]) +
                                 (pos[2] - o[2]) * (pos[2] - o[2])));
    }
    /* Sky: as far as twice the farthest surface or light, or a few mean
     * free paths at the fog's base without any; the outside chunks take
     * the rest. */
    double base = fmax(fp[FP_F_SIGMA], 0) + fmax(fp[FP_F_HAZE], 0);
    double sky = reach > 0 ? 2 * reach : base > 0 ? 4 / base : 100;
    for (int y = 0; y < v->height; y++)
        for (int x = 0; x < v->width; x++) {
            double dir[3], len, po[3];
            fp_view_ray(v, x, y, depth[(size_t)y * v->width + x], dir, &len);
            if (isfinite(len))
                continue;
            fp_view_origin_at(v, x, y, po);
            double te = fp_ref_fog_end(fp, po[0], po[1], po[2], dir[0], dir[1], dir[2], INFINITY);
            if (te > 0)
                grow_box(lo, hi, po, dir, fmin(te, sky));
        }
    /* Toward the sun: the box swept half its diagonal along the sun's
     * direction. */
    if (sd && sd->lt[FP_LT_SUN_ON] != 0 && (int)sd->lt[FP_LT_SELF] != FP_SELF_OFF) {
        double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                           (hi[2] - lo[2]) * (hi[2] - lo[2]));
        for (int i = 0; i < 3; i++) {
            double s = 0.5 * diag * sd->lt[FP_LT_SUN_DIR + i];
            lo[i] = fmin(lo[i], lo[i] + s);
            hi[i] = fmax(hi[i], hi[i] + s);
        }
    }
    double big = 0;
    for (int i = 0; i < 3; i++) {
        double pad = 1e-3 * (hi[i] - lo[i]) + 1e-6 * (1 + fabs(lo[i]) + fabs(hi[i]));
        lo[i] -= pad;
        hi[i] += pad;
        big = fmax(big, hi[i] - lo[i]);
    }
    /* F varies across, not along y: one cell in y, and about cells^2
     * columns shaped after the box. */
    if (cells < 1)
        cells = FP_REFERENCE_GRID;
    double ex = fmax(hi[0] - lo[0], 1e-2 * big), ez = fmax(hi[2] - lo[2], 1e-2 * big);
    double gm = sqrt(ex * ez);
    int n[3] = { 0, 1, 0 };
    for (int i = 0; i < 3; i += 2) {
        double c = round(cells * (i ? ez : ex) / gm);
        n[i] = c < 1 ? 1 : c > 8 * cells ? 8 * cells : (int)c;
    }
    return fp_reference_grid_fill(fog, lo, hi, n, g);
}

void fp_reference_grid_release(fp_reference_grid_t *g)
{
    free(g->cells);
    g->cells = NULL;
}

/* ------------------------------------------------------------ pieces */

double fp_reference_sigma_t(const fp_integrate_data_t *fog, const double x[3])
{
    const fp_fog_tables_t *t = fog->tables;
    return fp_sigma_t(fog->fp, TABLES(t), x[0], x[1], x[2]);
}

double fp_reference_fog_end(const fp_integrate_data_t *fog, const double o[3], const double d[3],
                            double len)
{
    return fp_ref_fog_end(fog->fp, o[0], o[1], o[2], d[0], d[1], d[2], len);
}

int fp_reference_segments(const fp_integrate_data_t *fog, const fp_reference_grid_t *g,
                          const double o[3], const double d[3], double tend, double *seg,
                          int max)
{
    fp_ref_walk_t w;
    fp_ref_walk_init(&w, fog->fp, g->rp, o[0], o[1], o[2], d[0], d[1], d[2], 0, tend,
                     fp_ref_step(fog->fp, g->rp[FP_RP_CONTROL] != 0));
    int n = 0;
    while (n < max && fp_ref_walk_next(&w, fog->fp, g->rp, g->cells)) {
        double *q = seg + FP_REFERENCE_SEG * n++;
        q[0] = w.s0;
        q[1] = w.s1;
        q[2] = w.mu;
        q[3] = w.r;
        q[4] = w.cm;
        q[5] = w.ch;
    }
    return n;
}

double fp_reference_control(const fp_integrate_data_t *fog, const double *seg, double y)
{
    fp_ref_walk_t w;
    memset(&w, 0, sizeof w);
    w.cm = seg[4];
    w.ch = seg[5];
    return fp_ref_control(&w, fog->fp, y);
}

double fp_reference_control_od(const fp_integrate_data_t *fog, const double o[3],
                               const double d[3], const double *seg)
{
    fp_ref_walk_t w;
    memset(&w, 0, sizeof w);
    for (int i = 0; i < 3; i++) {
        w.o[i] = o[i];
        w.d[i] = d[i];
    }
    w.s0 = seg[0];
    w.s1 = seg[1];
    w.cm = seg[4];
    w.ch = seg[5];
    return fp_ref_control_od(&w, fog->fp);
}

double fp_reference_free_flight(const fp_integrate_data_t *fog, const fp_reference_grid_t *g,
                                const double o[3], const double d[3], double tend,
                                uint32_t *rng)
{
    const fp_fog_tables_t *t = fog->tables;
    fp_rng_t r = { *rng };
    double u0 = FP_RNG_NEXT(&r), u1 = FP_RNG_NEXT(&r), tc;
    int hit = fp_ref_free_flight(fog->fp, TABLES(t), g->rp, g->cells, o[0], o[1], o[2], d[0], d[1],
                                 d[2], 0, tend, &r, u0, u1, &tc);
    *rng = r.state;
    return hit ? tc : INFINITY;
}

double fp_reference_ratio(const fp_integrate_data_t *fog, const fp_reference_grid_t *g,
                          const double o[3], const double d[3], double tend, uint32_t *rng)
{
    const fp_fog_tables_t *t = fog->tables;
    fp_rng_t r = { *rng };
    double T = fp_ref_transmittance(fog->fp, TABLES(t), g->rp, g->cells, o[0], o[1], o[2], d[0],
                                    d[1], d[2], 0, tend, &r);
    *rng = r.state;
    return T;
}

/* ------------------------------------------------------------ frames */

/* The light parameters: the scatter stage's, or ambient fog alone. */
static void light_params(const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                         double lt[FP_LT_COUNT])
{
    if (sd) {
        memcpy(lt, sd->lt, FP_LT_COUNT * sizeof *lt);
        return;
    }
    memset(lt, 0, FP_LT_COUNT * sizeof *lt);
    lt[FP_LT_ALBEDO] = 1;
    for (int c = 0; c < 3; c++)
        lt[FP_LT_AMB + c] = fog->fog_color[c];
    lt[FP_LT_PHASE] = FP_PHASE_ISO;
    lt[FP_LT_SHADOWS] = FP_SHADOWS_NONE;
    lt[FP_LT_SELF] = FP_SELF_EXACT;
}

static int check_params(const fp_params_t *p)
{
    if (p->reference.spp < 1)
        return fp_usage_error("--spp: expected at least 1 sample per pixel (got %d)",
                              p->reference.spp);
    if (p->reference.bounces < 0 || p->reference.bounces > 64)
        return fp_usage_error("--bounces: expected 0 to 64 (got %d)", p->reference.bounces);
    return FP_OK;
}

/* The geometry of scattered paths (fp_ref_solid): the camera's inverse
 * matrices, and the march's step, a third of the shadow map's texel
 * (the smaller side) in scene units; 0 without a map, bounces or
 * --ref-geometry. */
static int solid_setup(const fp_params_t *p, const fp_scatter_data_t *sd, const fp_view_t *v,
                       const float *depth, fp_reference_grid_t *g)
{
    g->rp[FP_RP_SOLID] = 0;
    if (!sd || !v || !depth || p->reference.bounces < 1 || !p->reference.geometry)
        return FP_OK;
    int mode = (int)sd->lt[FP_LT_SHADOWS];
    if (mode != FP_SHADOWS_MAP && mode != FP_SHADOWS_MAP_SCREEN)
        return FP_OK;
    if (fp_mat3_inverse(v->m, g->rp + FP_RP_CAM_INV) ||
        fp_mat3_inverse(v->h, g->rp + FP_RP_NDC_INV))
        return fp_error("reference: the camera's matrices are singular");
    const double *m = sd->lt + FP_LT_SM_NDC;
    double gu = sd->lt[FP_LT_SM_W] * sqrt(m[0] * m[0] + m[4] * m[4] + m[8] * m[8]);
    double gv = sd->lt[FP_LT_SM_H] * sqrt(m[1] * m[1] + m[5] * m[5] + m[9] * m[9]);
    double texel = 1 / fmax(gu, gv);
    if (!(texel > 0) || !isfinite(texel))
        return fp_error("reference: the shadow map has no texel size");
    g->rp[FP_RP_SOLID] = texel / 3;
    return FP_OK;
}

static int setup_grid(const fp_params_t *p, const fp_scatter_data_t *sd,
                      const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                      const fp_reference_opts_t *o, fp_reference_grid_t *g)
{
    fp_reference_opts_t def = { 1, 1, 0 };
    if (!o)
        o = &def;
    int rc = check_params(p);
    if (rc || (rc = fp_reference_grid_build(fog, sd, v, depth, o->cells, g)))
        return rc;
    g->rp[FP_RP_BOUNCES] = p->reference.bounces;
    g->rp[FP_RP_CONTROL] = o->control != 0;
    g->rp[FP_RP_STRATIFY] = o->stratify != 0;
    return solid_setup(p, sd, v, depth, g);
}

/* Means and standard errors from sums over n samples. */
static void finish_pixel(const double *sum, const double *sq, int n, float *out, float *se)
{
    for (int c = 0; c < 4; c++) {
        double m = sum[c] / n;
        out[c] = (float)m;
        if (se) {
            double var = n > 1 ? fmax(sq[c] - sum[c] * m, 0) / (n - 1) : INFINITY;
            se[c] = (float)sqrt(var / n);
        }
    }
}

typedef struct c_job_t {
    const fp_params_t *p;
    const fp_scatter_data_t *sd;
    const fp_integrate_data_t *fog;
    const fp_view_t *v;
    const float *depth;
    const fp_reference_grid_t *g;
    double lt[FP_LT_COUNT];
    float view[FP_VIEW_FLOATS];
    const int *pix;      /* the pixel list (NULL: the frame) */
    size_t npix;         /* entries: the list's, or the frame's pixels */
    float *out, *se;     /* per entry */
    atomic_size_t next;  /* the next chunk of entries to take */
} c_job_t;

static void *c_entries(void *arg)
{
    c_job_t *job = arg;
    const fp_view_t *v = job->v;
    const fp_fog_tables_t *t = job->fog->tables;
    const float *smap = job->sd && job->sd->smap ? job->sd->smap : no_map;
    const float *grid = job->g->cells ? job->g->cells : no_grid;
    const double *lights = job->sd && job->sd->lights ? job->sd->lights : no_lights;
    int spp = job->p->reference.spp;
    uint32_t seed = (uint32_t)job->p->anim.seed;
    size_t chunk = (size_t)v->width;
    for (size_t e0; (e0 = atomic_fetch_add(&job->next, chunk)) < job->npix;)
        for (size_t e = e0; e < e0 + chunk && e < job->npix; e++) {
            size_t i = job->pix ? (size_t)job->pix[e] : e;
            int x = (int)(i % (size_t)v->width), y = (int)(i / (size_t)v->width);
            double dir[3], len, sum[4] = { 0, 0, 0, 0 }, sq[4] = { 0, 0, 0, 0 }, o[3];
            fp_view_ray(v, x, y, job->depth[i], dir, &len);
            fp_view_origin_at(v, x, y, o);
            for (int s = 0; s < spp; s++) {
                double S[3];
                double tau = fp_ref_sample(job->fog->fp, TABLES(t), job->lt, lights, smap, job->view,
                                           job->depth, v->width, v->height, job->g->rp, grid,
                                           seed, (uint32_t)i, (uint32_t)s, o[0],
                                           o[1], o[2], dir[0], dir[1], dir[2],
                                           len, S);
                for (int c = 0; c < 3; c++) {
                    sum[c] += S[c];
                    sq[c] += S[c] * S[c];
                }
                sum[3] += tau;
                sq[3] += tau * tau;
            }
            finish_pixel(sum, sq, spp, job->out + 4 * e, job->se ? job->se + 4 * e : NULL);
        }
    return NULL;
}

/* The C version for the frame (pix NULL) or a pixel list. */
static int reference_c(const fp_params_t *p, const fp_scatter_data_t *sd,
                       const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                       const fp_reference_opts_t *o, const int *pix, size_t npix, float *out,
                       float *se)
{
    fp_reference_grid_t g;
    int rc = setup_grid(p, sd, fog, v, depth, o, &g);
    if (rc)
        return rc;
    c_job_t *job = malloc(sizeof *job);
    if (!job) {
        fp_reference_grid_release(&g);
        return fp_error("reference: out of memory");
    }
    job->p = p;
    job->sd = sd;
    job->fog = fog;
    job->v = v;
    job->depth = depth;
    job->g = &g;
    light_params(sd, fog, job->lt);
    fp_view_pack(v, job->view);
    job->pix = pix;
    job->npix = pix ? npix : (size_t)v->width * v->height;
    job->out = out;
    job->se = se;
    atomic_init(&job->next, 0);
    /* Pixels are independent: threads take chunks of entries, the bits do
     * not depend on how many. */
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    int nt = ncpu < 1 ? 1 : ncpu > 64 ? 64 : (int)ncpu;
    pthread_t th[64];
    int started = 0;
    for (; started < nt - 1; started++)
        if (fp_thread_start(&th[started], c_entries, job))
            break;
    c_entries(job);
    for (int k = 0; k < started; k++)
        pthread_join(th[k], NULL);
    free(job);
    fp_reference_grid_release(&g);
    return FP_OK;
}

int fp_reference_process_se(const fp_params_t *p, const fp_scatter_data_t *sd,
                            const fp_integrate_data_t *fog, const fp_view_t *v,
                            const float *depth, const fp_reference_opts_t *o, float *out,
                            float *se)
{
    return reference_c(p, sd, fog, v, depth, o, NULL, 0, out, se);
}

int fp_reference_pixels(const fp_params_t *p, const fp_scatter_data_t *sd,
                        const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                        const int *pix, size_t npix, float *out)
{
    return npix ? reference_c(p, sd, fog, v, depth, NULL, pix, npix, out, NULL) : FP_OK;
}

int fp_reference_process(const fp_params_t *p, const fp_scatter_data_t *sd,
                         const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                         float *out)
{
    return fp_reference_process_se(p, sd, fog, v, depth, NULL, out, NULL);
}

/* ------------------------------------------------------------ OpenCL */

int fp_reference_cl_init(fp_cl_t *cl, fp_reference_cl_t *s)
{
    memset(s, 0, sizeof *s);
    s->cl = cl;
    cl_program prog;
    if (fp_cl_program(cl, "reference", "-cl-std=CL1.2", &prog) ||
        fp_cl_kernel(prog, "reference_fog", &s->kernel))
        return FP_ERR;
    cl_context ctx = fp_cl_context(cl);
    struct { cl_mem *m; size_t size; } fixed[] = {
        { &s->view, FP_VIEW_FLOATS * sizeof(float) },
        { &s->fp, FP_F_COUNT * sizeof(float) },
        { &s->lvi, FP_LEVEL_TABLE * FP_LI_STRIDE * sizeof(cl_int) },
        { &s->lvf, FP_LEVEL_TABLE * FP_LR_STRIDE * sizeof(float) },
        { &s->lt, FP_LT_COUNT * sizeof(float) },
        { &s->rp, FP_RP_COUNT * sizeof(float) },
    };
    for (size_t k = 0; k < FP_ARRAY_LEN(fixed); k++) {
        cl_int err;
        *fixed[k].m = clCreateBuffer(ctx, CL_MEM_READ_ONLY, fixed[k].size, NULL, &err);
        if (fp_cl_check(err, "reference: parameter buffer"))
            return FP_ERR;
    }
    return FP_OK;
}

/* A read-only buffer of at least n bytes holding `data`; recreated when
 * it is too small. */
static int upload(fp_reference_cl_t *s, cl_mem *m, size_t *have, const void *data, size_t n,
                  const char *what)
{
    cl_int err;
    if (!*m || *have < n) {
        if (*m)
            clReleaseMemObject(*m);
        *m = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY, n, NULL, &err);
        *have = *m ? n : 0;
        if (fp_cl_check(err, what))
            return FP_ERR;
    }
    return fp_cl_check(clEnqueueWriteBuffer(fp_cl_queue(s->cl), *m, CL_TRUE, 0, n, data, 0, NULL,
                                            NULL), what);
}

static int upload_reals(fp_reference_cl_t *s, cl_mem m, const double *v, int n, const char *what)
{
    float f[FP_LT_COUNT];
    for (int i = 0; i < n; i++)
        f[i] = (float)v[i];
    return fp_cl_check(clEnqueueWriteBuffer(fp_cl_queue(s->cl), m, CL_TRUE, 0, n * sizeof(float),
                                            f, 0, NULL, NULL), what);
}

/* Buffers for a frame of n pixels, launched in bands of at most m. */
static int ensure_frame(fp_reference_cl_t *s, size_t n, size_t m)
{
    cl_int err;
    cl_context ctx = fp_cl_context(s->cl);
    if (n > s->capacity) {
        if (s->depth)
            clReleaseMemObject(s->depth);
        s->capacity = 0;
        s->depth = clCreateBuffer(ctx, CL_MEM_READ_ONLY, n * sizeof(float), NULL, &err);
        if (fp_cl_check(err, "reference: depth buffer"))
            return FP_ERR;
        s->capacity = n;
    }
    if (m > s->band) {
        if (s->acc)
            clReleaseMemObject(s->acc);
        free(s->sum);
        free(s->part);
        s->sum = NULL;
        s->part = NULL;
        s->band = 0;
        s->acc = clCreateBuffer(ctx, CL_MEM_WRITE_ONLY, m * 8 * sizeof(float), NULL, &err);
        if (fp_cl_check(err, "reference: sum buffer"))
            return FP_ERR;
        s->sum = malloc(m * 8 * sizeof *s->sum);
        s->part = malloc(m * 8 * sizeof *s->part);
        if (!s->sum || !s->part)
            return fp_error("reference: out of memory");
        s->band = m;
    }
    return FP_OK;
}

/* The OpenCL version for the frame (pix NULL) or a pixel list. */
static int reference_cl(fp_reference_cl_t *s, const fp_params_t *p, const fp_scatter_data_t *sd,
                        const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                        const fp_reference_opts_t *o, const int *pix, size_t npix, float *out,
                        float *se)
{
    fp_reference_grid_t g;
    int rc = setup_grid(p, sd, fog, v, depth, o, &g);
    if (rc)
        return rc;
    size_t n = (size_t)v->width * v->height;
    const fp_fog_tables_t *t = fog->tables;
    double lt[FP_LT_COUNT];
    light_params(sd, fog, lt);
    float view[FP_VIEW_FLOATS], lvf[FP_LEVEL_TABLE * FP_LR_STRIDE];
    fp_view_pack(v, view);
    for (int i = 0; i < FP_LEVEL_TABLE * FP_LR_STRIDE; i++)
        lvf[i] = (float)(t ? t->lvf[i] : 0);
    cl_command_queue q = fp_cl_queue(s->cl);
    size_t ns = sd && sd->smap ? sd->smap_n : 1;
    /* The lights' table in single precision (at least one row). */
    size_t nlf = (size_t)(sd && sd->nlights > 0 ? sd->nlights : 1) * FP_LL_STRIDE;
    float *lf = calloc(nlf, sizeof *lf);
    if (!lf) {
        fp_reference_grid_release(&g);
        return fp_error("reference: out of memory");
    }
    for (size_t i = 0; sd && sd->lights && i < (size_t)sd->nlights * FP_LL_STRIDE; i++)
        lf[i] = (float)sd->lights[i];
    size_t ng = g.cells ? 2 * (size_t)g.n[0] * g.n[1] * g.n[2] : 2;
    /* Launches of at most FP_REF_LAUNCH pixel-samples (fewer with
     * bounces): bands of entries (whole rows' worth), each through batches
     * of samples, fixed by the frame's size and spp alone. */
    int w = v->width, h = v->height, spp = p->reference.spp;
    double budget = (double)FP_REF_LAUNCH / (1 + p->reference.bounces);
    int rows = (double)w * h <= budget ? h : (int)fmax(1, budget / w);
    int batch = (int)fmin(fmin(spp, FP_REF_BATCH), fmax(1, budget / ((double)w * rows)));
    size_t band = (size_t)w * rows, entries = pix ? npix : n;
    static const int no_pix[1] = { 0 };
    rc = FP_ERR;
    if (ensure_frame(s, n, band) ||
        upload(s, &s->pix, &s->pix_n, pix && npix ? pix : no_pix,
               (pix && npix ? npix : 1) * sizeof(int), "reference: pixel list") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->view, CL_TRUE, 0, sizeof view, view, 0, NULL, NULL),
                    "reference: upload view") ||
        upload_reals(s, s->fp, fog->fp, FP_F_COUNT, "reference: upload fog parameters") ||
        upload_reals(s, s->lt, lt, FP_LT_COUNT, "reference: upload light parameters") ||
        upload_reals(s, s->rp, g.rp, FP_RP_COUNT, "reference: upload grid parameters") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->lvi, CL_TRUE, 0,
                                         FP_LEVEL_TABLE * FP_LI_STRIDE * sizeof(int),
                                         fp_fog_tables_or_empty(t)->lvi, 0, NULL, NULL),
                    "reference: upload level table") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->lvf, CL_TRUE, 0, sizeof lvf, lvf, 0, NULL, NULL),
                    "reference: upload level table") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->depth, CL_TRUE, 0, n * sizeof(float), depth, 0,
                                         NULL, NULL), "reference: upload depth") ||
        upload(s, &s->smap, &s->smap_n, sd && sd->smap ? sd->smap : no_map, ns * sizeof(float),
               "reference: shadow map") ||
        upload(s, &s->grid, &s->grid_n, g.cells ? g.cells : no_grid, ng * sizeof(float),
               "reference: majorant grid") ||
        upload(s, &s->lights, &s->lights_n, lf, nlf * sizeof(float), "reference: lights"))
        goto done;
    unsigned long serial = t ? t->serial : 0;
    if (!s->coef || s->tables != serial) {
        size_t nc = t ? t->ncoef : 1;
        if (upload(s, &s->coef, &s->coef_n, fp_fog_tables_or_empty(t)->coef, nc * sizeof(float),
                   "reference: fogmap coefficients"))
            goto done;
        s->tables = serial;
    }
    cl_uint seed = (cl_uint)p->anim.seed;
    cl_kernel k = s->kernel;
    cl_int cw = w, ch = h, cnpix = pix ? (cl_int)npix : 0;
    for (size_t at = 0; at < entries; at += band) {
        size_t np = at + band < entries ? band : entries - at;
        cl_int e0 = (cl_int)at, ne = (cl_int)np;
        size_t global = fp_cl_round_up(np, 64);
        memset(s->sum, 0, np * 8 * sizeof *s->sum);
        for (int s0 = 0; s0 < spp; s0 += batch) {
            cl_int b0 = s0, b1 = s0 + batch < spp ? s0 + batch : spp;
            if (FP_CL_ARG(k, 0, s->depth) || FP_CL_ARG(k, 1, s->acc) || FP_CL_ARG(k, 2, s->view) ||
                FP_CL_ARG(k, 3, cw) || FP_CL_ARG(k, 4, ch) || FP_CL_ARG(k, 5, s->pix) ||
                FP_CL_ARG(k, 6, cnpix) || FP_CL_ARG(k, 7, e0) || FP_CL_ARG(k, 8, ne) ||
                FP_CL_ARG(k, 9, s->fp) || FP_CL_ARG(k, 10, s->lvi) || FP_CL_ARG(k, 11, s->lvf) ||
                FP_CL_ARG(k, 12, s->coef) || FP_CL_ARG(k, 13, s->lt) ||
                FP_CL_ARG(k, 14, s->smap) || FP_CL_ARG(k, 15, s->rp) || FP_CL_ARG(k, 16, s->grid) ||
                FP_CL_ARG(k, 17, seed) || FP_CL_ARG(k, 18, b0) || FP_CL_ARG(k, 19, b1) ||
                FP_CL_ARG(k, 20, s->lights))
                goto done;
            if (fp_cl_check(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, NULL, 0, NULL, NULL),
                            "reference_fog") ||
                fp_cl_check(clEnqueueReadBuffer(q, s->acc, CL_TRUE, 0, np * 8 * sizeof(float),
                                                s->part, 0, NULL, NULL), "reference: read sums"))
                goto done;
            for (size_t i = 0; i < np * 8; i++)
                s->sum[i] += s->part[i];
        }
        for (size_t i = 0; i < np; i++)
            finish_pixel(s->sum + 8 * i, s->sum + 8 * i + 4, spp, out + 4 * (at + i),
                         se ? se + 4 * (at + i) : NULL);
    }
    rc = FP_OK;
done:
    free(lf);
    fp_reference_grid_release(&g);
    return rc;
}

int fp_reference_process_cl_se(fp_reference_cl_t *s, const fp_params_t *p,
                               const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                               const fp_view_t *v, const float *depth,
                               const fp_reference_opts_t *o, float *out, float *se)
{
    return reference_cl(s, p, sd, fog, v, depth, o, NULL, 0, out, se);
}

int fp_reference_pixels_cl(fp_reference_cl_t *s, const fp_params_t *p,
                           const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                           const fp_view_t *v, const float *depth, const int *pix, size_t npix,
                           float *out)
{
    return npix ? reference_cl(s, p, sd, fog, v, depth, NULL, pix, npix, out, NULL) : FP_OK;
}

int fp_reference_process_cl(fp_reference_cl_t *s, const fp_params_t *p,
                            const fp_scatter_data_t *sd, const fp_integrate_data_t *fog,
                            const fp_view_t *v, const float *depth, float *out)
{
    return fp_reference_process_cl_se(s, p, sd, fog, v, depth, NULL, out, NULL);
}

void fp_reference_cl_release(fp_reference_cl_t *s)
{
    cl_mem *mems[] = { &s->depth, &s->acc, &s->view, &s->fp, &s->lvi, &s->lvf,
                       &s->coef, &s->lt, &s->smap, &s->rp, &s->grid, &s->pix, &s->lights };
    if (s->kernel)
        clReleaseKernel(s->kernel);
    for (size_t i = 0; i < FP_ARRAY_LEN(mems); i++)
        if (*mems[i])
            clReleaseMemObject(*mems[i]);
    free(s->sum);
    free(s->part);
    memset(s, 0, sizeof *s);
}
