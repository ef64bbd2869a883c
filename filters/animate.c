#include "animate.h"
#include "fogmap_image.h"
#include "fp.h"
#include "oiio_bridge.h"
#include "options.h"
#include "seq.h"
#include "textfile.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "../kernels/fog_core.h"

#define AN(f) offsetof(fp_params_t, anim.f)
const fp_option_t fp_animate_options[] = {
    { "fps", 0, FP_OPT_REAL, AN(fps), 0, 0, "24", 1e-3, 1e6, NULL, "FPS",
      "frames per second: a frame's time is t = frame / FPS seconds", NULL, 0 },
    { "wind", 0, FP_OPT_VEC, AN(wind), 3, 2, "0,0,0", -1e6, 1e6, NULL, "VX,VZ[,DEG]",
      "wind: the fog drifts by (VX,VZ) t scene units (the --fog-rect axes: X,Z with --up y, X,Y "
      "with --up z) and turns by DEG t degrees about the vertical through its moving offset",
      NULL, 0 },
    { "fogmap-interp", 0, FP_OPT_ENUM, AN(interp), 0, 0, "linear", 0, 0, "hold|linear|smooth",
      NULL, "a fogmap sequence (--fogmap fog.####.png; its keys are the frames on disk) between "
      "keys: the previous key held, or the two keys' wavelet coefficients blended linearly or "
      "with smoothstep weights", NULL, 0 },
    { "turbulence", 0, FP_OPT_REAL, AN(turbulence), 0, 0, "0", 0, 100, NULL, "AMOUNT",
      "detail noise per wavelet level, AMOUNT times the fogmap's mean at the coarsest detail "
      "level and 2^(-5/6) of it per finer level (Kolmogorov); the density is clamped at 0",
      NULL, 0 },
    { "turbulence-speed", 0, FP_OPT_REAL, AN(turbulence_speed), 0, 0, "1", 0, 1e4, NULL, "RATE",
      "noise steps per second at the coarsest detail level, 2^(2/3) times more per finer level",
      NULL, 0 },
    { "seed", 0, FP_OPT_INT, AN(seed), 0, 0, "0", 0, 2147483647, NULL, "N",
      "seed of the turbulence noise and of the Monte Carlo reference (--integrator reference)",
      NULL, 0 },
    { "advect", 0, FP_OPT_ENUM, AN(advect), 0, 0, "off", 0, 0, "off|semi-lagrangian|maccormack",
      NULL, "carry the fogmap through its rectangle by the wind, one step per frame from "
      "--advect-start (instead of moving the rectangle); bilinear, boundary per --fog-wrap",
      NULL, 0 },
    { "advect-start", 0, FP_OPT_INT, AN(advect_start), 0, 0, "1", -1e9, 1e9, NULL, "FRAME",
      "frame at which the advected fogmap is the fogmap itself (earlier frames too)", NULL, 0 },
    { "cache-dir", 0, FP_OPT_STRING, AN(cache_dir), 0, 0, NULL, 0, 0, NULL, "DIR",
      "keep every 8th advection state in DIR (keyed by the inputs), so that a run starting late "
      "resumes from the nearest one instead of recomputing from --advect-start", NULL, 0 },
    FP_OPT_END
};

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

/* ------------------------------------------------------------ options */

static int is_sequence(const fp_params_t *p)
{
    return p->fogmap.fogmap && fp_seq_has_placeholder(p->fogmap.fogmap) == 1;
}

int fp_animate_check(const fp_params_t *p)
{
    const fp_animate_params_t *a = &p->anim;
    if (!p->fogmap.fogmap) {
        if (a->turbulence > 0)
            return fp_usage_error("--turbulence needs --fogmap FILE");
        if (a->advect != FP_ADVECT_OFF)
            return fp_usage_error("--advect needs --fogmap FILE");
        return FP_OK;
    }
    if (a->advect != FP_ADVECT_OFF && is_sequence(p))
        return fp_usage_error("--advect needs a still --fogmap (%s is a sequence, which animates "
                              "the fog already)", p->fogmap.fogmap);
    if (a->advect != FP_ADVECT_OFF && a->wind[0] == 0 && a->wind[1] == 0)
        fp_warn("--advect without --wind: the fogmap stays where it is");
    return FP_OK;
}

