/* fogpipe stage "deep", one frame: the deep image of a flat plate (the
 * fog's samples in front of the surface's) or of a deep input (the fog
 * and the input's samples made tidy together), rows shared among threads.
 * See deep_frame.h. */
#include "deep_frame.h"
#include "fp.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* One output sample as stored until the image is made. */
typedef struct osample_t {
    float v[6];   /* R G B A Z ZBack, output space */
    long src;     /* FP_DEEP_SRC_*, or the input sample */
} osample_t;

typedef struct row_t {
    uint32_t *counts;
    osample_t *s;
    size_t n, cap;
} row_t;

typedef struct job_t {
    const fp_deep_fog_t *f;
    const fp_color_frame_t *color;
    const float *work;          /* flat plate: RGBA in the working space */
    const float *depth;
    const fp_deep_image_t *din;
    int w, h;
    row_t *rows;
    atomic_int next_row;
    pthread_mutex_t mu;
    fp_deep_stats_t st;
    int rc;
    char msg[512];              /* the first worker's bad-input message ("": memory) */
    const char *where;
    long frame;
} job_t;

static float role_value(const fp_deep_image_t *d, int role, uint64_t k, float dflt)
{
    if (d->role[role] < 0)
        return dflt;
    float v;
    memcpy(&v, &d->data[d->role[role]][k], 4);
    return v;
}

/* A deep input's pixel i as samples in the working space. */
static int input_pixel(job_t *j, size_t i, int x, int y, fp_dlist_t *l)
{
    const fp_deep_image_t *d = j->din;
    for (uint64_t k = d->offsets[i]; k < d->offsets[i + 1]; k++) {
        fp_dsample_t s;
        s.z = role_value(d, FP_DCH_Z, k, 0);
        s.zb = role_value(d, FP_DCH_ZBACK, k, (float)s.z);
        if (!(s.zb >= s.z))
            s.zb = s.z;
        /* a point at infinity is the sky (oiiotool --deepen writes one) */
        if (!(s.z >= 0) || (isinf(s.zb) && !isinf(s.z))) {
            /* kept for the calling thread, which holds the frame's messages */
            pthread_mutex_lock(&j->mu);
            if (!j->msg[0])
                snprintf(j->msg, sizeof j->msg, "%s: frame %ld: deep sample at pixel %d,%d has "
                         "depth %g..%g (expected Z >= 0, ZBack finite unless Z is infinite)",
                         j->where, j->frame, x + d->info.data_x0, y + d->info.data_y0, s.z,
                         s.zb);
            pthread_mutex_unlock(&j->mu);
            return FP_EUSAGE;
        }
        float rgba[4] = { role_value(d, FP_DCH_R, k, 0), role_value(d, FP_DCH_G, k, 0),
                          role_value(d, FP_DCH_B, k, 0), role_value(d, FP_DCH_A, k, 1) };
        fp_color_to_working(j->color, rgba, 1);
        for (int c = 0; c < 3; c++)
            s.c[c] = rgba[c];
        s.a = rgba[3] < 0 ? 0 : rgba[3] > 1 ? 1 : rgba[3];
        s.src = (long)k;
        if (fp_dlist_push(l, &s))
            return FP_ERR;
    }
    return fp_deep_tidy(l);
}

