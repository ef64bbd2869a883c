#include "frameloop.h"
#include "exrio.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "config.h"

const char *const fp_loop_timer_names[FP_T_COUNT] = {
    "read", "decode", "fogmap", "fog", "composite", "encode", "write"
};

double fp_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* ------------------------------------------------------------ signals */

/* The handler only writes the signal number into a pipe; a thread of ours
 * reads it and does the rest in a normal context.  Every other thread
 * blocks the signals (the mask is set before they are made), so the
 * handler runs on that thread, never in the middle of a write. */
static struct {
    int active;
    int pipe[2];
    pthread_t thread;
    int caught[2];                    /* SIGINT, SIGTERM: handler installed */
    struct sigaction old[2];
    sigset_t old_mask;
    atomic_int sig;                   /* the first signal, 0: none */
    atomic_int progress_shown;        /* a progress line is on the terminal */
    atomic_int serial_blocked;        /* the only thread waits on stdin (--pipeline off) */
    pthread_mutex_t watch_mu;         /* guards the two below */
    pthread_mutex_t *loop_mu;         /* the running loop, woken on a signal */
    pthread_cond_t *loop_cv;
    pthread_mutex_t commit;           /* held while an output is being written */
    int have_last;                    /* the last complete frame (under commit) */
    long last_frame;
    char last_out[FP_LOOP_PATH];
} sg = { .watch_mu = PTHREAD_MUTEX_INITIALIZER, .commit = PTHREAD_MUTEX_INITIALIZER };

static const int sig_nums[2] = { SIGINT, SIGTERM };

static const char *sig_name(int sig)
{
    return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal";
}

static void on_signal(int sig)
{
    int e = errno;
    unsigned char b = (unsigned char)sig;
    ssize_t n = write(sg.pipe[1], &b, 1);
    (void)n;
    errno = e;
}

/* "last complete frame 12 (out.0012.exr)", under the commit lock. */
static void last_text(char *buf, size_t n)
{
    if (sg.have_last)
        snprintf(buf, n, "last complete frame %ld (%.*s)%s", sg.last_frame, (int)(n / 2),
                 sg.last_out, strcmp(sg.last_out, "<stdout>") ? "; --skip-existing resumes" : "");
    else
        snprintf(buf, n, "no frame was complete");
}

/* A second signal, or one while the only thread waits on stdin: wait for
 * the write in flight, then go. */
static void hard_exit(int sig, int again)
{
    char last[FP_LOOP_PATH + 64], line[FP_LOOP_PATH + 160];
    pthread_mutex_lock(&sg.commit);
    last_text(last, sizeof last);
    int n = snprintf(line, sizeof line, "%sfogpipe: interrupted %s(%s): %s%s\n",
                     atomic_load(&sg.progress_shown) ? "\r\033[K" : "", again ? "again " : "",
                     sig_name(sig), again ? "stopped at once; " : "", last);
    if (n > 0) {
        ssize_t w = write(STDERR_FILENO, line, (size_t)n < sizeof line ? (size_t)n : sizeof line - 1);
        (void)w;
    }
    _exit(FP_ESIGNAL + sig);
}

static void *sig_main(void *arg)
{
    (void)arg;
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    pthread_sigmask(SIG_UNBLOCK, &set, NULL);
    for (;;) {
        /* poll, not a bare read: it returns after the handler even under
         * SA_RESTART (which ThreadSanitizer's deferred handlers need). */
        struct pollfd pfd = { sg.pipe[0], POLLIN, 0 };
        if (poll(&pfd, 1, -1) < 0)
            continue;
        unsigned char b;
        ssize_t n = read(sg.pipe[0], &b, 1);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0 || b == 0)
            break;
        int none = 0;
        if (!atomic_compare_exchange_strong(&sg.sig, &none, (int)b))
            hard_exit(b, 1);
        if (atomic_load(&sg.serial_blocked))
            hard_exit(b, 0);   /* nothing in flight: every frame read is finished */
        pthread_mutex_lock(&sg.watch_mu);
        if (sg.loop_mu) {
            pthread_mutex_lock(sg.loop_mu);
            pthread_cond_broadcast(sg.loop_cv);
            pthread_mutex_unlock(sg.loop_mu);
        }
        pthread_mutex_unlock(&sg.watch_mu);
    }
    return NULL;
}

