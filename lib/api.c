/* libfogpipe's public API (fogpipe.h) over the engine: options, the frame
 * pipeline for files and streams, sessions for frames in memory.  The only
 * file whose symbols the shared library exports (lib/libfogpipe.map). */
#include "fogpipe.h"

#include "clrt.h"
#include "color.h"
#include "exrio.h"
#include "fp.h"
#include "options_all.h"
#include "pipeline.h"
#include "session.h"

#include "config.h"

#include <limits.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct fogpipe {
    fp_params_t p;
    fp_session_t *session;    /* frames in memory: made by the first apply */
    fogpipe_message_fn fn;
    void *user;
    char msg[2048];           /* the last failed call's message */
    char last[2048];          /* the last error-like line of the call in progress */
    char **argv;              /* fogpipe_parse_args' copy of the command line (--stats) */
    int argc;
    int free_pending;         /* fogpipe_free from a message handler: freed at the call's end */
    fogpipe_t *next_live;
    /* Everything a call changes is the context's (issue 27): its engine
     * context (messages, verbosity, EXR threads, image budget, warnings
     * given: src/base/fp_ctx.h), current on the calling thread and on the
     * threads the call starts; its lock, so one call at a time on it and
     * calls on other contexts at once. */
    fp_ctx_t ctx;
    fp_ctx_t *outer;          /* the calling thread's context before the call */
    pthread_mutex_t lock;     /* held through a call on this context */
    pthread_mutex_t emit_lock; /* one message at a time to the handler */
    int pins;                 /* threads waiting for `lock` (under live_lock) */
    int dead;                 /* freed while they waited: the last one frees it */
};

/* The contexts made by fogpipe_new and not yet freed (under live_lock, held
 * only to look one up): a call on a freed context, or one that waited for
 * its lock while another thread freed it, is refused without reading it.
 * The list is the process's only state here, and guards nothing but the
 * look-up: calls on different contexts do not wait for each other. */
static pthread_mutex_t live_lock = PTHREAD_MUTEX_INITIALIZER;
static fogpipe_t *live;

/* The context of the call that holds a context's lock on this thread, and
 * whether this thread runs a message handler (fogpipe_run's frame loop
 * hands messages on from its own threads while the caller's thread holds
 * the lock): a call from a handler is re-entry, refused (the lock is not
 * recursive, and the call in progress is half done). */
static _Thread_local fogpipe_t *in_call;
static _Thread_local int in_handler;

static int reentry(void)
{
    return in_call != NULL || in_handler > 0;
}

static int alive(const fogpipe_t *c)
{
    pthread_mutex_lock(&live_lock);
    const fogpipe_t *l = live;
    while (l && l != c)
        l = l->next_live;
    pthread_mutex_unlock(&live_lock);
    return l != NULL;
}

static void live_add(fogpipe_t *c)
{
    pthread_mutex_lock(&live_lock);
    c->next_live = live;
    live = c;
    pthread_mutex_unlock(&live_lock);
}

/* Off the list; under live_lock.  1 when no thread waits for its lock
 * (the caller frees it), else the last waiter frees it. */
static int live_remove_locked(fogpipe_t *c)
{
    for (fogpipe_t **l = &live; *l; l = &(*l)->next_live)
        if (*l == c) {
            *l = c->next_live;
            break;
        }
    c->dead = 1;
    return c->pins == 0;
}

static void destroy(fogpipe_t *c)
{
    pthread_mutex_destroy(&c->lock);
    pthread_mutex_destroy(&c->emit_lock);
    free(c);
}

/* Lock `c` for a call: FP_OK with c->lock held, or FOGPIPE_EUSAGE (nothing
 * held) when it is not alive or was freed while this thread waited. */
static int lock_live(fogpipe_t *c)
{
    pthread_mutex_lock(&live_lock);
    const fogpipe_t *l = live;
    while (l && l != c)
        l = l->next_live;
    if (!l) {
        pthread_mutex_unlock(&live_lock);
        return FOGPIPE_EUSAGE;
    }
    c->pins++;
    pthread_mutex_unlock(&live_lock);
    pthread_mutex_lock(&c->lock);
    pthread_mutex_lock(&live_lock);
    int dead = c->dead, last = --c->pins == 0;
    pthread_mutex_unlock(&live_lock);
    if (!dead)
        return FP_OK;
    pthread_mutex_unlock(&c->lock);
    if (last)
        destroy(c);
    return FOGPIPE_EUSAGE;
}

