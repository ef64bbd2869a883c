#include "integrate.h"
#include "fp.h"
#include "options.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* The reference: fog_core.h in double precision with higher-order
 * quadrature (FP_GL_EXTRA, FP_EXP_STEP defaults for C). */
#include "../kernels/fog_core.h"

_Static_assert(FP_F_COUNT == FP_F_COUNT_, "fog parameter count");
_Static_assert(FP_MAX_LEVELS_ALL == FP_LEVEL_TABLE, "level table size");
_Static_assert(FP_LI_STRIDE == 8 && FP_LR_STRIDE == 8, "level table strides");

static int set_visibility(fp_params_t *p, const fp_option_t *o, const char *value)
{
    char *end;
    double d = strtod(value, &end);
    if (end == value || *end || !(d > 0) || isinf(d))
        return fp_usage_error("--%s: expected a distance > 0 in scene units, got '%s'", o->name,
                              value);
    /* Visibility: the distance at which 90% of light is lost. */
    *(double *)((char *)p + o->offset) = log(10.0) / d;
    return FP_OK;
}

#define FOG(f) offsetof(fp_params_t, fog.f)
/* --fog-color R,G,B | auto (auto: derived per frame, filters/ms.c fp_ms_frame;
 * without a sun the look's old constant stays). */
static int set_fog_color(fp_params_t *p, const fp_option_t *o, const char *value)
{
    static const double def[3] = { 0.7, 0.75, 0.8 };
    if (value && strcmp(value, "auto") == 0) {
        /* Derived per frame (fp_ms_frame); without a sun this look's old
         * constant stays. */
        memcpy(p->fog.color, def, sizeof def);
        p->ms.color_typed = 0;
        return FP_OK;
    }
    double v[3];
    const char *s = value ? value : "";
    char *end;
    for (int i = 0; i < 3; i++) {
        v[i] = strtod(s, &end);
        if (end == s || !(v[i] >= o->min && v[i] <= o->max) ||
            (i < 2 ? *end != ',' : *end != 0))
            return fp_usage_error("--%s: expected R,G,B (three reals in [0, %g]) or auto, "
                                  "got '%s'", o->name, o->max, s == value ? value : value);
        s = end + 1;
    }
    memcpy(p->fog.color, v, sizeof v);
    p->ms.color_typed = 1;
    return FP_OK;
}

const fp_option_t fp_integrate_options[] = {
    { "density", 0, FP_OPT_REAL, FOG(density), 0, 0, "0.02", 0, 1e6, NULL, "SIGMA",
      "extinction per scene unit at the base of the fog (times the fogmap's value with "
      "--fogmap)", NULL, 0 },
    { "visibility", 0, FP_OPT_REAL, FOG(density), 0, 0, NULL, 0, INFINITY, NULL, "D",
      "set the density by visibility: 90% of light lost over D scene units "
      "(sigma = ln(10)/D)", set_visibility, 0 },
    { "height", 0, FP_OPT_VEC, FOG(height), 3, 2, "0,20,inf", -1e9, INFINITY, NULL, "Y0,H[,TOP]",
      "height profile: full density below Y0, exp(-(y-Y0)/H) above it, none above TOP "
      "(H = inf: homogeneous)", NULL, 0 },
    { "haze", 0, FP_OPT_REAL, FOG(haze), 0, 0, "0", 0, 1e6, NULL, "SIGMA",
      "homogeneous haze added to the fog, extinction per scene unit", NULL, 0 },
    { "haze-visibility", 0, FP_OPT_REAL, FOG(haze), 0, 0, NULL, 0, INFINITY, NULL, "D",
      "set the haze by visibility (sigma = ln(10)/D)", set_visibility, 0 },
    { "haze-height", 0, FP_OPT_VEC, FOG(haze_height), 3, 2, "0,inf,inf", -1e9, INFINITY, NULL,
      "Y0,H[,TOP]", "height profile of the haze, as --height", NULL, 0 },
    { "fog-color", 0, FP_OPT_VEC, FOG(color), 3, 3, "auto", 0, 1e6, NULL, "R,G,B|auto",
      "fog color: in-scattered ambient radiance, scene-linear, in the working space "
      "(--working-space); auto: derived from the sun and the fog (0 with "
      "--multiple-scattering on, which then carries that light; the column's mean "
      "multiply scattered light with it off; 0.7,0.75,0.8 without a sun)",
      set_fog_color, 0 },
    { "fog-box", 0, FP_OPT_VEC, FOG(box), 6, 6, "-inf,-inf,-inf,inf,inf,inf", -INFINITY,
      INFINITY, NULL, "X0,Y0,Z0,X1,Y1,Z1",
      "no fog outside this box: world axes, in the fog's own frame (it moves and turns with "
      "--fog-offset and --fog-rotate)",
      NULL, 0 },
    { "fog-offset", 0, FP_OPT_VEC, FOG(offset), 3, 3, "0,0,0", -1e9, 1e9, NULL, "X,Y,Z",
      "move the fog (fogmap, height profile and box) in the world", NULL, 0 },
    { "sky", 0, FP_OPT_ENUM, FOG(sky), 0, 0, "fog", 0, 0, "fog|keep", "fog|keep",
      "pixels with no geometry (sky depth): fog to the end of the fog, meeting the horizon "
      "without a seam (fog), or left exactly as they are (keep)", NULL, 0 },
    { "fog-rotate", 0, FP_OPT_REAL, FOG(rotate), 0, 0, "0", -36000, 36000, NULL, "DEG",
      "turn the fog about the vertical axis through --fog-offset, degrees", NULL, 0 },
    FP_OPT_END
};

