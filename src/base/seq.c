#include "seq.h"
#include "fp.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

/* Locate the single placeholder: [*start, *end) in the pattern, its width
 * (0 for a plain %d).  Returns 1 found, 0 none, -1 malformed/ambiguous. */
static int find_placeholder(const char *pat, size_t *start, size_t *end, int *width)
{
    int found = 0;
    for (size_t i = 0; pat[i];) {
        if (pat[i] == '%') {
            if (pat[i + 1] == '%') {
                i += 2;
                continue;
            }
            size_t j = i + 1;
            int w = 0;
            while (isdigit((unsigned char)pat[j]))
                w = w * 10 + (pat[j++] - '0');
            if (pat[j] != 'd' || w > 32)
                return -1;
            if (found++)
                return -1;
            *start = i;
            *end = j + 1;
            *width = w;
            i = j + 1;
        } else if (pat[i] == '#' || pat[i] == '@') {
            char c = pat[i];
            size_t j = i;
            while (pat[j] == c)
                j++;
            if (found++)
                return -1;
            *start = i;
            *end = j;
            *width = (int)(j - i);
            i = j;
        } else {
            i++;
        }
    }
    return found;
}

int fp_seq_has_placeholder(const char *pattern)
{
    size_t s, e;
    int w;
    return find_placeholder(pattern, &s, &e, &w);
}

int fp_seq_format(const char *pattern, long frame, char *out, size_t outsz)
{
    size_t s = 0, e = 0;
    int w = 0;
    int k = find_placeholder(pattern, &s, &e, &w);
    if (k < 0)
        return fp_usage_error("%s: malformed sequence pattern (expected one %%0Nd, "
                              "or one run of # or @)", pattern);
    int n;
    if (k == 0) {
        n = snprintf(out, outsz, "%s", pattern);
    } else {
        /* "%%" outside the placeholder stays literal only for %-patterns. */
        n = snprintf(out, outsz, "%.*s%0*ld%s", (int)s, pattern, w, frame, pattern + e);
    }
    if (n < 0 || (size_t)n >= outsz)
        return fp_usage_error("%s: file name too long", pattern);
    return FP_OK;
}

static int parse_long(const char **s, long *out)
{
    const char *p = *s;
    int neg = 0;
    if (*p == '-') {
        neg = 1;
        p++;
    }
    if (!isdigit((unsigned char)*p))
        return -1;
    long v = 0;
    while (isdigit((unsigned char)*p)) {
        if (v > (LONG_MAX - 9) / 10)
            return -1;
        v = v * 10 + (*p++ - '0');
    }
    *out = neg ? -v : v;
    *s = p;
    return 0;
}

static int push(fp_frame_list_t *l, size_t *cap, long f)
{
    if (l->count == *cap) {
        size_t nc = *cap ? *cap * 2 : 64;
        long *nf = realloc(l->frames, nc * sizeof *nf);
        if (!nf)
            return fp_error("out of memory");
        l->frames = nf;
        *cap = nc;
    }
    l->frames[l->count++] = f;
    return FP_OK;
}

/* A frame list longer than this is surely a typo (1-1000000000). */
#define FP_MAX_FRAMES 10000000L

int fp_frames_parse(const char *spec, fp_frame_list_t *out)
{
    fp_frame_list_t l = { NULL, 0 };
    size_t cap = 0;
    const char *p = spec;
    if (!spec || !*spec)
        return fp_usage_error("--frames: empty frame list");
    for (;;) {
        long a, b, step = 1;
        while (*p == ' ')
            p++;
        if (parse_long(&p, &a))
            goto bad;
        b = a;
        if (*p == '-') {
            p++;
            if (parse_long(&p, &b))
                goto bad;
            if (*p == 'x' || *p == 'X') {
                p++;
                if (parse_long(&p, &step) || step < 1)
                    goto bad;
            }
            if (b < a) {
                fp_frames_free(&l);
                return fp_usage_error("--frames %s: range %ld-%ld runs backwards (expected A-B with A <= B)",
                                      spec, a, b);
            }
        }
        if ((b - a) / step + 1 + (long)l.count > FP_MAX_FRAMES) {
            fp_frames_free(&l);
            return fp_usage_error("--frames %s: more than %ld frames", spec, FP_MAX_FRAMES);
        }
        for (long f = a; f <= b; f += step)
            if (push(&l, &cap, f)) {
                fp_frames_free(&l);
                return FP_ERR;
            }
        while (*p == ' ')
            p++;
        if (*p == 0)
            break;
        if (*p != ',')
            goto bad;
        p++;
    }
    *out = l;
    return FP_OK;
bad:
    fp_frames_free(&l);
    return fp_usage_error("--frames %s: malformed frame list (expected e.g. 1001-1100, "
                          "1-100x2, 5, -3, 1,3,7-9)", spec);
}

