/* fogpipe kernels: layout of the packed view buffer (fp_view_pack() in
 * src/scene/camera.c), for the OpenCL kernels and the C versions of the shared
 * kernel code alike. */
#ifndef FP_VIEW_LAYOUT_H
#define FP_VIEW_LAYOUT_H

#define FP_VIEW_ORIGIN 0
#define FP_VIEW_M 3
#define FP_VIEW_H 12
#define FP_VIEW_NDC_SCALE 21
#define FP_VIEW_NDC_OFFSET 23
#define FP_VIEW_FAR 25
#define FP_VIEW_DEPTH_KIND 26
#define FP_VIEW_ORTHO 27      /* 1: orthographic (rays along the view axis from the camera's plane) */
#define FP_VIEW_CLIP 28       /* clip start: the fog begins at this planar depth (0: at the camera) */

#endif