static void check_profile(const char *name, const double *h, int *rc)
{
    if (*rc)
        return;
    if (!(h[1] > 0))
        *rc = fp_usage_error("--%s: the scale height H must be > 0 (got %g)", name, h[1]);
    else if (!(h[2] > h[0]))
        *rc = fp_usage_error("--%s: TOP (%g) must be above Y0 (%g)", name, h[2], h[0]);
}

void fp_integrate_fog_offset(const fp_params_t *p, double off[3])
{
    fp_world_to_fog(p->camera.up, p->fog.offset, off);
}

int fp_integrate_commit(const fp_params_t *p, fp_integrate_data_t *d)
{
    memset(d, 0, sizeof *d);
    const fp_fog_params_t *f = &p->fog;
    int rc = FP_OK;
    check_profile("height", f->height, &rc);
    check_profile("haze-height", f->haze_height, &rc);
    for (int i = 0; i < 3 && rc == FP_OK; i++)
        if (!(f->box[i + 3] > f->box[i]))
            rc = fp_usage_error("--fog-box: expected X0,Y0,Z0 below X1,Y1,Z1");
    if (rc)
        return rc;
    double *v = d->fp;
    v[FP_F_SIGMA] = f->density;
    v[FP_F_Y0] = f->height[0];
    v[FP_F_H] = f->height[1];
    v[FP_F_TOP] = f->height[2];
    fp_integrate_fog_offset(p, v + FP_F_OFF);
    /* The fog turns by +angle: world -> fog-local turns by -angle. */
    v[FP_F_COS] = cos(f->rotate * M_PI / 180);
    v[FP_F_SIN] = sin(f->rotate * M_PI / 180);
    /* The box is given on the world's axes: turn its corners into fog
     * space (with --up z the axes swap and one flips). */
    double lo[3], hi[3];
    fp_world_to_fog(p->camera.up, f->box, lo);
    fp_world_to_fog(p->camera.up, f->box + 3, hi);
    for (int i = 0; i < 3; i++) {
        v[FP_F_BOX + i] = fmin(lo[i], hi[i]);
        v[FP_F_BOX + 3 + i] = fmax(lo[i], hi[i]);
    }
    v[FP_F_HAZE] = f->haze;
    for (int i = 0; i < 3; i++)
        v[FP_F_HAZE + 1 + i] = f->haze_height[i];
    v[FP_F_OD_MAX] = INFINITY;
    v[FP_F_CAP] = INFINITY;
    v[FP_F_STEPS] = 1;
    memcpy(d->fog_color, f->color, sizeof d->fog_color);
    return FP_OK;
}

