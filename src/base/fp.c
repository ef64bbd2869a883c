#include "fp.h"

#include <stdlib.h>
#include <errno.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static _Thread_local fp_msgbuf_t *tl_sink;

void fp_msg_set_emitter(fp_emit_fn fn, void *user)
{
    fp_ctx_t *c = fp_ctx();
    c->emit = fn;
    c->emit_user = user;
}

void fp_emit(int kind, const char *text, size_t len)
{
    const fp_ctx_t *c = fp_ctx();
    if (c->emit)
        c->emit(c->emit_user, kind, text, len);
    else
        fwrite(text, 1, len, stderr);
}

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
        fp_emit(FP_MSG_KEPT, b->text, b->len);
    b->len = 0;
}

void fp_msg_free(fp_msgbuf_t *b)
{
    free(b->text);
    memset(b, 0, sizeof *b);
}

static void vmsg(int kind, const char *prefix, const char *fmt, va_list ap)
{
    /* One write per message keeps lines whole when threads print. */
    char buf[2048], line[2200];
    vsnprintf(buf, sizeof buf, fmt, ap);
    int n = snprintf(line, sizeof line, "fogpipe: %s%s\n", prefix, buf);
    size_t len = n < 0 ? 0 : (size_t)n < sizeof line ? (size_t)n : sizeof line - 1;
    if (tl_sink && keep(tl_sink, line, len) == 0)
        return;
    fp_emit(kind, line, len);
}

int fp_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vmsg(FP_MSG_ERROR, "", fmt, ap);
    va_end(ap);
    return FP_ERR;
}

int fp_usage_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vmsg(FP_MSG_ERROR, "", fmt, ap);
    va_end(ap);
    return FP_EUSAGE;
}

void fp_warn(const char *fmt, ...)
{
    if (fp_quiet)
        return;
    va_list ap;
    va_start(ap, fmt);
    vmsg(FP_MSG_WARNING, "warning: ", fmt, ap);
    va_end(ap);
}

void fp_info(const char *fmt, ...)
{
    if (fp_verbose <= 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    vmsg(FP_MSG_INFO, "", fmt, ap);
    va_end(ap);
}

int fp_mkdir_p(const char *dir)
{
    char buf[4096];
    size_t len = strlen(dir);
    struct stat st;
    if (len == 0 || len >= sizeof buf) {
        errno = len ? ENAMETOOLONG : ENOENT;
        return -1;
    }
    memcpy(buf, dir, len + 1);
    for (char *p = buf + 1;; p++) {
        if (*p != '/' && *p != '\0')
            continue;
        char c = *p;
        *p = '\0';
        if (mkdir(buf, 0777) != 0 && errno != EEXIST && !(stat(buf, &st) == 0 && S_ISDIR(st.st_mode)))
            return -1;
        *p = c;
        if (c == '\0')
            break;
    }
    if (stat(buf, &st) != 0)
        return -1;
    if (!S_ISDIR(st.st_mode)) {
        errno = ENOTDIR;
        return -1;
    }
    return 0;
}

int fp_make_parent_dir(const char *path, long frame)
{
    const char *slash = strrchr(path, '/');
    char dir[4096];
    struct stat st;
    if (!slash || slash == path)
        return FP_OK;
    size_t len = (size_t)(slash - path);
    if (len >= sizeof dir)
        return fp_error("%s: frame %ld: file name too long", path, frame);
    memcpy(dir, path, len);
    dir[len] = 0;
    if (stat(dir, &st) == 0 && S_ISDIR(st.st_mode))
        return FP_OK;
    if (fp_mkdir_p(dir) != 0)
        return fp_error("%s: frame %ld: cannot create the directory %s (%s)", path, frame, dir,
                        strerror(errno));
    return FP_OK;
}
