#include "shadowcheck.h"
#include "camera.h"
#include "fp.h"
#include "params.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Nothing seen: farther than any depth (finite, so differences stay finite). */
#define FAR 1e30

typedef struct {
    int start;
    double zmax;   /* the deepest of its own texels so far */
} open_run_t;

/* Width b - a over [a, b) where the texel has none or a wider one. */
static void mark(unsigned char *wl, int a, int b)
{
    int wd = b - a > 255 ? 255 : b - a;
    for (int t = a; t < b; t++)
        if (!wl[t] || wl[t] > wd)
            wl[t] = (unsigned char)wd;
}

/* A jump between texels k - 1 and k: a change of more than step that
 * also differs by more than step from the changes beside it (a surface
 * the sun sees at a grazing angle changes fast, but evenly: no jump). */
static int jump_at(const double *v, int n, int k, double step)
{
    double d = v[k] - v[k - 1];
    if (!(fabs(d) > step))
        return 0;
    double before = k >= 2 ? v[k - 1] - v[k - 2] : 0, after = k + 1 < n ? v[k + 1] - v[k] : 0;
    return fabs(d - before) > step && fabs(d - after) > step;
}

/* The runs of v[0..n) in front of their neighbours on both sides by more
 * than step: per texel the width of the innermost run holding it (0:
 * none), into wl.  A jump toward the sun opens a run; a jump away closes
 * every open run that all lies in front of the texel jumped to (a pillar
 * before a wall closes alone, the wall later). */
static void runs_line(const double *v, int n, double step, open_run_t *st, unsigned char *wl)
{
    memset(wl, 0, (size_t)n);
    int top = 0;
    for (int k = 1; k < n; k++) {
        if (top)
            st[top - 1].zmax = fmax(st[top - 1].zmax, v[k - 1]);
        if (!jump_at(v, n, k, step))
            continue;
        if (v[k] < v[k - 1]) {
            st[top].start = k;
            st[top].zmax = -INFINITY;
            top++;
            continue;
        }
        while (top > 0 && st[top - 1].zmax < v[k] - step) {
            top--;
            mark(wl, st[top].start, k);
            if (top)
                st[top - 1].zmax = fmax(st[top - 1].zmax, st[top].zmax);
        }
    }
}

/* One line of the map (n texels, `stride` apart): each texel's width
 * along it into out (same stride).  sign -1: gaps (runs behind both
 * sides). */
static void line_widths(const float *z, int n, ptrdiff_t stride, double step, double sign,
                        double *v, open_run_t *st, unsigned char *wl, unsigned char *out)
{
    for (int k = 0; k < n; k++) {
        double zk = z[k * stride];
        v[k] = sign * (isfinite(zk) ? zk : FAR);
    }
    runs_line(v, n, step, st, wl);
    for (int k = 0; k < n; k++)
        out[k * stride] = wl[k];
}

/* Widths along x (rows) into wx, along y (columns) into wy. */
static int widths(const float *z, int w, int h, double step, double sign, unsigned char *wx,
                  unsigned char *wy)
{
    int n = w > h ? w : h;
    double *v = malloc((size_t)n * sizeof *v);
    open_run_t *st = malloc((size_t)n * sizeof *st);
    unsigned char *wa = malloc((size_t)n);
    if (!v || !st || !wa) {
        free(v);
        free(st);
        free(wa);
        return -1;
    }
    for (int j = 0; j < h; j++)
        line_widths(z + (size_t)j * w, w, 1, step, sign, v, st, wa, wx + (size_t)j * w);
    for (int i = 0; i < w; i++)
        line_widths(z + i, h, w, step, sign, v, st, wa, wy + i);
    free(v);
    free(st);
    free(wa);
    return 0;
}

/* The features of texels narrower than FP_SHADOWCHECK_TEXELS (the smaller
 * of wx and wy, where any), 4-connected; the thinnest that is long for
 * its width into t. */