/* An empty table set for fog without a fogmap (the kernel still takes
 * buffers). */
static const int no_lvi[FP_LEVEL_TABLE * 8];
static const float no_coef[1];
static const unsigned char no_occ[1];
static const fp_fog_tables_t no_tables = { .coef = (float *)no_coef, .ncoef = 1,
                                           .occ = (unsigned char *)no_occ, .nocc = 1 };

const fp_fog_tables_t *fp_fog_tables_or_empty(const fp_fog_tables_t *t)
{
    return t ? t : &no_tables;
}

double fp_integrate_optical_depth(const fp_integrate_data_t *d, const double o[3],
                                  const double dir[3], double len, double jitter)
{
    const fp_fog_tables_t *t = fp_fog_tables_or_empty(d->tables);
    return fp_fog_od(d->fp, FP_TABLES(t), o[0], o[1], o[2], dir[0], dir[1], dir[2], len, jitter);
}

float fp_integrate_jitter(int x, int y)
{
    /* Must match pixel_jitter() in kernels/integrate.cl. */
    unsigned h = (unsigned)x * 73856093u ^ (unsigned)y * 19349663u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return (float)(h & 0xffffffu) / 16777216.0f - 0.5f;
}

int fp_integrate_process(const fp_integrate_data_t *d, const fp_view_t *v,
                         const float *depth, float *fog, long *suspicious)
{
    if (suspicious) {
        long bad = 0;
        size_t n = (size_t)v->width * v->height;
        for (size_t i = 0; i < n; i++) {
            int s;
            fp_view_is_sky(v, depth[i], &s);
            bad += s;
        }
        *suspicious = bad;
    }
    return fp_integrate_pixels(d, v, depth, NULL, (size_t)v->width * v->height, fog);
}

int fp_integrate_pixels(const fp_integrate_data_t *d, const fp_view_t *v, const float *depth,
                        const int *pix, size_t npix, float *fog)
{
    int jitter = d->fp[FP_F_JITTER] != 0;
    for (size_t k = 0; k < npix; k++) {
        size_t i = pix ? (size_t)pix[k] : k;
        int x = (int)(i % (size_t)v->width), y = (int)(i / (size_t)v->width);
        double dir[3], len, o[3];
        fp_view_ray(v, x, y, depth[i], dir, &len);
        fp_view_origin_at(v, x, y, o);
        double od = fp_integrate_optical_depth(d, o, dir, len,
                                               jitter ? fp_integrate_jitter(x, y) : 0);
        double tau = exp(-od);
        for (int c = 0; c < 3; c++)
            fog[4 * k + c] = (float)((1 - tau) * d->fog_color[c]);
        fog[4 * k + 3] = (float)tau;
    }
    return FP_OK;
}