int fp_animate_fogmap_animated(const fp_params_t *p)
{
    return p->fogmap.fogmap && (is_sequence(p) || p->anim.turbulence > 0 ||
                                p->anim.advect != FP_ADVECT_OFF);
}

double fp_animate_time(const fp_params_t *p, long frame)
{
    return (double)frame / p->anim.fps;
}

void fp_animate_wind(const fp_params_t *p, double w[3])
{
    /* Fog space is world space with up along y; with --up z, fog z is
     * -world y (src/scene/camera.c fp_world_to_fog). */
    w[0] = p->anim.wind[0];
    w[1] = 0;
    w[2] = p->camera.up == FP_UP_Z ? -p->anim.wind[1] : p->anim.wind[1];
}

void fp_animate_transform(const fp_params_t *p, long frame, fp_integrate_data_t *d)
{
    const double *wind = p->anim.wind;
    if (wind[0] == 0 && wind[1] == 0 && wind[2] == 0)
        return;
    double t = fp_animate_time(p, frame), w[3], off[3];
    fp_animate_wind(p, w);
    fp_integrate_fog_offset(p, off);
    if (p->anim.advect == FP_ADVECT_OFF)
        for (int i = 0; i < 3; i++)
            d->fp[FP_F_OFF + i] = off[i] + w[i] * t;
    /* fog-local = R(t)^T (p - offset(t)): the same angle convention as
     * fp_integrate_commit, reduced mod 360 so that long sequences keep
     * their precision. */
    double deg = wind[2] != 0 ? fmod(p->fog.rotate + wind[2] * t, 360.0) : p->fog.rotate;
    d->fp[FP_F_COS] = cos(deg * M_PI / 180);
    d->fp[FP_F_SIN] = sin(deg * M_PI / 180);
}

/* ------------------------------------------------------------ advection */

static float fetch(const float *s, int w, int h, int wrap, int i, int j)
{
    if (wrap == FP_WRAP_REPEAT) {
        i = ((i % w) + w) % w;
        j = ((j % h) + h) % h;
    } else if (wrap == FP_WRAP_CLAMP) {
        i = i < 0 ? 0 : i >= w ? w - 1 : i;
        j = j < 0 ? 0 : j >= h ? h - 1 : j;
    } else if (i < 0 || j < 0 || i >= w || j >= h) {
        return 0;
    }
    return s[(size_t)j * w + i];
}

/* Bilinear sample between pixel centers at index-space (x, y); the four
 * samples' range in *lo, *hi. */
static double sample(const float *s, int w, int h, int wrap, double x, double y, float *lo,
                     float *hi)
{
    double fx = floor(x), fy = floor(y), ax = x - fx, ay = y - fy;
    int i0 = (int)fx, j0 = (int)fy;
    float p00 = fetch(s, w, h, wrap, i0, j0), p10 = fetch(s, w, h, wrap, i0 + 1, j0);
    float p01 = fetch(s, w, h, wrap, i0, j0 + 1), p11 = fetch(s, w, h, wrap, i0 + 1, j0 + 1);
    if (lo) {
        *lo = fminf(fminf(p00, p10), fminf(p01, p11));
        *hi = fmaxf(fmaxf(p00, p10), fmaxf(p01, p11));
    }
    return (1 - ay) * ((1 - ax) * p00 + ax * p10) + ay * ((1 - ax) * p01 + ax * p11);
}

/* Semi-Lagrangian: the value at a pixel center is the one found a step
 * upwind (Stam 1999). */
static void advect_sl(const float *src, int w, int h, int wrap, double du, double dv,
                      float *dst)
{
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            dst[(size_t)j * w + i] = (float)sample(src, w, h, wrap, i - du, j - dv, NULL, NULL);
}