int fp_loop_signals_start(void)
{
    if (sg.active)
        return FP_OK;
    atomic_store(&sg.sig, 0);
    if (pipe(sg.pipe) != 0)
        return fp_error("cannot catch signals (pipe: %s)", strerror(errno));
    for (int i = 0; i < 2; i++)
        fcntl(sg.pipe[i], F_SETFD, FD_CLOEXEC);
    fcntl(sg.pipe[1], F_SETFL, O_NONBLOCK);
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set, &sg.old_mask);
    for (int i = 0; i < 2; i++) {
        sg.caught[i] = 0;
        if (sigaction(sig_nums[i], NULL, &sg.old[i]) != 0 || sg.old[i].sa_handler == SIG_IGN)
            continue;   /* ignored on entry (a background job): leave it so */
        struct sigaction sa;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sa.sa_flags = SA_RESTART;
        sigfillset(&sa.sa_mask);
        if (sigaction(sig_nums[i], &sa, NULL) == 0)
            sg.caught[i] = 1;
    }
    if (pthread_create(&sg.thread, NULL, sig_main, NULL) != 0) {
        for (int i = 0; i < 2; i++)
            if (sg.caught[i])
                sigaction(sig_nums[i], &sg.old[i], NULL);
        pthread_sigmask(SIG_SETMASK, &sg.old_mask, NULL);
        close(sg.pipe[0]);
        close(sg.pipe[1]);
        return fp_error("cannot catch signals (no thread)");
    }
    sg.active = 1;
    return FP_OK;
}

void fp_loop_signals_stop(void)
{
    if (!sg.active)
        return;
    unsigned char b = 0;
    ssize_t n;
    do
        n = write(sg.pipe[1], &b, 1);
    while (n < 0 && errno == EINTR);
    pthread_join(sg.thread, NULL);
    for (int i = 0; i < 2; i++)
        if (sg.caught[i])
            sigaction(sig_nums[i], &sg.old[i], NULL);
    pthread_sigmask(SIG_SETMASK, &sg.old_mask, NULL);
    close(sg.pipe[0]);
    close(sg.pipe[1]);
    sg.active = 0;
}

int fp_loop_interrupted(void)
{
    return atomic_load(&sg.sig);
}

/* Only the pipelined reader thread is ever cancelled. */
static _Thread_local int tl_cancellable;

void fp_loop_blocking_begin(void)
{
    if (tl_cancellable)
        pthread_setcancelstate(PTHREAD_CANCEL_ENABLE, NULL);
    else
        atomic_store(&sg.serial_blocked, 1);
}

void fp_loop_blocking_end(void)
{
    if (tl_cancellable)
        pthread_setcancelstate(PTHREAD_CANCEL_DISABLE, NULL);
    else
        atomic_store(&sg.serial_blocked, 0);
}

void fp_loop_commit_begin(void)
{
    pthread_mutex_lock(&sg.commit);
}

void fp_loop_commit_end(const fp_loop_job_t *done)
{
    if (done) {
        sg.have_last = 1;
        sg.last_frame = done->frame;
        snprintf(sg.last_out, sizeof sg.last_out, "%s", done->out[0] ? done->out : done->in);
    }
    pthread_mutex_unlock(&sg.commit);
}

/* ------------------------------------------------------------ the loop */

enum { REC_OK, REC_SKIPPED, REC_FAILED };

typedef struct rec_t {       /* a finished frame, for --stats */
    long frame;
    char *in, *out;
    int state;
    double ms[FP_T_COUNT];
    double decompose_ms;
    double t_done;           /* since the loop started */
} rec_t;