int fp_integrate_cl_init(fp_cl_t *cl, fp_integrate_cl_t *s)
{
    memset(s, 0, sizeof *s);
    s->cl = cl;
    cl_program prog;
    if (fp_cl_program(cl, "integrate", "-cl-std=CL1.2", &prog) ||
        fp_cl_kernel(prog, "integrate_fog", &s->kernel) ||
        fp_cl_kernel(prog, "integrate_height", &s->height) ||
        fp_cl_kernel(prog, "integrate_height_list", &s->height_list) ||
        fp_cl_kernel(prog, "integrate_height_over", &s->height_over) ||
        fp_cl_kernel(prog, "integrate_fogmap", &s->fogmap) ||
        fp_cl_kernel(prog, "integrate_fogmap_list", &s->fogmap_list))
        return FP_ERR;
    cl_int err;
    cl_context ctx = fp_cl_context(cl);
    s->view = clCreateBuffer(ctx, CL_MEM_READ_ONLY, FP_VIEW_FLOATS * sizeof(float), NULL, &err);
    if (fp_cl_check(err, "integrate: view buffer"))
        return FP_ERR;
    s->params = clCreateBuffer(ctx, CL_MEM_READ_ONLY, FP_F_COUNT * sizeof(float), NULL, &err);
    if (fp_cl_check(err, "integrate: parameter buffer"))
        return FP_ERR;
    s->lvi = clCreateBuffer(ctx, CL_MEM_READ_ONLY, sizeof no_lvi, NULL, &err);
    if (fp_cl_check(err, "integrate: level buffer"))
        return FP_ERR;
    s->lvf = clCreateBuffer(ctx, CL_MEM_READ_ONLY, FP_LEVEL_TABLE * FP_LR_STRIDE * sizeof(float),
                            NULL, &err);
    if (fp_cl_check(err, "integrate: level buffer"))
        return FP_ERR;
    /* A device in the host's memory (PoCL's CPU device) can write a whole
     * frame's fog layer where the caller wants it (run_read_layer). */
    cl_bool unified = CL_FALSE;
    cl_uint align_bits = 0;
    if (clGetDeviceInfo(fp_cl_device(cl), CL_DEVICE_HOST_UNIFIED_MEMORY, sizeof unified, &unified,
                        NULL) == CL_SUCCESS &&
        clGetDeviceInfo(fp_cl_device(cl), CL_DEVICE_MEM_BASE_ADDR_ALIGN, sizeof align_bits,
                        &align_bits, NULL) == CL_SUCCESS &&
        unified)
        s->host_align = align_bits >= 8 ? align_bits / 8 : 1;
    return FP_OK;
}

/* Run kernel k (its argument 1 the fog layer) and read nout pixels of
 * the layer into `fog`.  With in_place, where the device works in the
 * host's memory and `fog` is aligned as it wants, the kernel writes into
 * `fog` itself (a
 * buffer on it, CL_MEM_USE_HOST_PTR, mapped to read): no copy of the
 * layer (33 MB a 1080p frame, ~2.5 ns per pixel on PoCL); otherwise into
 * the device's buffer (s->fog, which later kernels may go on with), read
 * back. */
static int run_read_layer(fp_integrate_cl_t *s, cl_kernel k, cl_uint dims, const size_t *global,
                          const size_t *local, size_t nout, float *fog, int in_place,
                          const char *what)
{
    cl_command_queue q = fp_cl_queue(s->cl);
    size_t bytes = nout * 4 * sizeof(float);
    if (in_place && s->host_align && (uintptr_t)fog % s->host_align == 0) {
        /* in_place 2: the kernel also reads what `fog` holds. */
        cl_int err;
        cl_mem out = clCreateBuffer(fp_cl_context(s->cl),
                                    (in_place == 2 ? CL_MEM_READ_WRITE : CL_MEM_WRITE_ONLY) |
                                        CL_MEM_USE_HOST_PTR,
                                    bytes, fog, &err);
        if (fp_cl_check(err, "integrate: fog layer in host memory"))
            return FP_ERR;
        int rc = FP_CL_ARG(k, 1, out) ||
                 fp_cl_check(clEnqueueNDRangeKernel(q, k, dims, NULL, global, local, 0, NULL, NULL),
                             what);
        if (rc == FP_OK) {
            void *m = clEnqueueMapBuffer(q, out, CL_TRUE, CL_MAP_READ, 0, bytes, 0, NULL, NULL,
                                         &err);
            rc = fp_cl_check(err, "map the fog layer");
            if (rc == FP_OK && m != fog) {
                /* Mapped elsewhere: the implementation kept its own copy. */
                memcpy(fog, m, bytes);
            }
            if (rc == FP_OK)
                rc = fp_cl_check(clEnqueueUnmapMemObject(q, out, m, 0, NULL, NULL),
                                 "unmap the fog layer") ||
                     fp_cl_check(clFinish(q), "unmap the fog layer");
        }
        clReleaseMemObject(out);
        return rc ? FP_ERR : FP_OK;
    }
    if (FP_CL_ARG(k, 1, s->fog) ||
        fp_cl_check(clEnqueueNDRangeKernel(q, k, dims, NULL, global, local, 0, NULL, NULL), what))
        return FP_ERR;
    return fp_cl_check(clEnqueueReadBuffer(q, s->fog, CL_TRUE, 0, bytes, fog, 0, NULL, NULL),
                       "read the fog layer");
}