static int do_pixel(job_t *j, int x, int y, fp_dlist_t *l, fp_dlist_t *fog, double *forced,
                    size_t cap_forced, fp_deep_stats_t *st)
{
    const fp_deep_fog_t *f = j->f;
    const fp_view_t *v = f->view;
    size_t i = (size_t)y * j->w + x;
    int rc;
    l->n = fog->n = 0;
    if (j->din) {
        if ((rc = input_pixel(j, i, x, y, l)))
            return rc;
        /* the fog stops at the first opaque sample; without one the
         * pixel is sky (--sky keep: the fog goes as far as the samples) */
        double z_end = INFINITY;
        size_t nf = 0;
        for (size_t k = 0; k < l->n; k++) {
            if (l->s[k].a >= 1) {
                z_end = l->s[k].z;
                break;
            }
        }
        if (isinf(z_end) && f->deep->sky_keep)
            z_end = l->n ? l->s[l->n - 1].zb : 0;
        for (size_t k = 0; k < l->n && nf + 2 <= cap_forced; k++)
            if (l->s[k].z < z_end) {
                forced[nf++] = l->s[k].z;
                forced[nf++] = l->s[k].zb < z_end ? l->s[k].zb : z_end;
            }
        if (z_end > 0 && (rc = fp_deep_fog_pixel(f, x, y, z_end, forced, nf, fog, st)))
            return rc;
        st->fog_samples += (long)fog->n;
        for (size_t k = 0; k < fog->n; k++)
            if (fp_dlist_push(l, &fog->s[k]))
                return FP_ERR;
        return fp_deep_tidy(l);
    }
    int suspicious;
    float d = j->depth[i];
    int sky = fp_view_is_sky(v, d, &suspicious);
    double zs = v->depth_kind == FP_DEPTH_INVERSE ? 1.0 / d : d;
    if (!(sky && f->deep->sky_keep) &&
        (rc = fp_deep_fog_pixel(f, x, y, sky ? INFINITY : zs, NULL, 0, l, st)))
        return rc;
    st->fog_samples += (long)l->n;
    const float *p = j->work + 4 * i;
    fp_dsample_t s;
    for (int c = 0; c < 3; c++)
        s.c[c] = p[c];
    s.a = p[3];
    s.src = FP_DEEP_SRC_PLATE;
    if (sky) {
        /* the sky's own colour, behind the fog */
        if (s.a == 0 && s.c[0] == 0 && s.c[1] == 0 && s.c[2] == 0)
            return FP_OK;
        double z = isfinite(zs) && zs > 0 ? zs : 0;
        if (l->n && l->s[l->n - 1].zb > z)
            z = l->s[l->n - 1].zb;
        zs = z > 0 ? z : 1e10;
    }
    s.z = s.zb = zs;
    return fp_dlist_push(l, &s);
}

static void *worker(void *arg)
{
    job_t *j = arg;
    fp_dlist_t l = { NULL, 0, 0 }, fog = { NULL, 0, 0 };
    fp_deep_stats_t st;
    memset(&st, 0, sizeof st);
    size_t cap_forced = 0;
    double *forced = NULL;
    int rc = FP_OK;
    float *rgba = NULL;
    size_t rgba_cap = 0;
    for (;;) {
        int y = atomic_fetch_add(&j->next_row, 1);
        if (y >= j->h)
            break;
        pthread_mutex_lock(&j->mu);
        int stop = j->rc != FP_OK;
        pthread_mutex_unlock(&j->mu);
        if (stop)
            break;
        row_t *r = &j->rows[y];
        if (!(r->counts = calloc((size_t)j->w, sizeof *r->counts))) {
            rc = FP_ERR;
            break;
        }
        for (int x = 0; x < j->w && rc == FP_OK; x++) {
            if (j->din) {
                size_t i = (size_t)y * j->w + x;
                size_t need = 2 * (size_t)j->din->counts[i] + 2;
                if (need > cap_forced) {
                    free(forced);
                    forced = malloc(need * sizeof *forced);
                    cap_forced = forced ? need : 0;
                    if (!forced) {
                        rc = FP_ERR;
                        break;
                    }
                }
            }
            if ((rc = do_pixel(j, x, y, &l, &fog, forced, cap_forced, &st)))
                break;
            if (r->n + l.n > r->cap) {
                size_t cap = (r->cap + l.n) * 2 + 16;
                osample_t *ns = realloc(r->s, cap * sizeof *ns);
                if (!ns) {
                    rc = FP_ERR;
                    break;
                }
                r->s = ns;
                r->cap = cap;
            }
            if (l.n > rgba_cap) {
                free(rgba);
                rgba_cap = l.n * 2;
                if (!(rgba = malloc(rgba_cap * 4 * sizeof *rgba))) {
                    rgba_cap = 0;
                    rc = FP_ERR;
                    break;
                }
            }
            for (size_t k = 0; k < l.n; k++) {
                for (int c = 0; c < 3; c++)
                    rgba[4 * k + c] = (float)l.s[k].c[c];
                rgba[4 * k + 3] = (float)l.s[k].a;
            }
            fp_color_to_output(j->color, rgba, l.n);
            for (size_t k = 0; k < l.n; k++) {
                osample_t *o = &r->s[r->n++];
                memcpy(o->v, rgba + 4 * k, 4 * sizeof(float));
                o->v[4] = (float)l.s[k].z;
                o->v[5] = (float)l.s[k].zb;
                o->src = l.s[k].src;
            }
            r->counts[x] = (uint32_t)l.n;
            st.samples += (long)l.n;
        }
        if (rc)
            break;
    }
    pthread_mutex_lock(&j->mu);
    if (rc && j->rc == FP_OK)
        j->rc = rc;
    j->st.evals += st.evals;
    j->st.capped += st.capped;
    j->st.samples += st.samples;
    j->st.fog_samples += st.fog_samples;
    pthread_mutex_unlock(&j->mu);
    free(forced);
    free(rgba);
    fp_dlist_free(&l);
    fp_dlist_free(&fog);
    return NULL;
}

