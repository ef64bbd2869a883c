/* fogpipe stage "deep": the fog of one ray as deep samples, and the deep
 * sample arithmetic of OpenEXR's "Interpreting OpenEXR Deep Pixels"
 * (splitting, tidying, flattening).  See deep.h. */
#include "deep.h"
#include "fp.h"
#include "options.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/scatter_core.h"

/* Probes per segment: at its quarters. */
#ifndef FP_DEEP_PROBES
#define FP_DEEP_PROBES 4
#endif
/* Segments first made per span between forced boundaries. */
#define FP_DEEP_FIRST_DIVISION 8
/* The largest alpha of a segment checked by probes at its quarters: in a
 * more opaque one they would all lie where little light is left. */
#define FP_DEEP_PROBE_ALPHA 0.75

#define DP(f) offsetof(fp_params_t, deep.f)
const fp_option_t fp_deep_options[] = {
    { "deep", 0, FP_OPT_FLAG, DP(deep), 0, 0, NULL, 0, 1, NULL, NULL,
      "write deep scanline EXR: the fog as volumetric samples [Z, ZBack] in front of the "
      "surface's sample (R G B A Z ZBack and the plate's other channels), so that elements "
      "merged later sit inside the fog; a deep input is fogged sample by sample", NULL, 0 },
    { "deep-bound", 0, FP_OPT_REAL, DP(bound), 0, 0, "1e-4", 1e-7, 0.1, NULL, "E",
      "largest error of the fog that splitting the deep samples at any depth may give "
      "(|dS| + |dtau| per channel, times max(1, the pixel's fog brightness)); smaller: "
      "more samples", NULL, 0 },
    { "deep-max-samples", 0, FP_OPT_INT, DP(max_samples), 0, 0, "128", 1, 4096, NULL, "N",
      "at most N fog samples per pixel (a pixel that needs more keeps N and is counted in "
      "--stats and -v)", NULL, 0 },
    { "deep-max-alpha", 0, FP_OPT_REAL, DP(max_alpha), 0, 0, "1", 0.01, 1, NULL, "A",
      "split fog samples until none has an alpha above A (for deep mergers that order "
      "overlapping samples without splitting them, such as oiiotool --deepmerge: their "
      "error is at most about A of what they misplace)", NULL, 0 },
    FP_OPT_END
};

int fp_deep_commit(const fp_params_t *p, fp_deep_data_t *d)
{
    memset(d, 0, sizeof *d);
    d->on = p->deep.deep;
    d->bound = p->deep.bound > 0 ? p->deep.bound : 1e-4;
    d->max_samples = p->deep.max_samples > 0 ? p->deep.max_samples : 128;
    d->max_alpha = p->deep.max_alpha > 0 && p->deep.max_alpha <= 1 ? p->deep.max_alpha : 1;
    d->sky_keep = p->fog.sky == 1;
    if (!d->on)
        return FP_OK;
    if (p->fogmap.integrator == FP_INTEGRATOR_REFERENCE)
        return fp_usage_error("--deep: the Monte Carlo reference (--integrator reference) "
                              "cannot be split into deep samples (use exact or march)");
    if (p->buffers.blur != FP_BLUR_OFF || p->buffers.resolution > 1)
        return fp_usage_error("--deep: --blur and --fog-resolution filter the flat fog "
                              "layer; deep samples are computed per ray (leave them off)");
    const char *cz = p->io.compression;
    if (cz && strcmp(cz, "input") != 0 && strcmp(cz, "none") != 0 && strcmp(cz, "rle") != 0 &&
        strcmp(cz, "zips") != 0)
        return fp_usage_error("--deep: --compression %s cannot hold deep data (expected "
                              "input, none, rle or zips, the codecs OpenEXR allows for deep "
                              "files)", cz);
    const char *o = p->io.output, *ext = o ? strrchr(o, '.') : NULL;
    if (p->preview.preview || p->preview.contact_sheet ||
        (ext && (strcasecmp(ext, ".png") == 0 || strcasecmp(ext, ".tif") == 0 ||
                 strcasecmp(ext, ".tiff") == 0 || strcasecmp(ext, ".jpg") == 0 ||
                 strcasecmp(ext, ".jpeg") == 0)))
        return fp_usage_error("--deep: previews and image outputs (-o x.png) show a flat "
                              "frame; write deep EXR (-o x.exr) and flatten it");
    if (p->aov.aov || p->aov.aov_only)
        return fp_usage_error("--deep: --aov/--aov-only write flat fog layers (deep samples "
                              "carry the fog themselves)");
    return FP_OK;
}