void fp_advect_step(const float *src, int w, int h, int wrap, int mode, double du, double dv,
                    float *dst, float *tmp)
{
    if (mode != FP_ADVECT_MACCORMACK) {
        advect_sl(src, w, h, wrap, du, dv, dst);
        return;
    }
    /* MacCormack (Selle et al. 2008): forward, backward, half the round
     * trip's error added back, clamped to the forward samples' range
     * (unconditionally stable, no new extrema, so >= 0 stays >= 0). */
    size_t n = (size_t)w * h;
    float *fwd = tmp, *back = tmp + n;
    advect_sl(src, w, h, wrap, du, dv, fwd);
    advect_sl(fwd, w, h, wrap, -du, -dv, back);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            size_t at = (size_t)j * w + i;
            float lo, hi;
            sample(src, w, h, wrap, i - du, j - dv, &lo, &hi);
            double v = fwd[at] + 0.5 * ((double)src[at] - back[at]);
            dst[at] = (float)(v < lo ? lo : v > hi ? hi : v);
        }
}

/* ------------------------------------------------------------ turbulence */

static uint64_t mix64(uint64_t z)
{
    /* splitmix64's finalizer. */
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/* Independent uniform value in [-1, 1) per (seed, level, i, j, step). */
static double noise_value(unsigned seed, int l, int i, int j, long k)
{
    uint64_t h = mix64((uint64_t)k);
    h = mix64(h ^ ((uint64_t)(uint32_t)i | (uint64_t)(uint32_t)j << 32));
    h = mix64(h ^ ((uint64_t)seed << 8 | (uint64_t)(unsigned)l));
    return (double)(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

/* Periodic refinement of a level's coefficients to the next finer grid:
 * phi_i = sum_k synth[0].tap[k - lo] f_{2i+k} (filters/wavelet.h), so the
 * surface is unchanged. */
static void refine(const fp_wavelet_filter_t *f, const double *c, int cx, int cy, double *tmp,
                   double *out)
{
    int nx = 2 * cx, ny = 2 * cy;
    memset(tmp, 0, (size_t)nx * cy * sizeof *tmp);
    memset(out, 0, (size_t)nx * ny * sizeof *out);
    for (int j = 0; j < cy; j++)
        for (int i = 0; i < cx; i++) {
            double v = c[(size_t)j * cx + i];
            for (int k = f->lo; k <= f->hi; k++)
                tmp[(size_t)j * nx + (((2 * i + k) % nx) + nx) % nx] += f->tap[k - f->lo] * v;
        }
    for (int j = 0; j < cy; j++)
        for (int k = f->lo; k <= f->hi; k++) {
            double *row = out + (size_t)((((2 * j + k) % ny) + ny) % ny) * nx;
            const double *src = tmp + (size_t)j * nx;
            double tap = f->tap[k - f->lo];
            for (int i = 0; i < nx; i++)
                row[i] += tap * src[i];
        }
}

int fp_turbulence_field(const fp_fogmap_t *g, unsigned seed, double speed, double t,
                        unsigned level_mask, double *out)
{
    size_t n = (size_t)g->dom_w * g->dom_h;
    memset(out, 0, n * sizeof *out);
    int L = g->levels;
    if (L < 1)
        return FP_OK;
    double *acc = calloc(n, sizeof *acc), *tmp = calloc(n, sizeof *tmp);
    if (!acc || !tmp) {
        free(acc);
        free(tmp);
        return fp_error("turbulence: out of memory");
    }
    int cx = 0, cy = 0;
    for (int l = 1; l <= L; l++) {
        int nx = g->dom_w >> (L - l), ny = g->dom_h >> (L - l);
        if (l > 1) {
            refine(&g->synth[0], acc, cx, cy, tmp, out);
            memcpy(acc, out, (size_t)nx * ny * sizeof *acc);
        }
        cx = nx;
        cy = ny;
        if (!(level_mask & (1u << l)))
            continue;
        /* Kim et al. 2008: amplitude 2^(-5/6) per octave; eddies turn
         * over in ~ k^(-2/3), so finer levels change faster. */
        double amp = pow(2.0, -5.0 / 6.0 * (l - 1));
        double tau = t * speed * pow(2.0, 2.0 / 3.0 * (l - 1));
        double fl = floor(tau), f = tau - fl, f2 = f * f, f3 = f2 * f;
        long k0 = (long)fl;
        /* Uniform cubic B-spline in time: C2, no pauses at the steps. */
        double wt[4] = { (1 - f) * (1 - f) * (1 - f) / 6, (3 * f3 - 6 * f2 + 4) / 6,
                         (-3 * f3 + 3 * f2 + 3 * f + 1) / 6, f3 / 6 };
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                double v = 0;
                for (int m = 0; m < 4; m++)
                    v += wt[m] * noise_value(seed, l, i, j, k0 - 1 + m);
                acc[(size_t)j * nx + i] += amp * v;
            }
    }
    memcpy(out, acc, n * sizeof *out);
    free(acc);
    free(tmp);
    return FP_OK;
}

/* ------------------------------------------------------------ state */

#define KEY_SLOTS 4

typedef struct key_slot_t {
    long frame;
    int loaded, decomposed;
    unsigned long used;
    float *img;
    fp_fogmap_t map;
} key_slot_t;

typedef struct frame_sig_t {
    long k0, k1, steps;
    double w, tau;
} frame_sig_t;

struct fp_animate_t {
    char *pattern, *channel;
    int w, h, degree, levels, wrap;
    double od_scale;           /* fp_fogmap_od_scale: checks the keys' values */
    float *base;
    fp_fogmap_t geom;          /* geometry and filters only (no coefficients) */
    double *field;             /* turbulence, dom_w x dom_h */
    /* sequence */
    int is_seq, interp;
    fp_frame_list_t keys;
    key_slot_t slot[KEY_SLOTS];
    unsigned long clock;
    /* turbulence */
    double turbulence, speed, fps;
    unsigned seed;
    /* advection */
    int advect;
    long start;
    double du, dv;
    char *cache_dir;
    char key[33];
    float *state, *next, *tmp;
    long state_frame;
    int have_state;
    /* output */
    fp_fogmap_t own;
    int own_like;              /* own's arrays are allocated like geom (for blending) */
    float *own_img;
    float *work;
    int have_last;
    frame_sig_t last;
    const fp_fogmap_t *last_map;
    const float *last_img;
    int cl_failed;
};

/* Arrays of the same shape as g's, zeroed. */
static int map_like(const fp_fogmap_t *g, fp_fogmap_t *out)
{
    *out = *g;
    for (int l = 0; l <= FP_MAX_LEVELS; l++) {
        out->level[l].coef = NULL;
        for (int b = 0; b < 3; b++)
            out->band[l][b].coef = NULL;
    }
    for (int l = 0; l <= g->levels; l++)
        for (int b = 0; b < (l ? 4 : 1); b++) {
            fp_fog_level_t *lv = b ? &out->band[l][b - 1] : &out->level[l];
            lv->coef = calloc((size_t)lv->nx * lv->ny, sizeof(float));
            if (!lv->coef) {
                fp_fogmap_free(out);
                return fp_error("fogmap: out of memory");
            }
        }
    return FP_OK;
}

/* Seed 000's decomposition is linear, so blending the keys' coefficients
 * is decomposing the blended fogmap (within float rounding); w = 0 gives
 * the first key exactly. */
static void map_blend(const fp_fogmap_t *a, const fp_fogmap_t *b, double w, fp_fogmap_t *out)
{
    for (int l = 0; l <= a->levels; l++)
        for (int k = 0; k < (l ? 4 : 1); k++) {
            const fp_fog_level_t *la = k ? &a->band[l][k - 1] : &a->level[l];
            const fp_fog_level_t *lb = k ? &b->band[l][k - 1] : &b->level[l];
            fp_fog_level_t *lo = k ? &out->band[l][k - 1] : &out->level[l];
            float amax = 0;
            for (size_t i = 0, n = (size_t)la->nx * la->ny; i < n; i++) {
                float v = (float)((1 - w) * la->coef[i] + w * lb->coef[i]);
                lo->coef[i] = v;
                amax = fabsf(v) > amax ? fabsf(v) : amax;
            }
            lo->amax = amax;
        }
}

static void img_blend(const float *a, const float *b, double w, size_t n, float *out)
{
    for (size_t i = 0; i < n; i++)
        out[i] = (float)((1 - w) * a[i] + w * b[i]);
}

static int decompose(fp_animate_t *a, fp_cl_t *cl, const float *img, fp_fogmap_t *out,
                     fp_animate_frame_t *fr)
{
    double t0 = now_ms();
    int rc = FP_ERR;
    fp_fogmap_free(out);
    if (cl && !a->cl_failed) {
        rc = fp_wavelet_decompose_cl(cl, img, a->w, a->h, a->degree, a->levels, a->wrap, out);
        if (rc) {
            a->cl_failed = 1;
            fp_warn("%s: OpenCL decomposition failed; using the C reference from now on",
                    a->pattern);
        }
        fr->used_cl = rc == FP_OK;
    }
    if (rc)
        rc = fp_wavelet_decompose(img, a->w, a->h, a->degree, a->levels, a->wrap, out);
    fr->decompose_ms += now_ms() - t0;
    fr->decompositions++;
    return rc;
}

/* A key of the sequence, loaded (and decomposed when `need_map`), from the
 * little cache of recent keys; `keep` is a slot not to evict. */
static int get_key(fp_animate_t *a, fp_cl_t *cl, long at, long frame, int need_map,
                   const key_slot_t *keep, key_slot_t **out, fp_animate_frame_t *fr)
{
    key_slot_t *s = NULL;
    for (int i = 0; i < KEY_SLOTS && !s; i++)
        if (a->slot[i].loaded && a->slot[i].frame == frame)
            s = &a->slot[i];
    if (!s) {
        /* An empty slot, else the least recently used one. */
        for (int i = 0; i < KEY_SLOTS; i++) {
            key_slot_t *c = &a->slot[i];
            if (c == keep)
                continue;
            if (!c->loaded) {
                s = c;
                break;
            }
            if (!s || c->used < s->used)
                s = c;
        }
        free(s->img);
        fp_fogmap_free(&s->map);
        memset(s, 0, sizeof *s);
        char path[4096];
        int w, h, rc;
        if ((rc = fp_seq_format(a->pattern, frame, path, sizeof path)) ||
            (rc = fp_image_file_check(path, "fogmap")) ||
            (rc = fp_oiio_read_channel(path, a->channel, &s->img, &w, &h)))
            return rc;
        if (w != a->w || h != a->h) {
            free(s->img);
            s->img = NULL;
            return fp_error("%s: frame %ld: fogmap key %ld is %dx%d, but the sequence's first "
                            "key is %dx%d (the keys of a fogmap sequence must have one size)",
                            path, at, frame, w, h, a->w, a->h);
        }
        fp_fogmap_clamp_negative(path, s->img, w, h);
        if ((rc = fp_fogmap_check_values(path, s->img, w, h, a->od_scale))) {
            free(s->img);
            s->img = NULL;
            return rc;
        }
        s->frame = frame;
        s->loaded = 1;
        fp_info("%s: key %ld loaded", path, frame);
    }
    s->used = ++a->clock;
    if (need_map && !s->decomposed) {
        int rc = decompose(a, cl, s->img, &s->map, fr);
        if (rc)
            return rc;
        s->decomposed = 1;
    }
    *out = s;
    return FP_OK;
}

/* ---- advection states and their cache ---- */

static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ull;
    }
    return h;
}