static int ensure_capacity(fp_integrate_cl_t *s, size_t n)
{
    if (n <= s->capacity)
        return FP_OK;
    if (s->depth)
        clReleaseMemObject(s->depth);
    if (s->fog)
        clReleaseMemObject(s->fog);
    s->depth = s->fog = NULL;
    s->capacity = 0;
    cl_int err;
    s->depth = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY, n * sizeof(float), NULL, &err);
    if (fp_cl_check(err, "integrate: depth buffer"))
        return FP_ERR;
    s->fog = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_WRITE_ONLY, n * 4 * sizeof(float), NULL,
                            &err);
    if (fp_cl_check(err, "integrate: fog buffer"))
        return FP_ERR;
    s->capacity = n;
    return FP_OK;
}

void *fp_fog_tables_alloc(size_t n)
{
    void *m = NULL;
    return posix_memalign(&m, 4096, n ? n : 1) == 0 ? m : NULL;
}

/* A read-only device buffer of the n bytes at host: the host's memory
 * itself where the device works in it and host is aligned as it wants
 * (no second copy of a big fogmap's tables: 200 MB for a 4096 map), else
 * the device's copy. */
static cl_mem table_buffer(fp_integrate_cl_t *s, const void *host, size_t n, cl_int *err)
{
    cl_mem_flags how = s->host_align && (uintptr_t)host % s->host_align == 0
                           ? CL_MEM_USE_HOST_PTR : CL_MEM_COPY_HOST_PTR;
    return clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY | how, n, (void *)host, err);
}

/* The fogmap tables go to the device once, not per frame.  On a device in
 * the host's memory the buffers are the tables themselves: the fogmap
 * stage keeps them until these buffers are released (the tables of the
 * frame before stay while a new set is uploaded, filters/fogmap.c; the run
 * releases the device before the fogmap stage, lib/pipeline.c). */
static int upload_tables(fp_integrate_cl_t *s, const fp_fog_tables_t *t)
{
    unsigned long serial = t ? t->serial : 0;
    if (s->coef && s->uploaded == serial)
        return FP_OK;
    cl_command_queue q = fp_cl_queue(s->cl);
    if (s->coef)
        clReleaseMemObject(s->coef);
    if (s->occ)
        clReleaseMemObject(s->occ);
    s->coef = s->occ = NULL;
    cl_int err;
    const void *coef = t ? (const void *)t->coef : no_coef;
    size_t ncoef = t ? t->ncoef : 1, nocc = t ? t->nocc : 1;
    const void *occ = t ? (const void *)t->occ : no_occ;
    s->coef = table_buffer(s, coef, ncoef * sizeof(float), &err);
    if (fp_cl_check(err, "integrate: fogmap coefficients"))
        return FP_ERR;
    s->occ = table_buffer(s, occ, nocc, &err);
    if (fp_cl_check(err, "integrate: fogmap occupancy"))
        return FP_ERR;
    float lvf[FP_LEVEL_TABLE * FP_LR_STRIDE];
    for (int i = 0; i < FP_LEVEL_TABLE * FP_LR_STRIDE; i++)
        lvf[i] = (float)(t ? t->lvf[i] : 0);
    if (fp_cl_check(clEnqueueWriteBuffer(q, s->lvi, CL_TRUE, 0, sizeof no_lvi, t ? t->lvi : no_lvi,
                                         0, NULL, NULL), "integrate: upload level table") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->lvf, CL_TRUE, 0, sizeof lvf, lvf, 0, NULL, NULL),
                    "integrate: upload level table"))
        return FP_ERR;
    s->uploaded = serial;
    return FP_OK;
}

