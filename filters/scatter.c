#include "scatter.h"
#include "exrio.h"
#include "fp.h"
#include "options.h"
#include "seq.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The reference: the shared ray code in double precision. */
#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/scatter_core.h"

_Static_assert(FP_LT_COUNT == FP_LT_COUNT_, "light parameter count");
_Static_assert(FP_SCATTER_MAX_STEPS == FP_SCATTER_MAX_STEPS_, "segment limit");
_Static_assert(FP_MAX_LIGHTS == FP_LT_MAX_LIGHTS, "light count");

/* --phase iso | hg:G | cs:G | rayleigh | mix:W,G | mixhg:W,G */
static int set_phase(fp_params_t *p, const fp_option_t *o, const char *value)
{
    fp_light_params_t *l = &p->light;
    static const struct { const char *name; int kind, nargs; } kinds[] = {
        { "iso", FP_PHASE_ISO, 0 },      { "hg", FP_PHASE_HG, 1 },
        { "cs", FP_PHASE_CS, 1 },        { "rayleigh", FP_PHASE_RAYLEIGH, 0 },
        { "mix", FP_PHASE_MIX, 2 },      { "mixhg", FP_PHASE_MIXHG, 2 },
    };
    const char *colon = strchr(value, ':');
    size_t nlen = colon ? (size_t)(colon - value) : strlen(value);
    for (size_t k = 0; k < FP_ARRAY_LEN(kinds); k++) {
        if (strlen(kinds[k].name) != nlen || strncmp(value, kinds[k].name, nlen) != 0)
            continue;
        double a[2] = { 0, 0 };
        int n = 0;
        if (colon) {
            char *end;
            const char *s = colon + 1;
            for (; n < 2; n++) {
                a[n] = strtod(s, &end);
                if (end == s)
                    break;
                s = end;
                if (*s != ',') {
                    n++;
                    break;
                }
                s++;
            }
            if (*s)
                n = -1;
        }
        if (n != kinds[k].nargs)
            break;
        double g = kinds[k].nargs == 2 ? a[1] : a[0], w = kinds[k].nargs == 2 ? a[0] : 0;
        if (!(g > -1 && g < 1) || !(w >= 0 && w <= 1))
            return fp_usage_error("--%s: '%s': expected G in (-1, 1) and W in [0, 1]", o->name,
                                  value);
        l->phase_kind = kinds[k].kind;
        l->phase_g = g;
        l->phase_w = w;
        free(l->phase);
        l->phase = strdup(value);
        return FP_OK;
    }
    return fp_usage_error("--%s: '%s': expected iso, hg:G, cs:G, rayleigh, mix:W,G or mixhg:W,G",
                          o->name, value);
}

/* Comma-separated reals, exactly n of them. */
static int parse_reals(const char *s, size_t len, double *out, int n)
{
    char buf[256];
    if (len >= sizeof buf)
        return -1;
    memcpy(buf, s, len);
    buf[len] = 0;
    char *at = buf, *end;
    for (int i = 0; i < n; i++) {
        out[i] = strtod(at, &end);
        if (end == at || !isfinite(out[i]))
            return -1;
        at = end;
        if (i + 1 < n) {
            if (*at != ',')
                return -1;
            at++;
        }
    }
    return *at ? -1 : 0;
}

/* --light point:X,Y,Z:R,G,B:I
 * --light spot:X,Y,Z:R,G,B:I:DX,DY,DZ:INNER,OUTER  (cone half-angles, degrees) */
static int set_light(fp_params_t *p, const fp_option_t *o, const char *value)
{
    fp_light_params_t *l = &p->light;
    if (l->num_lights >= FP_MAX_LIGHTS)
        return fp_usage_error("--%s: at most %d lights", o->name, FP_MAX_LIGHTS);
    fp_light_t li;
    memset(&li, 0, sizeof li);
    const char *f[6];
    size_t flen[6];
    int nf = 0;
    for (const char *s = value; nf < 6;) {
        const char *c = strchr(s, ':');
        f[nf] = s;
        flen[nf++] = c ? (size_t)(c - s) : strlen(s);
        if (!c)
            break;
        s = c + 1;
    }
    int spot = nf > 0 && flen[0] == 4 && strncmp(f[0], "spot", 4) == 0;
    int point = nf > 0 && flen[0] == 5 && strncmp(f[0], "point", 5) == 0;
    double cone[2] = { 0, 0 };
    if (!(point && nf == 4) && !(spot && nf == 6))
        goto bad;
    if (parse_reals(f[1], flen[1], li.pos, 3) || parse_reals(f[2], flen[2], li.color, 3) ||
        parse_reals(f[3], flen[3], &li.intensity, 1))
        goto bad;
    if (spot && (parse_reals(f[4], flen[4], li.axis, 3) || parse_reals(f[5], flen[5], cone, 2)))
        goto bad;
    if (li.intensity < 0 || li.color[0] < 0 || li.color[1] < 0 || li.color[2] < 0)
        return fp_usage_error("--%s: '%s': color and intensity must be >= 0", o->name, value);
    if (spot) {
        double n = sqrt(li.axis[0] * li.axis[0] + li.axis[1] * li.axis[1] + li.axis[2] * li.axis[2]);
        if (!(n > 0) || !(cone[0] >= 0 && cone[0] <= cone[1] && cone[1] > 0 && cone[1] <= 180))
            return fp_usage_error("--%s: '%s': expected a non-zero direction and cone angles "
                                  "0 <= INNER <= OUTER <= 180 degrees (OUTER > 0)", o->name, value);
        li.kind = 1;
        li.inner = cone[0];
        li.outer = cone[1];
    }
    l->lights[l->num_lights++] = li;
    free(l->light);
    l->light = strdup(value);
    return FP_OK;
bad:
    return fp_usage_error("--%s: '%s': expected point:X,Y,Z:R,G,B:I or "
                          "spot:X,Y,Z:R,G,B:I:DX,DY,DZ:INNER,OUTER", o->name, value);
}

