/* fogpipe stage "preview": see preview.h. */
#include "preview.h"
#include "fp.h"
#include "oiio_bridge.h"
#include "options.h"
#include "seq.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#define PV(f) offsetof(fp_params_t, preview.f)
const fp_option_t fp_preview_options[] = {
    { "preview", 0, FP_OPT_STRING, PV(preview), 0, 0, NULL, 0, 0, NULL, "PATTERN",
      "also write a display-referred preview per frame (.png, .jpg or .tif; a pattern such as "
      "prev.####.png for a sequence or stream) through --display and --view, 8-bit, dithered",
      NULL, 0 },
    { "contact-sheet", 0, FP_OPT_STRING, PV(contact_sheet), 0, 0, NULL, 0, 0, NULL, "FILE",
      "tile the previews this run wrote, in frame order, into one image (needs --preview)",
      NULL, 0 },
    { "contact-sheet-columns", 0, FP_OPT_INT, PV(columns), 0, 0, "0", 0, 10000, NULL, "N",
      "columns of the contact sheet (0: ceil(sqrt(frames)))", NULL, 0 },
    { "contact-sheet-size", 0, FP_OPT_INT, PV(sheet_size), 0, 0, "4096", 16, 65536, NULL, "PIXELS",
      "the contact sheet's longer side at most this: the previews are scaled down to fit",
      NULL, 0 },
    FP_OPT_END
};

static const char *const image_exts[] = { ".png", ".jpg", ".jpeg", ".tif", ".tiff" };

/* The output (-o) by its extension: *image 0 for EXR ("-", no extension,
 * .exr), 1 for an image written as the previews are; anything else is a
 * usage error listing what is accepted: never EXR bytes under another
 * format's name. */
static int output_kind(const fp_params_t *p, int *image)
{
    const char *out = p->io.output;
    *image = 0;
    if (!out || strcmp(out, "-") == 0)
        return FP_OK;
    const char *slash = strrchr(out, '/');
    const char *dot = strrchr(slash ? slash + 1 : out, '.');
    if (!dot || dot == (slash ? slash + 1 : out) || strcasecmp(dot, ".exr") == 0)
        return FP_OK;
    int known = 0;
    for (size_t i = 0; i < FP_ARRAY_LEN(image_exts); i++)
        known |= strcasecmp(dot, image_exts[i]) == 0;
    if (!known)
        return fp_usage_error("-o %s: unknown output extension \"%s\" (expected .exr, or .png, "
                              ".tif, .tiff, .jpg, .jpeg for the display-referred frame through "
                              "--display and --view)", out, dot);
    static const char *const exr_only[] = { "aov", "aov-only", "float", "compression",
                                            "dwa-level" };
    for (size_t i = 0; i < FP_ARRAY_LEN(exr_only); i++)
        if (fp_options_given(p, exr_only[i]))
            return fp_usage_error("-o %s: --%s shapes EXR output only (a %s output is the "
                                  "display-referred frame, 8-bit; use a .exr name)", out,
                                  exr_only[i], dot);
    *image = 1;
    return FP_OK;
}

/* An image name OpenImageIO writes as 8-bit RGB. */
static int check_name(const char *what, const char *name)
{
    const char *slash = strrchr(name, '/');
    const char *base = slash ? slash + 1 : name;
    const char *dot = strrchr(base, '.');
    int known = 0;
    for (size_t i = 0; dot && i < FP_ARRAY_LEN(image_exts); i++)
        known |= strcasecmp(dot, image_exts[i]) == 0;
    if (!known)
        return fp_usage_error("%s %s: expected a .png, .jpg or .tif file name", what, name);
    if (slash) {
        /* A missing directory is made when the first preview is written;
         * a file in its place is refused before any frame. */
        char dir[4096];
        size_t len = (size_t)(slash - name);
        struct stat st;
        if (len >= sizeof dir)
            return fp_usage_error("%s %s: name too long", what, name);
        memcpy(dir, name, len);
        dir[len] = 0;
        if (len > 0 && fp_seq_has_placeholder(dir) == 0 && stat(dir, &st) == 0 &&
            !S_ISDIR(st.st_mode))
            return fp_error("%s %s: %s is not a directory", what, name, dir);
    }
    return FP_OK;
}

/* `name` made absolute through its directory when that exists ("p.png",
 * "./p.png" and "/abs/p.png" are one file), else as given. */
