/* The scatter stage's lights: --light's parsing, the checks every light
 * passes (from --light or a frame's rig), and the table the kernels read
 * (kernels/light_core.h FP_LL_*). */
#include "scatter_internal.h"
#include "fp.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"

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
