#include "fp.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int fp_quiet = 0;
int fp_verbose = 0;

static _Thread_local fp_msgbuf_t *tl_sink;

fp_msgbuf_t *fp_msg_capture(fp_msgbuf_t *sink)
{
    fp_msgbuf_t *old = tl_sink;
    tl_sink = sink;
    return old;
}

/* Append a line to the sink; 0 on success (else the caller prints it). */
static int keep(fp_msgbuf_t *b, const char *line, size_t n)
{
    if (b->len + n > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->len + n)
            cap *= 2;
        char *t = realloc(b->text, cap);
        if (!t)
            return -1;
        b->text = t;
        b->cap = cap;
    }
    memcpy(b->text + b->len, line, n);
    b->len += n;
    return 0;
}

void fp_msg_flush(fp_msgbuf_t *b)
{
    if (b->len)
        fwrite(b->text, 1, b->len, stderr);
    b->len = 0;
}

void fp_msg_free(fp_msgbuf_t *b)
{
    free(b->text);
    memset(b, 0, sizeof *b);
}

static void vmsg(const char *prefix, const char *fmt, va_list ap)
{
    /* One write per message keeps lines whole when threads print. */
    char buf[2048], line[2200];
    vsnprintf(buf, sizeof buf, fmt, ap);
    int n = snprintf(line, sizeof line, "fogpipe: %s%s\n", prefix, buf);
    size_t len = n < 0 ? 0 : (size_t)n < sizeof line ? (size_t)n : sizeof line - 1;
    if (tl_sink && keep(tl_sink, line, len) == 0)
        return;
    fputs(line, stderr);
}

int fp_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vmsg("", fmt, ap);
    va_end(ap);
    return FP_ERR;
}

int fp_usage_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vmsg("", fmt, ap);
    va_end(ap);
    return FP_EUSAGE;
}

void fp_warn(const char *fmt, ...)
{
    if (fp_quiet)
        return;
    va_list ap;
    va_start(ap, fmt);
    vmsg("warning: ", fmt, ap);
    va_end(ap);
}

void fp_info(const char *fmt, ...)
{
    if (fp_verbose <= 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vmsg("", fmt, ap);
    va_end(ap);
}

int fp_exe_dir(char *dir, size_t n)
{
    char buf[4096];
    ssize_t len = readlink("/proc/self/exe", buf, sizeof buf - 1);
    char *slash = NULL;
    if (len > 0) {
        buf[len] = 0;
        slash = strrchr(buf, '/');
    }
    if (!n)
        return -1;
    if (!slash || (size_t)(slash - buf) >= n) {
        dir[0] = 0;
        return -1;
    }
    memcpy(dir, buf, (size_t)(slash - buf));
    dir[slash - buf] = 0;
    return 0;
}