typedef struct loop_t {
    const fp_loop_ops_t *ops;
    const fp_loop_opts_t *o;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    fp_loop_job_t *q_read;       /* reader -> process, one frame */
    fp_loop_job_t *q_write;      /* process -> writer, one frame */
    int read_done, process_done;
    int halt;                    /* a frame failed: stop everything */
    int status;                  /* that frame's status */
    /* Finished frames: the writer's (or the only thread's) until joined. */
    long n_ok, n_skipped;
    double t0, t_drawn;
    int shown;                   /* progress line on the terminal */
    rec_t *recs;
    size_t nrecs, caprecs;
    int recs_lost;               /* out of memory for the stats */
} loop_t;

static int stopping(const loop_t *l)
{
    return l->halt || fp_loop_interrupted();
}

static void job_free(loop_t *l, fp_loop_job_t *job)
{
    if (!job)
        return;
    if (l->ops->release)
        l->ops->release(l->ops->ctx, job);
    fp_msg_free(&job->msgs);
    free(job);
}

/* Read the next frame into a new job.  FP_EOF: none (no job); otherwise
 * *out is a job, failed (job->status) or not. */
static int run_next(loop_t *l, long seq, fp_loop_job_t **out)
{
    *out = NULL;
    fp_loop_job_t *job = calloc(1, sizeof *job);
    if (!job)
        return fp_error("out of memory");
    job->seq = seq;
    fp_msgbuf_t *old = fp_msg_capture(&job->msgs);
    int rc = l->ops->next(l->ops->ctx, job);
    fp_msg_capture(old);
    if (rc == FP_EOF) {
        fp_msg_flush(&job->msgs);   /* nothing, unless `next` said something */
        job_free(l, job);
        return FP_EOF;
    }
    job->status = rc;
    *out = job;
    return FP_OK;
}

static void run_stage(loop_t *l, fp_loop_job_t *job,
                      int (*stage)(void *, fp_loop_job_t *))
{
    if (job->status != FP_OK || job->skipped)
        return;
    fp_msgbuf_t *old = fp_msg_capture(&job->msgs);
    job->status = stage(l->ops->ctx, job);
    fp_msg_capture(old);
}