/* The cache key: everything the states depend on. */
static void advect_key(fp_animate_t *a)
{
    uint64_t h[2] = { 0xcbf29ce484222325ull, 0x84222325cbf29ce4ull };
    for (int k = 0; k < 2; k++) {
        const char tag[] = "fogpipe advect v1";
        int ints[4] = { a->w, a->h, a->wrap, a->advect };
        h[k] = fnv1a(h[k], tag, sizeof tag);
        h[k] = fnv1a(h[k], ints, sizeof ints);
        h[k] = fnv1a(h[k], &a->start, sizeof a->start);
        h[k] = fnv1a(h[k], &a->du, sizeof a->du);
        h[k] = fnv1a(h[k], &a->dv, sizeof a->dv);
        h[k] = fnv1a(h[k], a->base, (size_t)a->w * a->h * sizeof(float));
        h[k] = mix64(h[k] + (uint64_t)k);
    }
    snprintf(a->key, sizeof a->key, "%016llx%016llx", (unsigned long long)h[0],
             (unsigned long long)h[1]);
}

#define STATE_MAGIC "FPADVST1"

static void state_path(const fp_animate_t *a, long frame, char *buf, size_t n)
{
    snprintf(buf, n, "%s/advect-%s-%ld.state", a->cache_dir, a->key, frame);
}

