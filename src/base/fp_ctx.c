/* fogpipe: the context a call runs in (src/base/fp_ctx.h). */
#include "fp_ctx.h"

#include <errno.h>
#include <stdlib.h>

/* Thread-local: a thread's own default and its current context, not the
 * process's. */
static _Thread_local fp_ctx_t tl_default;
static _Thread_local fp_ctx_t *tl_current;

fp_ctx_t *fp_ctx(void)
{
    return tl_current ? tl_current : &tl_default;
}

fp_ctx_t *fp_ctx_use(fp_ctx_t *c)
{
    fp_ctx_t *old = tl_current;
    tl_current = c;
    return old;
}

int fp_once(const void *key)
{
    fp_ctx_t *c = fp_ctx();
    for (int i = 0; i < FP_ONCE_MAX; i++) {
        const void *k = __atomic_load_n(&c->once[i], __ATOMIC_ACQUIRE);
        if (k == key)
            return 0;
        if (!k) {
            const void *expect = NULL;
            if (__atomic_compare_exchange_n(&c->once[i], &expect, key, 0, __ATOMIC_ACQ_REL,
                                            __ATOMIC_ACQUIRE))
                return 1;
            if (expect == key)
                return 0;
        }
    }
    return 0;   /* more keys than slots: the rest say nothing */
}

int fp_once_done(const void *key)
{
    const fp_ctx_t *c = fp_ctx();
    for (int i = 0; i < FP_ONCE_MAX; i++)
        if (__atomic_load_n(&c->once[i], __ATOMIC_ACQUIRE) == key)
            return 1;
    return 0;
}

typedef struct start_t {
    void *(*fn)(void *);
    void *arg;
    fp_ctx_t *ctx;
} start_t;

static void *trampoline(void *v)
{
    start_t s = *(start_t *)v;
    free(v);
    fp_ctx_use(s.ctx);
    return s.fn(s.arg);
}

int fp_thread_start(pthread_t *t, void *(*fn)(void *), void *arg)
{
    start_t *s = malloc(sizeof *s);
    if (!s)
        return ENOMEM;
    s->fn = fn;
    s->arg = arg;
    s->ctx = fp_ctx();
    int rc = pthread_create(t, NULL, trampoline, s);
    if (rc)
        free(s);
    return rc;
}