#define LI(f) offsetof(fp_params_t, light.f)
const fp_option_t fp_scatter_options[] = {
    { "sun", 0, FP_OPT_VEC, LI(sun), 3, 3, NULL, -1e9, 1e9, NULL, "DX,DY,DZ",
      "light the fog with a sun: the direction toward it, world axes (any length)", NULL, 0 },
    { "sun-color", 0, FP_OPT_VEC, LI(sun_color), 3, 3, "1,1,1", 0, 1e6, NULL, "R,G,B",
      "color of the sun (times --sun-intensity), working space", NULL, 0 },
    { "sun-intensity", 0, FP_OPT_REAL, LI(sun_intensity), 0, 0, "3", 0, 1e9, NULL, "E",
      "the sun's irradiance on a surface facing it, as Blender's sun Strength", NULL, 0 },
    { "albedo", 0, FP_OPT_REAL, LI(albedo), 0, 0, "1", 0, 1, NULL, "A",
      "single-scattering albedo sigma_s / sigma_t: the part of the extinguished light that "
      "is scattered, not absorbed", NULL, 0 },
    { "phase", 0, FP_OPT_STRING, LI(phase), 0, 0, "iso", 0, 0, NULL, "KIND",
      "phase function: iso, hg:G (Henyey-Greenstein), cs:G (Cornette-Shanks), rayleigh, "
      "mix:W,G (W Rayleigh + (1-W) Cornette-Shanks), mixhg:W,G; G > 0 scatters forward",
      set_phase, 0 },
    { "light", 0, FP_OPT_STRING, LI(light), 0, 0, NULL, 0, 0, NULL, "SPEC",
      "a local light, repeatable (up to 8): point:X,Y,Z:R,G,B:I or "
      "spot:X,Y,Z:R,G,B:I:DX,DY,DZ:INNER,OUTER; I is the radiant intensity (W/sr: "
      "irradiance I/d^2; a light of P watts radiating evenly has I = P/(4 pi)), cone "
      "half-angles in degrees; the fog between light and point attenuates it",
      set_light, 0 },
    { "shadow-map", 0, FP_OPT_STRING, LI(shadow_map), 0, 0, NULL, 0, 0, NULL, "PATTERN",
      "the sun's depth map per frame: orthographic, camera-space depth Z, worldToCamera and "
      "worldToNDC in its header (as fp-scene writes shadow.####.exr)", NULL, 0 },
    { "shadows", 0, FP_OPT_ENUM, LI(shadows), 0, 0, "auto", 0, 0, "auto|none|map|screen",
      "auto|none|map|screen",
      "the sun's shadows in the fog: from --shadow-map (auto: when given), by marching "
      "toward the sun over the camera's depth buffer (screen), or none", NULL, 0 },
    { "shadow-bias", 0, FP_OPT_REAL, LI(shadow_bias), 0, 0, "0", 0, 1e6, NULL, "D",
      "shadow map depth bias in scene units (0: one and a half texels)", NULL, 0 },
    { "shadow-filter", 0, FP_OPT_INT, LI(shadow_filter), 0, 0, "1", 0, 8, NULL, "R",
      "shadow map filtering: percentage-closer taps over (2R+1)^2 texels, bilinear", NULL, 0 },
    { "screen-shadow", 0, FP_OPT_VEC, LI(screen_shadow), 3, 3, "32,20,1", 0, 1e6, NULL,
      "STEPS,DIST,THICK",
      "--shadows screen: steps toward the sun, how far (scene units), and the thickness "
      "assumed behind what the depth buffer shows", NULL, 0 },
    { "self-shadow", 0, FP_OPT_ENUM, LI(self_shadow), 0, 0, "exact", 0, 0, "off|exact|map",
      "off|exact|map",
      "fog shadowing itself: sunlight reaching a point is attenuated by the fog between it "
      "and the sun, integrated exactly per point, or looked up in a per-frame grid of exact "
      "values (map; faster with a fogmap)", NULL, 0 },
    { "self-shadow-grid", 0, FP_OPT_VEC, LI(self_shadow_grid), 3, 3, "96,48,96", 2, 1024, NULL,
      "NX,NY,NZ", "nodes of the self-shadow grid (--self-shadow map) over the visible fog",
      NULL, 0 },
    { "scatter-steps", 0, FP_OPT_INT, LI(scatter_steps), 0, 0, "64", 1, FP_SCATTER_MAX_STEPS / 2,
      NULL, "N",
      "segments along each view ray for the sun's in-scattering (each integrated exactly "
      "for extinction, the light linear within it)", NULL, 0 },
    { "interleave", 0, FP_OPT_VEC, LI(interleave), 2, 2, "1,1", 1, 16, NULL, "N,M",
      "interleaved sampling (Keller and Heidrich 2001): the samples along each ray shift by "
      "one of N x M offsets, a tile repeated over the frame (the same every frame), for the "
      "depth-aware blur (--blur) to reconstruct: fewer --scatter-steps, no banding",
      NULL, 0 },
    { "light-panels", 0, FP_OPT_INT, LI(light_panels), 0, 0, "8", 1, 64, NULL, "N",
      "--light-quad panels: Gauss-Legendre panels (4 nodes each), equiangular around each "
      "local light", NULL, 0 },
    { "light-quad", 0, FP_OPT_ENUM, LI(light_quad), 0, 0, "fast", 0, 0, "fast|panels",
      "fast|panels",
      "local lights' quadrature along the view ray: fast (4 pieces of 8 Gauss-Legendre "
      "nodes per light, the phase function's peak and the spot's cone taken out in closed "
      "form, exact optical depths; used without a fogmap and with spots up to 90 degrees) or "
      "panels (--light-panels equiangular panels, always used with a fogmap)", NULL, 0 },
    FP_OPT_END
};