/* Header (magic, key, frame, size), the pixels, their FNV-1a: a truncated
 * or foreign file is ignored. */
static int state_load(fp_animate_t *a, long frame, float *dst)
{
    char path[4200], magic[8], key[32];
    state_path(a, frame, path, sizeof path);
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    int64_t fr;
    int32_t wh[2];
    uint64_t sum;
    size_t n = (size_t)a->w * a->h;
    int ok = fread(magic, 1, 8, f) == 8 && memcmp(magic, STATE_MAGIC, 8) == 0 &&
             fread(key, 1, 32, f) == 32 && memcmp(key, a->key, 32) == 0 &&
             fread(&fr, sizeof fr, 1, f) == 1 && fr == frame &&
             fread(wh, sizeof wh, 1, f) == 1 && wh[0] == a->w && wh[1] == a->h &&
             fread(dst, sizeof(float), n, f) == n && fread(&sum, sizeof sum, 1, f) == 1 &&
             fgetc(f) == EOF && sum == fnv1a(0xcbf29ce484222325ull, dst, n * sizeof(float));
    fclose(f);
    if (ok)
        fp_info("%s: advection state of frame %ld read from the cache", path, frame);
    else if (unlink(path) == 0)   /* damaged (whole files only ever appear): rewrite it */
        fp_warn("%s: damaged advection state removed", path);
    return ok;
}