static void canonical(const char *name, char *out, size_t n)
{
    const char *slash = strrchr(name, '/');
    char dir[4096], real[4096];
    size_t len = slash ? (size_t)(slash - name) : 0;
    snprintf(out, n, "%s", name);
    if (len >= sizeof dir)
        return;
    memcpy(dir, name, len);
    dir[len] = 0;
    if (realpath(slash ? (len ? dir : "/") : ".", real))
        snprintf(out, n, "%s/%s", strcmp(real, "/") ? real : "", slash ? slash + 1 : name);
}

/* A pattern's text before and after its frame number (# or @ runs, %0Nd). */
static int split_pattern(const char *pat, size_t *pre, const char **post)
{
    for (size_t i = 0; pat[i]; i++) {
        if (pat[i] == '#' || pat[i] == '@') {
            size_t j = i;
            while (pat[j] == pat[i])
                j++;
            *pre = i;
            *post = pat + j;
            return 1;
        }
        if (pat[i] == '%' && pat[i + 1] != '%') {
            size_t j = i + 1;
            while (pat[j] >= '0' && pat[j] <= '9')
                j++;
            *pre = i;
            *post = pat + j + (pat[j] == 'd');
            return 1;
        }
    }
    return 0;
}

/* Whether two output names (patterns or files) can name one file. */
static int may_collide(const char *a, const char *b)
{
    char ca[4200], cb[4200];
    canonical(a, ca, sizeof ca);
    canonical(b, cb, sizeof cb);
    size_t pa, pb;
    const char *sa, *sb;
    int ha = split_pattern(ca, &pa, &sa), hb = split_pattern(cb, &pb, &sb);
    if (!ha && !hb)
        return strcmp(ca, cb) == 0;
    if (ha && hb)
        return pa == pb && strncmp(ca, cb, pa) == 0 && strcmp(sa, sb) == 0;
    /* A pattern and a file: the file is one of its frames. */
    const char *pat = ha ? ca : cb, *file = ha ? cb : ca, *post = ha ? sa : sb;
    size_t pre = ha ? pa : pb, fl = strlen(file), ql = strlen(post);
    if (fl < pre + ql + 1 || strncmp(pat, file, pre) != 0 || strcmp(file + fl - ql, post) != 0)
        return 0;
    for (size_t i = pre; i < fl - ql; i++)
        if ((file[i] < '0' || file[i] > '9') && !(i == pre && file[i] == '-'))
            return 0;
    return 1;
}

int fp_preview_commit(const fp_params_t *p, fp_preview_t *s)
{
    int rc;
    memset(s, 0, sizeof *s);
    s->pattern = p->preview.preview;
    s->sheet = p->preview.contact_sheet;
    s->columns = p->preview.columns;
    s->sheet_size = p->preview.sheet_size;
    if ((rc = output_kind(p, &s->out_image)))
        return rc;
    if (s->sheet && !s->pattern)
        return fp_usage_error("--contact-sheet %s needs --preview PATTERN (the sheet tiles the "
                              "previews)", s->sheet);
    if (!s->pattern)
        return FP_OK;
    int placeholder = fp_seq_has_placeholder(s->pattern);
    if (placeholder < 0)
        return fp_usage_error("--preview %s: malformed sequence pattern (expected one %%0Nd, or "
                              "one run of # or @)", s->pattern);
    const char *in = p->io.input;
    int many = !in || strcmp(in, "-") == 0 || fp_seq_has_placeholder(in) == 1;
    if (many && !placeholder)
        return fp_usage_error("--preview %s: a sequence or a stream needs a preview pattern with "
                              "a frame number (e.g. prev.####.png)", s->pattern);
    if ((rc = check_name("--preview", s->pattern)))
        return rc;
    if (s->sheet && (rc = check_name("--contact-sheet", s->sheet)))
        return rc;
    /* Two outputs in one file: the later would silently replace the other. */
    const char *out = p->io.output;
    if (s->sheet && may_collide(s->sheet, s->pattern))
        return fp_usage_error("--contact-sheet %s: the same file as --preview %s (each output "
                              "needs its own file)", s->sheet, s->pattern);
    if (out && strcmp(out, "-") != 0 && may_collide(out, s->pattern))
        return fp_usage_error("--preview %s: the same file as the output %s (each output needs "
                              "its own file)", s->pattern, out);
    if (out && s->sheet && strcmp(out, "-") != 0 && may_collide(out, s->sheet))
        return fp_usage_error("--contact-sheet %s: the same file as the output %s (each output "
                              "needs its own file)", s->sheet, out);
    if (pthread_mutex_init(&s->lock, NULL) != 0)
        return fp_error("cannot make a mutex");
    s->lock_ok = 1;
    return FP_OK;
}

