/* fogpipe stage "preview": a display-referred image per frame, for looking
 * at a run without a compositor, and a contact sheet of the run.
 *
 * The output frame (its color, in the output space, after the composite) goes
 * through the OpenColorIO display and view (--display, --view: the same
 * processor as `oiiotool --ociodisplay DISPLAY VIEW`), then is written by
 * OpenImageIO as 8-bit RGB with a deterministic dither (PNG, JPEG or TIFF by
 * the extension).  Alpha is not shown: the color is premultiplied, so the
 * preview is the frame over black.
 *
 * Thread safety: fp_preview_frame may run from several threads at once. */
#ifndef FP_PREVIEW_H
#define FP_PREVIEW_H

#include <pthread.h>
#include <stddef.h>

#include "color.h"
#include "params.h"

typedef struct fp_preview_done_t {
    long frame;
    char *path;
} fp_preview_done_t;

typedef struct fp_preview_t {
    const char *pattern;        /* --preview, NULL: none */
    const char *sheet;          /* --contact-sheet, NULL: none */
    int columns, sheet_size;
    int out_image;              /* -o names a .png, .tif or .jpg: fp_preview_output */
    pthread_mutex_t lock;
    int lock_ok;
    fp_preview_done_t *done;    /* previews written, for the sheet */
    size_t n, cap;
} fp_preview_t;


/* Check the names (pattern, extension, directory) before any frame, and
 * the output's extension (-o: .exr or none for EXR, an image extension for
 * s->out_image, anything else a usage error). */
int fp_preview_commit(const fp_params_t *p, fp_preview_t *s);
/* Write frame `frame`'s preview from its output color (n = w*h RGBA). */
int fp_preview_frame(fp_preview_t *s, const fp_color_frame_t *cf, const float *rgba, int w,
                     int h, long frame);
/* The output frame itself as an image (-o x.png, .tif, .jpg; s->out_image),
 * written as the previews are: through --display and --view, 8-bit RGB,
 * dithered, atomically. */
int fp_preview_output(const fp_color_frame_t *cf, const float *rgba, int w, int h,
                      const char *path, long frame);
/* After the last frame: the contact sheet, the previews in frame order. */
int fp_preview_finish(fp_preview_t *s);
void fp_preview_release(fp_preview_t *s);

/* Columns of a sheet of n cells: given, else ceil(sqrt(n)). */
int fp_preview_columns(int given, size_t n);

#endif
