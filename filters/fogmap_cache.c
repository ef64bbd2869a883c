#include "fogmap_cache.h"

#include <errno.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "animate.h"
#include "fp.h"

/* File: magic, key, payload size, checksum, payload (the fixed part, the
 * coefficients, the occupancy).  Native byte order and struct layout: the
 * key holds both (key_params), so another machine's file is a miss. */
#define FP_FMC_MAGIC "FPFMAP01"
#define FP_FMC_VERSION "fogpipe-fogmap-cache-1"
#define FP_FMC_HEADER (8 + 32 + 8 + 32)

static char *xprintf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static char *xprintf(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s) {
        va_start(ap, fmt);
        vsnprintf(s, (size_t)n + 1, fmt, ap);
        va_end(ap);
    }
    return s;
}

/* ------------------------------------------------------------ the hash */

/* A 256-bit hash of a byte string, four lanes of xxHash64's round (Collet,
 * xxhash.h) over 32-byte stripes: several GB/s, so hashing a 4096x4096
 * map's 64 MB costs tens of ms where SHA-256 (src/clrt.c) would cost a
 * quarter of a second.  Its job is telling apart maps by accident, not
 * resisting an adversary (whoever can write the cache can write the
 * tables). */
#define P1 0x9E3779B185EBCA87ull
#define P2 0xC2B2AE3D27D4EB4Full
#define P3 0x165667B19E3779F9ull

static uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

static uint64_t round64(uint64_t acc, uint64_t w)
{
    return rotl(acc + w * P2, 31) * P1;
}

static uint64_t avalanche(uint64_t h)
{
    h ^= h >> 33;
    h *= P2;
    h ^= h >> 29;
    h *= P3;
    return h ^ (h >> 32);
}

typedef struct hash_t {
    uint64_t acc[4];
    uint64_t len;
} hash_t;

static void hash_init(hash_t *s, uint64_t seed)
{
    s->acc[0] = seed + P1 + P2;
    s->acc[1] = seed + P2;
    s->acc[2] = seed;
    s->acc[3] = seed - P1;
    s->len = 0;
}

/* Whole stripes of `data`, then the tail zero-padded into one more: the
 * length is hashed at the end, so padding cannot collide. */
static void hash_update(hash_t *s, const void *data, size_t n)
{
    const unsigned char *b = data;
    size_t i = 0;
    for (; i + 32 <= n; i += 32) {
        uint64_t w[4];
        memcpy(w, b + i, 32);
        for (int k = 0; k < 4; k++)
            s->acc[k] = round64(s->acc[k], w[k]);
    }
    if (i < n) {
        uint64_t w[4] = { 0, 0, 0, 0 };
        memcpy(w, b + i, n - i);
        for (int k = 0; k < 4; k++)
            s->acc[k] = round64(s->acc[k], w[k] ^ P3);
    }
    s->len += n;
}

static void hash_final(const hash_t *s, unsigned char out[32])
{
    uint64_t mix = s->len * P1;
    for (int k = 0; k < 4; k++)
        mix = round64(mix, s->acc[k]);
    for (int k = 0; k < 4; k++) {
        uint64_t v = avalanche(s->acc[k] ^ rotl(mix, 8 * k + 1) ^ (uint64_t)k * P3);
        memcpy(out + 8 * k, &v, 8);
    }
}

/* ------------------------------------------------------------ the key */

/* What the tables depend on besides the pixels.  The sizes and a byte
 * order marker make another build's or machine's file a miss. */
typedef struct key_params_t {
    char version[32];
    int32_t w, h, basis, levels, wrap, deconstruct;
    uint32_t byte_order;
    uint32_t sizes[4];
    char device[256];
} key_params_t;

static char *default_dir(void)
{
    const char *env = getenv("FOGPIPE_CACHE_DIR");
    if (env && strcmp(env, "off") == 0)
        return NULL;
    if (env && *env)
        return xprintf("%s/fogmaps", env);
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    if (xdg && xdg[0] == '/')
        return xprintf("%s/fogpipe/fogmaps", xdg);
    if (home && *home)
        return xprintf("%s/.cache/fogpipe/fogmaps", home);
    return NULL;
}