/* Written under a temporary name and renamed, so concurrent runs (a farm
 * sharing the directory) only ever see whole files. */
static void state_save(fp_animate_t *a, long frame, const float *src)
{
    char path[4200], tmp[4300];
    state_path(a, frame, path, sizeof path);
    if (access(path, F_OK) == 0)
        return;
    snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        fp_warn("%s: cannot write an advection state (%s)", tmp, strerror(errno));
        return;
    }
    int64_t fr = frame;
    int32_t wh[2] = { a->w, a->h };
    size_t n = (size_t)a->w * a->h;
    uint64_t sum = fnv1a(0xcbf29ce484222325ull, src, n * sizeof(float));
    int ok = fwrite(STATE_MAGIC, 1, 8, f) == 8 && fwrite(a->key, 1, 32, f) == 32 &&
             fwrite(&fr, sizeof fr, 1, f) == 1 && fwrite(wh, sizeof wh, 1, f) == 1 &&
             fwrite(src, sizeof(float), n, f) == n && fwrite(&sum, sizeof sum, 1, f) == 1;
    ok = fclose(f) == 0 && ok;
    if (!ok || rename(tmp, path) != 0) {
        fp_warn("%s: cannot write an advection state (%s)", path, strerror(errno));
        unlink(tmp);
    }
}

/* The advected fogmap at `frame`: frame - start steps from the fogmap,
 * continuing from the state in memory or the latest cached one when they
 * are on the way, else from the start. */
static void advect_to(fp_animate_t *a, long frame)
{
    long n = frame < a->start ? a->start : frame;
    size_t px = (size_t)a->w * a->h;
    if (!a->have_state || a->state_frame > n) {
        memcpy(a->state, a->base, px * sizeof(float));
        a->state_frame = a->start;
        a->have_state = 1;
    }
    if (a->cache_dir) {
        long kmin = (a->state_frame - a->start) / FP_ADVECT_CHECKPOINT;
        for (long k = (n - a->start) / FP_ADVECT_CHECKPOINT; k > kmin; k--)
            if (state_load(a, a->start + k * FP_ADVECT_CHECKPOINT, a->next)) {
                float *t = a->state;
                a->state = a->next;
                a->next = t;
                a->state_frame = a->start + k * FP_ADVECT_CHECKPOINT;
                break;
            }
    }
    while (a->state_frame < n) {
        fp_advect_step(a->state, a->w, a->h, a->wrap, a->advect, a->du, a->dv, a->next, a->tmp);
        float *t = a->state;
        a->state = a->next;
        a->next = t;
        a->state_frame++;
        if (a->cache_dir && (a->state_frame - a->start) % FP_ADVECT_CHECKPOINT == 0)
            state_save(a, a->state_frame, a->state);
    }
}

/* ------------------------------------------------------------ open */