static int cmp_long(const void *x, const void *y)
{
    long a = *(const long *)x, b = *(const long *)y;
    return (a > b) - (a < b);
}

int fp_frames_scan(const char *pattern, fp_frame_list_t *out)
{
    size_t s = 0, e = 0;
    int w = 0;
    if (find_placeholder(pattern, &s, &e, &w) != 1)
        return fp_usage_error("%s: not a sequence pattern", pattern);
    /* Split directory / file-name parts; the placeholder must be in the name. */
    const char *slash = strrchr(pattern, '/');
    size_t base = slash ? (size_t)(slash - pattern) + 1 : 0;
    if (base > s)
        return fp_usage_error("%s: the frame placeholder must be in the file name", pattern);
    char dir[4096];
    if (base) {
        if (base >= sizeof dir)
            return fp_usage_error("%s: path too long", pattern);
        memcpy(dir, pattern, base);
        dir[base] = 0;
    } else {
        strcpy(dir, ".");
    }
    const char *prefix = pattern + base;
    size_t prefix_len = s - base;
    const char *suffix = pattern + e;
    size_t suffix_len = strlen(suffix);
    DIR *d = opendir(dir);
    if (!d)
        return fp_error("%s: cannot list directory '%s' (%s)", pattern, dir, strerror(errno));
    fp_frame_list_t l = { NULL, 0 };
    size_t cap = 0;
    struct dirent *de;
    int rc = FP_OK;
    while ((de = readdir(d))) {
        const char *n = de->d_name;
        size_t len = strlen(n);
        if (len < prefix_len + suffix_len + 1 || strncmp(n, prefix, prefix_len) ||
            strcmp(n + len - suffix_len, suffix))
            continue;
        const char *num = n + prefix_len, *q = num;
        long f;
        if (parse_long(&q, &f) || (size_t)(q - n) != len - suffix_len)
            continue;
        /* Only names this pattern would write for f (padding must agree). */
        char numbuf[64];
        snprintf(numbuf, sizeof numbuf, "%0*ld", w, f);
        if (strlen(numbuf) != (size_t)(q - num) || strncmp(numbuf, num, (size_t)(q - num)))
            continue;
        if ((rc = push(&l, &cap, f)))
            break;
    }
    closedir(d);
    if (rc) {
        fp_frames_free(&l);
        return rc;
    }
    if (l.count == 0)
        return fp_error("%s: no frames found (give --frames, or check the pattern)", pattern);
    qsort(l.frames, l.count, sizeof *l.frames, cmp_long);
    *out = l;
    return FP_OK;
}

void fp_frames_free(fp_frame_list_t *l)
{
    free(l->frames);
    l->frames = NULL;
    l->count = 0;
}

int fp_seq_frame_of_name(const char *path, long *frame)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot || dot == base)
        return 0;
    const char *e = dot, *b = dot;
    while (b > base && isdigit((unsigned char)b[-1]))
        b--;
    /* At most 9 digits: a frame number, not a date or a hash; after a
     * letter, at least 4 (a padded number, as Blender's #### writes: not
     * the 44 of "huge_b44" or the 3 of "p3"). */
    if (b == e || e - b > 9)
        return 0;
    if (b > base && isalpha((unsigned char)b[-1]) && e - b < 4)
        return 0;
    long v = 0;
    for (const char *c = b; c < e; c++)
        v = v * 10 + (*c - '0');
    *frame = v;
    return 1;
}