static int features(const unsigned char *wx, const unsigned char *wy, int w, int h,
                    const double *texel, fp_smap_thin_t *t)
{
    const int lim = FP_SHADOWCHECK_TEXELS;
    size_t n = (size_t)w * h, cap = 1024, sp = 0;
    unsigned char *seen = calloc(n, 1);
    size_t *stack = malloc(cap * sizeof *stack);
    if (!seen || !stack) {
        free(seen);
        free(stack);
        return -1;
    }
    memset(t, 0, sizeof *t);
#define WIDTH(i) (wx[i] && (!wy[i] || wx[i] <= wy[i]) ? wx[i] : wy[i])
#define THIN(i) (WIDTH(i) > 0 && WIDTH(i) < lim)
    for (size_t s = 0; s < n; s++) {
        if (seen[s] || !THIN(s))
            continue;
        long hist[FP_SHADOWCHECK_TEXELS] = { 0 }, count = 0, along_y = 0;
        double sx = 0, sy = 0;
        int x0 = w, x1 = -1, y0 = h, y1 = -1;
        seen[s] = 1;
        stack[sp++] = s;
        while (sp) {
            size_t i = stack[--sp];
            int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w);
            hist[WIDTH(i)]++;
            along_y += !(wx[i] && (!wy[i] || wx[i] <= wy[i]));
            count++;
            sx += x;
            sy += y;
            x0 = x < x0 ? x : x0;
            x1 = x > x1 ? x : x1;
            y0 = y < y0 ? y : y0;
            y1 = y > y1 ? y : y1;
            size_t nb[4];
            int nn = 0;
            if (x > 0)
                nb[nn++] = i - 1;
            if (x + 1 < w)
                nb[nn++] = i + 1;
            if (y > 0)
                nb[nn++] = i - (size_t)w;
            if (y + 1 < h)
                nb[nn++] = i + (size_t)w;
            for (int k = 0; k < nn; k++) {
                if (seen[nb[k]] || !THIN(nb[k]))
                    continue;
                if (sp == cap) {
                    size_t *bigger = realloc(stack, 2 * cap * sizeof *stack);
                    if (!bigger) {
                        free(seen);
                        free(stack);
                        return -1;
                    }
                    stack = bigger;
                    cap *= 2;
                }
                seen[nb[k]] = 1;
                stack[sp++] = nb[k];
            }
        }
        int median = 1;
        for (long c = 0; median < lim; median++)
            if ((c += hist[median]) * 2 >= count)
                break;
        int length = x1 - x0 > y1 - y0 ? x1 - x0 + 1 : y1 - y0 + 1;
        if (length < 4 || length < 2 * median || 128 * length < (w > h ? w : h))
            continue;
        t->count++;
        if (t->found && (median > t->width || (median == t->width && length <= t->length)))
            continue;
        t->found = 1;
        t->width = median;
        t->length = length;
        t->axis = 2 * along_y > count;
        t->width_units = median * texel[t->axis];
        t->x = sx / count;
        t->y = sy / count;
    }
#undef THIN
#undef WIDTH
    free(seen);
    free(stack);
    return 0;
}

int fp_shadowcheck(const float *z, int w, int h, double texel_x, double texel_y, double step,
                   fp_smap_report_t *r)
{
    memset(r, 0, sizeof *r);
    r->w = w;
    r->h = h;
    r->texel[0] = texel_x;
    r->texel[1] = texel_y;
    r->step = step;
    if (w < 3 || h < 3)
        return 0;
    size_t n = (size_t)w * h;
    unsigned char *wx = malloc(n), *wy = malloc(n);
    int rc = !wx || !wy ? -1 : 0;
    for (int g = 0; g < 2 && rc == 0; g++) {
        rc = widths(z, w, h, step, g ? -1 : 1, wx, wy);
        if (rc == 0)
            rc = features(wx, wy, w, h, r->texel, g ? &r->gap : &r->caster);
    }
    free(wx);
    free(wy);
    return rc;
}

double fp_shadowcheck_needed(const fp_smap_report_t *r, const fp_smap_thin_t *t, long *w, long *h)
{
    double texel = t->width_units / FP_SHADOWCHECK_TEXELS;
    *w = (long)ceil(r->w * r->texel[0] / texel - 1e-9);
    *h = (long)ceil(r->h * r->texel[1] / texel - 1e-9);
    return texel;
}

/* World point of map texel coordinates (x, y) (texel centers at + 0.5)
 * at the map's depth zc: the three affine rows of the map's projection
 * solved for the fog point, then fog -> world (fp_world_to_fog's
 * inverse).  0 when they cannot be solved. */
static int texel_world(const double *ndc, const double *cz, int up, int w, int h, double x,
                       double y, double zc, double out[3])
{
    double a[9] = { ndc[0], ndc[4], ndc[8], ndc[1], ndc[5], ndc[9], cz[0], cz[1], cz[2] }, ai[9];
    if (fp_mat3_inverse(a, ai))
        return 0;
    double b[3] = { (x + 0.5) / w - ndc[12], (y + 0.5) / h - ndc[13], zc - cz[3] }, f[3];
    for (int r = 0; r < 3; r++)
        f[r] = ai[3 * r] * b[0] + ai[3 * r + 1] * b[1] + ai[3 * r + 2] * b[2];
    out[0] = f[0];
    out[1] = up == FP_UP_Z ? -f[2] : f[1];
    out[2] = up == FP_UP_Z ? f[1] : f[2];
    return isfinite(out[0]) && isfinite(out[1]) && isfinite(out[2]);
}

/* The depth to place a feature at: the nearest finite texel to (x, y)
 * along its row (a gap sees nothing or far ground: the casters beside it). */