int fp_integrate_cl_prepare(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                            const fp_view_t *v, const float *depth)
{
    size_t n = (size_t)v->width * v->height;
    if (ensure_capacity(s, n) || upload_tables(s, d->tables))
        return FP_ERR;
    cl_command_queue q = fp_cl_queue(s->cl);
    float view[FP_VIEW_FLOATS], params[FP_F_COUNT];
    fp_view_pack(v, view);
    for (int i = 0; i < FP_F_COUNT; i++)
        params[i] = (float)d->fp[i];
    /* Blocking: view and params live on this function's stack. */
    if (fp_cl_check(clEnqueueWriteBuffer(q, s->view, CL_TRUE, 0, sizeof view, view, 0, NULL, NULL),
                    "integrate: upload view") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->params, CL_TRUE, 0, sizeof params, params, 0, NULL,
                                         NULL), "integrate: upload parameters"))
        return FP_ERR;
    /* The caller's depth outlives the blocking read that ends the frame. */
    return depth ? fp_cl_check(clEnqueueWriteBuffer(q, s->depth, CL_FALSE, 0, n * sizeof(float),
                                                    depth, 0, NULL, NULL), "integrate: upload depth")
                 : FP_OK;
}

int fp_integrate_process_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                            const fp_view_t *v, const float *depth, float *fog)
{
    return fp_integrate_pixels_cl(s, d, v, depth, NULL, 0, fog);
}

static int upload_pixels(fp_integrate_cl_t *s, const int *pix, size_t npix);

/* Fog without a fogmap: integrate_height(_list), 16 pixels per work-item
 * (kernels/integrate.cl), with the arguments of integrate_fog: set them
 * (the layer s->fog), *k the kernel (NULL when the list is empty: nothing
 * to run), global its work size.  lanes_k: a linear fogmap's exact walk
 * (integrate_fogmap(_list)) on the same arguments, or NULL. */
static int height_args(fp_integrate_cl_t *s, const fp_view_t *v, const int *pix, size_t npix,
                       cl_float4 color, int over, cl_mem depth, cl_kernel lanes_k,
                       cl_kernel *k, size_t *global)
{
    const size_t lanes = 16;   /* FP_SIMD in kernels/fog_core.h */
    cl_int w = v->width, h = v->height;
    *k = NULL;
    if (npix > (size_t)w * h)
        return fp_error("integrate_height: %zu pixels listed, the frame has %d", npix, w * h);
    if (pix && npix == 0)
        return FP_OK;
    *k = lanes_k ? lanes_k : over ? s->height_over : npix ? s->height_list : s->height;
    cl_int cnpix = (cl_int)npix;
    if (upload_pixels(s, pix, npix) || FP_CL_ARG(*k, 0, depth) || FP_CL_ARG(*k, 1, s->fog) ||
        FP_CL_ARG(*k, 2, s->view) || FP_CL_ARG(*k, 3, w) || FP_CL_ARG(*k, 4, h) ||
        FP_CL_ARG(*k, 5, s->params) || FP_CL_ARG(*k, 6, s->lvi) || FP_CL_ARG(*k, 7, s->lvf) ||
        FP_CL_ARG(*k, 8, s->coef) || FP_CL_ARG(*k, 9, s->occ) || FP_CL_ARG(*k, 10, s->pix) ||
        FP_CL_ARG(*k, 11, cnpix) || FP_CL_ARG(*k, 12, color))
        return FP_ERR;
    global[0] = npix ? (npix + lanes - 1) / lanes : ((size_t)w + lanes - 1) / lanes;
    global[1] = npix ? 1 : (size_t)h;
    return FP_OK;
}

static int launch_height(fp_integrate_cl_t *s, const fp_view_t *v, const int *pix, size_t npix,
                         cl_float4 color, float *fog, int over, cl_mem depth, cl_kernel lanes_k)
{
    if (!pix)
        npix = 0;
    cl_kernel k;
    size_t global[2];
    if (height_args(s, v, pix, npix, color, over, depth, lanes_k, &k, global) || !k)
        return k ? FP_ERR : FP_OK;
    return run_read_layer(s, k, npix ? 1 : 2, global, NULL,
                          npix ? npix : (size_t)v->width * v->height, fog, over ? 2 : 1,
                          lanes_k ? (npix ? "integrate_fogmap_list" : "integrate_fogmap")
                                  : over ? "integrate_height_over" : "integrate_height");
}