static const char not_live[] = "fogpipe: not a live context (freed, or not made by fogpipe_new)";

/* Keep the last line that is not a warning or progress (the error a failed
 * call printed last), and hand the text to the context's handler. */
static void api_emit_locked(fogpipe_t *c, int kind, const char *text, size_t len);

/* The frame loop's threads emit too: one message at a time, so that a
 * handler is never run on two threads at once and c->last is whole. */
static void api_emit(void *user, int kind, const char *text, size_t len)
{
    fogpipe_t *c = user;
    pthread_mutex_lock(&c->emit_lock);
    api_emit_locked(c, kind, text, len);
    pthread_mutex_unlock(&c->emit_lock);
}

static void api_emit_locked(fogpipe_t *c, int kind, const char *text, size_t len)
{
    if (kind == FP_MSG_ERROR || kind == FP_MSG_KEPT) {
        const char *p = text, *end = text + len;
        while (p < end) {
            const char *nl = memchr(p, '\n', (size_t)(end - p));
            const char *e = nl ? nl : end;
            size_t n = (size_t)(e - p);
            if (n && strncmp(p, "fogpipe: warning: ", n < 18 ? n : 18) != 0) {
                /* Without the "fogpipe: " of the program's lines. */
                if (n > 9 && strncmp(p, "fogpipe: ", 9) == 0) {
                    p += 9;
                    n -= 9;
                }
                if (n >= sizeof c->last)
                    n = sizeof c->last - 1;
                memcpy(c->last, p, n);
                c->last[n] = 0;
            }
            p = nl ? nl + 1 : end;
        }
    }
    if (!c->fn)
        return;
    char buf[4096];
    char *t = len < sizeof buf ? buf : malloc(len + 1);
    if (!t)
        return;
    memcpy(t, text, len);
    t[len] = 0;
    in_handler++;
    c->fn(c->user, kind, t);
    in_handler--;
    if (t != buf)
        free(t);
}

/* Start a call on `c`: FP_OK with c->lock held and c's engine context the
 * thread's current one, or the refusal (nothing held) of a call from a
 * message handler (its message kept in c when c lives) or on a context
 * that is not alive. */
static int enter(fogpipe_t *c, const char *fn)
{
    if (reentry()) {
        if (alive(c))
            snprintf(c->msg, sizeof c->msg, "%s: called from a message handler (the library "
                     "is not re-entrant: call it after the call in progress returns)", fn);
        return FOGPIPE_ERROR;
    }
    if (lock_live(c))
        return FOGPIPE_EUSAGE;
    in_call = c;
    c->outer = fp_ctx_use(&c->ctx);
    c->ctx.emit = api_emit;
    c->ctx.emit_user = c;
    c->ctx.quiet = c->p.io.quiet;
    c->ctx.verbose = c->p.io.verbose;
    c->last[0] = 0;
    return FP_OK;
}

static void drop_session(fogpipe_t *c)
{
    fp_session_close(c->session);
    c->session = NULL;
}

static void free_argv(char **argv, int argc);

/* What a context owns, with its lock held; the caller frees `c` itself
 * after unlocking when this returns 1 (else a thread waiting for the lock
 * does, lock_live). */
static int release(fogpipe_t *c)
{
    pthread_mutex_lock(&live_lock);
    int mine = live_remove_locked(c);
    pthread_mutex_unlock(&live_lock);
    drop_session(c);
    fp_options_free(&c->p);
    free_argv(c->argv, c->argc);
    c->argv = NULL;
    return mine;
}

/* The call's status; its message kept when it failed.  Contexts freed by a
 * message handler during the call go now. */
static int leave(fogpipe_t *c, int rc)
{
    if (rc != FP_OK) {
        snprintf(c->msg, sizeof c->msg, "%s",
                 c->last[0] ? c->last : "fogpipe: failed (no message)");
    } else {
        c->msg[0] = 0;
    }
    fp_ctx_use(c->outer);
    in_call = NULL;
    pthread_mutex_lock(&live_lock);
    int self = c->free_pending && !c->dead;
    c->free_pending = 0;
    pthread_mutex_unlock(&live_lock);
    int mine = self ? release(c) : 0;
    pthread_mutex_unlock(&c->lock);
    if (mine)
        destroy(c);
    /* Other contexts a handler of this call freed: freed as fogpipe_free
     * frees them (after a call in progress on them on another thread). */
    for (;;) {
        pthread_mutex_lock(&live_lock);
        fogpipe_t *d = live;
        while (d && !d->free_pending)
            d = d->next_live;
        if (d)
            d->free_pending = 0;
        pthread_mutex_unlock(&live_lock);
        if (!d)
            break;
        fogpipe_free(d);
    }
    return rc;
}

