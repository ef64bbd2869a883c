#include "textfile.h"
#include "fp.h"
#include "fp_limits.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int fp_text_open(fp_text_t *t, const char *path, const char *what, int err_usage)
{
    memset(t, 0, sizeof *t);
    t->path = path;
    t->what = what;
    t->err_usage = err_usage;
    t->rc = err_usage ? FP_EUSAGE : FP_ERR;
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
        errno = EISDIR;
    else
        t->f = fopen(path, "r");
    if (!t->f) {
        const char *why = strerror(errno);
        return err_usage ? fp_usage_error("%s: cannot open %s (%s)", path, what, why)
                         : fp_error("%s: cannot open %s (%s)", path, what, why);
    }
    return FP_OK;
}

/* The error of the line in progress: printed, t->rc returned as -1. */
#define TEXT_FAIL(t, ...)                         \
    do {                                          \
        if ((t)->err_usage)                       \
            fp_usage_error(__VA_ARGS__);          \
        else                                      \
            fp_error(__VA_ARGS__);                \
        return -1;                                \
    } while (0)

/* What a text input must be, ending every message about its size. */
#define EXPECTED "(expected a %s: text of at most %lld MiB, lines of at most %zu KiB)"
#define LIMITS(t) (t)->what, (long long)(FP_TEXT_MAX_BYTES >> 20), FP_TEXT_MAX_LINE >> 10

int fp_text_next(fp_text_t *t, char **line)
{
    *line = NULL;
    if (!t->line) {
        t->cap = 1024;
        if (!(t->line = malloc(t->cap)))
            TEXT_FAIL(t, "%s: out of memory", t->path);
    }
    size_t n = 0;
    int c;
    t->lineno++;
    while ((c = getc(t->f)) != EOF) {
        if (++t->bytes > FP_TEXT_MAX_BYTES)
            TEXT_FAIL(t, "%s: more than %lld MiB " EXPECTED, t->path,
                      (long long)(FP_TEXT_MAX_BYTES >> 20), LIMITS(t));
        if (c == '\n')
            break;
        if (c == 0)
            TEXT_FAIL(t, "%s:%d: a NUL byte " EXPECTED, t->path, t->lineno, LIMITS(t));
        if (n + 1 >= FP_TEXT_MAX_LINE)
            TEXT_FAIL(t, "%s:%d: a line longer than %zu KiB " EXPECTED, t->path, t->lineno,
                      FP_TEXT_MAX_LINE >> 10, LIMITS(t));
        if (n + 1 >= t->cap) {
            size_t cap = t->cap * 2;
            char *l = realloc(t->line, cap);
            if (!l)
                TEXT_FAIL(t, "%s: out of memory", t->path);
            t->line = l;
            t->cap = cap;
        }
        t->line[n++] = (char)c;
    }
    if (c == EOF && ferror(t->f))
        TEXT_FAIL(t, "%s: read error (%s)", t->path, strerror(errno));
    if (c == EOF && n == 0)
        return 0;
    if (n && t->line[n - 1] == '\r')
        n--;
    t->line[n] = 0;
    *line = t->line;
    return 1;
}

void fp_text_close(fp_text_t *t)
{
    if (t->f)
        fclose(t->f);
    free(t->line);
    memset(t, 0, sizeof *t);
}

int fp_text_read_all(const char *path, const char *what, int err_usage, char **out,
                     size_t *len)
{
    *out = NULL;
    *len = 0;
    fp_text_t t;
    int rc = fp_text_open(&t, path, what, err_usage);
    if (rc)
        return rc;
    size_t n = 0, cap = 4096;
    char *buf = malloc(cap);
    int c;
    rc = t.rc;
    if (!buf) {
        fp_error("%s: out of memory", path);
        goto fail;
    }
    t.lineno = 1;
    while ((c = getc(t.f)) != EOF) {
        if (++t.bytes > FP_TEXT_MAX_BYTES) {
            (err_usage ? fp_usage_error : fp_error)(
                "%s: more than %lld MiB (expected a %s: text of at most %lld MiB)", path,
                (long long)(FP_TEXT_MAX_BYTES >> 20), what, (long long)(FP_TEXT_MAX_BYTES >> 20));
            goto fail;
        }
        if (c == 0) {
            (err_usage ? fp_usage_error : fp_error)("%s:%d: a NUL byte (expected a %s, a text "
                                                    "file)", path, t.lineno, what);
            goto fail;
        }
        t.lineno += c == '\n';
        if (n + 1 >= cap) {
            char *b = realloc(buf, cap * 2);
            if (!b) {
                fp_error("%s: out of memory", path);
                goto fail;
            }
            buf = b;
            cap *= 2;
        }
        buf[n++] = (char)c;
    }
    if (ferror(t.f)) {
        (err_usage ? fp_usage_error : fp_error)("%s: read error (%s)", path, strerror(errno));
        goto fail;
    }
    buf[n] = 0;
    fp_text_close(&t);
    *out = buf;
    *len = n;
    return FP_OK;
fail:
    free(buf);
    fp_text_close(&t);
    return rc;
}

int64_t fp_image_file_max_bytes(void)
{
    const fp_image_limits_t *l = fp_image_limits();
    return l->max_pixels > (INT64_MAX >> 5) ? INT64_MAX : l->max_pixels * 16 + ((int64_t)16 << 20);
}

int fp_image_file_check(const char *path, const char *what)
{
    int64_t max_bytes = fp_image_file_max_bytes();
    struct stat st;
    if (stat(path, &st) != 0)
        return fp_error("%s: cannot open %s (%s)", path, what, strerror(errno));
    if (!S_ISREG(st.st_mode))
        return fp_error("%s: not a regular file (expected a %s image file; devices, pipes and "
                        "directories are not read)", path, what);
    if ((int64_t)st.st_size > max_bytes)
        return fp_error("%s: %lld bytes (expected a %s image file of at most %lld MiB, the "
                        "image budget; --max-image-pixels raises it)", path,
                        (long long)st.st_size, what, (long long)(max_bytes >> 20));
    return FP_OK;
}
