#include "scatter.h"
#include "exrio.h"
#include "fp.h"
#include "options.h"
#include "seq.h"
#include "shadowcheck.h"
#include "shafts.h"
#include "lamp_shadow.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The reference: the shared ray code in double precision. */
#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/scatter_core.h"

_Static_assert(FP_LT_COUNT == FP_LT_COUNT_, "light parameter count");
_Static_assert(FP_SCATTER_MAX_STEPS == FP_SCATTER_MAX_STEPS_, "segment limit");
_Static_assert(FP_LL_STRIDE == FP_LL_STRIDE_, "light row");

static void normalize3(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

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

/* --screen-shadow DIST,THICK.  The old STEPS,DIST,THICK still runs, with a
 * warning: the walk over the depth buffer is exact, so STEPS changed
 * nothing, and command lines, presets and farm scripts that pinned it keep
 * their frames. */
static int set_screen_shadow(fp_params_t *p, const fp_option_t *o, const char *value)
{
    double v[3];
    int n = 0, bad = 0;
    const char *s = value;
    for (;;) {
        char *end;
        v[n] = strtod(s, &end);
        if (end == s || !(v[n] >= o->min && v[n] <= o->max)) {
            bad = 1;
            break;
        }
        n++;
        s = end;
        if (*s != ',')
            break;
        if (n == 3) {
            bad = 1;
            break;
        }
        s++;
    }
    if (bad || *s || n < 2)
        return fp_usage_error("--%s: expected DIST,THICK (two numbers in %g..%g), got '%s'",
                              o->name, o->min, o->max, value);
    if (n == 3)
        fp_warn("--%s %s: STEPS is no longer used (the walk over the depth buffer is "
                "exact); give DIST,THICK: %g,%g", o->name, value, v[1], v[2]);
    p->light.screen_shadow[0] = v[n - 2];
    p->light.screen_shadow[1] = v[n - 1];
    return FP_OK;
}

static double len3(const double v[3])
{
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

static int finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* What is wrong with a light, or NULL. */
static const char *light_problem(const fp_light_t *li)
{
    if (li->kind < 0 || li->kind > 3)
        return "kind must be 0 (point), 1 (spot), 2 (area) or 3 (directional)";
    if (!finite3(li->pos) || !finite3(li->color) || !isfinite(li->intensity) ||
        !finite3(li->axis))
        return "its numbers must be finite";
    if (li->intensity < 0 || li->color[0] < 0 || li->color[1] < 0 || li->color[2] < 0)
        return "color and intensity must be >= 0";
    if (!(li->radius >= 0 && isfinite(li->radius)))
        return "the radius must be >= 0";
    if (li->kind == 3 && !(len3(li->axis) > 0))
        return "a directional light needs a non-zero direction toward it";
    if ((li->kind == 1 || li->kind == 2) && !(len3(li->axis) > 0))
        return "expected a non-zero direction";
    if (li->kind == 1 && li->spot_profile == 0 &&
        !(li->inner >= 0 && li->inner <= li->outer && li->outer > 0 && li->outer <= 180))
        return "expected cone angles 0 <= INNER <= OUTER <= 180 degrees (OUTER > 0)";
    if (li->kind == 1 && li->spot_profile == 1 &&
        !(li->outer > 0 && li->outer <= 90 && li->blend >= 0 && li->blend <= 1))
        return "expected a spot size 0 < SIZE <= 180 degrees and a blend in [0, 1]";
    if (li->kind == 2) {
        double n[3] = { li->axis[0], li->axis[1], li->axis[2] };
        normalize3(n);
        double un = li->u[0] * n[0] + li->u[1] * n[1] + li->u[2] * n[2];
        double up[3] = { li->u[0] - un * n[0], li->u[1] - un * n[1], li->u[2] - un * n[2] };
        if (!finite3(li->u) || !(len3(up) > 1e-9 * len3(li->u)))
            return "expected an X axis U not along the normal";
        if (!(li->size[0] > 0 && li->size[1] > 0 && isfinite(li->size[0]) &&
              isfinite(li->size[1])))
            return "expected sizes SU, SV > 0";
        if (li->shape != 0 && li->shape != 1)
            return "the shape must be 0 (rectangle) or 1 (ellipse)";
    }
    return NULL;
}

int fp_light_append(fp_light_params_t *l, const fp_light_t *li)
{
    const char *why = light_problem(li);
    if (why)
        return fp_error("light %d: %s", l->num_lights + 1, why);
    if (l->num_lights >= FP_MAX_LIGHTS)
        return fp_error("light %d: at most %d lights", l->num_lights + 1, FP_MAX_LIGHTS);
    if (l->num_lights == l->cap_lights) {
        int cap = l->cap_lights ? 2 * l->cap_lights : 16;
        fp_light_t *a = realloc(l->lights, (size_t)cap * sizeof *a);
        if (!a)
            return fp_error("light %d: out of memory", l->num_lights + 1);
        l->lights = a;
        l->cap_lights = cap;
    }
    l->lights[l->num_lights++] = *li;
    return FP_OK;
}

void fp_light_clear(fp_light_params_t *l)
{
    free(l->lights);
    l->lights = NULL;
    l->num_lights = l->cap_lights = 0;
}

/* --light, repeatable:
 *   point:X,Y,Z:R,G,B:I[:RADIUS]
 *   spot:X,Y,Z:R,G,B:I:DX,DY,DZ:INNER,OUTER[:RADIUS]   (half-angles, degrees)
 *   spot:X,Y,Z:R,G,B:I:DX,DY,DZ:cycles:SIZE,BLEND[:RADIUS]  (Cycles 3.x: full angle)
 *   area:X,Y,Z:R,G,B:I:NX,NY,NZ:UX,UY,UZ:SU,SV[:rectangle|ellipse]
 *   dir:DX,DY,DZ:R,G,B:E   (toward the light; irradiance) */
static int set_light(fp_params_t *p, const fp_option_t *o, const char *value)
{
    fp_light_params_t *l = &p->light;
    fp_light_t li;
    memset(&li, 0, sizeof li);
    enum { NF = 9 };
    const char *f[NF];
    size_t flen[NF];
    int nf = 0;
    for (const char *s = value; nf < NF;) {
        const char *c = strchr(s, ':');
        f[nf] = s;
        flen[nf++] = c ? (size_t)(c - s) : strlen(s);
        if (!c)
            break;
        s = c + 1;
        if (nf == NF)
            goto bad;
    }
#define FIELD_IS(k, name) (nf > (k) && flen[k] == strlen(name) && strncmp(f[k], name, flen[k]) == 0)
    double cone[2] = { 0, 0 };
    if (FIELD_IS(0, "dir")) {
        li.kind = 3;
        if (nf != 4 || parse_reals(f[1], flen[1], li.axis, 3) ||
            parse_reals(f[2], flen[2], li.color, 3) || parse_reals(f[3], flen[3], &li.intensity, 1))
            goto bad;
    } else if (FIELD_IS(0, "point")) {
        if ((nf != 4 && nf != 5) || (nf == 5 && parse_reals(f[4], flen[4], &li.radius, 1)))
            goto bad;
    } else if (FIELD_IS(0, "spot")) {
        li.kind = 1;
        int cyc = FIELD_IS(5, "cycles");
        int base = cyc ? 7 : 6;
        if ((nf != base && nf != base + 1) || parse_reals(f[4], flen[4], li.axis, 3) ||
            parse_reals(f[base - 1], flen[base - 1], cone, 2) ||
            (nf == base + 1 && parse_reals(f[base], flen[base], &li.radius, 1)))
            goto bad;
        if (cyc) {
            li.spot_profile = 1;
            li.outer = cone[0] / 2;
            li.blend = cone[1];
        } else {
            li.inner = cone[0];
            li.outer = cone[1];
        }
    } else if (FIELD_IS(0, "area")) {
        li.kind = 2;
        if ((nf != 7 && nf != 8) || parse_reals(f[4], flen[4], li.axis, 3) ||
            parse_reals(f[5], flen[5], li.u, 3) || parse_reals(f[6], flen[6], li.size, 2))
            goto bad;
        if (nf == 8) {
            if (FIELD_IS(7, "ellipse"))
                li.shape = 1;
            else if (!FIELD_IS(7, "rectangle"))
                goto bad;
        }
    } else {
        goto bad;
    }
#undef FIELD_IS
    if (li.kind != 3 &&
        (parse_reals(f[1], flen[1], li.pos, 3) || parse_reals(f[2], flen[2], li.color, 3) ||
         parse_reals(f[3], flen[3], &li.intensity, 1)))
        goto bad;
    const char *why = light_problem(&li);
    if (why)
        return fp_usage_error("--%s: '%s': %s", o->name, value, why);
    if (fp_light_append(l, &li))
        return fp_usage_error("--%s: '%s': at most %d lights (or out of memory)", o->name, value,
                              FP_MAX_LIGHTS);
    free(l->light);
    l->light = strdup(value);
    return FP_OK;
bad:
    return fp_usage_error("--%s: '%s': expected point:X,Y,Z:R,G,B:I[:RADIUS], "
                          "spot:X,Y,Z:R,G,B:I:DX,DY,DZ:INNER,OUTER[:RADIUS], "
                          "spot:X,Y,Z:R,G,B:I:DX,DY,DZ:cycles:SIZE,BLEND[:RADIUS], "
                          "area:X,Y,Z:R,G,B:I:NX,NY,NZ:UX,UY,UZ:SU,SV[:rectangle|ellipse] or "
                          "dir:DX,DY,DZ:R,G,B:E", o->name, value);
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
      "a light, repeatable (any number; D, N, U: three numbers X,Y,Z): "
      "point:X,Y,Z:R,G,B:I[:RADIUS], spot:X,Y,Z:R,G,B:I:D:INNER,OUTER[:RADIUS] (cone "
      "half-angles, degrees), spot:X,Y,Z:R,G,B:I:D:cycles:SIZE,BLEND[:RADIUS] (Cycles 3.x: "
      "SIZE the full angle, intensity c smoothstep(BLEND)), "
      "area:X,Y,Z:R,G,B:I:N:U:SU,SV[:ellipse] (one-sided, I along its normal N times the "
      "cosine, U its X axis; Cycles: power/4), dir:D:R,G,B:E (an extra sun: toward it, "
      "irradiance E; no shadow map, screen shadows with --shadows screen); I is the radiant "
      "intensity (W/sr: irradiance I/d^2; Cycles' point and spot: power/(4 pi)); RADIUS the "
      "soft size (no 1/d^2 peak within it); the fog between light and point attenuates it",
      set_light, 0 },
    { "light-cull", 0, FP_OPT_REAL, LI(light_cull), 0, 0, "1e-4", 0, 1e6, NULL, "E",
      "each pixel pays for the local lights that reach it: lights are left out of a pixel "
      "while the bounds of what they could add to it sum to at most E (so the fog layer "
      "differs by at most E in each channel from computing every light; 0: every light)",
      NULL, 0 },
    { "shadow-map", 0, FP_OPT_STRING, LI(shadow_map), 0, 0, NULL, 0, 0, NULL, "PATTERN",
      "the sun's depth map per frame: orthographic, camera-space depth Z, worldToCamera and "
      "worldToNDC in its header (as fogpipe-scene writes shadow.####.exr)", NULL, 0 },
    { "shadows", 0, FP_OPT_ENUM, LI(shadows), 0, 0, "auto", 0, 0,
      "auto|none|map|screen|map+screen", "auto|none|map|screen|map+screen",
      "the sun's shadows in the fog: from --shadow-map (auto: when given), by marching "
      "toward the sun over the camera's depth buffer (screen), both (map+screen: shadowed "
      "where either shadows, so casters too thin for the map that the camera sees shadow, "
      "and those outside the frame shadow through the map), or none", NULL, 0 },
    { "wants", 0, FP_OPT_ENUM, LI(wants), 0, 0, "none", 0, 0, "none|shadow-map",
      "none|shadow-map",
      "what the look needs to be itself, for a preset to say: shadow-map (its shafts come from "
      "the sun's shadow map: a warning, once, when a frame is fogged without one)", NULL, 0 },
    { "shadow-bias", 0, FP_OPT_REAL, LI(shadow_bias), 0, 0, "0", 0, 1e6, NULL, "D",
      "shadow map depth bias in scene units, added to each texel's own (half the depth's change "
      "across the texel on its surface, at most what level ground needs under this sun)", NULL, 0 },
    { "shadow-filter", 0, FP_OPT_INT, LI(shadow_filter), 0, 0, "1", 0, 8, NULL, "R",
      "soften the shadows' edges: along each view ray the sun's visibility ramps over R texels "
      "each side of an edge, at most half of the stretch on either side (0: hard, exact for the "
      "map)", NULL, 0 },
    { "screen-shadow", 0, FP_OPT_VEC, LI(screen_shadow), 2, 2, "20,1", 0, 1e6, NULL,
      "DIST,THICK",
      "--shadows screen: how far toward the sun the depth buffer is searched for what "
      "shadows a point (scene units), and the thickness assumed behind what it shows "
      "(the old STEPS,DIST,THICK still runs, with a warning)", set_screen_shadow, 0 },
    { "lamp-shadows", 0, FP_OPT_ENUM, LI(lamp_shadows), 0, 0, "screen", 0, 0, "screen|none",
      "screen|none", "the point, spot and area lights' shadows in the fog: by walking toward "
      "each lamp over the camera's depth buffer (screen; --screen-shadow's THICK), or none",
      NULL, 0 },
    { "self-shadow", 0, FP_OPT_ENUM, LI(self_shadow), 0, 0, "auto", 0, 0, "off|exact|map|auto",
      "off|exact|map|auto",
      "fog shadowing itself: sunlight reaching a point is attenuated by the fog between it "
      "and the sun, integrated exactly per point, or looked up in a per-frame grid aligned "
      "with the sun of exact values at its nodes (map; --self-shadow-grid); without a "
      "fogmap both are the exact closed form; auto: map", NULL, 0 },
    { "self-shadow-grid", 0, FP_OPT_VEC, LI(self_shadow_grid), 3, 3, "0,0,32", 0, 1024, NULL,
      "NA,NB,NY", "nodes of each cascade of the self-shadow grid (--self-shadow map): across "
      "the sun (NA x NB) and along its rays by height (NY), each at least 2; NA, NB 0: half "
      "the square root of the frame's pixel count (64 to 256), so that filling the grid costs "
      "about the same per pixel at every resolution", NULL, 0 },
    { "self-shadow-cascades", 0, FP_OPT_INT, LI(self_shadow_cascades), 0, 0, "3", 1,
      FP_LT_MAX_CASCADES, NULL, "K",
      "cascades of the self-shadow grid, nested around the camera: K distances in geometric "
      "progression from the nearest fog (at least 1/64 of the farthest) to the farthest, "
      "the view rays' fog within each a cascade of its own", NULL, 0 },
    { "scatter-steps", 0, FP_OPT_INT, LI(scatter_steps), 0, 0, "64", 1, FP_SCATTER_MAX_STEPS / 2,
      NULL, "N",
      "segments along each view ray for the sun's in-scattering without a shadow map or "
      "screen shadows (each integrated exactly for extinction, the light linear within it); "
      "the shafts with them need none", NULL, 0 },
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

/* The lights' table (kernels/light_core.h FP_LL_*), fog space: local
 * lights first, then the directional ones. */
static int pack_lights(const fp_params_t *p, fp_scatter_data_t *d)
{
    const fp_light_params_t *l = &p->light;
    int n = l->num_lights, nl = 0, nd = 0;
    free(d->lights);
    d->lights = calloc((size_t)(n > 0 ? n : 1) * FP_LL_STRIDE, sizeof *d->lights);
    if (!d->lights)
        return fp_error("lights: out of memory");
    for (int pass = 0; pass < 2; pass++)
        for (int k = 0; k < n; k++) {
            const fp_light_t *li = &l->lights[k];
            if ((li->kind == 3) != pass)
                continue;
            double *row = d->lights + (size_t)(nl + nd) * FP_LL_STRIDE;
            pass ? nd++ : nl++;
            for (int c = 0; c < 3; c++)
                row[FP_LL_I + c] = li->color[c] * li->intensity;
            row[FP_LL_IMAX] = fmax(row[FP_LL_I], fmax(row[FP_LL_I + 1], row[FP_LL_I + 2]));
            if (li->kind == 3) {
                row[FP_LL_TYPE] = FP_LIGHT_DIR;
                fp_world_to_fog(p->camera.up, li->axis, row + FP_LL_POS);
                normalize3(row + FP_LL_POS);
                continue;
            }
            row[FP_LL_TYPE] = li->kind == 1 ? FP_LIGHT_SPOT : li->kind == 2 ? FP_LIGHT_AREA
                                                                            : FP_LIGHT_POINT;
            fp_world_to_fog(p->camera.up, li->pos, row + FP_LL_POS);
            row[FP_LL_RADIUS] = li->kind == 2 ? 0 : li->radius;
            if (li->kind == 0)
                continue;
            fp_world_to_fog(p->camera.up, li->axis, row + FP_LL_AXIS);
            normalize3(row + FP_LL_AXIS);
            if (li->kind == 1 && li->spot_profile == 0) {
                row[FP_LL_COS_IN] = cos(li->inner * M_PI / 180);
                row[FP_LL_COS_OUT] = cos(li->outer * M_PI / 180);
            } else if (li->kind == 1) {
                /* Cycles 3.x spot_attenuation: spread = (1 - cos(half)) blend;
                 * the smooth edge ends at cos(half) + spread. */
                double co = cos(li->outer * M_PI / 180), spread = (1 - co) * li->blend;
                row[FP_LL_PROFILE] = 1;
                row[FP_LL_COS_OUT] = co;
                row[FP_LL_SPREAD] = spread;
                row[FP_LL_COS_IN] = fmin(co + spread, 1);
            } else {
                /* Area: U in its plane (made orthogonal to N), V = N x U. */
                double *N = row + FP_LL_AXIS, U[3], V[3];
                fp_world_to_fog(p->camera.up, li->u, U);
                double un = U[0] * N[0] + U[1] * N[1] + U[2] * N[2];
                for (int c = 0; c < 3; c++)
                    U[c] -= un * N[c];
                normalize3(U);
                V[0] = N[1] * U[2] - N[2] * U[1];
                V[1] = N[2] * U[0] - N[0] * U[2];
                V[2] = N[0] * U[1] - N[1] * U[0];
                for (int c = 0; c < 3; c++) {
                    row[FP_LL_U + c] = 0.5 * li->size[0] * U[c];
                    row[FP_LL_V + c] = 0.5 * li->size[1] * V[c];
                }
                row[FP_LL_SHAPE] = li->shape;
                row[FP_LL_AREA] = li->size[0] * li->size[1] * (li->shape ? M_PI / 4 : 1);
                row[FP_LL_REACH] = 0.5 * sqrt(li->size[0] * li->size[0] + li->size[1] * li->size[1]);
                row[FP_LL_COS_OUT] = 0;
                row[FP_LL_COS_IN] = 0;
            }
        }
    d->nlights = nl + nd;
    d->lt[FP_LT_NLIGHTS] = nl;
    d->lt[FP_LT_NDIR] = nd;
    return FP_OK;
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
    if ((shadows == FP_SHADOWS_WITH_MAP || shadows == FP_SHADOWS_WITH_MAP_SCREEN) &&
        !l->shadow_map)
        return fp_usage_error("--shadows %s: needs --shadow-map PATTERN",
                              shadows == FP_SHADOWS_WITH_MAP ? "map" : "map+screen");
    if (l->shadow_map && !sun)
        return fp_usage_error("--shadow-map: the shadows are the sun's; give --sun too");
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
    int dirs = 0;
    for (int k = 0; k < l->num_lights; k++)
        dirs |= l->lights[k].kind == 3;
    /* The extra directional lights have screen shadows (no map). */
    lt[FP_LT_SHADOWS] = !sun ? (dirs && shadows == FP_SHADOWS_WITH_SCREEN ? FP_SHADOWS_SCREEN
                                                                          : FP_SHADOWS_NONE)
                        : shadows == FP_SHADOWS_WITH_MAP ? FP_SHADOWS_MAP
                        : shadows == FP_SHADOWS_WITH_SCREEN ? FP_SHADOWS_SCREEN
                        : shadows == FP_SHADOWS_WITH_MAP_SCREEN ? FP_SHADOWS_MAP_SCREEN
                                                                : FP_SHADOWS_NONE;
    lt[FP_LT_SELF] = l->self_shadow == FP_SELF_SHADOW_OFF ? FP_SELF_OFF
                     : l->self_shadow == FP_SELF_SHADOW_EXACT ? FP_SELF_EXACT : FP_SELF_MAP;
    lt[FP_LT_STEPS] = l->scatter_steps;
    lt[FP_LT_PANELS] = l->light_panels;
    /* The fast rule cuts a spot's range at its cone, one interval when the
     * cone is at most 90 degrees wide: wider spots take the panels. */
    int wide = 0;
    for (int k = 0; k < l->num_lights; k++)
        wide |= l->lights[k].kind == 1 && l->lights[k].outer > 90;
    lt[FP_LT_LIGHT_QUAD] = l->light_quad == FP_LIGHT_QUAD_FAST && !wide;
    lt[FP_LT_INTERLEAVE] = floor(l->interleave[0]);
    lt[FP_LT_INTERLEAVE + 1] = floor(l->interleave[1]);
    lt[FP_LT_SM_RADIUS] = l->shadow_filter;
    lt[FP_LT_SS_DIST] = l->screen_shadow[0];
    lt[FP_LT_SS_THICK] = l->screen_shadow[1];
    for (int i = 0; i < 3; i++)
        lt[FP_LT_GRID_N + i] = floor(l->self_shadow_grid[i]);
    lt[FP_LT_GRID_K] = l->self_shadow_cascades;
    {
        const double *g = l->self_shadow_grid;
        int autosize = floor(g[0]) == 0 && floor(g[1]) == 0;
        if (!(g[2] >= 2) || (!autosize && !(g[0] >= 2 && g[1] >= 2)))
            return fp_usage_error("--self-shadow-grid: expected NA,NB,NY of at least 2 each "
                                  "(or NA, NB 0: sized by the frame)");
        double na = autosize ? 256 : floor(g[0]), nb = autosize ? 256 : floor(g[1]);
        if (lt[FP_LT_GRID_K] * na * nb * floor(g[2]) > (double)(1 << 26))
            return fp_usage_error("--self-shadow-grid: %g x %g x %g nodes times %d cascades: at "
                                  "most 2^26 nodes in all", na, nb, floor(g[2]),
                                  l->self_shadow_cascades);
    }
    if (sun) {
        /* The self-shadow grid's frame: e1 horizontal across the sun (x when
         * the sun is overhead), e2 horizontal toward it. */
        const double *sl = lt + FP_LT_SUN_DIR;
        double *e1 = lt + FP_LT_SUN_E1, *e2 = lt + FP_LT_SUN_E2;
        double hn = sqrt(sl[0] * sl[0] + sl[2] * sl[2]);
        e1[0] = hn > 1e-9 ? -sl[2] / hn : 1;
        e1[1] = 0;
        e1[2] = hn > 1e-9 ? sl[0] / hn : 0;
        e2[0] = -e1[2];
        e2[1] = 0;
        e2[2] = e1[0];
    }
    /* Beyond an optical depth of 30 (transmittance 1e-13) nothing shows. */
    lt[FP_LT_OD_STOP] = 30;
    lt[FP_LT_SEG_OD] = 0.25;
    lt[FP_LT_SEG_JUMP] = 0.002;
    int rc = pack_lights(p, d);
    if (rc)
        return rc;
    lt[FP_LT_CULL] = l->light_cull;
    d->lamp_shadows = l->lamp_shadows == FP_LAMP_SHADOWS_SCREEN && lt[FP_LT_NLIGHTS] > 0;
    /* The phase function's largest value: at mu = 1 or -1 for every kind. */
    lt[FP_LT_PMAX] = fmax(fp_phase(l->phase_kind, l->phase_g, l->phase_w, 1),
                          fp_phase(l->phase_kind, l->phase_g, l->phase_w, -1));
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
    int rc = FP_OK;
    /* A frame's rig names its own map: no frame number in it. */
    if (p->light.shadow_map_literal)
        snprintf(path, sizeof path, "%s", p->light.shadow_map);
    else if ((rc = fp_seq_format(p->light.shadow_map, frame, path, sizeof path)))
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
    /* The sun camera: its header's matrices, or its fogpipe-camera text
     * (a map rendered in Blender with the add-on). */
    double w2c[16], w2n[16];
    if ((rc = fp_camera_matrices(info, path, frame, "shadow map", w2c, w2n))) {
        fp_frame_free(f);
        return rc;
    }
    size_t n = (size_t)info->width * info->height;
    float *z = malloc(n * sizeof *z);
    if (!z) {
        fp_frame_free(f);
        return fp_error("%s: frame %ld: out of memory", path, frame);
    }
    memcpy(z, fp_frame_depth(f), n * sizeof *z);
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
    fp_mat4_mul(f2w, w2n, m);
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
    fp_mat4_mul(f2w, w2c, c);
    for (int r = 0; r < 4; r++)
        d->lt[FP_LT_SM_Z + r] = c[r * 4 + 2];
    d->lt[FP_LT_SM_W] = info->width;
    d->lt[FP_LT_SM_H] = info->height;
    /* The walk (kernels/shafts_core.h) needs the map's coordinates affine
     * in the point: an orthographic sun camera, w = 1. */
    double *q = d->lt + FP_LT_SM_NDC;
    if (!(fabs(q[3]) + fabs(q[7]) + fabs(q[11]) <= 1e-6 * fabs(q[15]))) {
        fp_frame_free(f);
        free(z);
        return fp_error("%s: frame %ld: shadow map with a perspective worldToNDC (expected the "
                        "sun's orthographic camera, w = 1)", path, frame);
    }
    for (int i = 0; i < 16; i++)
        if (i % 4 != 3)
            q[i] /= q[15];
    q[15] = 1;
    /* The bias, per texel in scene units (filters/shafts.c): half the
     * depth's change across the texel on its own surface, at most what
     * level ground under this sun needs (a texel times the sun's
     * horizontal over vertical component, at least one texel), plus
     * --shadow-bias. */
    double gx = sqrt(m[0] * m[0] + m[4] * m[4] + m[8] * m[8]) * info->disp_w;
    double gy = sqrt(m[1] * m[1] + m[5] * m[5] + m[9] * m[9]) * info->disp_h;
    double texel = fmax(gx > 0 ? 1 / gx : 0, gy > 0 ? 1 / gy : 0);
    const double *l = d->lt + FP_LT_SUN_DIR;
    double slope = sqrt(l[0] * l[0] + l[2] * l[2]) / fmax(l[1], 0.05);
    d->lt[FP_LT_SM_BIAS] = p->light.shadow_bias;
    /* Casters and gaps too thin for the map (filters/shadowcheck.h): a
     * depth step of two texels of level ground under this sun. */
    fp_shadowcheck_frame(path, frame, z, info->width, info->height, gx > 0 ? 1 / gx : 0,
                         gy > 0 ? 1 / gy : 0, 2 * texel * fmax(1, slope) + p->light.shadow_bias,
                         d->lt + FP_LT_SM_NDC, d->lt + FP_LT_SM_Z, p->camera.up);
    float *packed = NULL;
    size_t np = 0;
    int levels = 0;
    if (fp_shafts_build(z, info->width, info->height, texel * fmax(1, slope),
                        p->light.shadow_bias, &packed, &np, &levels)) {
        fp_frame_free(f);
        free(z);
        return fp_error("%s: frame %ld: out of memory", path, frame);
    }
    free(d->smap);
    free(z);
    d->smap = packed;
    d->smap_n = np;
    d->smap_w = info->width;
    d->smap_h = info->height;
    d->lt[FP_LT_SM_LEVELS] = levels;
    fp_frame_free(f);
    return FP_OK;
}

static const float no_map[1] = { INFINITY };
static const double no_lights[FP_LL_STRIDE];

#define FP_GRID_MIN_SUN_Y 0.05

#define TABLES(t) FP_TABLES(fp_fog_tables_or_empty(t))

/* The self-shadow grid's cascades (kernels/light_core.h): the stretch of
 * every 8th pixel's ray (each way) that holds fog, from ta to tb, in the
 * grid's frame.  The coarsest cascade holds all of it; cascade c < K - 1
 * the part within R_c = N (F / N)^((c + 1) / K) of the camera (the
 * pixels' footprint grows with the distance), F the farthest tb and N the
 * nearest ta, at least F / 64; each slightly enlarged.  A point that no
 * cascade holds (between the sampled rays) is integrated exactly. */
static int grid_bounds(fp_scatter_data_t *d, const fp_integrate_data_t *fog, const fp_view_t *v,
                       const float *depth)
{
    const int st = 8;
    size_t nr = (size_t)((v->width + st - 1) / st) * (size_t)((v->height + st - 1) / st), m = 0;
    double *ray = malloc(nr * 8 * sizeof *ray);
    if (!ray)
        return fp_error("self-shadow grid: out of memory");
    double far = 0, near = INFINITY;
    for (int y = 0; y < v->height; y += st)
        for (int x = 0; x < v->width; x += st) {
            double dir[3], len, ta, tb, o[3];
            fp_view_ray(v, x, y, depth[(size_t)y * v->width + x], dir, &len);
            fp_view_origin_at(v, x, y, o);
            if (!fp_fog_span(fog->fp, o[0], o[1], o[2], dir[0], dir[1],
                             dir[2], len, &ta, &tb))
                continue;
            if (isinf(tb)) {
                /* Unbounded: as far as the integrator goes (fp_scatter_ray_core:
                 * until the optical depth from ta passes its stop, or
                 * nearly all of it is behind), found by doubling. */
                const double *fp = fog->fp;
                double od0 = fp_fog_od(fp, TABLES(fog->tables), o[0], o[1], o[2], dir[0],
                                       dir[1], dir[2], ta, 0);
                double odt = fp_fog_od(fp, TABLES(fog->tables), o[0], o[1], o[2], dir[0],
                                       dir[1], dir[2], len, 0);
                double step = fmax(1 / fmax(fp[FP_F_SIGMA] + fp[FP_F_HAZE], 1e-12), 1e-3);
                for (int k = 0; k < 80 && step < fp[FP_F_CAP]; k++, step *= 2) {
                    double od = fp_fog_od(fp, TABLES(fog->tables), o[0], o[1], o[2], dir[0],
                                          dir[1], dir[2], ta + step, 0);
                    if (od - od0 >= d->lt[FP_LT_OD_STOP] ||
                        (isfinite(odt) && odt - od <= 1e-4 * odt))
                        break;
                }
                tb = ta + fmin(step, fp[FP_F_CAP]);
            }
            double *r = ray + 8 * m++;
            for (int i = 0; i < 3; i++) {
                r[i] = o[i];
                r[3 + i] = dir[i];
            }
            r[6] = ta;
            r[7] = tb;
            far = fmax(far, tb);
            near = fmin(near, ta);
        }
    double *lt = d->lt;
    int K = (int)lt[FP_LT_GRID_K];
    const double *l = lt + FP_LT_SUN_DIR, *e1 = lt + FP_LT_SUN_E1, *e2 = lt + FP_LT_SUN_E2;
    double shear = (l[0] * e2[0] + l[2] * e2[2]) / l[1];
    /* The fog's top in fog space (a plane of nodes goes there), else its
     * base Y0 (where the height profile bends); the weight of the nodes
     * (fp_sun_od_weight) from the main fog's height profile. */
    double top = fmin(fog->fp[FP_F_TOP], fog->fp[FP_F_BOX + 4]) + fog->fp[FP_F_OFF + 1];
    double base = fog->fp[FP_F_Y0] + fog->fp[FP_F_OFF + 1];
    lt[FP_LT_GRID_W] = base;
    lt[FP_LT_GRID_W + 1] = isfinite(fog->fp[FP_F_H]) && fog->fp[FP_F_H] > 0 ? fog->fp[FP_F_H] : 0;
    for (int c = K - 1; c >= 0; c--) {
        double n0 = fmax(near, far / 64);
        double reach = c + 1 == K ? INFINITY : n0 * pow(far / n0, (c + 1.0) / K);
        double lo[3] = { INFINITY, INFINITY, INFINITY };
        double hi[3] = { -INFINITY, -INFINITY, -INFINITY };
        for (size_t k = 0; k < m; k++) {
            const double *r = ray + 8 * k;
            if (!(r[6] < reach))
                continue;
            for (int e = 0; e < 2; e++) {
                double t = e ? fmin(r[7], reach) : r[6], p[3], q[3];
                for (int i = 0; i < 3; i++)
                    p[i] = r[i] + t * r[3 + i];
                q[0] = p[0] * e1[0] + p[2] * e1[2];
                q[1] = p[0] * e2[0] + p[2] * e2[2] - p[1] * shear;
                q[2] = p[1];
                for (int i = 0; i < 3; i++) {
                    lo[i] = fmin(lo[i], q[i]);
                    hi[i] = fmax(hi[i], q[i]);
                }
            }
        }
        double *box = lt + FP_LT_CASCADE + 6 * c;
        if (!(lo[0] <= hi[0])) {
            /* No fog this near: the next cascade's box again (or, when
             * no ray holds fog, a unit box at the camera). */
            for (int i = 0; i < 6; i++)
                box[i] = c + 1 < K ? box[6 + i] : i < 3 ? 0 : 1;
            if (c + 1 == K) {
                const double *o = v->origin;
                box[0] = o[0] * e1[0] + o[2] * e1[2];
                box[1] = o[0] * e2[0] + o[2] * e2[2] - o[1] * shear;
                box[2] = o[1];
            }
            continue;
        }
        for (int i = 0; i < 3; i++) {
            double pad = 0.02 * (hi[i] - lo[i]) + 1e-6;
            int n = (int)lt[FP_LT_GRID_N + i];
            box[i] = lo[i] - pad;
            box[3 + i] = (hi[i] - lo[i] + 2 * pad) / (n - 1);
            /* The extinction jumps at the fog's top (and bends at Y0):
             * within the heights, the nodes are shifted down (one more
             * cell in all) so that a plane of them lies on it. */
            double plane = top > box[2] && top < hi[2] + pad ? top : base;
            if (i == 2 && n > 2 && plane > box[2] && plane < hi[2] + pad) {
                double h = (hi[2] - lo[2] + 2 * pad) / (n - 2);
                box[5] = h;
                box[2] = plane - ceil((plane - box[2]) / h) * h;
            }
        }
    }
    free(ray);
    return FP_OK;
}

static _Atomic unsigned long serial;

int fp_scatter_screen(fp_scatter_data_t *d, const fp_view_t *v, const float *depth, long frame)
{
    double *lt = d->lt;
    int both = (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP_SCREEN;
    /* The lamps' walk (--lamp-shadows) reads the same pyramid, after the
     * sun's map when there is one. */
    int lamps = d->lamp_shadows && depth;
    lt[FP_LT_LS_ON] = 0;
    if (!d->active || ((int)lt[FP_LT_SHADOWS] != FP_SHADOWS_SCREEN && !both && !lamps))
        return FP_OK;
    both |= lamps && (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP;
    /* The deepest thing the depth buffer shows: no shadow reaches beyond
     * it (fp_shafts_screen). */
    float view[FP_VIEW_FLOATS];
    fp_view_pack(v, view);
    size_t np = (size_t)v->width * v->height;
    float *z = malloc(np * sizeof *z);
    if (!z)
        return fp_error("frame %ld: out of memory", frame);
    double zmax = 0;
    for (int y = 0; y < v->height; y++)
        for (int x = 0; x < v->width; x++) {
            double zs = fp_scene_z(view, depth, v->width, x, y);
            z[(size_t)y * v->width + x] = (float)zs;
            if (zs < INFINITY)
                zmax = fmax(zmax, zs);
        }
    lt[FP_LT_SS_ZMAX] = zmax;
    /* The walk's map: the scene z per pixel and its min-max pyramid, with
     * its own size and pixels (the walk does not take them from the view
     * it traces). */
    float *packed = NULL;
    int levels = 0;
    int bad = fp_shafts_pyramid(z, v->width, v->height, &packed, &np, &levels);
    free(z);
    if (bad)
        return fp_error("frame %ld: out of memory", frame);
    if (both) {
        /* map+screen: after the shadow map's floats in one buffer
         * (kernels/light_core.h fp_ss_zpyr), the map kept. */
        size_t nm = fp_shafts_size((int)lt[FP_LT_SM_W], (int)lt[FP_LT_SM_H],
                                   (int)lt[FP_LT_SM_LEVELS]);
        float *all = d->smap && d->smap_n >= nm ? malloc((nm + np) * sizeof *all) : NULL;
        if (!all) {
            free(packed);
            return fp_error("frame %ld: %s", frame,
                            d->smap ? "out of memory" : "--shadows map+screen without its map");
        }
        memcpy(all, d->smap, nm * sizeof *all);
        memcpy(all + nm, packed, np * sizeof *all);
        lt[FP_LT_LS_ZOFF] = (double)nm;
        free(packed);
        packed = all;
        np += nm;
    } else {
        lt[FP_LT_LS_ZOFF] = 0;
        d->smap_w = v->width;
        d->smap_h = v->height;
        lt[FP_LT_SM_W] = v->width;
        lt[FP_LT_SM_H] = v->height;
        lt[FP_LT_SM_LEVELS] = levels;
    }
    free(d->smap);
    d->smap = packed;
    d->smap_n = np;
    lt[FP_LT_SS_PW] = v->width;
    lt[FP_LT_SS_PH] = v->height;
    lt[FP_LT_SS_PLEVELS] = levels;
    lt[FP_LT_LS_ON] = lamps;
    for (int i = 0; i < 2; i++) {
        lt[FP_LT_SS_NDC + i] = v->ndc_scale[i];
        lt[FP_LT_SS_NDC + 2 + i] = v->ndc_offset[i];
    }
    d->serial = ++serial;
    return FP_OK;
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
    if ((int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP ||
        (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP_SCREEN) {
        int rc = load_shadow_map(p, d, frame);
        if (rc)
            return rc;
    }
    fp_shadowcheck_wants(p, (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP ||
                                (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP_SCREEN);
    int rc = fp_scatter_screen(d, v, depth, frame);
    if (rc)
        return rc;
    /* Without a fogmap the exact optical depth toward the sun is a closed
     * form: faster than any grid. */
    if ((int)lt[FP_LT_SELF] == FP_SELF_MAP && fog->fp[FP_F_HAS_MAP] == 0)
        lt[FP_LT_SELF] = FP_SELF_EXACT;
    /* The grid's columns follow the sun's rays by height: a sun lower than
     * FP_GRID_MIN_SUN_Y (3 degrees) takes the exact path. */
    if ((int)lt[FP_LT_SELF] == FP_SELF_MAP && !(lt[FP_LT_SUN_DIR + 1] >= FP_GRID_MIN_SUN_Y))
        lt[FP_LT_SELF] = FP_SELF_EXACT;
    if ((int)lt[FP_LT_SELF] == FP_SELF_MAP && lt[FP_LT_SUN_ON] != 0) {
        /* NA, NB 0: sized by the frame (filling the grid then costs about
         * the same per pixel at every resolution). */
        const double *g = p->light.self_shadow_grid;
        int autosize = floor(g[0]) == 0 && floor(g[1]) == 0;
        double side = fmin(fmax(round(0.5 * sqrt((double)v->width * v->height)), 64), 256);
        lt[FP_LT_GRID_N] = autosize ? side : floor(g[0]);
        lt[FP_LT_GRID_N + 1] = autosize ? side : floor(g[1]);
        if ((rc = grid_bounds(d, fog, v, depth)))
            return rc;
    }
    d->serial = ++serial;
    return FP_OK;
}

void fp_scatter_release(fp_scatter_data_t *d)
{
    free(d->smap);
    free(d->grid);
    free(d->lights);
    d->lights = NULL;
    d->nlights = 0;
    d->smap = d->grid = NULL;
    d->grid_n = 0;
    d->grid_key.valid = 0;
}

/* One ray with the light data as they are (the self-shadow grid, when
 * used, already filled: fp_scatter_pixels). */
static double ray_at(const fp_scatter_data_t *d, const double *lt, const fp_integrate_data_t *fog,
                     const fp_view_t *v, const float *view_packed, const float *depth,
                     const double o[3], const double dir[3], double len, double offset,
                     double S[3])
{
    const fp_fog_tables_t *t = fog->tables;
    double tau = fp_scatter_ray_core(fog->fp, TABLES(t), lt, d->lights ? d->lights : no_lights,
                                     d->smap ? d->smap : no_map,
                                     d->grid ? d->grid : no_map, view_packed, depth, v->width,
                                     v->height, o[0], o[1], o[2], dir[0], dir[1], dir[2], len,
                                     offset, S);
    if (view_packed && d->smap)   /* the fast rule's lamps' shadows, as kernel lamp_shadows */
        fp_ls_fix(fog->fp, lt, d->lights ? d->lights : no_lights, view_packed, d->smap, o[0],
                  o[1], o[2], dir[0], dir[1], dir[2], len, tau, S);
    return tau;
}

static int ensure_grid(const fp_scatter_data_t *d, const fp_integrate_data_t *fog);

double fp_scatter_ray_at(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                         const fp_view_t *v, const float *view_packed, const float *depth,
                         const double o[3], const double dir[3], double len, double offset,
                         double S[3])
{
    /* A ray on its own fills the self-shadow grid it looks up; when that
     * fails (memory), its optical depth toward the sun is exact. */
    if (ensure_grid(d, fog) == FP_OK)
        return ray_at(d, d->lt, fog, v, view_packed, depth, o, dir, len, offset, S);
    double lt[FP_LT_COUNT];
    memcpy(lt, d->lt, sizeof lt);
    lt[FP_LT_SELF] = FP_SELF_EXACT;
    return ray_at(d, lt, fog, v, view_packed, depth, o, dir, len, offset, S);
}

double fp_scatter_ray(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                      const fp_view_t *v, const float *view_packed, const float *depth,
                      const double o[3], const double dir[3], double len, double S[3])
{
    return fp_scatter_ray_at(d, fog, v, view_packed, depth, o, dir, len, 0, S);
}

double fp_scatter_sun_brute(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                            const double o[3], const double dir[3], double len, long n,
                            double (*vis)(void *ctx, const double p[3]), void *ctx)
{
    const double *fp = fog->fp, *lt = d->lt, *l = lt + FP_LT_SUN_DIR;
    const fp_fog_tables_t *t = fog->tables;
    const float *smap = d->smap ? d->smap : no_map;
    double ta, tb;
    if (n < 1 || !fp_fog_span(fp, o[0], o[1], o[2], dir[0], dir[1], dir[2], len, &ta, &tb))
        return 0;
    if (isinf(tb)) {
        double od0 = fp_fog_od(fp, TABLES(t), o[0], o[1], o[2], dir[0], dir[1], dir[2], ta, 0);
        double all = fp_fog_od(fp, TABLES(t), o[0], o[1], o[2], dir[0], dir[1], dir[2],
                               INFINITY, 0);
        double step = 1;
        for (; step < 1e7; step *= 2) {
            double od = fp_fog_od(fp, TABLES(t), o[0], o[1], o[2], dir[0], dir[1], dir[2],
                                  ta + step, 0);
            if (od - od0 > 25 || (isfinite(all) && all - od <= 1e-9 * all))
                break;
        }
        tb = ta + step;
    }
    double dt = (tb - ta) / n, s = 0, prev = ta + 0.5 * dt;
    double u = fp_fog_od(fp, TABLES(t), o[0], o[1], o[2], dir[0], dir[1], dir[2], prev, 0);
    int self = (int)lt[FP_LT_SELF] != FP_SELF_OFF;
    for (long i = 0; i < n; i++) {
        double tm = ta + (i + 0.5) * dt;
        double p[3] = { o[0] + tm * dir[0], o[1] + tm * dir[1], o[2] + tm * dir[2] };
        if (i > 0)
            u += fp_fog_od(fp, TABLES(t), o[0] + prev * dir[0], o[1] + prev * dir[1],
                           o[2] + prev * dir[2], dir[0], dir[1], dir[2], tm - prev, 0);
        prev = tm;
        double v = vis ? vis(ctx, p) : fp_shadow_map(lt, smap, p[0], p[1], p[2]);
        if (v == 0)
            continue;
        double sig = fp_sigma_t(fp, FP_TABLES3(fp_fog_tables_or_empty(t)), p[0], p[1], p[2]);
        double ts = self ? exp(-fp_fog_od(fp, TABLES(t), p[0], p[1], p[2], l[0], l[1], l[2],
                                          INFINITY, 0))
                         : 1;
        s += sig * exp(-u) * v * ts * dt;
    }
    return s;
}

static size_t grid_nodes(const double *lt)
{
    return (size_t)lt[FP_LT_GRID_K] * (size_t)lt[FP_LT_GRID_N] * (size_t)lt[FP_LT_GRID_N + 1] *
           (size_t)lt[FP_LT_GRID_N + 2];
}

/* The self-shadow grid on the CPU, column by column (fp_sun_od_column). */
static int fill_grid(fp_scatter_data_t *d, const fp_integrate_data_t *fog)
{
    const double *lt = d->lt;
    size_t n = grid_nodes(lt);
    if (d->grid_n != n) {
        free(d->grid);
        d->grid = malloc(n * sizeof *d->grid);
        d->grid_n = d->grid ? n : 0;
        if (!d->grid)
            return fp_error("self-shadow grid: out of memory");
    }
    const fp_fog_tables_t *t = fog->tables;
    int na = (int)lt[FP_LT_GRID_N], nb = (int)lt[FP_LT_GRID_N + 1], K = (int)lt[FP_LT_GRID_K];
    for (int c = 0; c < K; c++)
        for (int j = 0; j < nb; j++)
            for (int i = 0; i < na; i++)
                fp_sun_od_column(fog->fp, TABLES(t), lt, d->grid, c, i, j);
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

/* The self-shadow grid, when d uses one, filled for d and fog (the grid is
 * a cache of d). */
static int ensure_grid(const fp_scatter_data_t *d, const fp_integrate_data_t *fog)
{
    fp_scatter_data_t *dw = (fp_scatter_data_t *)d;
    if (uses_grid(d) && !grid_current(&dw->grid_key, d, fog) && fill_grid(dw, fog)) {
        dw->grid_key.valid = 0;
        return FP_ERR;
    }
    return FP_OK;
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
    if (ensure_grid(d, fog))
        return FP_ERR;
    float view[FP_VIEW_FLOATS];
    fp_view_pack(v, view);
    for (size_t k = 0; k < npix; k++) {
        size_t i = pix ? (size_t)pix[k] : k;
        int x = (int)(i % (size_t)v->width), y = (int)(i / (size_t)v->width);
        double dir[3], len, S[3], o[3];
        fp_view_ray(v, x, y, depth[i], dir, &len);
        fp_view_origin_at(v, x, y, o);
        double tau = ray_at(d, d->lt, fog, v, view, depth, o, dir, len,
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
        fp_cl_kernel(prog, "scatter_lights", &s->light_kernel) ||
        fp_cl_kernel(prog, "lamp_shadows", &s->ls_kernel))
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
    /* The lights' table: a global buffer of any size (at least one row). */
    size_t nf = (size_t)(d->nlights > 0 ? d->nlights : 1) * FP_LL_STRIDE;
    float *lf = calloc(nf, sizeof *lf);
    if (!lf)
        return fp_error("scatter: out of memory");
    for (size_t i = 0; d->lights && i < (size_t)d->nlights * FP_LL_STRIDE; i++)
        lf[i] = (float)d->lights[i];
    cl_int err = CL_SUCCESS;
    if (!s->lights || s->lights_n != nf) {
        if (s->lights)
            clReleaseMemObject(s->lights);
        s->lights = clCreateBuffer(ctx, CL_MEM_READ_ONLY, nf * sizeof(float), NULL, &err);
        s->lights_n = err == CL_SUCCESS ? nf : 0;
    }
    if (err == CL_SUCCESS)
        err = clEnqueueWriteBuffer(q, s->lights, CL_TRUE, 0, nf * sizeof(float), lf, 0, NULL, NULL);
    free(lf);
    if (fp_cl_check(err, "scatter: upload the lights"))
        return FP_ERR;
    if (s->smap && s->uploaded == d->serial)
        return FP_OK;
    if (s->smap)
        clReleaseMemObject(s->smap);
    size_t ns = d->smap ? d->smap_n : 1;
    s->smap = clCreateBuffer(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, ns * sizeof(float),
                             (void *)(d->smap ? d->smap : no_map), &err);
    if (fp_cl_check(err, "scatter: shadow map"))
        return FP_ERR;
    size_t ng = uses_grid(d) ? grid_nodes(d->lt) : 1;
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
                             (size_t)d->lt[FP_LT_GRID_K] };
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
        FP_CL_ARG(k, 15, s->lights) ||
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
        FP_CL_ARG(lk, 9, s->lights) ||
        fp_cl_check(clEnqueueNDRangeKernel(q, lk, 2, NULL, global, NULL, 0, NULL, NULL),
                    "scatter_lights") ||
        fp_lamp_shadow_cl(s, ic, d, v, pix, npix))
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
    if (s->ls_kernel)
        clReleaseKernel(s->ls_kernel);
    cl_mem *mems[] = { &s->lt, &s->smap, &s->grid, &s->lights };
    for (size_t i = 0; i < FP_ARRAY_LEN(mems); i++)
        if (*mems[i])
            clReleaseMemObject(*mems[i]);
    memset(s, 0, sizeof *s);
}
