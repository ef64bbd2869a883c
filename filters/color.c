/* fogpipe stage "color": see color.h. */
#include "color.h"
#include "fp.h"
#include "options.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CO(f) offsetof(fp_params_t, color.f)
const fp_option_t fp_color_options[] = {
    { "ocio", 0, FP_OPT_STRING, CO(ocio), 0, 0, NULL, 0, 0, NULL, "CONFIG",
      "OpenColorIO config (default: $OCIO, else fogpipe's own: linear Rec.709, ACEScg, "
      "ACES2065-1, data, an sRGB display)", NULL, 0 },
    { "input-space", 0, FP_OPT_STRING, CO(input_space), 0, 0, NULL, 0, 0, NULL, "NAME",
      "color space of the input's color: a name, alias or role (default: the one the EXR's "
      "chromaticities attribute identifies, else the scene_linear role)", NULL, 0 },
    { "working-space", 0, FP_OPT_STRING, CO(working_space), 0, 0, NULL, 0, 0, NULL, "NAME",
      "linear color space the fog is computed and composited in, and --fog-color is given in "
      "(default: the input's)", NULL, 0 },
    { "output-space", 0, FP_OPT_STRING, CO(output_space), 0, 0, NULL, 0, 0, NULL, "NAME",
      "color space of the output's color and fog layers (default: the input's)", NULL, 0 },
    { "display", 0, FP_OPT_STRING, CO(display), 0, 0, NULL, 0, 0, NULL, "NAME",
      "OpenColorIO display of --preview (default: the config's default display)", NULL, 0 },
    { "view", 0, FP_OPT_STRING, CO(view), 0, 0, NULL, 0, 0, NULL, "NAME",
      "view of --display for --preview (default: the display's default view)", NULL, 0 },
    { "list-spaces", 0, FP_OPT_FLAG, CO(list_spaces), 0, 0, NULL, 0, 1, NULL, NULL,
      "list the OpenColorIO config's color spaces, roles, displays and views, and exit", NULL,
      FP_OPTF_CLI_ONLY },
    FP_OPT_END
};

/* ------------------------------------------------------------ 3x3 algebra */

static void mat_mul(const double a[9], const double b[9], double out[9])
{
    double t[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            t[i * 3 + j] = a[i * 3] * b[j] + a[i * 3 + 1] * b[3 + j] + a[i * 3 + 2] * b[6 + j];
    memcpy(out, t, sizeof t);
}

static int mat_inv(const double m[9], double out[9])
{
    double c[9] = {
        m[4] * m[8] - m[5] * m[7], m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
        m[5] * m[6] - m[3] * m[8], m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
        m[3] * m[7] - m[4] * m[6], m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3],
    };
    double det = m[0] * c[0] + m[1] * c[3] + m[2] * c[6];
    if (!(fabs(det) > 1e-12) || !isfinite(det))
        return FP_ERR;
    for (int i = 0; i < 9; i++)
        out[i] = c[i] / det;
    return FP_OK;
}

/* The chromaticity (x, y) as XYZ with Y = 1. */
static int xy_to_xyz(double x, double y, double out[3])
{
    if (!(fabs(y) > 1e-9))
        return FP_ERR;
    out[0] = x / y;
    out[1] = 1.0;
    out[2] = (1.0 - x - y) / y;
    return FP_OK;
}

/* RGB -> XYZ of the primaries and white (SMPTE RP 177 "normalized primary
 * matrix"): white (1,1,1) maps to the white point with Y = 1. */
static int rgb_to_xyz(const double chr[8], double m[9])
{
    double p[9], w[3], pi[9];
    for (int k = 0; k < 3; k++) {
        double v[3];
        if (xy_to_xyz(chr[2 * k], chr[2 * k + 1], v))
            return FP_ERR;
        for (int i = 0; i < 3; i++)
            p[i * 3 + k] = v[i];
    }
    if (xy_to_xyz(chr[6], chr[7], w) || mat_inv(p, pi))
        return FP_ERR;
    for (int k = 0; k < 3; k++) {
        double s = pi[k * 3] * w[0] + pi[k * 3 + 1] * w[1] + pi[k * 3 + 2] * w[2];
        for (int i = 0; i < 3; i++)
            m[i * 3 + k] = p[i * 3 + k] * s;
    }
    return FP_OK;
}

