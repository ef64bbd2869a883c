/* fogpipe: the one budget for every image fogpipe reads (src/base/fp_limits.h). */
#include "fp_limits.h"

#include "fp.h"

#include <ctype.h>
#include <errno.h>
#include <stdlib.h>

static const fp_image_limits_t defaults = {
    FP_LIMIT_PIXELS, FP_LIMIT_DIM, FP_LIMIT_LINE_BYTES, FP_LIMIT_CHANNELS,
    FP_LIMIT_PARTS
};

void fp_image_limits_default(fp_image_limits_t *l)
{
    l->max_pixels = FP_LIMIT_PIXELS;
    l->max_dim = FP_LIMIT_DIM;
    l->max_line_bytes = FP_LIMIT_LINE_BYTES;
    l->max_channels = FP_LIMIT_CHANNELS;
    l->max_parts = FP_LIMIT_PARTS;
}

const fp_image_limits_t *fp_image_limits(void)
{
    const fp_ctx_t *c = fp_ctx();
    return c->has_limits ? &c->limits : &defaults;
}

void fp_image_limits_set(const fp_image_limits_t *l)
{
    fp_ctx_t *c = fp_ctx();
    c->limits = *l;
    c->has_limits = 1;
}

void fp_image_limits_scaled(fp_image_limits_t *l, int64_t max_pixels)
{
    fp_image_limits_default(l);
    l->max_pixels = max_pixels;
    int64_t dim = max_pixels / 256;
    if (dim < FP_LIMIT_DIM)
        dim = FP_LIMIT_DIM;
    if (dim > max_pixels)
        dim = max_pixels;
    if (dim > INT32_MAX)
        dim = INT32_MAX;
    l->max_dim = dim;
    l->max_line_bytes = dim * 1024;
}

int fp_image_limits_parse(const char *text, int64_t *max_pixels)
{
    char *end = NULL;
    if (!text || !isdigit((unsigned char) text[0]))
        return FP_ERR;
    errno = 0;
    unsigned long long v = strtoull(text, &end, 10);
    int shift = 0;
    switch (*end) {
    case 'k': case 'K': shift = 10; end++; break;
    case 'm': case 'M': shift = 20; end++; break;
    case 'g': case 'G': shift = 30; end++; break;
    default: break;
    }
    /* at most 2^62 pixels, so that products with a few bytes stay in range */
    if (errno || *end || v < 1 || v > ((unsigned long long) 1 << (62 - shift)))
        return FP_ERR;
    *max_pixels = (int64_t) (v << shift);
    return FP_OK;
}

int fp_image_limits_apply(const char *text)
{
    fp_image_limits_t l;
    int64_t n = FP_LIMIT_PIXELS;
    if (text && fp_image_limits_parse(text, &n) != FP_OK)
        return fp_usage_error("--max-image-pixels: '%s' is not a pixel count (expected "
                              "digits with an optional K, M or G: 268435456 or 256M)", text);
    fp_image_limits_scaled(&l, n);
    fp_image_limits_set(&l);
    return FP_OK;
}

int fp_image_limits_check(const char *file, long frame, const char *kind,
                          int64_t width, int64_t height, int64_t channels,
                          int64_t bytes_per_sample)
{
    char fr[32] = "";
    if (frame >= 0)
        snprintf(fr, sizeof fr, " frame %ld:", frame);
    const fp_image_limits_t *l = fp_image_limits();
    if (width < 1 || height < 1)
        return fp_error("%s:%s %s %lldx%lld is empty (expected a positive "
                        "width and height)", file, fr, kind,
                        (long long) width, (long long) height);
    if (width > l->max_dim || height > l->max_dim ||
        width > l->max_pixels / height)
        return fp_error("%s:%s %s %lldx%lld exceeds the image budget of %lld "
                        "pixels (%lld along an axis; --max-image-pixels raises "
                        "it)", file, fr, kind, (long long) width,
                        (long long) height, (long long) l->max_pixels,
                        (long long) l->max_dim);
    if (channels < 0 || channels > l->max_channels)
        return fp_error("%s:%s %s has %lld channels (at most %d expected)",
                        file, fr, kind, (long long) channels, l->max_channels);
    if (bytes_per_sample > 0 && channels > 0 &&
        width > l->max_line_bytes / (channels * bytes_per_sample))
        return fp_error("%s:%s %s: a line of %lld pixels x %lld channels "
                        "exceeds %lld bytes", file, fr, kind, (long long) width,
                        (long long) channels, (long long) l->max_line_bytes);
    return 0;
}