int fp_fogmap_cache_open(const fp_params_t *p, fp_cl_t *cl, const float *img, int w, int h,
                         fp_fogmap_cache_t *c)
{
    const fp_fogmap_params_t *fm = &p->fogmap;
    memset(c, 0, sizeof *c);
    const char *opt = fm->cache;
    if ((opt && strcmp(opt, "off") == 0) || (size_t)w * h < FP_FOGMAP_CACHE_MIN ||
        fm->preview || fp_animate_fogmap_animated(p))
        return FP_OK;
    char *dir = opt && *opt ? xprintf("%s", opt) : default_dir();
    if (!dir)
        return FP_OK;
    struct stat st;
    if (fp_mkdir_p(dir) != 0 || stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        fp_warn("%s: cannot use the fogmap cache directory (%s); fogmap cache off", dir,
                strerror(errno ? errno : ENOTDIR));
        free(dir);
        return FP_OK;
    }
    key_params_t kp;
    memset(&kp, 0, sizeof kp);
    snprintf(kp.version, sizeof kp.version, "%s", FP_FMC_VERSION);
    kp.w = w;
    kp.h = h;
    kp.basis = fm->basis;
    kp.levels = fm->levels;
    kp.wrap = fm->wrap;
    kp.deconstruct = fm->deconstruct;
    kp.byte_order = 0x01020304u;
    kp.sizes[0] = sizeof(fp_wavelet_filter_t);
    kp.sizes[1] = sizeof(fp_fog_tables_t);
    kp.sizes[2] = sizeof(double);
    kp.sizes[3] = FP_LEVEL_TABLE;
    snprintf(kp.device, sizeof kp.device, "%s", cl ? fp_cl_device_label(cl) : "C reference");
    hash_t s;
    hash_init(&s, 0);
    hash_update(&s, &kp, sizeof kp);
    hash_update(&s, img, (size_t)w * h * sizeof(float));
    hash_final(&s, c->key);
    char hex[65];
    for (int i = 0; i < 32; i++)
        snprintf(hex + 2 * i, 3, "%02x", c->key[i]);
    c->path = xprintf("%s/%s.fogmap", dir, hex);
    free(dir);
    return c->path ? FP_OK : fp_error("out of memory");
}

void fp_fogmap_cache_close(fp_fogmap_cache_t *c)
{
    free(c->path);
    c->path = NULL;
}

/* ------------------------------------------------------------ the file */

/* The part of the payload before the coefficients. */
typedef struct fixed_t {
    int32_t degree, wrap, levels, width, height, dom_w, dom_h, pad_x0, pad_y0, num_levels;
    int32_t nlevels, pad;
    uint64_t ncoef, nocc;
    fp_wavelet_filter_t synth[2];
    int lvi[FP_LEVEL_TABLE * 8];
    double lvf[FP_LEVEL_TABLE * 8];
} fixed_t;

static void checksum(const fixed_t *fx, const float *coef, const unsigned char *occ,
                     unsigned char out[32])
{
    hash_t s;
    hash_init(&s, 1);
    hash_update(&s, fx, sizeof *fx);
    hash_update(&s, coef, fx->ncoef * sizeof(float));
    hash_update(&s, occ, fx->nocc);
    hash_final(&s, out);
}

int fp_fogmap_cache_load(const fp_fogmap_cache_t *c, fp_fogmap_t *m, fp_fog_tables_t *t)
{
    memset(t, 0, sizeof *t);
    if (!c->path)
        return 0;
    FILE *f = fopen(c->path, "rb");
    if (!f)
        return 0;   /* not cached yet */
    const char *why = NULL;
    unsigned char head[FP_FMC_HEADER];
    fixed_t fx;
    uint64_t size = 0;
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || fread(head, 1, sizeof head, f) != sizeof head ||
        memcmp(head, FP_FMC_MAGIC, 8) != 0) {
        why = "not a fogmap cache file";
        goto fail;
    }
    memcpy(&size, head + 40, 8);
    if (memcmp(head + 8, c->key, 32) != 0) {
        why = "its key is another map's";
        goto fail;
    }
    if (size < sizeof fx || (uint64_t)st.st_size != FP_FMC_HEADER + size ||
        fread(&fx, sizeof fx, 1, f) != 1) {
        why = "truncated";
        goto fail;
    }
    if (fx.ncoef > size / sizeof(float) || fx.nocc > size ||
        sizeof fx + fx.ncoef * sizeof(float) + fx.nocc != size || fx.nlevels < 1 ||
        fx.nlevels >= FP_LEVEL_TABLE || fx.num_levels != fx.nlevels) {
        why = "inconsistent sizes";
        goto fail;
    }
    t->coef = fp_fog_tables_alloc(fx.ncoef * sizeof(float));
    t->occ = fp_fog_tables_alloc(fx.nocc);
    if (!t->coef || !t->occ) {
        why = "out of memory";
        goto fail;
    }
    if (fread(t->coef, sizeof(float), fx.ncoef, f) != fx.ncoef ||
        fread(t->occ, 1, fx.nocc, f) != fx.nocc) {
        why = "truncated";
        goto fail;
    }
    unsigned char sum[32];
    checksum(&fx, t->coef, t->occ, sum);
    if (memcmp(sum, head + 48, 32) != 0) {
        why = "checksum mismatch";
        goto fail;
    }
    fclose(f);
    memset(m, 0, sizeof *m);
    m->degree = fx.degree;
    m->wrap = fx.wrap;
    m->levels = fx.levels;
    m->width = fx.width;
    m->height = fx.height;
    m->dom_w = fx.dom_w;
    m->dom_h = fx.dom_h;
    m->pad_x0 = fx.pad_x0;
    m->pad_y0 = fx.pad_y0;
    m->num_levels = fx.num_levels;
    memcpy(m->synth, fx.synth, sizeof m->synth);
    t->nlevels = fx.nlevels;
    memcpy(t->lvi, fx.lvi, sizeof t->lvi);
    memcpy(t->lvf, fx.lvf, sizeof t->lvf);
    t->ncoef = fx.ncoef;
    t->nocc = fx.nocc;
    return 1;
