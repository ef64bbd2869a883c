/* fogpipe: camera and per-pixel view rays.
 *
 * Camera space is OpenEXR's: left-handed, +x right, +y up in the image, +z
 * the viewing direction.  Header matrices are row-vector (p' = p * M).
 * NDC (0,0) is the top-left and (1,1) the bottom-right corner of the
 * display window, y down.  Fog space is world space turned so that its +y
 * is up: identity for --up y, (x, y, z) -> (x, z, -y) for --up z. */
#ifndef FP_CAMERA_H
#define FP_CAMERA_H

#include <stdio.h>
#include "params.h"
#include "exrio.h"

typedef struct fp_camera_t {
    double origin[3];      /* world position */
    double c2w[9];         /* row-major 3x3: world vector = c2w * camera vector */
    double ndc_to_cam[9];  /* (x/z, y/z, 1) ~ ndc_to_cam * (nx, ny, 1); orthographic:
                              (x, y, 1) ~ ndc_to_cam * (nx, ny, 1) */
    int ortho;             /* orthographic: the ray of NDC (nx, ny) starts at the camera-space
                              point (x, y, 0) and runs along +z */
    char source[512];      /* what it came from, for --print-camera */
} fp_camera_t;

/* The camera for one frame: header attributes, then overrides by options
 * (--camera-pos, --camera-target | --camera-rot, --vfov) or a Nuke .chan
 * file.  Message names file and frame when nothing defines a camera. */
int fp_camera_resolve(const fp_params_t *p, const fp_frame_info_t *info,
                      const char *where_file, long frame, fp_camera_t *out);

/* The camera matrices a frame carries (OpenEXR's row-vector
 * worldToCamera and worldToNDC): its header's, else those of its
 * "fogpipe-camera 1 ..." text.  An error naming the file and frame when
 * it has neither (`what` says what the frame is: "shadow map"). */
int fp_camera_matrices(const fp_frame_info_t *info, const char *where_file, long frame,
                       const char *what, double w2c[16], double w2n[16]);

void fp_camera_print(FILE *out, const fp_camera_t *c, const fp_frame_info_t *info,
                     const char *where_file, long frame);

/* Everything a per-pixel integrator needs, in fog space. */
typedef struct fp_view_t {
    double origin[3];      /* camera position, fog space */
    double m[9];           /* fog vector = m * camera vector */
    double h[9];           /* ndc_to_cam */
    double ndc_scale[2];   /* nx = (x + ndc_offset[0]) * ndc_scale[0], x in data window */
    double ndc_offset[2];
    double far;            /* depth beyond this is sky */
    int depth_kind;        /* FP_DEPTH_* */
    int width, height;     /* data window size */
    int ortho;             /* orthographic: rays start on the camera's plane (fp_view_origin_at) */
    double clip;           /* clip start: the fog begins on the plane at this planar depth
                              (Cycles' camera rays start there; orthographic: along the view
                              axis from the camera's plane); 0: at the camera */
} fp_view_t;

void fp_world_to_fog(int up, const double w[3], double f[3]);

int fp_view_setup(const fp_camera_t *c, const fp_params_t *p,
                  const fp_frame_info_t *info, fp_view_t *out);

/* 1 if this depth sample is sky (inf, NaN, >= 1e10, <= 0 inverse, beyond
 * far, negative); *suspicious set for NaN/negative (counted in a warning). */
int fp_view_is_sky(const fp_view_t *v, float depth, int *suspicious);

/* The view ray of pixel (x, y) of the data window with its depth sample:
 * unit direction in fog space and length (INFINITY for sky), from where
 * the fog starts (fp_view_origin_at): the clip plane, so that the length
 * is the surface's distance less the clip's along the ray, at least 0. */
void fp_view_ray(const fp_view_t *v, int x, int y, float depth,
                 double dir[3], double *len);
/* Where that ray starts, fog space: the camera, or for an orthographic
 * camera the pixel's point on the camera's plane; moved along the ray to
 * the clip plane (v->clip > 0). */
void fp_view_origin_at(const fp_view_t *v, int x, int y, double o[3]);

/* Layout of the view for kernels (kernels/fp_common.h, FP_VIEW_*). */
#define FP_VIEW_FLOATS 32
void fp_view_pack(const fp_view_t *v, float out[FP_VIEW_FLOATS]);

/* Small linear algebra shared by the camera code and the tests. */
int fp_mat4_inverse(const double m[16], double out[16]);
void fp_mat4_mul(const double a[16], const double b[16], double out[16]);
int fp_mat3_inverse(const double m[9], double out[9]);

#endif