/* A call on a NULL context or with bad arguments: no context to keep the
 * message in, or a message of our own. */
static int fail(fogpipe_t *c, int rc, const char *fmt, const char *a)
{
    snprintf(c->last, sizeof c->last, fmt, a ? a : "");
    return rc;
}

const char *fogpipe_version(void)
{
    return PACKAGE_VERSION;
}

int fogpipe_new(fogpipe_t **out)
{
    if (!out)
        return FOGPIPE_EUSAGE;
    *out = NULL;
    if (reentry())
        return FOGPIPE_ERROR;   /* from a message handler (see enter) */
    fogpipe_t *c = calloc(1, sizeof *c);
    if (!c)
        return FOGPIPE_ERROR;
    pthread_mutex_init(&c->lock, NULL);
    pthread_mutex_init(&c->emit_lock, NULL);
    live_add(c);
    int rc = enter(c, "fogpipe_new");
    if (rc)
        return rc;   /* freed meanwhile by another thread that guessed its address */
    rc = fp_options_defaults(&c->p);
    int mine = rc ? release(c) : 0;
    leave(c, rc);
    if (rc) {
        if (mine)
            destroy(c);
        return rc;
    }
    *out = c;
    return FOGPIPE_OK;
}

static void free_argv(char **argv, int argc)
{
    for (int i = 0; argv && i < argc; i++)
        free(argv[i]);
    free(argv);
}

void fogpipe_free(fogpipe_t *c)
{
    if (!c)
        return;
    if (reentry()) {
        /* From a message handler (the call in progress holds a lock): the
         * call in progress frees it when it leaves. */
        pthread_mutex_lock(&live_lock);
        for (fogpipe_t *l = live; l; l = l->next_live)
            if (l == c)
                c->free_pending = 1;
        pthread_mutex_unlock(&live_lock);
        return;
    }
    if (enter(c, "fogpipe_free"))
        return;   /* freed already */
    int mine = release(c);
    leave(c, FP_OK);
    if (mine)
        destroy(c);
}

const char *fogpipe_error(const fogpipe_t *c)
{
    if (!c)
        return "fogpipe_error: no context (NULL)";
    return alive(c) ? c->msg : not_live;
}

void fogpipe_set_message_handler(fogpipe_t *c, fogpipe_message_fn fn, void *user)
{
    if (!c)
        return;
    if (reentry()) {
        /* From a handler: the call in progress holds the lock (and the
         * handler runs under emit_lock). */
        if (alive(c)) {
            c->fn = fn;
            c->user = user;
        }
        return;
    }
    if (lock_live(c))
        return;
    pthread_mutex_lock(&c->emit_lock);
    c->fn = fn;
    c->user = user;
    pthread_mutex_unlock(&c->emit_lock);
    pthread_mutex_unlock(&c->lock);
}

int fogpipe_set(fogpipe_t *c, const char *name, const char *value, const char *origin)
{
    if (!c)
        return FOGPIPE_EUSAGE;
    int rc = enter(c, "fogpipe_set");
    if (rc)
        return rc;
    if (!name || !*name) {
        rc = fail(c, FP_EUSAGE, "fogpipe_set: no option name%s", NULL);
        return leave(c, rc);
    }
    if (strncmp(name, "--", 2) == 0)
        name += 2;
    const fp_option_t *o = fp_options_find(name);
    if (!origin)
        origin = "fogpipe_set";
    if (!o) {
        rc = fp_usage_error("%s: unknown option --%s (see fogpipe --help)", origin, name);
    } else if (strcmp(o->name, "preset") == 0) {
        rc = value ? fp_options_load_preset(&c->p, value)
                   : fp_usage_error("%s: --preset needs a NAME or FILE", origin);
    } else {
        if (!value && o->type != FP_OPT_FLAG)
            rc = fp_usage_error("%s: --%s needs a value", origin, o->name);
        else
            rc = fp_options_apply(&c->p, o->name, value ? value : "1", origin);
    }
    /* The next frame sets up again with the new options. */
    drop_session(c);
    return leave(c, rc);
}

