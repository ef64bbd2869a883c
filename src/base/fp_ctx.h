/* fogpipe: the context a call runs in (issue 27: no process-wide state).
 *
 * What used to be the process's is the context's: where messages go and
 * how many (the emitter, quiet, verbose), the EXR chunk threads and codec,
 * the image budget, the warnings given once a run.  Each thread has a
 * current context: libfogpipe's API makes its own the current one on entry
 * to every call (lib/api.c) and restores the previous one on return, and
 * every thread the library starts runs in the context of the thread that
 * started it (fp_thread_start), so a call's workers speak for that call.
 * A thread that never set one (the unit tests, a tool linking the engine)
 * has a default of its own, starting as zeros: messages on stderr, not
 * quiet, not verbose, the default budget.
 *
 * Why a current context rather than one passed down: every function of the
 * engine may report (fp_error), and the fogmap, camera and EXR code is
 * called from tests and tools without a pipeline; a pointer in every
 * signature would change hundreds of calls for one thing they all share.
 * The current context is the least change that lets two contexts run at
 * once on two threads (doc/design.md). */
#ifndef FP_CTX_H
#define FP_CTX_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The image budget (src/base/fp_limits.h reads and sets it). */
typedef struct fp_image_limits_t {
    int64_t max_pixels;      /* pixels in one image (one EXR part) */
    int64_t max_dim;         /* pixels along one axis */
    int64_t max_line_bytes;  /* decoded bytes of one scanline, all channels */
    int max_channels;        /* channels in one image */
    int max_parts;           /* parts in one EXR file */
} fp_image_limits_t;

/* A message's destination (src/base/fp.h: FP_MSG_* says what `text` is). */
typedef void (*fp_emit_fn)(void *user, int kind, const char *text, size_t len);

#define FP_ONCE_MAX 16

typedef struct fp_ctx_t {
    fp_emit_fn emit;            /* NULL: stderr */
    void *emit_user;
    int quiet;                  /* no warnings */
    int verbose;                /* > 0: informational messages too */
    int exr_threads;            /* chunk threads of one EXR part; 0: one per core */
    int zip_off;                /* OpenEXR's zlib instead of fogpipe's ZIP codec */
    int has_limits;             /* `limits` set (else the defaults) */
    fp_image_limits_t limits;
    const void *once[FP_ONCE_MAX];  /* the warnings given (fp_once; atomic access) */
} fp_ctx_t;

/* The calling thread's current context (never NULL). */
fp_ctx_t *fp_ctx(void);
/* Make `c` the calling thread's current context (NULL: its default);
 * returns the previous one, for the caller to restore. */
fp_ctx_t *fp_ctx_use(fp_ctx_t *c);

/* 1 the first time the current context asks with `key` (the address of
 * a static of the caller's), 0 after: a warning given once a run.
 * Safe from the context's threads at once. */
int fp_once(const void *key);
/* Whether fp_once(key) has answered 1 in the current context. */
int fp_once_done(const void *key);

/* pthread_create(t, NULL, fn, arg), the new thread running in the calling
 * thread's current context.  0 or an errno value. */
int fp_thread_start(pthread_t *t, void *(*fn)(void *), void *arg);

#ifdef __cplusplus
}
#endif

#endif
