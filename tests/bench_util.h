/* fogpipe benchmarks: what the bench programs share (bench_light,
 * bench_looks, bench_selfshadow, bench_fogmap, bench_lod).  Header-only; include after the
 * fogpipe headers (camera.h, exrio.h, fogmap.h, integrate.h, options_all.h,
 * scatter.h). */
#ifndef FP_BENCH_UTIL_H
#define FP_BENCH_UTIL_H

#include <sys/resource.h>

/* CPU seconds of this process so far (user + sys, every thread). */
static inline double cpu_s(void)
{
    struct rusage r;
    getrusage(RUSAGE_SELF, &r);
    return r.ru_utime.tv_sec + r.ru_utime.tv_usec * 1e-6 + r.ru_stime.tv_sec +
           r.ru_stime.tv_usec * 1e-6;
}

/* Frame 1 of the EXR at path and the view its camera gives under p's
 * options: what every bench reads its frames with. */
static inline int bench_frame_view(const char *path, fp_params_t *p, fp_frame_t **frame,
                                   fp_view_t *view)
{
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    fp_camera_t cam;
    if (fp_exr_read_file(path, 1, &sel, frame))
        return FP_ERR;
    const fp_frame_info_t *info = fp_frame_info(*frame);
    if (fp_camera_resolve(p, info, path, 1, &cam) || fp_view_setup(&cam, p, info, view))
        return FP_ERR;
    return FP_OK;
}

/* A look: the options and the stages they commit. */
typedef struct look_t {
    fp_params_t p;
    fp_integrate_data_t fog;
    fp_fogmap_stage_t fm;
    fp_scatter_data_t light;
} look_t;

/* Commit l->p (already filled) for frame 1 seen through view with its
 * depth: the integrate and scatter stages, the fogmap (on cl when given). */
static inline int look_commit(look_t *l, fp_cl_t *cl, const fp_view_t *view, const float *depth)
{
    int active;
    if (fp_integrate_commit(&l->p, &l->fog) || fp_scatter_commit(&l->p, &l->light) ||
        fp_fogmap_commit(&l->p, cl, &l->fm, &l->fog, &active) ||
        fp_fogmap_frame(&l->p, cl, &l->fm, 1, view, &l->fog) ||
        fp_scatter_frame(&l->p, &l->light, &l->fog, view, depth, 1))
        return FP_ERR;
    return FP_OK;
}

static inline void look_release(look_t *l)
{
    fp_scatter_release(&l->light);
    fp_fogmap_release(&l->fm);
    fp_options_free(&l->p);
}

#endif