int fp_animate_open(const fp_params_t *p, const float *base, int w, int h,
                    const fp_fogmap_t *geom, double uscale, double vscale,
                    fp_animate_t **out)
{
    const fp_animate_params_t *ap = &p->anim;
    size_t n = (size_t)w * h;
    int rc = FP_OK;
    *out = NULL;
    fp_animate_t *a = calloc(1, sizeof *a);
    if (!a)
        return fp_error("fogmap: out of memory");
    a->pattern = strdup(p->fogmap.fogmap);
    a->channel = p->fogmap.channel ? strdup(p->fogmap.channel) : NULL;
    a->base = malloc(n * sizeof(float));
    a->work = malloc(n * sizeof(float));
    a->own_img = malloc(n * sizeof(float));
    if (!a->pattern || (p->fogmap.channel && !a->channel) || !a->base || !a->work ||
        !a->own_img) {
        rc = fp_error("fogmap: out of memory");
        goto done;
    }
    memcpy(a->base, base, n * sizeof(float));
    a->w = w;
    a->h = h;
    a->degree = p->fogmap.basis;
    a->levels = p->fogmap.levels;
    a->wrap = p->fogmap.wrap;
    a->geom = *geom;
    for (int l = 0; l <= FP_MAX_LEVELS; l++) {
        a->geom.level[l].coef = NULL;
        for (int b = 0; b < 3; b++)
            a->geom.band[l][b].coef = NULL;
    }
    a->fps = ap->fps;
    a->interp = ap->interp;
    a->turbulence = ap->turbulence;
    a->speed = ap->turbulence_speed;
    a->od_scale = fp_fogmap_od_scale(p, w, h);
    a->seed = (unsigned)ap->seed;
    a->advect = ap->advect;
    a->start = ap->advect_start;
    a->is_seq = is_sequence(p);
    if (a->is_seq && (rc = fp_frames_scan(a->pattern, &a->keys)))
        goto done;
    if (a->turbulence > 0) {
        if (geom->levels < 1)
            fp_warn("--turbulence: the fogmap has no detail levels (--levels 0): no turbulence");
        a->field = malloc((size_t)geom->dom_w * geom->dom_h * sizeof *a->field);
        if (!a->field) {
            rc = fp_error("fogmap: out of memory");
            goto done;
        }
    }
    if (a->advect != FP_ADVECT_OFF) {
        /* The wind in the fogmap's pixels per frame: fog space, turned into
         * the fog's frame by --fog-rotate (fog-local = R^T p), scaled. */
        double wv[3], c = cos(p->fog.rotate * M_PI / 180), s = sin(p->fog.rotate * M_PI / 180);
        fp_animate_wind(p, wv);
        a->du = (c * wv[0] - s * wv[2]) * uscale / a->fps;
        a->dv = (s * wv[0] + c * wv[2]) * vscale / a->fps;
        a->state = malloc(n * sizeof(float));
        a->next = malloc(n * sizeof(float));
        a->tmp = malloc(2 * n * sizeof(float));
        if (!a->state || !a->next || !a->tmp) {
            rc = fp_error("fogmap: out of memory");
            goto done;
        }
        if (ap->cache_dir) {
            if (mkdir(ap->cache_dir, 0777) != 0 && errno != EEXIST)
                fp_warn("--cache-dir %s: cannot create it (%s); advection states are not "
                        "cached", ap->cache_dir, strerror(errno));
            else if (!(a->cache_dir = strdup(ap->cache_dir)))
                rc = fp_error("fogmap: out of memory");
            advect_key(a);
        }
        fp_info("advection: %.4g, %.4g fogmap pixels per frame from frame %ld", a->du, a->dv,
                a->start);
    }
done:
    if (rc)
        fp_animate_close(a);
    else
        *out = a;
    return rc;
}

void fp_animate_close(fp_animate_t *a)
{
    if (!a)
        return;
    for (int i = 0; i < KEY_SLOTS; i++) {
        free(a->slot[i].img);
        fp_fogmap_free(&a->slot[i].map);
    }
    fp_frames_free(&a->keys);
    fp_fogmap_free(&a->own);
    free(a->pattern);
    free(a->channel);
    free(a->base);
    free(a->work);
    free(a->own_img);
    free(a->field);
    free(a->state);
    free(a->next);
    free(a->tmp);
    free(a->cache_dir);
    free(a);
}