/* ------------------------------------------------------------ lists */

int fp_dlist_push(fp_dlist_t *l, const fp_dsample_t *s)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        fp_dsample_t *ns = realloc(l->s, cap * sizeof *ns);
        if (!ns)
            return FP_ERR;
        l->s = ns;
        l->cap = cap;
    }
    l->s[l->n++] = *s;
    return FP_OK;
}

void fp_dlist_free(fp_dlist_t *l)
{
    free(l->s);
    memset(l, 0, sizeof *l);
}

/* ------------------------------------------------------------ sample rules */

/* The part of a homogeneous sample over a fraction f of its range
 * ("Interpreting OpenEXR Deep Pixels", splitting a volume sample):
 * alpha 1 - (1 - a)^f, colour c * a' / a (c * f when a = 0). */
static void part_of(const fp_dsample_t *s, double f, fp_dsample_t *out)
{
    *out = *s;
    if (f >= 1)
        return;
    if (f <= 0) {
        out->a = 0;
        out->c[0] = out->c[1] = out->c[2] = 0;
        return;
    }
    double a = s->a, ap, k;
    if (a >= 1) {
        ap = 1;
        k = 1;
    } else if (a <= 0) {
        ap = 0;
        k = f;
    } else {
        ap = -expm1(f * log1p(-a));
        k = ap / a;
    }
    out->a = ap;
    for (int c = 0; c < 3; c++)
        out->c[c] = s->c[c] * k;
}

void fp_deep_split_front(const fp_dsample_t *s, double z, fp_dsample_t *front)
{
    double f = s->zb > s->z ? (z - s->z) / (s->zb - s->z) : (z > s->z ? 1 : 0);
    part_of(s, f, front);
    if (f < 1)
        front->zb = z < s->z ? s->z : z;
}

/* Two samples over the same range combined (the document's merge of
 * coincident volumes: optical depths add, emission in proportion). */
static void combine(fp_dsample_t *x, const fp_dsample_t *y)
{
    double a1 = x->a, a2 = y->a;
    if (a1 >= 1 || a2 >= 1) {
        for (int c = 0; c < 3; c++)
            x->c[c] = a1 >= 1 && a2 >= 1 ? 0.5 * (x->c[c] + y->c[c])
                                          : (a1 >= 1 ? x->c[c] : y->c[c]);
        x->a = 1;
        if (a1 < 1)
            x->src = y->src;
        return;
    }
    const double tiny = 1e-12;
    double u1 = -log1p(-a1), u2 = -log1p(-a2), u = u1 + u2;
    double a = -expm1(-u);
    double w = u > tiny ? a / u : 1;
    for (int c = 0; c < 3; c++) {
        double v1 = u1 > tiny ? x->c[c] * u1 / a1 : x->c[c];
        double v2 = u2 > tiny ? y->c[c] * u2 / a2 : y->c[c];
        x->c[c] = (v1 + v2) * w;
    }
    x->a = a;
    /* the fog has no channels of its own: the input's are kept */
    if (x->src == FP_DEEP_SRC_FOG)
        x->src = y->src;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int cmp_sample(const void *a, const void *b)
{
    const fp_dsample_t *x = a, *y = b;
    if (x->z != y->z)
        return (x->z > y->z) - (x->z < y->z);
    if (x->zb != y->zb)
        return (x->zb > y->zb) - (x->zb < y->zb);
    /* stable among equals: the input before the fog (src order) */
    return (x->src < y->src) - (x->src > y->src);
}

int fp_deep_tidy(fp_dlist_t *l)
{
    size_t n = l->n;
    if (n < 2) {
        return FP_OK;
    }
    double *b = malloc(2 * n * sizeof *b);
    fp_dlist_t out = { NULL, 0, 0 };
    int rc = FP_OK;
    if (!b)
        return FP_ERR;
    size_t nb = 0;
    for (size_t i = 0; i < n; i++) {
        b[nb++] = l->s[i].z;
        b[nb++] = l->s[i].zb;
    }
    qsort(b, nb, sizeof *b, cmp_double);
    size_t u = 0;
    for (size_t i = 0; i < nb; i++)
        if (u == 0 || b[i] != b[u - 1])
            b[u++] = b[i];
    nb = u;
    for (size_t i = 0; i < n && rc == FP_OK; i++) {
        const fp_dsample_t *s = &l->s[i];
        if (!(s->zb > s->z)) {
            rc = fp_dlist_push(&out, s);
            continue;
        }
        /* the boundaries inside (z, zb): binary search for z */
        size_t lo = 0, hi = nb;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (b[mid] < s->z)
                lo = mid + 1;
            else
                hi = mid;
        }
        double range = s->zb - s->z;
        for (size_t k = lo; k + 1 < nb && b[k] < s->zb && rc == FP_OK; k++) {
            fp_dsample_t piece;
            part_of(s, (b[k + 1] - b[k]) / range, &piece);
            piece.z = b[k];
            piece.zb = b[k + 1];
            rc = fp_dlist_push(&out, &piece);
        }
    }
    free(b);
    if (rc) {
        fp_dlist_free(&out);
        return rc;
    }
    qsort(out.s, out.n, sizeof *out.s, cmp_sample);
    size_t m = 0;
    for (size_t i = 0; i < out.n; i++) {
        if (m > 0 && out.s[m - 1].z == out.s[i].z && out.s[m - 1].zb == out.s[i].zb)
            combine(&out.s[m - 1], &out.s[i]);
        else
            out.s[m++] = out.s[i];
    }
    out.n = m;
    fp_dlist_free(l);
    *l = out;
    return FP_OK;
}

