/* The scatter stage per frame: the sun's shadow map, the depth buffer the
 * screen-space walk reads, the self-shadow grid's cascades. */
#include "scatter.h"
#include "options.h"
#include "exrio.h"
#include "fp.h"
#include "ms.h"
#include "seq.h"
#include "shadowcheck.h"
#include "shafts.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/scatter_core.h"

/* Decode the shadow map file read into buf (taken) and pack it into d. */
static int pack_shadow_map(const fp_params_t *p, fp_scatter_data_t *d, long frame,
                           const char *path, void *buf, size_t size)
{
    int rc;
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
    /* The same depths as the map packed last, seen by the same sun camera,
     * under the same sun, bias and up axis (a still sun over a still
     * scene: every frame's map alike, whatever else its header says): the
     * packed map kept as it is, checked and uploaded once; not under -v,
     * where every frame's map is checked and reported. */
    double key[25];
    memcpy(key, d->lt + FP_LT_SM_NDC, 20 * sizeof *key);
    key[20] = l[0];
    key[21] = l[1];
    key[22] = l[2];
    key[23] = p->light.shadow_bias;
    key[24] = info->width + 65536.0 * info->height + 4294967296.0 * p->camera.up;
    if (d->smap && d->smap_z && fp_verbose <= 0 && !memcmp(key, d->smap_key, sizeof key) &&
        !memcmp(z, d->smap_z, n * sizeof *z)) {
        fp_frame_free(f);
        free(z);
        return FP_OK;
    }
    /* Casters and gaps too thin for the map (filters/shadowcheck.h): a
     * depth step of two texels of level ground under this sun. */
    fp_shadowcheck_frame(path, frame, z, info->width, info->height, gx > 0 ? 1 / gx : 0,
                         gy > 0 ? 1 / gy : 0, 2 * texel * fmax(1, slope) + p->light.shadow_bias,
                         d->lt + FP_LT_SM_NDC, d->lt + FP_LT_SM_Z, p->camera.up);
    float *packed = NULL;
    size_t np = 0;
    int levels = 0;
    fp_shafts_plane(d->lt + FP_LT_SM_NDC, d->lt + FP_LT_SM_Z, info->width, info->height,
                    d->lt + FP_LT_SM_GA, d->lt + FP_LT_SM_GB);
    if (fp_shafts_build(z, info->width, info->height, texel * fmax(1, slope),
                        p->light.shadow_bias, d->lt[FP_LT_SM_GA], d->lt[FP_LT_SM_GB], &packed,
                        &np, &levels)) {
        fp_frame_free(f);
        free(z);
        return fp_error("%s: frame %ld: out of memory", path, frame);
    }
    free(d->smap);
    free(d->smap_z);
    d->smap_z = z;
    memcpy(d->smap_key, key, sizeof key);
    d->smap = packed;
    d->smap_n = np;
    d->smap_w = info->width;
    d->smap_h = info->height;
    d->lt[FP_LT_SM_LEVELS] = levels;
    d->smap_serial = 0;
    fp_frame_free(f);
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
    return pack_shadow_map(p, d, frame, path, buf, size);
}

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
    d->smap_serial = 0;
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
        if (!d->smap_serial)
            d->smap_serial = ++serial;
    }
    fp_shadowcheck_wants(p, (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP ||
                                (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP_SCREEN);
    int rc = fp_scatter_screen(d, v, depth, frame);
    if (rc || (rc = fp_ms_frame(p, lt, fog->fp, d->smap)))
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