/* The frame's color through the display and view, written as 8-bit RGB
 * with dither to `path`. */
static int write_display(const char *path, const fp_color_frame_t *cf, const float *rgba, int w,
                         int h, long frame)
{
    size_t n = (size_t)w * h;
    float *rgb = malloc(n * 3 * sizeof(float));
    if (!rgb)
        return fp_error("%s: frame %ld: out of memory for the image", path, frame);
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            rgb[3 * i + c] = rgba[4 * i + c];
    if (cf->to_display)
        fp_ocio_apply(cf->to_display, rgb, n, 3);
    int rc = fp_make_parent_dir(path, frame);
    if (rc == FP_OK)
        rc = fp_oiio_write_preview(path, rgb, w, h, 3, 8, 1);
    free(rgb);
    return rc;
}

int fp_preview_output(const fp_color_frame_t *cf, const float *rgba, int w, int h,
                      const char *path, long frame)
{
    return write_display(path, cf, rgba, w, h, frame);
}

int fp_preview_frame(fp_preview_t *s, const fp_color_frame_t *cf, const float *rgba, int w,
                     int h, long frame)
{
    if (!s->pattern)
        return FP_OK;
    char path[4096];
    int rc = fp_seq_format(s->pattern, frame, path, sizeof path);
    if (rc)
        return rc;
    rc = write_display(path, cf, rgba, w, h, frame);
    if (rc || !s->sheet)
        return rc;
    char *copy = strdup(path);
    if (!copy)
        return fp_error("%s: frame %ld: out of memory", path, frame);
    pthread_mutex_lock(&s->lock);
    if (s->n == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 64;
        fp_preview_done_t *d = realloc(s->done, cap * sizeof *d);
        if (!d) {
            pthread_mutex_unlock(&s->lock);
            free(copy);
            return fp_error("%s: frame %ld: out of memory", path, frame);
        }
        s->done = d;
        s->cap = cap;
    }
    s->done[s->n].frame = frame;
    s->done[s->n++].path = copy;
    pthread_mutex_unlock(&s->lock);
    return FP_OK;
}

static int by_frame(const void *a, const void *b)
{
    long fa = ((const fp_preview_done_t *)a)->frame, fb = ((const fp_preview_done_t *)b)->frame;
    return fa < fb ? -1 : fa > fb;
}

int fp_preview_columns(int given, size_t n)
{
    if (given > 0)
        return given;
    int c = (int)ceil(sqrt((double)n));
    while ((size_t)c * c < n)   /* sqrt rounding */
        c++;
    return c > 0 ? c : 1;
}

int fp_preview_finish(fp_preview_t *s)
{
    if (!s->sheet)
        return FP_OK;
    if (s->n == 0) {
        fp_warn("--contact-sheet %s: no preview was written in this run; no sheet", s->sheet);
        return FP_OK;
    }
    qsort(s->done, s->n, sizeof *s->done, by_frame);
    const char **paths = malloc(s->n * sizeof *paths);
    if (!paths)
        return fp_error("%s: out of memory", s->sheet);
    for (size_t i = 0; i < s->n; i++)
        paths[i] = s->done[i].path;
    int rc = fp_make_parent_dir(s->sheet, s->done[s->n - 1].frame);
    if (rc == FP_OK)
        rc = fp_oiio_tile_sheet(paths, (int)s->n, fp_preview_columns(s->columns, s->n),
                                s->sheet_size, s->sheet);
    free(paths);
    if (rc == FP_OK)
        fp_info("%s: contact sheet of %zu previews", s->sheet, s->n);
    return rc;
}

void fp_preview_release(fp_preview_t *s)
{
    for (size_t i = 0; i < s->n; i++)
        free(s->done[i].path);
    free(s->done);
    s->done = NULL;
    s->n = s->cap = 0;
    if (s->lock_ok)
        pthread_mutex_destroy(&s->lock);
    s->lock_ok = 0;
}