void fp_deep_flatten(const fp_dsample_t *s, size_t n, double z_cut, double rgba[4])
{
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0;
    for (size_t i = 0; i < n; i++) {
        if (!(s[i].z < z_cut))
            break;
        fp_dsample_t p = s[i];
        if (s[i].zb > z_cut)
            fp_deep_split_front(&s[i], z_cut, &p);
        double t = 1 - rgba[3];
        for (int c = 0; c < 3; c++)
            rgba[c] += t * p.c[c];
        rgba[3] += t * p.a;
    }
}

/* ------------------------------------------------------------ the fog of one ray */

double fp_deep_ray_scale(const fp_view_t *v, int x, int y)
{
    if (v->depth_kind == FP_DEPTH_RADIAL)
        return 1;
    /* planar camera z (inverse depth is written as its z): the ray's
     * length at z = 1 */
    fp_view_t u = *v;
    u.depth_kind = FP_DEPTH_PLANAR;
    u.far = INFINITY;
    double dir[3], len;
    fp_view_ray(&u, x, y, 1.0f, dir, &len);
    return len > 0 && isfinite(len) ? len : 1;
}

/* A point of the ray evaluated exactly: transmittance and in-scatter of
 * the ray from the camera to t.  `node`: a sample boundary. */
typedef struct pt_t {
    double t, T, S[3];
    int node, forced;
    double err;     /* a node: its segment's error, when err_ok */
    int err_ok;
} pt_t;

typedef struct ray_t {
    const fp_deep_fog_t *f;
    float view[FP_VIEW_FLOATS];
    double o[3], dir[3];
    double jitter, offset;
    int lit;
    long evals;
    pt_t *p;
    size_t n, cap;
} ray_t;

static void ray_eval(ray_t *r, double t, pt_t *p)
{
    const fp_deep_fog_t *f = r->f;
    memset(p, 0, sizeof *p);
    p->t = t;
    if (r->lit) {
        p->T = fp_scatter_ray_at(f->light, f->fog, f->view, r->view, f->depth, r->o, r->dir, t,
                                 r->offset, p->S);
    } else {
        double od = fp_integrate_optical_depth(f->fog, r->o, r->dir, t, r->jitter);
        p->T = exp(-od);
        for (int c = 0; c < 3; c++)
            p->S[c] = (1 - p->T) * f->fog->fog_color[c];
    }
    r->evals++;
}