/* ------------------------------------------------------------ per frame */

int fp_animate_fogmap(fp_animate_t *a, fp_cl_t *cl, long frame, fp_animate_frame_t *out)
{
    memset(out, 0, sizeof *out);
    frame_sig_t sig;
    memset(&sig, 0, sizeof sig);
    if (a->is_seq) {
        /* The keys around the frame; before the first and after the last
         * key, that key is held. */
        const long *k = a->keys.frames;
        size_t nk = a->keys.count, i = 0;
        while (i + 1 < nk && k[i + 1] <= frame)
            i++;
        sig.k0 = sig.k1 = k[i];
        if (frame > k[i] && i + 1 < nk && a->interp != FP_INTERP_HOLD) {
            sig.k1 = k[i + 1];
            double w = (double)(frame - k[i]) / (double)(k[i + 1] - k[i]);
            sig.w = a->interp == FP_INTERP_SMOOTH ? w * w * (3 - 2 * w) : w;
        }
    }
    if (a->advect != FP_ADVECT_OFF)
        sig.steps = frame > a->start ? frame - a->start : 0;
    if (a->turbulence > 0)
        sig.tau = (double)frame / a->fps * a->speed;
    if (a->have_last && memcmp(&sig, &a->last, sizeof sig) == 0) {
        out->map = a->last_map;
        out->img = a->last_img;
        return FP_OK;
    }
    a->have_last = 0;
    int rc = FP_OK;
    size_t n = (size_t)a->w * a->h;
    const fp_fogmap_t *map = NULL;
    const float *src = a->base;
    key_slot_t *k0 = NULL, *k1 = NULL;
    int need_maps = a->turbulence <= 0;
    if (a->is_seq) {
        if ((rc = get_key(a, cl, frame, sig.k0, need_maps, NULL, &k0, out)))
            return rc;
        if (sig.w > 0 && (rc = get_key(a, cl, frame, sig.k1, need_maps, k0, &k1, out)))
            return rc;
        if (sig.w > 0) {
            img_blend(k0->img, k1->img, sig.w, n, a->work);
            src = a->work;
        } else {
            src = k0->img;
        }
    } else if (a->advect != FP_ADVECT_OFF) {
        advect_to(a, frame);
        src = a->state;
    }
    if (a->turbulence > 0) {
        /* Noise added to the fogmap's pixels (the fine B-spline
         * coefficients) and clamped at 0 there: B-splines are >= 0, so the
         * surface, hence the density, stays >= 0 everywhere. */
        double mean = 0;
        for (size_t i = 0; i < n; i++)
            mean += src[i];
        mean /= (double)n;
        double amp = a->turbulence * mean;
        if ((rc = fp_turbulence_field(&a->geom, a->seed, a->speed,
                                      (double)frame / a->fps, ~0u, a->field)))
            return rc;
        const fp_fogmap_t *g = &a->geom;
        for (int j = 0; j < a->h; j++)
            for (int i = 0; i < a->w; i++) {
                size_t at = (size_t)j * a->w + i;
                double v = src[at] + amp * a->field[(size_t)(j + g->pad_y0) * g->dom_w +
                                                     i + g->pad_x0];
                a->own_img[at] = v > 0 ? (float)v : 0.0f;
            }
        src = a->own_img;
        a->own_like = 0;
        if ((rc = decompose(a, cl, src, &a->own, out)))
            return rc;
        map = &a->own;
    } else if (a->is_seq && sig.w > 0) {
        if (!a->own_like) {
            fp_fogmap_free(&a->own);
            if ((rc = map_like(&k0->map, &a->own)))
                return rc;
            a->own_like = 1;
        }
        map_blend(&k0->map, &k1->map, sig.w, &a->own);
        map = &a->own;
    } else if (a->is_seq) {
        map = &k0->map;
    } else {
        a->own_like = 0;
        if ((rc = decompose(a, cl, src, &a->own, out)))
            return rc;
        map = &a->own;
    }
    out->map = map;
    out->img = src;
    out->changed = 1;
    a->last = sig;
    a->last_map = map;
    a->last_img = src;
    a->have_last = 1;
    return FP_OK;
}