fail:
    fclose(f);
    free(t->coef);
    free(t->occ);
    memset(t, 0, sizeof *t);
    fp_warn("%s: ignoring the cached fogmap tables (%s); decomposing the fogmap again",
            c->path, why);
    return 0;
}

void fp_fogmap_cache_store(const fp_fogmap_cache_t *c, const fp_fogmap_t *m,
                           const fp_fog_tables_t *t)
{
    if (!c->path)
        return;
    fixed_t fx;
    memset(&fx, 0, sizeof fx);
    fx.degree = m->degree;
    fx.wrap = m->wrap;
    fx.levels = m->levels;
    fx.width = m->width;
    fx.height = m->height;
    fx.dom_w = m->dom_w;
    fx.dom_h = m->dom_h;
    fx.pad_x0 = m->pad_x0;
    fx.pad_y0 = m->pad_y0;
    fx.num_levels = m->num_levels;
    fx.nlevels = t->nlevels;
    fx.ncoef = t->ncoef;
    fx.nocc = t->nocc;
    memcpy(fx.synth, m->synth, sizeof fx.synth);
    memcpy(fx.lvi, t->lvi, sizeof fx.lvi);
    memcpy(fx.lvf, t->lvf, sizeof fx.lvf);
    unsigned char head[FP_FMC_HEADER];
    uint64_t size = sizeof fx + fx.ncoef * sizeof(float) + fx.nocc;
    memcpy(head, FP_FMC_MAGIC, 8);
    memcpy(head + 8, c->key, 32);
    memcpy(head + 40, &size, 8);
    checksum(&fx, t->coef, t->occ, head + 48);
    char *tmp = xprintf("%s.XXXXXX", c->path);
    if (!tmp) {
        fp_warn("%s: out of memory; fogmap not cached", c->path);
        return;
    }
    int fd = mkstemp(tmp);
    FILE *f = fd >= 0 ? fdopen(fd, "wb") : NULL;
    int ok = f && fwrite(head, sizeof head, 1, f) == 1 && fwrite(&fx, sizeof fx, 1, f) == 1 &&
             fwrite(t->coef, sizeof(float), fx.ncoef, f) == fx.ncoef &&
             fwrite(t->occ, 1, fx.nocc, f) == fx.nocc;
    int err = errno;
    if (f) {
        ok = fclose(f) == 0 && ok;
        err = ok ? 0 : errno ? errno : err;
    } else if (fd >= 0) {
        close(fd);
    }
    /* mkstemp makes 0600; the cache may be shared by a farm's users. */
    if (ok && (chmod(tmp, 0644) != 0 || rename(tmp, c->path) != 0)) {
        ok = 0;
        err = errno;
    }
    if (!ok) {
        if (fd >= 0)
            unlink(tmp);
        fp_warn("%s: cannot write the fogmap cache (%s); fogmap not cached", c->path,
                strerror(err ? err : EIO));
    } else {
        fp_info("fogmap tables cached in %s (%.0f MB)", c->path,
                (FP_FMC_HEADER + (double)size) / 1e6);
    }
    free(tmp);
}