/* Insert a point (sorted by t); returns its index, or -1 (memory). */
static long ray_insert(ray_t *r, const pt_t *p)
{
    if (r->n == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 64;
        pt_t *np = realloc(r->p, cap * sizeof *np);
        if (!np)
            return -1;
        r->p = np;
        r->cap = cap;
    }
    size_t i = r->n;
    while (i > 0 && r->p[i - 1].t > p->t)
        i--;
    memmove(r->p + i + 1, r->p + i, (r->n - i) * sizeof *r->p);
    r->p[i] = *p;
    r->n++;
    return (long)i;
}

static long ray_add(ray_t *r, double t, int node)
{
    pt_t p;
    ray_eval(r, t, &p);
    p.node = node;
    return ray_insert(r, &p);
}

/* What the split rule gives at q from the segment a..b (deep.h). */
static double seg_error(const pt_t *a, const pt_t *b, const pt_t *q)
{
    double len = b->t - a->t;
    double f = len > 0 ? (q->t - a->t) / len : 1;
    double T, S[3];
    if (a->T <= 0) {
        T = 0;
        memcpy(S, a->S, sizeof S);
    } else {
        double ratio = b->T / a->T;
        if (ratio > 1)
            ratio = 1;
        double al = 1 - ratio, ap, k;
        if (al <= 0) {
            ap = 0;
            k = f;
        } else if (ratio <= 0) {
            ap = f > 0 ? 1 : 0;
            k = ap;
        } else {
            ap = -expm1(f * log(ratio));
            k = ap / al;
        }
        T = a->T * (1 - ap);
        for (int c = 0; c < 3; c++)
            S[c] = a->S[c] + (b->S[c] - a->S[c]) * k;
    }
    double e = 0;
    for (int c = 0; c < 3; c++) {
        double d = fabs(S[c] - q->S[c]);
        if (d > e)
            e = d;
    }
    return e + fabs(T - q->T);
}

/* The largest error of the segment between points i and j over the points
 * between them. */
static double span_error(const ray_t *r, size_t i, size_t j, size_t *worst)
{
    double e = 0;
    *worst = i;
    for (size_t k = i + 1; k < j; k++) {
        double ek = seg_error(&r->p[i], &r->p[j], &r->p[k]);
        if (ek > e) {
            e = ek;
            *worst = k;
        }
    }
    return e;
}

/* A segment whose alpha is above FP_DEEP_PROBE_ALPHA while the light in
 * front of it is above a tenth of the bound. */
static int too_opaque(const pt_t *a, const pt_t *b, double tol)
{
    return a->T > 0.1 * tol && b->T < (1 - FP_DEEP_PROBE_ALPHA) * a->T &&
           b->t - a->t > 1e-9 * (b->t + 1);
}

static size_t next_node(const ray_t *r, size_t i)
{
    size_t j = i + 1;
    while (j < r->n && !r->p[j].node)
        j++;
    return j;
}

/* Probes at 1/4, 1/2, 3/4 of the segment from node i to the next, where
 * none is already near them. */
static int probe_segment(ray_t *r, size_t i)
{
    size_t j = next_node(r, i);
    if (j >= r->n)
        return FP_OK;
    double t0 = r->p[i].t, t1 = r->p[j].t, len = t1 - t0;
    if (!(len > 1e-9 * (fabs(t1) + 1)))
        return FP_OK;
    for (int q = 1; q < FP_DEEP_PROBES; q++) {
        double t = t0 + len * q / FP_DEEP_PROBES;
        int near = 0;
        /* the points of this segment, found again (inserts move them) */
        for (size_t k = 0; k < r->n; k++)
            if (fabs(r->p[k].t - t) < 0.2 * len / FP_DEEP_PROBES) {
                near = 1;
                break;
            }
        if (!near && ray_add(r, t, 0) < 0)
            return FP_ERR;
    }
    return FP_OK;
}

static size_t count_nodes(const ray_t *r)
{
    size_t c = 0;
    for (size_t k = 0; k < r->n; k++)
        c += r->p[k].node != 0;
    return c;
}