static void normalize3(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

int fp_scatter_commit(const fp_params_t *p, fp_scatter_data_t *d)
{
    memset(d, 0, sizeof *d);
    const fp_light_params_t *l = &p->light;
    double *lt = d->lt;
    int sun = fp_options_given(p, "sun");
    if (sun) {
        double n = sqrt(l->sun[0] * l->sun[0] + l->sun[1] * l->sun[1] + l->sun[2] * l->sun[2]);
        if (!(n > 0))
            return fp_usage_error("--sun: expected a non-zero direction toward the sun");
    }
    int shadows = l->shadows;
    if (shadows == FP_SHADOWS_AUTO)
        shadows = l->shadow_map ? FP_SHADOWS_WITH_MAP : FP_SHADOWS_OFF;
    if (shadows == FP_SHADOWS_WITH_MAP && !l->shadow_map)
        return fp_usage_error("--shadows map: needs --shadow-map PATTERN");
    if (l->shadow_map && !sun)
        return fp_usage_error("--shadow-map: the shadows are the sun's; give --sun too");
    if (shadows == FP_SHADOWS_WITH_SCREEN && !(l->screen_shadow[0] >= 1))
        return fp_usage_error("--screen-shadow: expected at least one step");
    lt[FP_LT_ALBEDO] = l->albedo;
    memcpy(lt + FP_LT_AMB, p->fog.color, 3 * sizeof(double));
    lt[FP_LT_SUN_ON] = sun;
    if (sun) {
        fp_world_to_fog(p->camera.up, l->sun, lt + FP_LT_SUN_DIR);
        normalize3(lt + FP_LT_SUN_DIR);
        for (int c = 0; c < 3; c++)
            lt[FP_LT_SUN_E + c] = l->sun_color[c] * l->sun_intensity;
    }
    lt[FP_LT_PHASE] = l->phase_kind;
    lt[FP_LT_PHASE + 1] = l->phase_g;
    lt[FP_LT_PHASE + 2] = l->phase_w;
    lt[FP_LT_SHADOWS] = !sun ? FP_SHADOWS_NONE
                        : shadows == FP_SHADOWS_WITH_MAP ? FP_SHADOWS_MAP
                        : shadows == FP_SHADOWS_WITH_SCREEN ? FP_SHADOWS_SCREEN : FP_SHADOWS_NONE;
    lt[FP_LT_SELF] = l->self_shadow == FP_SELF_SHADOW_OFF ? FP_SELF_OFF
                     : l->self_shadow == FP_SELF_SHADOW_MAP ? FP_SELF_MAP : FP_SELF_EXACT;
    lt[FP_LT_STEPS] = l->scatter_steps;
    lt[FP_LT_PANELS] = l->light_panels;
    /* The fast rule cuts a spot's range at its cone, one interval when the
     * cone is at most 90 degrees wide: wider spots take the panels. */
    int wide = 0;
    for (int k = 0; k < l->num_lights; k++)
        wide |= l->lights[k].kind && l->lights[k].outer > 90;
    lt[FP_LT_LIGHT_QUAD] = l->light_quad == FP_LIGHT_QUAD_FAST && !wide;
    lt[FP_LT_INTERLEAVE] = floor(l->interleave[0]);
    lt[FP_LT_INTERLEAVE + 1] = floor(l->interleave[1]);
    lt[FP_LT_NLIGHTS] = l->num_lights;
    lt[FP_LT_SM_RADIUS] = l->shadow_filter;
    lt[FP_LT_SS_STEPS] = l->screen_shadow[0];
    lt[FP_LT_SS_DIST] = l->screen_shadow[1];
    lt[FP_LT_SS_THICK] = l->screen_shadow[2];
    for (int i = 0; i < 3; i++)
        lt[FP_LT_GRID_N + i] = floor(l->self_shadow_grid[i]);
    /* Beyond an optical depth of 30 (transmittance 1e-13) nothing shows. */
    lt[FP_LT_OD_STOP] = 30;
    lt[FP_LT_SEG_OD] = 0.25;
    lt[FP_LT_SEG_JUMP] = 0.002;
    for (int k = 0; k < l->num_lights; k++) {
        const fp_light_t *li = &l->lights[k];
        double *row = lt + FP_LT_LIGHTS + k * FP_LT_LIGHT_STRIDE;
        row[FP_LL_TYPE] = li->kind ? FP_LIGHT_SPOT : FP_LIGHT_POINT;
        fp_world_to_fog(p->camera.up, li->pos, row + FP_LL_POS);
        for (int c = 0; c < 3; c++)
            row[FP_LL_I + c] = li->color[c] * li->intensity;
        if (li->kind) {
            fp_world_to_fog(p->camera.up, li->axis, row + FP_LL_AXIS);
            normalize3(row + FP_LL_AXIS);
            row[FP_LL_COS_IN] = cos(li->inner * M_PI / 180);
            row[FP_LL_COS_OUT] = cos(li->outer * M_PI / 180);
        }
    }
    d->active = sun || l->num_lights > 0 || l->albedo != 1;
    /* Fog with no top soaks up all of the sun's light before it arrives. */
    const fp_fog_params_t *f = &p->fog;
    int open_main = f->density > 0 && isinf(f->height[1]) && isinf(f->height[2]) &&
                    isinf(f->box[4]);
    int open_haze = f->haze > 0 && isinf(f->haze_height[1]) && isinf(f->haze_height[2]);
    if (sun && l->self_shadow != FP_SELF_SHADOW_OFF && (open_main || open_haze))
        fp_warn("--sun: the %s has no top (--%s Y0,inf without TOP): no sunlight gets through it; "
                "give it a TOP or a finite H, or use --self-shadow off",
                open_main ? "fog" : "haze", open_main ? "height" : "haze-height");
    return FP_OK;
}

/* Load this frame's shadow map and pack its projection (fog space). */
static int load_shadow_map(const fp_params_t *p, fp_scatter_data_t *d, long frame)
{
    char path[4096];
    int rc = fp_seq_format(p->light.shadow_map, frame, path, sizeof path);
    if (rc)
        return rc;
    void *buf = NULL;
    size_t size = 0;
    if ((rc = fp_exr_load_file(path, frame, &buf, &size)))
        return rc;
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    sel.need_color = 0;
    sel.need_depth = 1;
    fp_frame_t *f = NULL;
    if ((rc = fp_exr_read_memory(buf, size, path, frame, &sel, &f)))
        return rc;
    const fp_frame_info_t *info = fp_frame_info(f);
    if (!info->has_world_to_ndc || !info->has_world_to_camera) {
        fp_frame_free(f);
        return fp_error("%s: frame %ld: shadow map without worldToCamera and worldToNDC in its "
                        "header (expected the sun camera's matrices, as fp-scene writes them)",
                        path, frame);
    }
    size_t n = (size_t)info->width * info->height;
    float *z = malloc(n * sizeof *z);
    if (!z) {
        fp_frame_free(f);
        return fp_error("%s: frame %ld: out of memory", path, frame);
    }
    memcpy(z, fp_frame_depth(f), n * sizeof *z);
    free(d->smap);
    d->smap = z;
    d->smap_w = info->width;
    d->smap_h = info->height;
    /* Fog point -> world point: the inverse of fp_world_to_fog, as a
     * row-vector 4x4, then world -> NDC.  NDC is relative to the display
     * window; texels are the data window's, so shift and scale. */
    double f2w[16] = { 0 }, m[16];
    double e[3][3];
    for (int a = 0; a < 3; a++) {
        double w[3] = { a == 0, a == 1, a == 2 }, fv[3];
        fp_world_to_fog(p->camera.up, w, fv);
        /* fv = image of world axis a: world = sum over fog axes of
         * fog_b * e[b][a] with e = transpose (a rotation). */
        for (int b = 0; b < 3; b++)
            e[b][a] = fv[b];
    }
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            f2w[r * 4 + c] = e[r][c];
    f2w[15] = 1;
    fp_mat4_mul(f2w, info->world_to_ndc, m);
    double sx = (double)info->disp_w / info->width, sy = (double)info->disp_h / info->height;
    double ox = (double)(info->data_x0 - info->disp_x0) / info->disp_w;
    double oy = (double)(info->data_y0 - info->disp_y0) / info->disp_h;
    /* texel coordinate = (ndc - o) * disp / data-size, per column. */
    for (int r = 0; r < 4; r++) {
        d->lt[FP_LT_SM_NDC + r * 4 + 0] = (m[r * 4 + 0] - ox * m[r * 4 + 3]) * sx;
        d->lt[FP_LT_SM_NDC + r * 4 + 1] = (m[r * 4 + 1] - oy * m[r * 4 + 3]) * sy;
        d->lt[FP_LT_SM_NDC + r * 4 + 2] = m[r * 4 + 2];
        d->lt[FP_LT_SM_NDC + r * 4 + 3] = m[r * 4 + 3];
    }
    double c[16];
    fp_mat4_mul(f2w, info->world_to_camera, c);
    for (int r = 0; r < 4; r++)
        d->lt[FP_LT_SM_Z + r] = c[r * 4 + 2];
    d->lt[FP_LT_SM_W] = info->width;
    d->lt[FP_LT_SM_H] = info->height;
    /* Default bias: one and a half texels in scene units (the world size
     * of a texel along the map's x axis). */
    double bias = p->light.shadow_bias;
    if (!(bias > 0)) {
        /* A texel in scene units, times 1.5, plus the rise of level ground
         * seen by the sun over the filter's reach: (R + 1) texels times
         * the sun's horizontal over its vertical component. */
        double gx = sqrt(m[0] * m[0] + m[4] * m[4] + m[8] * m[8]) * info->disp_w;
        double texel = gx > 0 ? 1 / gx : 0;
        const double *l = d->lt + FP_LT_SUN_DIR;
        double slope = sqrt(l[0] * l[0] + l[2] * l[2]) / fmax(l[1], 0.1);
        bias = texel * (1.5 + (p->light.shadow_filter + 1) * slope);
    }
    d->lt[FP_LT_SM_BIAS] = bias;
    fp_frame_free(f);
    return FP_OK;
}

static const float no_map[1] = { INFINITY };

#define TABLES(t) FP_TABLES(fp_fog_tables_or_empty(t))

/* The self-shadow grid's box: the camera and the stretch of every 8th
 * pixel's ray (each way) that holds fog, slightly enlarged. */
static void grid_bounds(fp_scatter_data_t *d, const fp_integrate_data_t *fog, const fp_view_t *v,
                        const float *depth)
{
    double lo[3], hi[3];
    for (int i = 0; i < 3; i++)
        lo[i] = hi[i] = v->origin[i];
    for (int y = 0; y < v->height; y += 8)
        for (int x = 0; x < v->width; x += 8) {
            double dir[3], len, ta, tb, o[3];
            fp_view_ray(v, x, y, depth[(size_t)y * v->width + x], dir, &len);
            fp_view_origin_at(v, x, y, o);
            if (!fp_fog_span(fog->fp, o[0], o[1], o[2], dir[0], dir[1],
                             dir[2], len, &ta, &tb))
                continue;
            if (isinf(tb)) {
                /* Unbounded: as far as the integrator goes (its optical
                 * depth stop), found by doubling. */
                double od0 = fp_fog_od(fog->fp, TABLES(fog->tables), o[0], o[1],
                                       o[2], dir[0], dir[1], dir[2], ta, 0);
                double step = 1;
                for (int k = 0; k < 40 && step < fog->fp[FP_F_CAP]; k++, step *= 2)
                    if (fp_fog_od(fog->fp, TABLES(fog->tables), o[0], o[1],
                                  o[2], dir[0], dir[1], dir[2], ta + step, 0) - od0 >=
                        d->lt[FP_LT_OD_STOP])
                        break;
                tb = ta + fmin(step, fog->fp[FP_F_CAP]);
            }
            for (int e = 0; e < 2; e++)
                for (int i = 0; i < 3; i++) {
                    double q = o[i] + (e ? tb : ta) * dir[i];
                    lo[i] = fmin(lo[i], q);
                    hi[i] = fmax(hi[i], q);
                }
        }
    double *lt = d->lt;
    for (int i = 0; i < 3; i++) {
        double pad = 0.01 * (hi[i] - lo[i]) + 1e-6;
        int n = (int)lt[FP_LT_GRID_N + i];
        lt[FP_LT_GRID + i] = lo[i] - pad;
        lt[FP_LT_GRID_CELL + i] = (hi[i] - lo[i] + 2 * pad) / (n - 1);
    }
}

int fp_scatter_frame(const fp_params_t *p, fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                     const fp_view_t *v, const float *depth, long frame)
{
    if (!d->active)
        return FP_OK;
    double *lt = d->lt;
    /* Screen-space shadows: fog vector -> camera vector, and camera
     * (x/z, y/z, 1) -> NDC. */
    if (fp_mat3_inverse(v->m, lt + FP_LT_SS_M) || fp_mat3_inverse(v->h, lt + FP_LT_SS_H))
        return fp_error("frame %ld: the camera's matrices cannot be inverted", frame);
    if ((int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP) {
        int rc = load_shadow_map(p, d, frame);
        if (rc)
            return rc;
    }
    /* Without a fogmap the exact optical depth toward the sun is a closed
     * form: faster than any grid. */
    if ((int)lt[FP_LT_SELF] == FP_SELF_MAP && fog->fp[FP_F_HAS_MAP] == 0)
        lt[FP_LT_SELF] = FP_SELF_EXACT;
    if ((int)lt[FP_LT_SELF] == FP_SELF_MAP && lt[FP_LT_SUN_ON] != 0)
        grid_bounds(d, fog, v, depth);
    static _Atomic unsigned long serial;
    d->serial = ++serial;
    return FP_OK;
}

void fp_scatter_release(fp_scatter_data_t *d)
{
    free(d->smap);
    free(d->grid);
    d->smap = d->grid = NULL;
    d->grid_n = 0;
    d->grid_key.valid = 0;
}

double fp_scatter_ray_at(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                         const fp_view_t *v, const float *view_packed, const float *depth,
                         const double o[3], const double dir[3], double len, double offset,
                         double S[3])
{
    const fp_fog_tables_t *t = fog->tables;
    return fp_scatter_ray_core(fog->fp, TABLES(t), d->lt, d->smap ? d->smap : no_map,
                               d->grid ? d->grid : no_map, view_packed, depth, v->width,
                               v->height, o[0], o[1], o[2], dir[0], dir[1], dir[2], len, offset,
                               S);
}

double fp_scatter_ray(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                      const fp_view_t *v, const float *view_packed, const float *depth,
                      const double o[3], const double dir[3], double len, double S[3])
{
    return fp_scatter_ray_at(d, fog, v, view_packed, depth, o, dir, len, 0, S);
}

/* The self-shadow grid on the CPU (exact optical depth at each node). */
static int fill_grid(fp_scatter_data_t *d, const fp_integrate_data_t *fog)
{
    const double *lt = d->lt;
    int nx = (int)lt[FP_LT_GRID_N], ny = (int)lt[FP_LT_GRID_N + 1], nz = (int)lt[FP_LT_GRID_N + 2];
    size_t n = (size_t)nx * ny * nz;
    if (d->grid_n != n) {
        free(d->grid);
        d->grid = malloc(n * sizeof *d->grid);
        d->grid_n = d->grid ? n : 0;
        if (!d->grid)
            return fp_error("self-shadow grid: out of memory");
    }
    const fp_fog_tables_t *t = fog->tables;
    for (int k = 0; k < nz; k++)
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                double x = lt[FP_LT_GRID] + i * lt[FP_LT_GRID_CELL];
                double y = lt[FP_LT_GRID + 1] + j * lt[FP_LT_GRID_CELL + 1];
                double z = lt[FP_LT_GRID + 2] + k * lt[FP_LT_GRID_CELL + 2];
                d->grid[((size_t)k * ny + j) * nx + i] = (float)fp_fog_od(
                    fog->fp, TABLES(t), x, y, z, lt[FP_LT_SUN_DIR], lt[FP_LT_SUN_DIR + 1],
                    lt[FP_LT_SUN_DIR + 2], INFINITY, 0);
            }
    return FP_OK;
}

/* 1 when the grid filled from k is the one d and fog ask for; else k
 * becomes theirs (the caller fills the grid, and clears k->valid if that
 * fails). */
static int grid_current(fp_grid_key_t *k, const fp_scatter_data_t *d,
                        const fp_integrate_data_t *fog)
{
    unsigned long tables = fog->tables ? fog->tables->serial : 0;
    if (k->valid && k->tables == tables && memcmp(k->lt, d->lt, sizeof k->lt) == 0 &&
        memcmp(k->fp, fog->fp, sizeof k->fp) == 0)
        return 1;
    k->valid = 1;
    k->tables = tables;
    memcpy(k->lt, d->lt, sizeof k->lt);
    memcpy(k->fp, fog->fp, sizeof k->fp);
    return 0;
}

static int uses_grid(const fp_scatter_data_t *d)
{
    return (int)d->lt[FP_LT_SELF] == FP_SELF_MAP && d->lt[FP_LT_SUN_ON] != 0;
}

int fp_scatter_process(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                       const fp_view_t *v, const float *depth, float *out)
{
    return fp_scatter_pixels(d, fog, v, depth, NULL, (size_t)v->width * v->height, out);
}

int fp_scatter_pixels(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                      const fp_view_t *v, const float *depth, const int *pix, size_t npix,
                      float *out)
{
    fp_scatter_data_t *dw = (fp_scatter_data_t *)d;   /* the grid is a cache of d */
    if (uses_grid(d) && !grid_current(&dw->grid_key, d, fog) && fill_grid(dw, fog)) {
        dw->grid_key.valid = 0;
        return FP_ERR;
    }
    float view[FP_VIEW_FLOATS];
    fp_view_pack(v, view);
    for (size_t k = 0; k < npix; k++) {
        size_t i = pix ? (size_t)pix[k] : k;
        int x = (int)(i % (size_t)v->width), y = (int)(i / (size_t)v->width);
        double dir[3], len, S[3], o[3];
        fp_view_ray(v, x, y, depth[i], dir, &len);
        fp_view_origin_at(v, x, y, o);
        double tau = fp_scatter_ray_at(d, fog, v, view, depth, o, dir, len,
                                       fp_interleave_offset(d->lt, x, y), S);
        for (int c = 0; c < 3; c++)
            out[4 * k + c] = (float)S[c];
        out[4 * k + 3] = (float)tau;
    }
    return FP_OK;
}

int fp_scatter_cl_init(fp_cl_t *cl, fp_scatter_cl_t *s)
{
    memset(s, 0, sizeof *s);
    s->cl = cl;
    cl_program prog;
    /* No -cl-fast-relaxed-math for scatter_lights: its lanes carry
     * infinities (sky rays' length, fog without a top, empty spans), which
     * that option lets the compiler assume away (it dropped the lights). */
    if (fp_cl_program(cl, "scatter", "-cl-std=CL1.2", &prog) ||
        fp_cl_kernel(prog, "scatter_fog", &s->kernel) ||
        fp_cl_kernel(prog, "sun_od_grid", &s->grid_kernel) ||
        fp_cl_kernel(prog, "scatter_lights", &s->light_kernel))
        return FP_ERR;
    cl_int err;
    s->lt = clCreateBuffer(fp_cl_context(cl), CL_MEM_READ_ONLY, FP_LT_COUNT * sizeof(float), NULL,
                           &err);
    return fp_cl_check(err, "scatter: light buffer");
}

static int upload(fp_scatter_cl_t *s, const fp_scatter_data_t *d)
{
    cl_context ctx = fp_cl_context(s->cl);
    cl_command_queue q = fp_cl_queue(s->cl);
    float lt[FP_LT_COUNT];
    for (int i = 0; i < FP_LT_COUNT; i++)
        lt[i] = (float)d->lt[i];
    if (fp_cl_check(clEnqueueWriteBuffer(q, s->lt, CL_TRUE, 0, sizeof lt, lt, 0, NULL, NULL),
                    "scatter: upload light parameters"))
        return FP_ERR;
    if (s->smap && s->uploaded == d->serial)
        return FP_OK;
    cl_int err;
    if (s->smap)
        clReleaseMemObject(s->smap);
    size_t ns = d->smap ? (size_t)d->smap_w * d->smap_h : 1;
    s->smap = clCreateBuffer(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, ns * sizeof(float),
                             (void *)(d->smap ? d->smap : no_map), &err);
    if (fp_cl_check(err, "scatter: shadow map"))
        return FP_ERR;
    size_t ng = uses_grid(d) ? (size_t)d->lt[FP_LT_GRID_N] * (size_t)d->lt[FP_LT_GRID_N + 1] *
                                   (size_t)d->lt[FP_LT_GRID_N + 2]
                             : 1;
    if (!s->grid || s->grid_n != ng) {
        if (s->grid)
            clReleaseMemObject(s->grid);
        s->grid_key.valid = 0;
        s->grid = clCreateBuffer(ctx, CL_MEM_READ_WRITE, ng * sizeof(float), NULL, &err);
        if (fp_cl_check(err, "scatter: self-shadow grid"))
            return FP_ERR;
        s->grid_n = ng;
    }
    s->uploaded = d->serial;
    return FP_OK;
}

int fp_scatter_process_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                          const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                          float *out)
{
    return fp_scatter_pixels_cl(s, ic, d, fog, v, depth, NULL, 0, out);
}