static double feature_z(const float *z, int w, int h, const fp_smap_thin_t *t)
{
    int x = (int)floor(t->x + 0.5), y = (int)floor(t->y + 0.5);
    x = x < 0 ? 0 : x >= w ? w - 1 : x;
    y = y < 0 ? 0 : y >= h ? h - 1 : y;
    double best = INFINITY;
    for (int d = 0; d < w + h; d++) {
        for (int s = -1; s <= 1; s += 2) {
            int i = t->axis ? x : x + s * d, j = t->axis ? y + s * d : y;
            if (i < 0 || j < 0 || i >= w || j >= h)
                continue;
            float zv = z[(size_t)j * w + i];
            if (isfinite(zv))
                best = fmin(best, zv);
        }
        if (isfinite(best))
            return best;
    }
    return NAN;
}

/* "2 texels (0.1 scene units) wide, 40 long, at texel (12, 40), world (..)" */
static void describe(char *buf, size_t size, const fp_smap_report_t *r, const fp_smap_thin_t *t,
                     const float *z, const double *ndc, const double *cz, int up)
{
    double p[3];
    char where[160] = "";
    double zc = feature_z(z, r->w, r->h, t);
    if (ndc && cz && isfinite(zc) && texel_world(ndc, cz, up, r->w, r->h, t->x, t->y, zc, p))
        snprintf(where, sizeof where, ", world (%.3g, %.3g, %.3g)", p[0], p[1], p[2]);
    snprintf(buf, size, "%d texel%s (%.3g scene units) across, %d long, at texel (%.0f, %.0f)%s",
             t->width, t->width == 1 ? "" : "s", t->width_units, t->length, t->x, t->y, where);
}

/* Once a run (the context's, src/base/fp_ctx.h). */
static const char warned = 0;

void fp_shadowcheck_frame(const char *path, long frame, const float *z, int w, int h,
                          double texel_x, double texel_y, double step, const double *ndc,
                          const double *cz, int up)
{
    if (fp_once_done(&warned) && fp_verbose <= 0)
        return;
    fp_smap_report_t r;
    if (fp_shadowcheck(z, w, h, texel_x, texel_y, step, &r)) {
        fp_info("%s: frame %ld: shadow map not checked (out of memory)", path, frame);
        return;
    }
    char cs[320] = "none narrower than 8 texels", gs[320] = "none narrower than 8 texels";
    if (r.caster.found)
        describe(cs, sizeof cs, &r, &r.caster, z, ndc, cz, up);
    if (r.gap.found)
        describe(gs, sizeof gs, &r, &r.gap, z, ndc, cz, up);
    fp_info("%s: frame %ld: shadow map %dx%d, texels %.4g x %.4g scene units, depth step %.3g: "
            "thinnest caster %s (%ld under 8 texels); thinnest gap %s (%ld under 8 texels)",
            path, frame, w, h, texel_x, texel_y, step, cs, r.caster.count, gs, r.gap.count);
    if (!r.caster.found && !r.gap.found)
        return;
    /* The thinner of the two in scene units decides the map needed. */
    const fp_smap_thin_t *t = !r.gap.found ? &r.caster
                              : !r.caster.found ? &r.gap
                              : r.gap.width_units < r.caster.width_units ? &r.gap : &r.caster;
    long nw, nh;
    double need = fp_shadowcheck_needed(&r, t, &nw, &nh);
    if (!fp_once(&warned))
        return;
    char what[400];
    describe(what, sizeof what, &r, t, z, ndc, cz, up);
    fp_warn("%s: frame %ld: the shadow map's thinnest %s is %s; shafts beside %s under %d "
            "texels across are lost along grazing rays: a map of %.3g scene units a texel "
            "(%ldx%ld over the same area) holds it %d texels across, or --shadows map+screen "
            "shadows what the camera sees (-v: every map's report)",
            path, frame, t == &r.gap ? "gap" : "caster", what,
            t == &r.gap ? "gaps" : "casters", FP_SHADOWCHECK_TEXELS, need, nw, nh,
            FP_SHADOWCHECK_TEXELS);
}

static const char wants_warned = 0;

void fp_shadowcheck_wants(const fp_params_t *p, int has_map)
{
    const fp_light_params_t *l = &p->light;
    if (!l->wants || has_map || l->shadows != FP_SHADOWS_AUTO)
        return;
    if (!fp_once(&wants_warned))
        return;
    const char *preset = p->io.preset ? strrchr(p->io.preset, '/') : NULL;
    preset = preset ? preset + 1 : p->io.preset ? p->io.preset : "the look";
    fp_warn("%s wants the sun's shadow map (its shafts come from it) and runs without one: give "
            "--shadow-map PATTERN (the sun's orthographic depth map per frame, as fogpipe-scene "
            "or the Blender add-on writes it; or a frame's rig names it), or --shadows screen "
            "or none to run without; its sun is the sample scene's, which a frame's own sun "
            "(its rig) or --sun replaces", preset);
}