int fp_deep_fog_pixel(const fp_deep_fog_t *f, int x, int y, double z_end, const double *forced,
                      size_t nforced, fp_dlist_t *out, fp_deep_stats_t *st)
{
    const fp_view_t *v = f->view;
    const fp_deep_data_t *dd = f->deep;
    ray_t r;
    memset(&r, 0, sizeof r);
    r.f = f;
    r.lit = f->light && f->light->active;
    fp_view_pack(v, r.view);
    double len_dummy;
    fp_view_ray(v, x, y, 1.0f, r.dir, &len_dummy);
    fp_view_origin_at(v, x, y, r.o);
    r.jitter = f->fog->fp[FP_F_JITTER] != 0 ? fp_integrate_jitter(x, y) : 0;
    r.offset = r.lit ? fp_interleave_offset(f->light->lt, x, y) : 0;
    double k = fp_deep_ray_scale(v, x, y);
    double t_end = isfinite(z_end) ? z_end * k : INFINITY;
    int rc = FP_OK;

    double ta, tb;
    if (!(t_end > 0) ||
        !fp_fog_span(f->fog->fp, r.o[0], r.o[1], r.o[2], r.dir[0], r.dir[1], r.dir[2], t_end,
                     &ta, &tb) ||
        !(tb > ta))
        goto done;
    if (ta < 0)
        ta = 0;
    if (tb > t_end)
        tb = t_end;
    pt_t end;
    if (isinf(tb)) {
        /* Unbounded fog (no top, a ray toward the horizon): the samples
         * stop where what is left beyond is a tenth of the bound, and the
         * last one ends with the whole ray's values, so that the flattened
         * sky is exact. */
        pt_t inf, p;
        ray_eval(&r, INFINITY, &inf);
        double tol = 0.1 * dd->bound * fmax(1, fmax(inf.S[0], fmax(inf.S[1], inf.S[2])));
        double step = 1;
        for (;; step *= 2) {
            ray_eval(&r, ta + step, &p);
            double e = fabs(p.T - inf.T);
            for (int c = 0; c < 3; c++)
                e = fmax(e, fabs(p.S[c] - inf.S[c]));
            if (e <= tol || step > 1e9)
                break;
        }
        tb = ta + step;
        end = inf;
        end.t = tb;
    } else {
        ray_eval(&r, tb, &end);
    }
    end.node = end.forced = 1;
    if (ray_add(&r, ta, 1) < 0 || ray_insert(&r, &end) < 0)
        goto oom;
    r.p[0].forced = 1;
    for (size_t i = 0; i < nforced; i++) {
        double t = forced[i] * k;
        if (t > ta && t < tb) {
            long at = ray_add(&r, t, 1);
            if (at < 0)
                goto oom;
            r.p[at].forced = 1;
        }
    }
    double smax = fmax(1, fmax(end.S[0], fmax(end.S[1], end.S[2])));
    /* with light, probes check half the bound: between them the fog may
     * differ from the split rule by a little more than at them (the
     * light's quadrature places its steps by the ray's end) */
    double tol = (r.lit ? 0.5 : 1.0) * dd->bound * smax;
    /* A first even division (features of the light, shafts, narrower than
     * a segment's quarter would pass between the probes), then probes. */
    {
        size_t n0 = r.n;
        for (size_t i = 0; i + 1 < n0; i++) {
            double t0 = r.p[i].t, t1 = r.p[i + 1].t;
            for (int q = 1; q < FP_DEEP_FIRST_DIVISION; q++)
                if (ray_add(&r, t0 + (t1 - t0) * q / FP_DEEP_FIRST_DIVISION, 1) < 0)
                    goto oom;
            i += FP_DEEP_FIRST_DIVISION - 1;
            n0 += FP_DEEP_FIRST_DIVISION - 1;
        }
    }
    for (size_t i = 0; i + 1 < r.n; i = next_node(&r, i))
        if (probe_segment(&r, i))
            goto oom;

    /* Bisection: the worst segment first, while it is off by more than the
     * bound and the pixel has samples left. */
    size_t limit = (size_t)dd->max_samples + nforced + 1, nodes = count_nodes(&r);
    for (;;) {
        /* each segment's error is kept at its first node until it is split */
        double worst_e = 0;
        size_t wi = r.n;
        for (size_t i = 0; i + 1 < r.n; i = next_node(&r, i)) {
            size_t j = next_node(&r, i), kk;
            if (j >= r.n)
                break;
            if (!r.p[i].err_ok) {
                r.p[i].err = span_error(&r, i, j, &kk);
                /* too opaque: its probes would all lie where little
                 * light is left (deep.h) */
                if (too_opaque(&r.p[i], &r.p[j], tol))
                    r.p[i].err = fmax(r.p[i].err, 2 * tol);
                r.p[i].err_ok = 1;
            }
            if (r.p[i].err > worst_e) {
                worst_e = r.p[i].err;
                wi = i;
            }
        }
        if (worst_e <= tol || wi >= r.n)
            break;
        if (nodes >= limit) {
            st->capped++;
            break;
        }
        /* the point nearest the middle becomes a boundary, and each half
         * gets its own probes */
        size_t j = next_node(&r, wi), mid = wi + 1;
        double tm = 0.5 * (r.p[wi].t + r.p[j].t);
        for (size_t kk = wi + 1; kk < j; kk++)
            if (fabs(r.p[kk].t - tm) < fabs(r.p[mid].t - tm))
                mid = kk;
        if (mid >= j)
            break;
        r.p[mid].node = 1;
        r.p[mid].err_ok = r.p[wi].err_ok = 0;
        nodes++;
        double t_mid = r.p[mid].t;
        if (probe_segment(&r, wi))
            goto oom;
        size_t m2 = wi;
        while (m2 < r.n && !(r.p[m2].node && r.p[m2].t == t_mid))
            m2++;
        if (m2 < r.n && probe_segment(&r, m2))
            goto oom;
    }

    /* Merge: from each boundary, reach as far as every point in between
     * stays within the bound (forced boundaries stay). */
    for (size_t i = 0; i + 1 < r.n;) {
        size_t j = next_node(&r, i);
        if (j >= r.n)
            break;
        for (;;) {
            if (r.p[j].forced)
                break;
            size_t j2 = next_node(&r, j), kk;
            if (j2 >= r.n || too_opaque(&r.p[i], &r.p[j2], tol) ||
                span_error(&r, i, j2, &kk) > tol)
                break;
            r.p[j].node = 0;
            j = j2;
        }
        i = j;
    }

    /* --deep-max-alpha, and 1 - 1e-3 at most: a float alpha nearer 1
     * loses the transmittance that the split rule raises to the power f
     * (1 - 3e-10 is 1.0f); halve the samples that are too opaque, unless
     * what is behind them is below the bound anyway. */
    double amax = fmin(dd->max_alpha, 1 - 1e-3);
    for (size_t i = 0; i + 1 < r.n;) {
        size_t j = next_node(&r, i);
        if (j >= r.n)
            break;
        double a = r.p[i].T > 0 ? 1 - r.p[j].T / r.p[i].T : 0;
        if (a > amax && r.p[i].T > 0.1 * tol && r.p[j].t - r.p[i].t > 1e-9 * (r.p[j].t + 1) &&
            nodes < limit + 4096) {
            if (ray_add(&r, 0.5 * (r.p[i].t + r.p[j].t), 1) < 0)
                goto oom;
            nodes++;
            continue;
        }
        i = j;
    }

    /* The samples. */
    for (size_t i = 0; i + 1 < r.n;) {
        size_t j = next_node(&r, i);
        if (j >= r.n)
            break;
        const pt_t *a = &r.p[i], *b = &r.p[j];
        if (a->T <= 0)
            break;
        fp_dsample_t s;
        s.z = a->t / k;
        s.zb = b->t / k;
        s.a = 1 - b->T / a->T;
        if (s.a < 0)
            s.a = 0;
        if (s.a > 1)
            s.a = 1;
        for (int c = 0; c < 3; c++)
            s.c[c] = (b->S[c] - a->S[c]) / a->T;
        s.src = FP_DEEP_SRC_FOG;
        if ((s.a > 0 || s.c[0] != 0 || s.c[1] != 0 || s.c[2] != 0) && s.zb > s.z &&
            fp_dlist_push(out, &s))
            goto oom;
        i = j;
    }
    goto done;
oom:
    rc = FP_ERR;   /* no message: this runs on the frame's worker threads */
done:
    st->evals += r.evals;
    free(r.p);
    return rc;
}
