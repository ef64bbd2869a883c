#include "scatter.h"
#include "options.h"
#include "exrio.h"
#include "fp.h"
#include "options.h"
#include "seq.h"
#include "shadowcheck.h"
#include "shafts.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The reference: the shared ray code in double precision. */
#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/scatter_core.h"
#include "../kernels/lamp_shadow_fix.h"

_Static_assert(FP_LT_COUNT == FP_LT_COUNT_, "light parameter count");
_Static_assert(FP_SCATTER_MAX_STEPS == FP_SCATTER_MAX_STEPS_, "segment limit");
_Static_assert(FP_LL_STRIDE == FP_LL_STRIDE_, "light row");


void fp_scatter_normalize3(double v[3])
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
      fp_scatter_set_light, 0 },
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
        fp_scatter_normalize3(lt + FP_LT_SUN_DIR);
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
    int rc = fp_scatter_pack_lights(p, d);
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

static const float no_map[1] = { INFINITY };
static const double no_lights[FP_LL_STRIDE];

#define TABLES(t) FP_TABLES(fp_fog_tables_or_empty(t))

void fp_scatter_release(fp_scatter_data_t *d)
{
    free(d->smap);
    free(d->smap_z);
    d->smap_z = NULL;
    d->smap_serial = 0;
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

size_t fp_scatter_grid_nodes(const double *lt)
{
    return (size_t)lt[FP_LT_GRID_K] * (size_t)lt[FP_LT_GRID_N] * (size_t)lt[FP_LT_GRID_N + 1] *
           (size_t)lt[FP_LT_GRID_N + 2];
}

/* The self-shadow grid on the CPU, column by column (fp_sun_od_column). */
static int fill_grid(fp_scatter_data_t *d, const fp_integrate_data_t *fog)
{
    const double *lt = d->lt;
    size_t n = fp_scatter_grid_nodes(lt);
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
int fp_scatter_grid_current(fp_grid_key_t *k, const fp_scatter_data_t *d,
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

int fp_scatter_uses_grid(const fp_scatter_data_t *d)
{
    return (int)d->lt[FP_LT_SELF] == FP_SELF_MAP && d->lt[FP_LT_SUN_ON] != 0;
}

/* The self-shadow grid, when d uses one, filled for d and fog (the grid is
 * a cache of d). */
static int ensure_grid(const fp_scatter_data_t *d, const fp_integrate_data_t *fog)
{
    fp_scatter_data_t *dw = (fp_scatter_data_t *)d;
    if (fp_scatter_uses_grid(d) && !fp_scatter_grid_current(&dw->grid_key, d, fog) && fill_grid(dw, fog)) {
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

/* ---- The lights: --light's parsing, the checks every light passes (from
 * --light or a frame's rig), and the table the kernels read
 * (kernels/light_core.h FP_LL_*). */

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
        fp_scatter_normalize3(n);
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
int fp_scatter_set_light(fp_params_t *p, const fp_option_t *o, const char *value)
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

/* The lights' table (kernels/light_core.h FP_LL_*), fog space: local
 * lights first, then the directional ones. */
int fp_scatter_pack_lights(const fp_params_t *p, fp_scatter_data_t *d)
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
                fp_scatter_normalize3(row + FP_LL_POS);
                continue;
            }
            row[FP_LL_TYPE] = li->kind == 1 ? FP_LIGHT_SPOT : li->kind == 2 ? FP_LIGHT_AREA
                                                                            : FP_LIGHT_POINT;
            fp_world_to_fog(p->camera.up, li->pos, row + FP_LL_POS);
            row[FP_LL_RADIUS] = li->kind == 2 ? 0 : li->radius;
            if (li->kind == 0)
                continue;
            fp_world_to_fog(p->camera.up, li->axis, row + FP_LL_AXIS);
            fp_scatter_normalize3(row + FP_LL_AXIS);
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
                fp_scatter_normalize3(U);
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
