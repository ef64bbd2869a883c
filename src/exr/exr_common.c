/* fogpipe: glue between exrio and OpenEXR's C API (error handler,
 * in-memory read and write callbacks), the chunk workers that decode and
 * encode chunks in parallel, and compression names. */
#include "exr_internal.h"
#include "fp.h"
#include "fp_limits.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

/* ------------------------------------------------------------ library glue */

/* The error callback cannot ask the context for its user data:
 * exr_get_user_data takes the context's lock, which a write context holds
 * while it reports, and deadlocks.  The library calls the handler on the
 * thread that made the failing call, so a thread-local pointer to the
 * message buffer of the call in progress is both safe and reentrant. */
_Thread_local char *fp_exr_tl_msg;

void fp_exr_lib_error_handler(exr_const_context_t ctxt, exr_result_t code,
                              const char *msg)
{
    (void) ctxt;
    char *dst = fp_exr_tl_msg;
    if (!dst || dst[0])
        return; /* keep the first message: later ones follow from it */
    snprintf(dst, FP_EXR_MSG_LEN, "%s",
             msg ? msg : exr_get_default_error_message(code));
    for (char *p = dst; *p; ++p)
        if (*p == '\n' || *p == '\r')
            *p = ' ';
}

/* The library's text for a failure: what its handler said, else the
 * generic text of the code.  Clears the buffer for the next call. */
const char *fp_exr_lib_text(fp_exr_io_t *io, exr_result_t rv, char *out,
                            size_t n)
{
    if (io->msg[0])
        snprintf(out, n, "%s", io->msg);
    else
        snprintf(out, n, "%s: %s", exr_get_error_code_as_string(rv),
                 exr_get_default_error_message(rv));
    io->msg[0] = '\0';
    return out;
}

const char *fp_exr_fail_text(fp_exr_io_t *io, const char *why, exr_result_t rv, char *out,
                             size_t n)
{
    if (!(why && why[0]))
        return fp_exr_lib_text(io, rv, out, n);
    snprintf(out, n, "%s", why);
    io->msg[0] = '\0';
    return out;
}

static uint8_t zero_bytes;

void *fp_exr_alloc(size_t n)
{
    return n ? malloc(n) : &zero_bytes;
}

void fp_exr_free(void *p)
{
    if (p != &zero_bytes)
        free(p);
}

int64_t fp_exr_mem_read(exr_const_context_t ctxt, void *userdata, void *buffer,
                        uint64_t sz, uint64_t offset,
                        exr_stream_error_func_ptr_t error_cb)
{
    fp_exr_io_t *io = userdata;
    if (offset > io->rd_size) {
        if (error_cb)
            error_cb(ctxt, EXR_ERR_READ_IO,
                     "read past the end of the data (offset %llu, %llu bytes held)",
                     (unsigned long long) offset,
                     (unsigned long long) io->rd_size);
        return -1;
    }
    uint64_t n = io->rd_size - offset;
    if (n > sz)
        n = sz;
    memcpy(buffer, io->rd + offset, (size_t) n);
    /* A short count is how a truncated file shows: the library reports it. */
    return (int64_t) n;
}

int64_t fp_exr_mem_size(exr_const_context_t ctxt, void *userdata)
{
    (void) ctxt;
    return (int64_t) ((fp_exr_io_t *) userdata)->rd_size;
}

/* pwrite semantics: the library writes the offset table last, at an
 * offset before the chunks, so writes land anywhere in the buffer. */
int64_t fp_exr_mem_write(exr_const_context_t ctxt, void *userdata,
                         const void *buffer, uint64_t sz, uint64_t offset,
                         exr_stream_error_func_ptr_t error_cb)
{
    fp_exr_io_t *io = userdata;
    if (offset > FP_EXR_MAX_FILE || sz > FP_EXR_MAX_FILE) {
        io->wr_failed = 1;
        if (error_cb)
            error_cb(ctxt, EXR_ERR_WRITE_IO, "output too large");
        return -1;
    }
    size_t end = (size_t) (offset + sz);
    if (end > io->wr_cap) {
        size_t cap = io->wr_cap ? io->wr_cap : 65536;
        while (cap < end)
            cap *= 2;
        uint8_t *nb = realloc(io->wr, cap);
        if (!nb) {
            io->wr_failed = 1;
            if (error_cb)
                error_cb(ctxt, EXR_ERR_OUT_OF_MEMORY, "out of memory");
            return -1;
        }
        io->wr = nb;
        io->wr_cap = cap;
    }
    if (offset > io->wr_size)
        memset(io->wr + io->wr_size, 0, (size_t) offset - io->wr_size);
    memcpy(io->wr + offset, buffer, (size_t) sz);
    if (end > io->wr_size)
        io->wr_size = end;
    return (int64_t) sz;
}