int fp_integrate_lanes_ok(const fp_integrate_data_t *d, const fp_view_t *v)
{
    const double *f = d->fp;
    int nl = (int)f[FP_F_NLEVELS];
    return f[FP_F_HAS_MAP] != 0 && d->tables && d->tables->lvi[FP_LI_APPROX] >= 0 &&
           (int)f[FP_F_MODE] == 0 && (int)f[FP_F_DEGREE] == 1 && (int)f[FP_F_WRAP] != 1 &&
           !(f[FP_F_LOD_BOUND] > 0) && !(f[FP_F_FOOTPRINT] > 0) &&
           (nl < 2 || f[FP_F_LOD_MU] >= 1) && isinf(f[FP_F_OD_MAX]) && !v->ortho;
}

int fp_integrate_height_layer_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                                 const fp_view_t *v, const int *pix, size_t npix,
                                 const double color[3])
{
    if (d->fp[FP_F_HAS_MAP] != 0 || v->ortho || v->clip > 0)
        return fp_error("integrate_height: a fogmap, an orthographic view or a clip plane");
    if (!pix)
        npix = 0;
    cl_float4 c = { { (float)color[0], (float)color[1], (float)color[2], 0 } };
    cl_kernel k;
    size_t global[2];
    if (height_args(s, v, pix, npix, c, 0, s->depth, NULL, &k, global) || !k)
        return k ? FP_ERR : FP_OK;
    return fp_cl_check(clEnqueueNDRangeKernel(fp_cl_queue(s->cl), k, npix ? 1 : 2, NULL, global,
                                              NULL, 0, NULL, NULL),
                       "integrate_height");
}

int fp_integrate_pixels_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                           const fp_view_t *v, const float *depth, const int *pix, size_t npix,
                           float *fog)
{
    if (fp_integrate_cl_prepare(s, d, v, depth))
        return FP_ERR;
    cl_float4 color = { { (float)d->fog_color[0], (float)d->fog_color[1],
                          (float)d->fog_color[2], 0 } };
    if (FP_CL_ARG(s->kernel, 12, color))
        return FP_ERR;
    /* integrate_height's lanes start every ray at the camera: an
     * orthographic camera's rays start on its plane, and rays from a clip
     * plane each at their own point: they go through integrate_fog
     * (fp_view_origin_at). */
    if (d->fp[FP_F_HAS_MAP] == 0 && !v->ortho && !(v->clip > 0))
        return launch_height(s, v, pix, npix, color, fog, 0, s->depth, NULL);
    if (!s->no_lanes && fp_integrate_lanes_ok(d, v))
        return launch_height(s, v, pix, npix, color, fog, 0, s->depth,
                             pix && npix ? s->fogmap_list : s->fogmap);
    return fp_integrate_cl_launch(s, s->kernel, v, pix, npix, fog, "integrate_fog");
}

int fp_integrate_over_ok(const fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                         const fp_view_t *v, const float *rgba)
{
    return s->host_align && s->height_over && (uintptr_t)rgba % s->host_align == 0 &&
           d->fp[FP_F_HAS_MAP] == 0 && !v->ortho && !(v->clip > 0);
}

int fp_integrate_over_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d, const fp_view_t *v,
                         const float *depth, float *rgba)
{
    if (!fp_integrate_over_ok(s, d, v, rgba))
        return fp_error("integrate_height_over: the device cannot work in this frame's memory");
    /* The depth read where it is too when it is aligned (no 8 MB copy a
     * 1080p frame), else uploaded. */
    size_t n = (size_t)v->width * v->height;
    int host_depth = (uintptr_t)depth % s->host_align == 0;
    if (fp_integrate_cl_prepare(s, d, v, host_depth ? NULL : depth))
        return FP_ERR;
    cl_mem dbuf = s->depth;
    if (host_depth) {
        cl_int err;
        dbuf = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                              n * sizeof(float), (void *)depth, &err);
        if (fp_cl_check(err, "integrate: depth in host memory"))
            return FP_ERR;
    }
    cl_float4 color = { { (float)d->fog_color[0], (float)d->fog_color[1],
                          (float)d->fog_color[2], 0 } };
    int rc = launch_height(s, v, NULL, 0, color, rgba, 1, dbuf, NULL);
    if (host_depth)
        clReleaseMemObject(dbuf);
    return rc;
}