static void fmt_duration(double s, char *buf, size_t n)
{
    long t = s < 0 ? 0 : (long)(s + 0.5);
    if (t >= 3600)
        snprintf(buf, n, "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
    else
        snprintf(buf, n, "%ld:%02ld", t / 60, t % 60);
}

static void progress_clear(loop_t *l)
{
    if (l->shown) {
        fp_emit(FP_MSG_PROGRESS, "\r\033[K", 4);
        l->shown = 0;
        atomic_store(&sg.progress_shown, 0);
    }
}

/* FP_PROGRESS_LINES, for farm logs (frameloop.h): one line per frame that
 * leaves the loop, whole, never redrawn. */
static void progress_line(loop_t *l, const fp_loop_job_t *job)
{
    long done = l->n_ok + l->n_skipped;
    double el = (fp_now_ms() - l->t0) / 1e3;
    char count[96], what[96], left[48] = "";
    if (l->o->total > 0)
        snprintf(count, sizeof count, "%ld of %ld frames (%ld%%)", done, l->o->total,
                 done * 100 / l->o->total);
    else
        snprintf(count, sizeof count, "%ld frame%s", done, done == 1 ? "" : "s");
    if (job->skipped) {
        snprintf(what, sizeof what, "frame %ld skipped", job->frame);
    } else {
        double ms = 0;
        for (int k = 0; k < FP_T_COUNT; k++)
            ms += job->ms[k];
        snprintf(what, sizeof what, "frame %ld in %.1f s", job->frame, ms / 1e3);
    }
    if (l->o->total > 0 && l->n_ok > 0 && el > 0) {
        char d[32];
        fmt_duration((l->o->total - done) / (l->n_ok / el), d, sizeof d);
        snprintf(left, sizeof left, ", %s left", d);
    }
    char line[320];
    int len = snprintf(line, sizeof line, "fogpipe: progress: %s, %s%s\n", count, what, left);
    fp_emit(FP_MSG_PROGRESS, line, len < (int)sizeof line ? (size_t)len : sizeof line - 1);
}

/* "frame 12/100  3.4 fps  0:25 left" */
static void progress_draw(loop_t *l, int final)
{
    double now = fp_now_ms();
    if (l->o->progress != FP_PROGRESS_BAR || (!final && l->shown && now - l->t_drawn < 100))
        return;
    l->t_drawn = now;
    double el = (now - l->t0) / 1e3;
    long done = l->n_ok + l->n_skipped;
    char line[160], tail[64] = "";
    int n = l->o->total > 0 ? snprintf(line, sizeof line, "frame %ld/%ld", done, l->o->total)
                            : snprintf(line, sizeof line, "frame %ld", done);
    if (l->n_ok > 0 && el > 0) {
        double fps = l->n_ok / el;
        char d[32];
        if (final) {
            fmt_duration(el, d, sizeof d);
            snprintf(tail, sizeof tail, "  done in %s", d);
        } else if (l->o->total > 0) {
            fmt_duration((l->o->total - done) / fps, d, sizeof d);
            snprintf(tail, sizeof tail, "  %s left", d);
        }
        snprintf(line + n, sizeof line - (size_t)n, "  %.1f fps%s", fps, tail);
    }
    char out[200];
    int len = snprintf(out, sizeof out, "\r\033[K%s%s", line, final ? "\n" : "");
    fp_emit(FP_MSG_PROGRESS, out, len < (int)sizeof out ? (size_t)len : sizeof out - 1);
    l->shown = !final;
    atomic_store(&sg.progress_shown, l->shown);
}

static void record(loop_t *l, const fp_loop_job_t *job, int state)
{
    if (!l->o->stats_path || l->recs_lost)
        return;
    if (l->nrecs == l->caprecs) {
        size_t cap = l->caprecs ? l->caprecs * 2 : 64;
        rec_t *r = realloc(l->recs, cap * sizeof *r);
        if (!r) {
            l->recs_lost = 1;
            return;
        }
        l->recs = r;
        l->caprecs = cap;
    }
    rec_t *r = &l->recs[l->nrecs];
    r->frame = job->frame;
    r->in = strdup(job->in);
    r->out = strdup(job->out);
    if (!r->in || !r->out) {
        free(r->in);
        free(r->out);
        l->recs_lost = 1;
        return;
    }
    r->state = state;
    memcpy(r->ms, job->ms, sizeof r->ms);
    r->decompose_ms = job->decompose_ms;
    r->t_done = fp_now_ms() - l->t0;
    l->nrecs++;
}

/* A frame leaves the loop, in order: its messages, progress, stats. */
static void finish(loop_t *l, fp_loop_job_t *job)
{
    if (job->msgs.len || fp_verbose > 0 || job->status != FP_OK)
        progress_clear(l);
    fp_msg_flush(&job->msgs);
    if (job->status == FP_OK) {
        fp_loop_commit_begin();
        fp_loop_commit_end(job);
        if (job->skipped) {
            l->n_skipped++;
        } else {
            l->n_ok++;
            if (fp_verbose > 0) {
                char t[256];
                int n = 0;
                for (int k = 0; k < FP_T_COUNT && n < (int)sizeof t - 40; k++)
                    if (job->ms[k] > 0 || k == FP_T_FOG)
                        n += snprintf(t + n, sizeof t - (size_t)n, "%s%s %.1f", n ? ", " : "",
                                      fp_loop_timer_names[k], job->ms[k]);
                fp_info("%s: frame %ld done (ms: %s)", job->in, job->frame, t);
            }
        }
        record(l, job, job->skipped ? REC_SKIPPED : REC_OK);
        if (l->o->progress == FP_PROGRESS_LINES)
            progress_line(l, job);
        progress_draw(l, 0);
    } else {
        record(l, job, REC_FAILED);
        pthread_mutex_lock(&l->mu);
        if (!l->halt) {
            l->halt = 1;
            l->status = job->status;
        }
        pthread_cond_broadcast(&l->cv);
        pthread_mutex_unlock(&l->mu);
    }
}

static void *reader_main(void *arg)
{
    loop_t *l = arg;
    tl_cancellable = 1;
    pthread_setcancelstate(PTHREAD_CANCEL_DISABLE, NULL);
    for (long seq = 0;; seq++) {
        pthread_mutex_lock(&l->mu);
        while (l->q_read && !stopping(l))
            pthread_cond_wait(&l->cv, &l->mu);
        int stop = stopping(l);
        pthread_mutex_unlock(&l->mu);
        if (stop)
            break;
        fp_loop_job_t *job;
        int rc = run_next(l, seq, &job);
        if (rc == FP_EOF)
            break;
        if (!job) {   /* out of memory: a failure in order */
            pthread_mutex_lock(&l->mu);
            if (!l->halt) {
                l->halt = 1;
                l->status = rc;
            }
            pthread_mutex_unlock(&l->mu);
            break;
        }
        int failed = job->status != FP_OK;
        pthread_mutex_lock(&l->mu);
        l->q_read = job;   /* only this thread fills it, and it was empty */
        pthread_cond_broadcast(&l->cv);
        pthread_mutex_unlock(&l->mu);
        if (failed)
            break;
    }
    pthread_mutex_lock(&l->mu);
    l->read_done = 1;
    pthread_cond_broadcast(&l->cv);
    pthread_mutex_unlock(&l->mu);
    return NULL;
}

static void *writer_main(void *arg)
{
    loop_t *l = arg;
    for (;;) {
        pthread_mutex_lock(&l->mu);
        while (!l->q_write && !l->process_done && !fp_loop_interrupted())
            pthread_cond_wait(&l->cv, &l->mu);
        fp_loop_job_t *job = fp_loop_interrupted() ? NULL : l->q_write;
        if (job) {
            l->q_write = NULL;
            pthread_cond_broadcast(&l->cv);
        }
        pthread_mutex_unlock(&l->mu);
        if (!job)
            break;
        run_stage(l, job, l->ops->write);
        finish(l, job);
        int failed = job->status != FP_OK;
        job_free(l, job);
        if (failed)
            break;
    }
    return NULL;
}

static int run_pipelined(loop_t *l)
{
    pthread_t reader, writer;
    if (fp_thread_start(&reader, reader_main, l) != 0)
        return fp_error("cannot start the reader thread");
    if (fp_thread_start(&writer, writer_main, l) != 0) {
        pthread_mutex_lock(&l->mu);
        l->halt = 1;
        pthread_cond_broadcast(&l->cv);
        pthread_mutex_unlock(&l->mu);
        pthread_join(reader, NULL);
        return fp_error("cannot start the writer thread");
    }
    for (;;) {
        pthread_mutex_lock(&l->mu);
        while (!l->q_read && !l->read_done && !stopping(l))
            pthread_cond_wait(&l->cv, &l->mu);
        fp_loop_job_t *job = stopping(l) ? NULL : l->q_read;
        if (job) {
            l->q_read = NULL;
            pthread_cond_broadcast(&l->cv);
        }
        pthread_mutex_unlock(&l->mu);
        if (!job)
            break;
        run_stage(l, job, l->ops->process);
        int failed = job->status != FP_OK;
        pthread_mutex_lock(&l->mu);
        while (l->q_write && !stopping(l))
            pthread_cond_wait(&l->cv, &l->mu);
        int stop = stopping(l);
        if (!stop) {
            l->q_write = job;
            pthread_cond_broadcast(&l->cv);
        }
        pthread_mutex_unlock(&l->mu);
        if (stop) {
            job_free(l, job);
            break;
        }
        if (failed)
            break;   /* the writer reports it, in order */
    }
    pthread_mutex_lock(&l->mu);
    l->process_done = 1;
    pthread_cond_broadcast(&l->cv);
    pthread_mutex_unlock(&l->mu);
    pthread_join(writer, NULL);
    /* A reader blocked on stdin would wait for its producer: on a signal it
     * is cancelled there (it can be nowhere else: fp_loop_blocking_*).  What
     * it held is left to the process's exit, which follows. */
    if (fp_loop_interrupted())
        pthread_cancel(reader);
    pthread_join(reader, NULL);
    job_free(l, l->q_read);
    job_free(l, l->q_write);
    l->q_read = l->q_write = NULL;
    return FP_OK;
}

static void run_serial(loop_t *l)
{
    for (long seq = 0; !stopping(l); seq++) {
        fp_loop_job_t *job;
        int rc = run_next(l, seq, &job);
        if (rc == FP_EOF)
            break;
        if (!job) {
            l->halt = 1;
            l->status = rc;
            break;
        }
        if (!fp_loop_interrupted())
            run_stage(l, job, l->ops->process);
        if (!fp_loop_interrupted())
            run_stage(l, job, l->ops->write);
        if (fp_loop_interrupted()) {
            job_free(l, job);
            break;
        }
        finish(l, job);
        job_free(l, job);
    }
}

/* ------------------------------------------------------------ --stats */

static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

static int write_stats(loop_t *l, int rc, double wall_ms)
{
    char *buf = NULL;
    size_t size = 0;
    FILE *f = open_memstream(&buf, &size);
    if (!f)
        return fp_error("%s: cannot write the stats (out of memory)", l->o->stats_path);
    const char *status = rc == FP_OK ? "ok" : rc >= FP_ESIGNAL ? "interrupted" : "error";
    double tot[FP_T_COUNT] = { 0 }, tot_decompose = 0;
    for (size_t i = 0; i < l->nrecs; i++) {
        for (int k = 0; k < FP_T_COUNT; k++)
            tot[k] += l->recs[i].ms[k];
        tot_decompose += l->recs[i].decompose_ms;
    }
    fprintf(f, "{\n  \"fogpipe\": \"%s\",\n  \"status\": \"%s\",\n", PACKAGE_VERSION, status);
    fprintf(f, "  \"exit_status\": %d,\n", rc == FP_OK ? 0 : rc >= FP_ESIGNAL ? rc
                                                     : rc == FP_EUSAGE ? 2 : 1);
    char host[256] = "";
    if (gethostname(host, sizeof host - 1) != 0)
        host[0] = 0;
    fputs("  \"host\": ", f);
    json_str(f, host);
    fputs(",\n  \"device\": ", f);
    json_str(f, l->o->device ? l->o->device : "-");
    fputs(",\n  \"argv\": [", f);
    for (int i = 0; l->o->argv && i < l->o->argc; i++) {
        fputs(i ? ", " : "", f);
        json_str(f, l->o->argv[i]);
    }
    fputs("],\n  \"input\": ", f);
    json_str(f, l->o->input ? l->o->input : "-");
    fputs(",\n  \"output\": ", f);
    json_str(f, l->o->output ? l->o->output : "-");
    fprintf(f, ",\n  \"pipelined\": %s,\n", l->o->pipelined ? "true" : "false");
    if (l->o->total > 0)
        fprintf(f, "  \"frames_planned\": %ld,\n", l->o->total);
    else
        fputs("  \"frames_planned\": null,\n", f);
    fprintf(f, "  \"frames_done\": %ld,\n  \"frames_skipped\": %ld,\n", l->n_ok, l->n_skipped);
    fprintf(f, "  \"setup_ms\": %.3f,\n  \"fogmap_setup_ms\": %.3f,\n", l->o->setup_ms,
            l->o->fogmap_setup_ms);
    fprintf(f, "  \"wall_ms\": %.3f,\n  \"fps\": %.4f,\n", wall_ms,
            wall_ms > 0 ? l->n_ok / (wall_ms / 1e3) : 0.0);
    if (l->recs_lost)
        fputs("  \"frames_incomplete\": true,\n", f);
    fputs("  \"totals_ms\": {", f);
    for (int k = 0; k < FP_T_COUNT; k++)
        fprintf(f, "%s\"%s\": %.3f", k ? ", " : " ", fp_loop_timer_names[k], tot[k]);
    fprintf(f, ", \"decompose\": %.3f },\n  \"frames\": [", tot_decompose);
    static const char *const states[] = { "ok", "skipped", "error" };
    for (size_t i = 0; i < l->nrecs; i++) {
        const rec_t *r = &l->recs[i];
        fprintf(f, "%s\n    { \"frame\": %ld, \"status\": \"%s\", \"input\": ", i ? "," : "",
                r->frame, states[r->state]);
        json_str(f, r->in);
        fputs(", \"output\": ", f);
        json_str(f, r->out);
        double sum = 0;
        for (int k = 0; k < FP_T_COUNT; k++) {
            fprintf(f, ", \"%s_ms\": %.3f", fp_loop_timer_names[k], r->ms[k]);
            sum += r->ms[k];
        }
        fprintf(f, ", \"decompose_ms\": %.3f, \"total_ms\": %.3f, \"done_at_ms\": %.3f }",
                r->decompose_ms, sum, r->t_done);
    }
    fputs(l->nrecs ? "\n  ]\n}\n" : "]\n}\n", f);
    if (fclose(f) != 0) {
        free(buf);
        return fp_error("%s: cannot write the stats (out of memory)", l->o->stats_path);
    }
    fp_loop_commit_begin();
    int wrc = fp_write_file_atomic(l->o->stats_path, buf, size);
    fp_loop_commit_end(NULL);
    free(buf);
    return wrc;
}

int fp_loop_run(const fp_loop_ops_t *ops, const fp_loop_opts_t *opts)
{
    loop_t l;
    memset(&l, 0, sizeof l);
    l.ops = ops;
    l.o = opts;
    pthread_mutex_init(&l.mu, NULL);
    pthread_cond_init(&l.cv, NULL);
    l.t0 = fp_now_ms();
    pthread_mutex_lock(&sg.commit);
    sg.have_last = 0;
    pthread_mutex_unlock(&sg.commit);
    pthread_mutex_lock(&sg.watch_mu);
    sg.loop_mu = &l.mu;
    sg.loop_cv = &l.cv;
    pthread_mutex_unlock(&sg.watch_mu);

    int rc = FP_OK;
    if (!fp_loop_interrupted()) {
        if (opts->pipelined)
            rc = run_pipelined(&l);
        else
            run_serial(&l);
    }
    double wall = fp_now_ms() - l.t0;

    pthread_mutex_lock(&sg.watch_mu);
    sg.loop_mu = NULL;
    sg.loop_cv = NULL;
    pthread_mutex_unlock(&sg.watch_mu);
    int sig = fp_loop_interrupted();
    if (sig || l.status != FP_OK)
        progress_clear(&l);
    else if (l.shown || (l.o->progress == FP_PROGRESS_BAR && l.n_ok + l.n_skipped > 0))
        progress_draw(&l, 1);
    if (rc == FP_OK)
        rc = l.status;
    if (sig && rc == FP_OK) {
        char last[FP_LOOP_PATH + 64];
        fp_loop_commit_begin();
        last_text(last, sizeof last);
        fp_loop_commit_end(NULL);
        fp_error("interrupted (%s): %s", sig_name(sig), last);
        rc = FP_ESIGNAL + sig;
    }
    if (opts->stats_path) {
        int src = write_stats(&l, rc, wall);
        if (rc == FP_OK)
            rc = src;
    }
    for (size_t i = 0; i < l.nrecs; i++) {
        free(l.recs[i].in);
        free(l.recs[i].out);
    }
    free(l.recs);
    pthread_cond_destroy(&l.cv);
    pthread_mutex_destroy(&l.mu);
    return rc;
}
