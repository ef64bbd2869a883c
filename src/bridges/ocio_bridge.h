/* fogpipe: a thin extern "C" bridge to OpenColorIO 2.1 (C++): configs,
 * color space names, and CPU processors between color spaces and to a
 * display and view.
 *
 * Every fallible function returns 0 (FP_OK) on success, or non-zero after
 * printing one line through fp_error() that names the config and says what
 * was expected; FP_EUSAGE when a name the user gave is not in the config.
 * No C++ exception crosses this boundary.
 *
 * Thread safety: a config and its processors are immutable once made, so
 * fp_ocio_apply() may run from several threads at once; making processors
 * (fp_ocio_processor, fp_ocio_display_processor) is safe too (OpenColorIO
 * locks its own caches). */
#ifndef FP_OCIO_BRIDGE_H
#define FP_OCIO_BRIDGE_H

#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct fp_ocio_t fp_ocio_t;
typedef struct fp_ocio_proc_t fp_ocio_proc_t;

/* Where the config comes from, first found wins:
 *   1. `explicit_path` (--ocio) when non-NULL and non-empty;
 *   2. $OCIO when set and non-empty;
 *   3. fogpipe's own config (samples/ocio/config.ocio in the sources),
 *      ocio/config.ocio where fogpipe's installed files are
 *      (src/base/install.h: the source tree from a build tree, beside the
 *      program or the library, so a relocated or DESTDIR install finds its
 *      own, then the configured $(pkgdatadir)).
 * Writes the path to `path` and what chose it ("--ocio", "$OCIO",
 * "fogpipe's config") to *origin.  Fails (listing where it looked) only when
 * nothing was given and no copy of fogpipe's config exists. */
int fp_ocio_find_config(const char *explicit_path, char *path, size_t n, const char **origin);

/* Load and validate a config. */
int fp_ocio_open(const char *path, fp_ocio_t **out);
void fp_ocio_close(fp_ocio_t *c);
const char *fp_ocio_path(const fp_ocio_t *c);

/* Resolve a color space name, alias or role (case-insensitive, as
 * OpenColorIO does) to the space's name in the config, written to `name`.
 * `what` labels the message ("--input-space").  An unknown name is a usage
 * error whose message names the config and lists some valid names. */
int fp_ocio_space(const fp_ocio_t *c, const char *name_or_role, const char *what, char *name,
                  size_t n);
/* The space a role points at; non-zero (no message) when the config has no
 * such role. */
int fp_ocio_role(const fp_ocio_t *c, const char *role, char *name, size_t n);
/* 1 when the space is data (isdata: true), else 0. */
int fp_ocio_is_data(const fp_ocio_t *c, const char *space);
/* 1 when the space is display-referred (a display color space), else 0. */
int fp_ocio_is_display_referred(const fp_ocio_t *c, const char *space);
/* Number of color spaces (scene- and display-referred) and their names. */
int fp_ocio_num_spaces(const fp_ocio_t *c);
const char *fp_ocio_space_name(const fp_ocio_t *c, int index);

/* A display and a view of it; NULL or "" for `display` is the config's
 * default display, and for `view` that display's default view.  The names
 * found are written to `d` and `v`; an unknown one is a usage error that
 * lists the valid ones. */
int fp_ocio_display_view(const fp_ocio_t *c, const char *display, const char *view, char *d,
                         size_t dn, char *v, size_t vn);

/* A CPU processor from one color space to another (names as the config
 * has them). */
int fp_ocio_processor(const fp_ocio_t *c, const char *src, const char *dst,
                      fp_ocio_proc_t **out);
/* A CPU processor from a color space through a display and view. */
int fp_ocio_display_processor(const fp_ocio_t *c, const char *src, const char *display,
                              const char *view, fp_ocio_proc_t **out);
/* 1 when the processor changes nothing. */
int fp_ocio_is_noop(const fp_ocio_proc_t *p);
/* Apply to `npix` pixels of `stride` floats each (3: RGB, 4: RGBA, ...),
 * the first three being R, G, B; the other floats (alpha) are untouched. */
void fp_ocio_apply(const fp_ocio_proc_t *p, float *pixels, size_t npix, int stride);
/* Apply to three planes of `npix` floats each (R, G, B). */
void fp_ocio_apply_planar(const fp_ocio_proc_t *p, float *r, float *g, float *b, size_t npix);
void fp_ocio_proc_free(fp_ocio_proc_t *p);

/* Probe the conversion src -> dst with a few colors: 0 with its 3x3 matrix
 * (row-major, dst = M * src) when it is one (linear, no offset, within
 * 1e-4), 1 when it is not linear, -1 when it cannot be made.  Prints
 * nothing: for telling linear spaces apart and identifying primaries. */
int fp_ocio_matrix(const fp_ocio_t *c, const char *src, const char *dst, double m[9]);

/* Describe the config: its path, color spaces (with aliases, family and
 * encoding), roles, displays and views.  For --list-spaces. */
int fp_ocio_print(const fp_ocio_t *c, FILE *out);

#ifdef __cplusplus
}
#endif

#endif