int fogpipe_parse_args(fogpipe_t *c, int argc, char **argv)
{
    if (!c)
        return FOGPIPE_EUSAGE;
    int rc = enter(c, "fogpipe_parse_args");
    if (rc)
        return rc;
    if (argc < 1 || !argv) {
        rc = fail(c, FP_EUSAGE, "fogpipe_parse_args: no argv%s (expected argc >= 1 and "
                  "argv[0] the program)", NULL);
        return leave(c, rc);
    }
    for (int i = 0; i < argc; i++)
        if (!argv[i]) {
            char at[32];
            snprintf(at, sizeof at, "%d", i);
            return leave(c, fail(c, FP_EUSAGE, "fogpipe_parse_args: argv[%s] is NULL "
                                 "(expected argc strings)", at));
        }
    /* The caller's strings are not kept (fogpipe.h, Ownership): --stats
     * writes the command line at the end of fogpipe_run, after a host may
     * have freed its argv.  The copy is parsed, so that nothing parsing
     * keeps points into the caller's either. */
    char **copy = calloc((size_t)argc + 1, sizeof *copy);
    for (int i = 0; copy && i < argc; i++)
        if (!(copy[i] = strdup(argv[i]))) {
            free_argv(copy, i);
            copy = NULL;
        }
    if (!copy)
        return leave(c, fp_error("fogpipe_parse_args: out of memory"));
    free_argv(c->argv, c->argc);
    c->argv = copy;
    c->argc = argc;
    rc = fp_options_parse(argc, copy, &c->p);
    c->p.cmd.argc = argc;
    c->p.cmd.argv = copy;
    fp_quiet = c->p.io.quiet;
    fp_verbose = c->p.io.verbose;
    if (rc == FP_OK && c->p.io.preset)
        fp_info("preset: %s", c->p.io.preset);
    drop_session(c);
    return leave(c, rc);
}

/* A frame in memory checked (fn names the call in messages) and
 * described as the pipeline's frames are. */
static int frame_info(fogpipe_t *c, const char *fn, const fogpipe_frame_t *in, const void *out,
                      fp_frame_info_t *info)
{
    char what[160];
    if (!in || !in->rgba || !in->depth || !out) {
        snprintf(what, sizeof what, "%s: %s is NULL (expected the frame's rgba and depth "
                 "arrays and an output)", fn, !in ? "the frame" : !in->rgba ? "rgba"
                                                      : !in->depth ? "depth" : "the output");
        return fail(c, FP_EUSAGE, "%s", what);
    }
    if (in->width < 1 || in->height < 1 || (size_t)in->width > SIZE_MAX / 16 / (size_t)in->height ||
        (long long)in->width * in->height > INT_MAX) {
        snprintf(what, sizeof what, "%s: a frame of %dx%d pixels (expected a width and height "
                 "of at least 1)", fn, in->width, in->height);
        return fail(c, FP_EUSAGE, "%s", what);
    }
    memset(info, 0, sizeof *info);
    info->width = info->disp_w = in->width;
    info->height = info->disp_h = in->height;
    info->pixel_aspect = 1;
    info->num_parts = 1;
    info->has_alpha = 1;
    if (in->world_to_camera) {
        info->has_world_to_camera = 1;
        memcpy(info->world_to_camera, in->world_to_camera, sizeof info->world_to_camera);
    }
    if (in->world_to_ndc) {
        info->has_world_to_ndc = 1;
        memcpy(info->world_to_ndc, in->world_to_ndc, sizeof info->world_to_ndc);
    }
    return FP_OK;
}

int fogpipe_apply(fogpipe_t *c, const fogpipe_frame_t *in, float *out_rgba, float *out_fog_rgba,
                  float *out_transmittance)
{
    if (!c)
        return FOGPIPE_EUSAGE;
    int rc = enter(c, "fogpipe_apply");
    if (rc)
        return rc;
    fp_frame_info_t info;
    if ((rc = frame_info(c, "fogpipe_apply", in, out_rgba, &info)))
        return leave(c, rc);
    const char *name = in->name ? in->name : "<memory>";
    if (!c->session && (rc = fp_session_open(&c->p, &c->session)))
        return leave(c, rc);
    size_t n = (size_t)in->width * in->height;
    if (out_rgba != in->rgba)
        memmove(out_rgba, in->rgba, n * 4 * sizeof *out_rgba);
    rc = fp_session_frame(c->session, &info, out_rgba, in->depth, name, in->frame, out_fog_rgba,
                          out_transmittance);
    return leave(c, rc);
}