/* Bradford chromatic adaptation from one white (x, y) to another, as
 * OpenColorIO's built-in *_BFD transforms adapt. */
static int bradford(const double from[2], const double to[2], double m[9])
{
    static const double b[9] = { 0.8951, 0.2664, -0.1614, -0.7502, 1.7135,
                                 0.0367, 0.0389, -0.0685, 1.0296 };
    double bi[9], ws[3], wd[3], s[9] = { 0 };
    if (mat_inv(b, bi) || xy_to_xyz(from[0], from[1], ws) || xy_to_xyz(to[0], to[1], wd))
        return FP_ERR;
    for (int i = 0; i < 3; i++) {
        double cs = b[i * 3] * ws[0] + b[i * 3 + 1] * ws[1] + b[i * 3 + 2] * ws[2];
        double cd = b[i * 3] * wd[0] + b[i * 3 + 1] * wd[1] + b[i * 3 + 2] * wd[2];
        if (!(fabs(cs) > 1e-12))
            return FP_ERR;
        s[i * 4] = cd / cs;
    }
    mat_mul(s, b, m);
    mat_mul(bi, m, m);
    return FP_OK;
}

/* Standard primaries: what the output's chromaticities attribute can say. */
static const struct {
    const char *name;
    double chr[8];
} standards[] = {
    { "Rec.709", { 0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290 } },
    { "ACES AP1", { 0.713, 0.293, 0.165, 0.830, 0.128, 0.044, 0.32168, 0.33767 } },
    { "ACES AP0", { 0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.0770, 0.32168, 0.33767 } },
    { "P3-D65", { 0.680, 0.320, 0.265, 0.690, 0.150, 0.060, 0.3127, 0.3290 } },
    { "Rec.2020", { 0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290 } },
};
#define AP0 2

int fp_color_chromaticities_to_ap0(const double chr[8], double m[9])
{
    double to_xyz[9], ap0[9], ap0_inv[9], cat[9];
    const double *a = standards[AP0].chr;
    if (rgb_to_xyz(chr, to_xyz) || rgb_to_xyz(a, ap0) || mat_inv(ap0, ap0_inv) ||
        bradford(chr + 6, a + 6, cat))
        return FP_ERR;
    mat_mul(cat, to_xyz, m);
    mat_mul(ap0_inv, m, m);
    return FP_OK;
}

/* Matrices this close are the same primaries (stored chromaticities are
 * often rounded to 3 or 4 digits; distinct standards differ by > 0.02). */
#define FP_COLOR_MATCH 2e-3

static int same_matrix(const double a[9], const double b[9])
{
    for (int i = 0; i < 9; i++)
        if (!(fabs(a[i] - b[i]) <= FP_COLOR_MATCH))
            return 0;
    return 1;
}

/* ------------------------------------------------------------ the config */

static void lock(fp_color_t *c)
{
    if (c->lock_ok)
        pthread_mutex_lock(&c->lock);
}

static void unlock(fp_color_t *c)
{
    if (c->lock_ok)
        pthread_mutex_unlock(&c->lock);
}

static int add_space(fp_color_t *c, const char *name)
{
    double m[9];
    for (int i = 0; i < c->nspaces; i++)
        if (strcmp(c->spaces[i].name, name) == 0)
            return FP_OK;
    if (strlen(name) >= FP_COLOR_NAME || fp_ocio_is_data(c->ocio, name) ||
        fp_ocio_is_display_referred(c->ocio, name) || fp_ocio_matrix(c->ocio, name, c->ref, m))
        return FP_OK;
    fp_color_space_t *s = &c->spaces[c->nspaces++];
    snprintf(s->name, sizeof s->name, "%s", name);
    memcpy(s->to_ref, m, sizeof m);
    return FP_OK;
}

/* The config's linear spaces and their matrices to aces_interchange, once
 * (probing every space of a large config takes a while). Under the lock. */