int fp_scatter_pixels_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                         const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                         const int *pix, size_t npix, float *out)
{
    if (fp_integrate_cl_prepare(ic, fog, v, depth) || upload(s, d))
        return FP_ERR;
    cl_command_queue q = fp_cl_queue(s->cl);
    if (uses_grid(d) && !grid_current(&s->grid_key, d, fog)) {
        cl_kernel g = s->grid_kernel;
        size_t global[3] = { (size_t)d->lt[FP_LT_GRID_N], (size_t)d->lt[FP_LT_GRID_N + 1],
                             (size_t)d->lt[FP_LT_GRID_N + 2] };
        if (FP_CL_ARG(g, 0, s->grid) || FP_CL_ARG(g, 1, ic->params) || FP_CL_ARG(g, 2, ic->lvi) ||
            FP_CL_ARG(g, 3, ic->lvf) || FP_CL_ARG(g, 4, ic->coef) || FP_CL_ARG(g, 5, ic->occ) ||
            FP_CL_ARG(g, 6, s->lt) ||
            fp_cl_check(clEnqueueNDRangeKernel(q, g, 3, NULL, global, NULL, 0, NULL, NULL),
                        "sun_od_grid")) {
            s->grid_key.valid = 0;
            return FP_ERR;
        }
    }
    cl_kernel k = s->kernel;
    if (FP_CL_ARG(k, 12, s->lt) || FP_CL_ARG(k, 13, s->smap) || FP_CL_ARG(k, 14, s->grid) ||
        fp_integrate_cl_launch(ic, k, v, pix, npix, out, "scatter_fog"))
        return FP_ERR;
    /* Local lights by the fast rule: scatter_fog left them out
     * (FP_LIGHTS_APART); one launch of scatter_lights adds them all to the
     * fog layer, 16 pixels per work-item (FP_LN_LANES). */
    int nl = (int)d->lt[FP_LT_NLIGHTS];
    if (!(d->lt[FP_LT_LIGHT_QUAD] != 0 && fog->fp[FP_F_HAS_MAP] == 0 && nl > 0) ||
        (pix && npix == 0))
        return FP_OK;
    const size_t lanes = 16;   /* FP_LN_LANES in kernels/scatter_lanes.h */
    cl_kernel lk = s->light_kernel;
    cl_int w = v->width, h = v->height, cnpix = pix ? (cl_int)npix : 0;
    size_t global[2] = { ((size_t)w + lanes - 1) / lanes, (size_t)h };
    if (cnpix) {
        global[0] = (npix + lanes - 1) / lanes;
        global[1] = 1;
    }
    if (FP_CL_ARG(lk, 0, ic->depth) || FP_CL_ARG(lk, 1, ic->fog) || FP_CL_ARG(lk, 2, ic->view) ||
        FP_CL_ARG(lk, 3, w) || FP_CL_ARG(lk, 4, h) || FP_CL_ARG(lk, 5, ic->params) ||
        FP_CL_ARG(lk, 6, ic->pix) || FP_CL_ARG(lk, 7, cnpix) || FP_CL_ARG(lk, 8, s->lt) ||
        fp_cl_check(clEnqueueNDRangeKernel(q, lk, 2, NULL, global, NULL, 0, NULL, NULL),
                    "scatter_lights"))
        return FP_ERR;
    size_t nout = cnpix ? npix : (size_t)w * h;
    return fp_cl_check(clEnqueueReadBuffer(q, ic->fog, CL_TRUE, 0, nout * 4 * sizeof(float), out, 0,
                                           NULL, NULL),
                       "scatter: read the fog layer with the local lights");
}

void fp_scatter_cl_release(fp_scatter_cl_t *s)
{
    if (s->kernel)
        clReleaseKernel(s->kernel);
    if (s->grid_kernel)
        clReleaseKernel(s->grid_kernel);
    if (s->light_kernel)
        clReleaseKernel(s->light_kernel);
    cl_mem *mems[] = { &s->lt, &s->smap, &s->grid };
    for (size_t i = 0; i < FP_ARRAY_LEN(mems); i++)
        if (*mems[i])
            clReleaseMemObject(*mems[i]);
    memset(s, 0, sizeof *s);
}