/* What fogpipe_apply_deep hands out: the public view and its arrays. */
typedef struct deep_result_t {
    fogpipe_deep_t pub;
    unsigned long long *offsets;
    float *rgba, *z, *zback;
} deep_result_t;

void fogpipe_deep_free(fogpipe_deep_t *d)
{
    deep_result_t *r = (deep_result_t *)d;
    if (!r)
        return;
    free((void *)r->pub.counts);
    free(r->offsets);
    free(r->rgba);
    free(r->z);
    free(r->zback);
    free(r);
}

int fogpipe_apply_deep(fogpipe_t *c, const fogpipe_frame_t *in, fogpipe_deep_t **out)
{
    if (!c)
        return FOGPIPE_EUSAGE;
    int rc = enter(c, "fogpipe_apply_deep");
    if (rc)
        return rc;
    fp_frame_info_t info;
    if (out)
        *out = NULL;
    if ((rc = frame_info(c, "fogpipe_apply_deep", in, out, &info)))
        return leave(c, rc);
    const char *name = in->name ? in->name : "<memory>";
    if (!c->session && (rc = fp_session_open(&c->p, &c->session)))
        return leave(c, rc);
    fp_deep_image_t *d = NULL;
    if ((rc = fp_session_deep(c->session, &info, in->rgba, in->depth, name, in->frame, &d)))
        return leave(c, rc);
    deep_result_t *r = calloc(1, sizeof *r);
    size_t n = d->npix, t = (size_t)d->total;
    unsigned int *counts = r ? malloc((n ? n : 1) * sizeof *counts) : NULL;
    if (r) {
        r->pub.counts = counts;
        r->offsets = malloc((n + 1) * sizeof *r->offsets);
        r->rgba = malloc((t ? t : 1) * 4 * sizeof(float));
        r->z = malloc((t ? t : 1) * sizeof(float));
        r->zback = malloc((t ? t : 1) * sizeof(float));
    }
    if (!r || !counts || !r->offsets || !r->rgba || !r->z || !r->zback) {
        if (r)
            fogpipe_deep_free(&r->pub);
        fp_deep_free(d);
        return leave(c, fp_error("%s: frame %ld: out of memory for deep samples", name,
                                 in->frame));
    }
    for (size_t i = 0; i <= n; i++) {
        if (i < n)
            counts[i] = d->counts[i];
        r->offsets[i] = d->offsets[i];
    }
    for (size_t k = 0; k < t; k++) {
        for (int ch = 0; ch < 4; ch++)
            memcpy(&r->rgba[4 * k + ch], &d->data[d->role[FP_DCH_R + ch]][k], sizeof(float));
        memcpy(&r->z[k], &d->data[d->role[FP_DCH_Z]][k], sizeof(float));
        memcpy(&r->zback[k], &d->data[d->role[FP_DCH_ZBACK]][k], sizeof(float));
    }
    r->pub.width = in->width;
    r->pub.height = in->height;
    r->pub.offsets = r->offsets;
    r->pub.total = t;
    r->pub.rgba = r->rgba;
    r->pub.z = r->z;
    r->pub.zback = r->zback;
    fp_deep_free(d);
    *out = &r->pub;
    return leave(c, FP_OK);
}

int fogpipe_run(fogpipe_t *c, int flags)
{
    if (!c)
        return FOGPIPE_EUSAGE;
    int rc = enter(c, "fogpipe_run");
    if (rc)
        return rc;
    fp_params_t *p = &c->p;
    if (p->cmd.help || p->cmd.help_markdown) {
        fp_options_print_help(stdout, p->cmd.help_markdown);
        rc = FP_OK;
    } else if (p->cmd.version) {
        printf("%s %s\n", PACKAGE_NAME, PACKAGE_VERSION);
        rc = FP_OK;
    } else if (p->cmd.list_devices) {
        rc = fp_cl_list_devices(stdout);
    } else if (p->color.list_spaces) {
        rc = fp_color_list(p, stdout);
    } else {
        p->run.catch_signals = (flags & FOGPIPE_RUN_SIGNALS) != 0;
        rc = fp_pipeline_run(p);
    }
    if (fflush(stdout) != 0 && rc == FP_OK)
        rc = fp_error("<stdout>: write failed");
    return leave(c, rc);
}