/* The pixel list on the device (a one-entry buffer when there is none:
 * the kernel argument is always a buffer). */
static int upload_pixels(fp_integrate_cl_t *s, const int *pix, size_t npix)
{
    size_t need = pix && npix ? npix : 1;
    if (need > s->pix_capacity) {
        if (s->pix)
            clReleaseMemObject(s->pix);
        s->pix = NULL;
        s->pix_capacity = 0;
        cl_int err;
        s->pix = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY, need * sizeof(cl_int),
                                NULL, &err);
        if (fp_cl_check(err, "integrate: pixel list buffer"))
            return FP_ERR;
        s->pix_capacity = need;
    }
    if (!pix || !npix)
        return FP_OK;
    /* Blocking: the caller's list may be gone before the launch ends. */
    return fp_cl_check(clEnqueueWriteBuffer(fp_cl_queue(s->cl), s->pix, CL_TRUE, 0,
                                            npix * sizeof(cl_int), pix, 0, NULL, NULL),
                       "integrate: upload pixel list");
}

int fp_integrate_cl_launch(fp_integrate_cl_t *s, cl_kernel k, const fp_view_t *v, const int *pix,
                           size_t npix, float *fog, const char *what)
{
    cl_int w = v->width, h = v->height;
    if (!pix)
        npix = 0;
    if (npix > (size_t)w * h)
        return fp_error("%s: %zu pixels listed, the frame has %d", what, npix, w * h);
    if (npix == 0 && pix)
        return FP_OK;
    cl_int cnpix = (cl_int)npix;
    if (upload_pixels(s, pix, npix) || FP_CL_ARG(k, 0, s->depth) || FP_CL_ARG(k, 1, s->fog) ||
        FP_CL_ARG(k, 2, s->view) || FP_CL_ARG(k, 3, w) || FP_CL_ARG(k, 4, h) ||
        FP_CL_ARG(k, 5, s->params) || FP_CL_ARG(k, 6, s->lvi) || FP_CL_ARG(k, 7, s->lvf) ||
        FP_CL_ARG(k, 8, s->coef) || FP_CL_ARG(k, 9, s->occ) || FP_CL_ARG(k, 10, s->pix) ||
        FP_CL_ARG(k, 11, cnpix))
        return FP_ERR;
    size_t local[2] = { 16, 8 };
    size_t global[2] = { fp_cl_round_up((size_t)w, local[0]), fp_cl_round_up((size_t)h, local[1]) };
    if (npix) {
        local[0] = 128;
        local[1] = 1;
        global[0] = fp_cl_round_up(npix, local[0]);
        global[1] = 1;
    }
    return run_read_layer(s, k, 2, global, local, npix ? npix : (size_t)w * h, fog, 0, what);
}

void fp_integrate_cl_release(fp_integrate_cl_t *s)
{
    cl_mem *mems[] = { &s->depth, &s->fog, &s->view, &s->params, &s->lvi, &s->lvf, &s->coef,
                       &s->occ, &s->pix };
    cl_kernel kernels[] = { s->kernel,      s->height, s->height_list,
                            s->height_over, s->fogmap, s->fogmap_list };
    for (size_t i = 0; i < FP_ARRAY_LEN(kernels); i++)
        if (kernels[i])
            clReleaseKernel(kernels[i]);
    for (size_t i = 0; i < FP_ARRAY_LEN(mems); i++)
        if (*mems[i])
            clReleaseMemObject(*mems[i]);
    memset(s, 0, sizeof *s);
}