static void scan_spaces(fp_color_t *c)
{
    if (c->scanned)
        return;
    c->scanned = 1;
    int n = fp_ocio_num_spaces(c->ocio);
    if (!c->ref[0] || n <= 0)
        return;
    c->spaces = calloc((size_t)n + 1, sizeof *c->spaces);
    if (!c->spaces)
        return;
    if (c->scene_linear[0])
        add_space(c, c->scene_linear);
    for (int i = 0; i < n && c->nspaces < n + 1; i++)
        add_space(c, fp_ocio_space_name(c->ocio, i));
}

const char *fp_color_identify(fp_color_t *c, const float chr[8])
{
    double d[8], m[9];
    for (int i = 0; i < 8; i++)
        d[i] = chr[i];
    if (!c->active || fp_color_chromaticities_to_ap0(d, m))
        return NULL;
    const char *found = NULL;
    lock(c);
    scan_spaces(c);
    for (int i = 0; i < c->nspaces && !found; i++)
        if (same_matrix(c->spaces[i].to_ref, m))
            found = c->spaces[i].name;
    unlock(c);
    return found;
}

int fp_color_space_chromaticities(fp_color_t *c, const char *space, float chr[8])
{
    int rc = FP_ERR;
    if (!c->active)
        return rc;
    lock(c);
    scan_spaces(c);
    for (int i = 0; i < c->nspaces && rc; i++) {
        if (strcmp(c->spaces[i].name, space) != 0)
            continue;
        for (size_t k = 0; k < FP_ARRAY_LEN(standards) && rc; k++) {
            double m[9];
            if (fp_color_chromaticities_to_ap0(standards[k].chr, m) == FP_OK &&
                same_matrix(c->spaces[i].to_ref, m)) {
                for (int j = 0; j < 8; j++)
                    chr[j] = (float)standards[k].chr[j];
                rc = FP_OK;
            }
        }
    }
    unlock(c);
    return rc;
}

/* A processor from the cache, made on first use.  `view` NULL: src -> dst
 * color spaces; else src through display `dst` and `view`. */
static int get_proc(fp_color_t *c, const char *src, const char *dst, const char *view,
                    const fp_ocio_proc_t **out)
{
    int rc = FP_OK;
    *out = NULL;
    lock(c);
    for (int i = 0; i < c->ncache; i++)
        if (strcmp(c->cache[i].src, src) == 0 && strcmp(c->cache[i].dst, dst) == 0 &&
            strcmp(c->cache[i].view, view ? view : "") == 0) {
            *out = c->cache[i].proc;
            goto done;
        }
    if (c->ncache == FP_COLOR_CACHE) {
        rc = fp_error("%s: more than %d different color conversions in one run",
                      fp_ocio_path(c->ocio), FP_COLOR_CACHE);
        goto done;
    }
    fp_ocio_proc_t *p = NULL;
    rc = view ? fp_ocio_display_processor(c->ocio, src, dst, view, &p)
              : fp_ocio_processor(c->ocio, src, dst, &p);
    if (rc)
        goto done;
    if (!view && fp_ocio_is_noop(p)) {
        /* Two names for the same space: kept as NULL, nothing to apply. */
        fp_ocio_proc_free(p);
        p = NULL;
    }
    snprintf(c->cache[c->ncache].src, FP_COLOR_NAME, "%s", src);
    snprintf(c->cache[c->ncache].dst, FP_COLOR_NAME, "%s", dst);
    snprintf(c->cache[c->ncache].view, FP_COLOR_NAME, "%s", view ? view : "");
    c->cache[c->ncache++].proc = p;
    *out = p;
done:
    unlock(c);
    return rc;
}

/* A space named by the user: known, and color rather than data. */
static int user_space(fp_color_t *c, const char *given, const char *what, char *name)
{
    int rc = fp_ocio_space(c->ocio, given, what, name, FP_COLOR_NAME);
    if (rc)
        return rc;
    if (fp_ocio_is_data(c->ocio, name))
        return fp_usage_error("%s: \"%s\" is a data space in the OpenColorIO config %s (depth "
                              "and fogmaps are data; expected a color space such as ACEScg)",
                              what, given, fp_ocio_path(c->ocio));
    return FP_OK;
}