/* The output's channels: R G B A Z ZBack and the input's others. */
static int out_channels(const fp_deep_image_t *din, const fp_deep_pass_t *pass, int npass,
                        int use_float, fp_deep_chan_t **out, int *n)
{
    static const char *const names[FP_DCH_COUNT] = { "R", "G", "B", "A", "Z", "ZBack" };
    int extra = din ? din->nchan : npass;
    fp_deep_chan_t *c = calloc((size_t)(FP_DCH_COUNT + extra), sizeof *c);
    if (!c)
        return FP_ERR;
    for (int r = 0; r < FP_DCH_COUNT; r++) {
        snprintf(c[r].name, sizeof c[r].name, "%s", names[r]);
        c[r].type = r >= FP_DCH_Z || use_float ? 2 : 1;
    }
    int k = FP_DCH_COUNT;
    for (int e = 0; e < extra; e++) {
        const fp_deep_chan_t *src = din ? &din->chans[e] : &pass[e].chan;
        int is_role = 0;
        for (int r = 0; r < FP_DCH_COUNT; r++)
            is_role |= strcmp(src->name, names[r]) == 0;
        if (!is_role)
            c[k++] = *src;
    }
    *out = c;
    *n = k;
    return FP_OK;
}

int fp_deep_frame(const fp_deep_fog_t *f, const fp_color_frame_t *color,
                  const fp_frame_info_t *info, const fp_frame_t *plate, const float *rgba,
                  const fp_deep_image_t *din, const char *where, long frame,
                  fp_deep_image_t **out, fp_deep_stats_t *st)
{
    const float *depth = f->depth;
    int w = info->width, h = info->height, rc = FP_OK, nch = 0, npass = 0;
    size_t n = (size_t)w * h;
    fp_deep_chan_t *chans = NULL;
    fp_deep_pass_t *pass = NULL;
    fp_deep_image_t *d = NULL;
    uint32_t *counts = NULL;
    float *work = NULL;
    job_t j;
    memset(&j, 0, sizeof j);
    *out = NULL;
    if (!din && plate && (rc = fp_deep_plate_pass(plate, &pass, &npass)))
        goto oom;
    if ((rc = out_channels(din, pass, npass, 0, &chans, &nch)))
        goto oom;
    if (!din) {
        if (!(work = malloc(n * 4 * sizeof *work)))
            goto oom;
        memcpy(work, rgba, n * 4 * sizeof *work);
        fp_color_to_working(color, work, n);
    }
    j.rows = calloc((size_t)h, sizeof *j.rows);
    if (!j.rows)
        goto oom;
    j.f = f;
    j.color = color;
    j.work = work;
    j.depth = depth;
    j.din = din;
    j.w = w;
    j.h = h;
    j.where = where;
    j.frame = frame;
    pthread_mutex_init(&j.mu, NULL);
    /* one ray first, on this thread: it fills what the light stage caches
     * (the self-shadow grid), which the threads then only read */
    if (n) {
        fp_dlist_t warm = { NULL, 0, 0 };
        fp_deep_stats_t ws;
        memset(&ws, 0, sizeof ws);
        rc = fp_deep_fog_pixel(f, 0, 0, 1, NULL, 0, &warm, &ws);
        fp_dlist_free(&warm);
    }
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    int nt = ncpu < 1 ? 1 : ncpu > 64 ? 64 : (int)ncpu;
    if (nt > h)
        nt = h > 0 ? h : 1;
    pthread_t th[64];
    int started = 0;
    for (int t = 1; t < nt && rc == FP_OK; t++)
        if (fp_thread_start(&th[t], worker, &j) == 0)
            started = t;
    if (rc == FP_OK)
        worker(&j);
    for (int t = 1; t <= started; t++)
        pthread_join(th[t], NULL);
    pthread_mutex_destroy(&j.mu);
    if (rc == FP_OK)
        rc = j.rc;
    if (rc && j.msg[0]) {
        rc = fp_error("%s", j.msg);
        goto done;
    }
    if (rc)
        goto oom;
    counts = malloc((n ? n : 1) * sizeof *counts);
    if (!counts || fp_deep_alloc(info, chans, nch, &d) || (d->info.has_alpha = 1, 0))
        goto oom;
    for (int y = 0; y < h; y++)
        memcpy(counts + (size_t)y * w, j.rows[y].counts, (size_t)w * sizeof *counts);
    if (fp_deep_alloc_samples(d, counts))
        goto oom;
    for (int y = 0; y < h; y++) {
        const row_t *r = &j.rows[y];
        uint64_t at = d->offsets[(size_t)y * w];
        size_t k = 0;
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            for (uint32_t s = 0; s < r->counts[x]; s++, k++, at++) {
                const osample_t *o = &r->s[k];
                for (int c = 0; c < FP_DCH_COUNT; c++)
                    memcpy(&d->data[c][at], &o->v[c], 4);
                for (int c = FP_DCH_COUNT; c < nch; c++) {
                    uint32_t v = 0;
                    if (din && o->src >= 0) {
                        for (int e = 0; e < din->nchan; e++)
                            if (strcmp(din->chans[e].name, chans[c].name) == 0)
                                v = din->data[e][o->src];
                    } else if (!din && o->src == FP_DEEP_SRC_PLATE) {
                        v = fp_deep_pass_value(&pass[c - FP_DCH_COUNT], i);
                    }
                    d->data[c][at] = v;
                }
            }
        }
    }
    fp_info("%s: frame %ld: deep: %.2f samples a pixel (%.2f of fog), %ld pixels at "
            "--deep-max-samples", where, frame, (double)j.st.samples / (double)(n ? n : 1),
            (double)j.st.fog_samples / (double)(n ? n : 1), j.st.capped);
    st->pixels += (long)n;
    st->samples += j.st.samples;
    st->fog_samples += j.st.fog_samples;
    st->evals += j.st.evals;
    st->capped += j.st.capped;
    *out = d;
    d = NULL;
    rc = FP_OK;
    goto done;
oom:
    rc = fp_error("%s: frame %ld: out of memory for deep samples", where, frame);
done:
    if (j.rows)
        for (int y = 0; y < h; y++) {
            free(j.rows[y].counts);
            free(j.rows[y].s);
        }
    free(j.rows);
    free(counts);
    free(work);
    free(chans);
    free(pass);
    fp_deep_free(d);
    return rc;
}

float *fp_deep_front_depth(const fp_deep_image_t *din, int depth_kind)
{
    float *z = malloc((din->npix ? din->npix : 1) * sizeof *z);
    if (!z)
        return NULL;
    for (size_t i = 0; i < din->npix; i++) {
        float best = INFINITY;
        for (uint64_t k = din->offsets[i]; k < din->offsets[i + 1]; k++)
            if (role_value(din, FP_DCH_A, k, 1) >= 1) {
                float zk = role_value(din, FP_DCH_Z, k, INFINITY);
                if (zk < best)
                    best = zk;
            }
        z[i] = depth_kind == FP_DEPTH_INVERSE ? (isinf(best) ? 0.0f : 1.0f / best) : best;
    }
    return z;
}