/* ------------------------------------------------------------ chunk workers */

/* Threads that decode or encode the chunks of one part: 0 = one per
 * online core (fp_exr_set_threads; the current context's). */
void fp_exr_set_threads(int n)
{
    fp_ctx()->exr_threads = n < 0 ? 0 : n;
}

int fp_exr_threads(void)
{
    int n = fp_ctx()->exr_threads;
    if (n > 0)
        return n;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    return cores < 1 ? 1 : cores > FP_EXR_MAX_THREADS ? FP_EXR_MAX_THREADS : (int) cores;
}

/* How many workers a part of `pixels` pixels in `chunks` chunks gets: one
 * for small images, where starting threads costs more than it saves. */
int fp_exr_start_read(fp_exr_io_t *io, exr_context_t *ctx, const char *where, long frame)
{
    char lt[512];
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = fp_exr_lib_error_handler;
    init.user_data = io;
    init.read_fn = fp_exr_mem_read;
    init.size_fn = fp_exr_mem_size;
    const fp_image_limits_t *lim = fp_image_limits();
    int max_dim = lim->max_dim < INT32_MAX ? (int) lim->max_dim : INT32_MAX;
    init.max_image_width = max_dim;
    init.max_image_height = max_dim;
    init.max_tile_width = max_dim;
    init.max_tile_height = max_dim;
    /* A missing chunk must fail loudly, not be searched for.  A strict
     * header: without it the library drops an attribute it cannot parse
     * (lineOrder 99, compression 99) and puts its default in place, so a
     * bad header would pass as another file. */
    init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION |
                 EXR_CONTEXT_FLAG_STRICT_HEADER;
    exr_result_t rv = exr_start_read(ctx, where, &init);
    if (rv != EXR_ERR_SUCCESS) {
        *ctx = NULL;
        return fp_error("%s: frame %ld: cannot read EXR header (%s)", where, frame,
                        fp_exr_lib_text(io, rv, lt, sizeof lt));
    }
    return FP_OK;
}

int fp_exr_workers(int64_t pixels, int64_t chunks)
{
    int n = fp_exr_threads();
    if (pixels < FP_EXR_PAR_MIN_PIXELS || chunks < 2)
        return 1;
    return chunks < n ? (int) chunks : n;
}

/* Run fn on each of the n workers (an array of n records of `size`
 * bytes): n - 1 new threads and the calling one.  A thread that cannot be
 * started leaves its record to the caller, which runs it after its own:
 * the work is claimed from a shared counter, so fewer threads only take
 * longer. */
fp_exr_worker_t *fp_exr_run_workers(void *(*fn)(void *), void *job, fp_exr_worker_t *wk, int n)
{
    pthread_t th[FP_EXR_MAX_THREADS];
    int started[FP_EXR_MAX_THREADS] = { 0 };
    for (int i = 0; i < n; ++i) {
        wk[i].job = job;
        wk[i].fail = -1;
    }
    for (int i = 1; i < n; ++i)
        started[i] = fp_thread_start(&th[i], fn, &wk[i]) == 0;
    fn(&wk[0]);
    for (int i = 1; i < n; ++i) {
        if (started[i])
            pthread_join(th[i], NULL);
        else
            fn(&wk[i]);
    }
    fp_exr_worker_t *first = NULL;
    for (int i = 0; i < n; ++i)
        if (wk[i].fail >= 0 && (!first || wk[i].fail < first->fail))
            first = &wk[i];
    return first;
}

static const char *const comp_names[] = {
    "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"
};

int fp_exr_compression_from_name(const char *name)
{
    if (!name)
        return -1;
    for (size_t i = 0; i < FP_ARRAY_LEN(comp_names); ++i)
        if (strcasecmp(name, comp_names[i]) == 0)
            return (int) i;
    return -1;
}

int fp_exr_compression_writable(int compression)
{
    /* the C library writes NONE..B44A; DWAA and DWAB go through exr_dwa.h */
    return compression >= 0 && (size_t) compression < FP_ARRAY_LEN(comp_names);
}

const char *fp_exr_compression_name(int compression)
{
    if (compression < 0 || (size_t) compression >= FP_ARRAY_LEN(comp_names))
        return "unknown";
    return comp_names[compression];
}