/* 1 when `space` is linear (its conversion to the config's reference, or
 * to scene_linear, is a matrix), 0 when not, 1 when it cannot be told. */
static int is_linear(fp_color_t *c, const char *space)
{
    double m[9];
    const char *to = c->ref[0] ? c->ref : c->scene_linear;
    if (!to[0])
        return 1;
    return fp_ocio_matrix(c->ocio, space, to, m) != 1;
}

int fp_color_commit(const fp_params_t *p, fp_color_t *c)
{
    const fp_color_params_t *cp = &p->color;
    int rc;
    memset(c, 0, sizeof *c);
    c->preview = p->preview.preview != NULL;
    c->aov = p->aov.aov || p->aov.aov_only;
    if (!cp->ocio && !cp->input_space && !cp->working_space && !cp->output_space &&
        !cp->display && !cp->view && !c->preview)
        return FP_OK;

    char path[4096];
    const char *origin = "";
    if ((rc = fp_ocio_find_config(cp->ocio, path, sizeof path, &origin)) ||
        (rc = fp_ocio_open(path, &c->ocio)))
        return rc;
    fp_info("OpenColorIO config (%s): %s", origin, path);
    if (pthread_mutex_init(&c->lock, NULL) != 0)
        return fp_error("cannot make a mutex");
    c->lock_ok = 1;
    c->active = 1;
    fp_ocio_role(c->ocio, "scene_linear", c->scene_linear, sizeof c->scene_linear);
    fp_ocio_role(c->ocio, "aces_interchange", c->ref, sizeof c->ref);

    if ((cp->input_space && (rc = user_space(c, cp->input_space, "--input-space", c->in))) ||
        (cp->working_space &&
         (rc = user_space(c, cp->working_space, "--working-space", c->work))) ||
        (cp->output_space && (rc = user_space(c, cp->output_space, "--output-space", c->out))))
        return rc;
    if (!c->in[0] && !c->scene_linear[0])
        return fp_error("%s: the OpenColorIO config has no scene_linear role (expected one, "
                        "or --input-space NAME)", path);

    /* The fog is light: it adds and attenuates linearly only in a linear
     * space. */
    const char *work = c->work[0] ? c->work : c->in[0] ? c->in : c->scene_linear;
    if (!is_linear(c, work)) {
        if (c->work[0])
            return fp_usage_error("--working-space: \"%s\" is not a linear color space in %s "
                                  "(fog is computed in light; expected e.g. ACEScg or "
                                  "lin_rec709)", cp->working_space, path);
        if (c->in[0])
            return fp_usage_error("--input-space: \"%s\" is not linear, so it cannot be the "
                                  "working space (expected --working-space NAME, e.g. ACEScg)",
                                  cp->input_space);
        return fp_error("%s: the scene_linear role (%s) is not a linear color space", path,
                        c->scene_linear);
    }
    /* fog.RGB is added to the plate: "over" holds only in linear light. */
    const char *outs = c->out[0] ? c->out : c->in[0] ? c->in : NULL;
    if (c->aov && outs && !is_linear(c, outs))
        return fp_usage_error("--aov: the output space \"%s\"%s is not linear (the fog layers "
                              "are light to merge over the plate; expected a linear "
                              "--output-space such as ACEScg)", outs,
                              c->out[0] ? "" : " (the input's)");
    if (c->preview || cp->display || cp->view)
        if ((rc = fp_ocio_display_view(c->ocio, cp->display, cp->view, c->display,
                                       sizeof c->display, c->view, sizeof c->view)))
            return rc;
    fp_info("color spaces: input %s, working %s, output %s%s%s%s%s",
            c->in[0] ? c->in : "(the frame's)", c->work[0] ? c->work : "(the input's)",
            c->out[0] ? c->out : "(the input's)", c->preview ? "; previews through " : "",
            c->preview ? c->display : "", c->preview ? ", " : "", c->preview ? c->view : "");
    return FP_OK;
}

