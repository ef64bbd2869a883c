#include "fp.h"

int fp_quiet = 0;
int fp_verbose = 0;

static void vmsg(const char *prefix, const char *fmt, va_list ap)
{
    /* One fprintf per message keeps lines whole when threads print. */
    char buf[2048];
    vsnprintf(buf, sizeof buf, fmt, ap);
    fprintf(stderr, "fogpipe: %s%s\n", prefix, buf);
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