int fp_color_frame(fp_color_t *c, const fp_frame_info_t *info, const char *where, long frame,
                   fp_color_frame_t *cf)
{
    static const fp_color_frame_t none = FP_COLOR_FRAME_INITIALIZER;
    int rc;
    *cf = none;
    if (!c->active)
        return FP_OK;
    const char *in = c->in[0] ? c->in : NULL;
    /* The chromaticities matter only where something is converted. */
    int converts = c->work[0] || c->out[0] || c->preview;
    if (!in && converts && info->has_chromaticities) {
        in = fp_color_identify(c, info->chromaticities);
        if (in) {
            fp_info("%s: frame %ld: input color space %s (from its chromaticities)", where,
                    frame, in);
        } else {
            lock(c);
            int first = !c->warned_ids;
            c->warned_ids = 1;
            unlock(c);
            const float *x = info->chromaticities;
            if (first && !c->ref[0])
                fp_warn("%s: frame %ld: its chromaticities cannot be matched: the OpenColorIO "
                        "config %s has no aces_interchange role; assuming %s (scene_linear; "
                        "use --input-space)", where, frame, fp_ocio_path(c->ocio),
                        c->scene_linear);
            else if (first)
                fp_warn("%s: frame %ld: its chromaticities (red %g,%g green %g,%g blue %g,%g "
                        "white %g,%g) match no linear color space of %s; assuming %s "
                        "(scene_linear; use --input-space)", where, frame, x[0], x[1], x[2],
                        x[3], x[4], x[5], x[6], x[7], fp_ocio_path(c->ocio), c->scene_linear);
        }
    }
    if (!in)
        in = c->scene_linear;
    cf->in = in;
    cf->work = c->work[0] ? c->work : in;
    cf->out = c->out[0] ? c->out : in;
    if (strcmp(cf->in, cf->work) != 0 && (rc = get_proc(c, cf->in, cf->work, NULL, &cf->to_work)))
        return rc;
    if (strcmp(cf->work, cf->out) != 0 && (rc = get_proc(c, cf->work, cf->out, NULL, &cf->to_out)))
        return rc;
    if (c->preview && (rc = get_proc(c, cf->out, c->display, c->view, &cf->to_display)))
        return rc;
    if (strcmp(cf->out, cf->in) != 0)
        cf->set_chromaticities =
            fp_color_space_chromaticities(c, cf->out, cf->chromaticities) == FP_OK ? 1 : -1;
    return FP_OK;
}

void fp_color_to_working(const fp_color_frame_t *cf, float *rgba, size_t n)
{
    if (cf->to_work)
        fp_ocio_apply(cf->to_work, rgba, n, 4);
}

void fp_color_to_output(const fp_color_frame_t *cf, float *rgba, size_t n)
{
    if (cf->to_out)
        fp_ocio_apply(cf->to_out, rgba, n, 4);
}

void fp_color_write_opts(const fp_color_frame_t *cf, fp_exr_write_opts_t *w)
{
    w->set_chromaticities = cf->set_chromaticities;
    memcpy(w->chromaticities, cf->chromaticities, sizeof w->chromaticities);
}

void fp_color_release(fp_color_t *c)
{
    for (int i = 0; i < c->ncache; i++)
        if (c->cache[i].proc)
            fp_ocio_proc_free(c->cache[i].proc);
    c->ncache = 0;
    free(c->spaces);
    c->spaces = NULL;
    c->nspaces = 0;
    if (c->ocio)
        fp_ocio_close(c->ocio);
    c->ocio = NULL;
    if (c->lock_ok)
        pthread_mutex_destroy(&c->lock);
    c->lock_ok = 0;
    c->active = 0;
}

int fp_color_list(const fp_params_t *p, FILE *out)
{
    char path[4096];
    const char *origin = "";
    fp_ocio_t *o = NULL;
    int rc = fp_ocio_find_config(p->color.ocio, path, sizeof path, &origin);
    if (rc == FP_OK)
        rc = fp_ocio_open(path, &o);
    if (rc == FP_OK && (rc = fp_ocio_print(o, out)) == FP_OK)
        fprintf(out, "(config chosen by %s)\n", origin);
    if (o)
        fp_ocio_close(o);
    return rc;
}
