#include "options_all.h"
#include "fp.h"
#include "install.h"
#include "textfile.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include "config.h"

extern const fp_option_t fp_io_options[];
extern const fp_option_t fp_camera_options[];
extern const fp_option_t fp_integrate_options[];
extern const fp_option_t fp_fogmap_options[];
extern const fp_option_t fp_scatter_options[];
extern const fp_option_t fp_reference_options[];
extern const fp_option_t fp_buffers_options[];
extern const fp_option_t fp_animate_options[];
extern const fp_option_t fp_color_options[];
extern const fp_option_t fp_aov_options[];
extern const fp_option_t fp_preview_options[];
extern const fp_option_t fp_run_options[];
extern const fp_option_t fp_rig_options[];
extern const fp_option_t fp_deep_options[];
extern const fp_option_t fp_ms_options[];

#define CMD(f) offsetof(fp_params_t, cmd.f)
static const fp_option_t cmd_options[] = {
    { "help", 'h', FP_OPT_FLAG, CMD(help), 0, 0, NULL, 0, 1, NULL, NULL,
      "print this help and exit", NULL, FP_OPTF_CLI_ONLY },
    { "help-markdown", 0, FP_OPT_FLAG, CMD(help_markdown), 0, 0, NULL, 0, 1, NULL, NULL,
      "print the option reference as a Markdown table (for the README)", NULL,
      FP_OPTF_CLI_ONLY | FP_OPTF_HIDDEN },
    { "version", 'V', FP_OPT_FLAG, CMD(version), 0, 0, NULL, 0, 1, NULL, NULL,
      "print the version and exit", NULL, FP_OPTF_CLI_ONLY },
    { "list-devices", 0, FP_OPT_FLAG, CMD(list_devices), 0, 0, NULL, 0, 1, NULL, NULL,
      "list the OpenCL devices, numbered as --device takes them, and exit", NULL,
      FP_OPTF_CLI_ONLY },
    { "print-camera", 0, FP_OPT_FLAG, CMD(print_camera), 0, 0, NULL, 0, 1, NULL, NULL,
      "print the camera understood for each frame (after overrides) and exit", NULL,
      FP_OPTF_CLI_ONLY },
    FP_OPT_END
};

const fp_option_group_t fp_option_groups[] = {
    { "Commands", cmd_options },
    { "Input and output", fp_io_options },
    { "Camera and depth", fp_camera_options },
    { "Fog", fp_integrate_options },
    { "Fogmap (wavelet fog)", fp_fogmap_options },
    { "Light (sun, local lights, shadows)", fp_scatter_options },
    { "Multiple scattering", fp_ms_options },
    { "Rig (from the host)", fp_rig_options },
    { "Monte Carlo reference", fp_reference_options },
    { "Fog buffers (blur, resolution)", fp_buffers_options },
    { "Animation", fp_animate_options },
    { "Color (OpenColorIO)", fp_color_options },
    { "Fog layers (AOVs)", fp_aov_options },
    { "Previews", fp_preview_options },
    { "Deep output", fp_deep_options },
    { "Sequences and farms", fp_run_options },
    { NULL, NULL }
};

const fp_option_t *fp_options_find(const char *name)
{
    for (const fp_option_group_t *g = fp_option_groups; g->title; g++)
        for (const fp_option_t *o = g->options; o->name; o++)
            if (strcmp(o->name, name) == 0)
                return o;
    return NULL;
}

static const fp_option_t *find_short(char c)
{
    for (const fp_option_group_t *g = fp_option_groups; g->title; g++)
        for (const fp_option_t *o = g->options; o->name; o++)
            if (o->short_name && o->short_name == c)
                return o;
    return NULL;
}

/* Parse a real, accepting inf/-inf as strtod does; the whole string must be
 * consumed. */
static int parse_real(const char *s, double *out)
{
    char *end;
    errno = 0;
    while (isspace((unsigned char)*s))
        s++;
    if (!*s)
        return -1;
    double v = strtod(s, &end);
    while (isspace((unsigned char)*end))
        end++;
    if (*end || errno == ERANGE || isnan(v))
        return -1;
    *out = v;
    return 0;
}

static void range_text(const fp_option_t *o, char *buf, size_t n)
{
    if (o->type == FP_OPT_ENUM) {
        snprintf(buf, n, "%s", o->choices);
        return;
    }
    char a[32], b[32];
    if (isinf(o->min))
        snprintf(a, sizeof a, "%s", o->min < 0 ? "-inf" : "inf");
    else
        snprintf(a, sizeof a, "%g", o->min);
    if (isinf(o->max))
        snprintf(b, sizeof b, "%s", o->max < 0 ? "-inf" : "inf");
    else
        snprintf(b, sizeof b, "%g", o->max);
    snprintf(buf, n, "%s..%s", a, b);
}

static int check_range(const fp_option_t *o, double v, const char *origin)
{
    if (v < o->min || v > o->max) {
        char r[64];
        range_text(o, r, sizeof r);
        return fp_usage_error("%s: --%s: %g is out of range (expected %s)",
                              origin, o->name, v, r);
    }
    return FP_OK;
}

static int parse_bool(const char *s, int *out)
{
    if (!strcasecmp(s, "1") || !strcasecmp(s, "true") || !strcasecmp(s, "yes") ||
        !strcasecmp(s, "on"))
        *out = 1;
    else if (!strcasecmp(s, "0") || !strcasecmp(s, "false") || !strcasecmp(s, "no") ||
             !strcasecmp(s, "off"))
        *out = 0;
    else
        return -1;
    return 0;
}

static int set_value(fp_params_t *p, const fp_option_t *o, const char *value,
                     const char *origin)
{
    char *field = (char *)p + o->offset;
    if (o->set)
        return o->set(p, o, value);
    switch (o->type) {
    case FP_OPT_FLAG: {
        int b = 1;
        if (value && parse_bool(value, &b))
            return fp_usage_error("%s: --%s: expected a yes/no value, got '%s'",
                                  origin, o->name, value);
        *(int *)field = b;
        return FP_OK;
    }
    case FP_OPT_INT: {
        double v;
        if (parse_real(value, &v) || v != floor(v))
            return fp_usage_error("%s: --%s: expected an integer, got '%s'",
                                  origin, o->name, value);
        if (check_range(o, v, origin))
            return FP_EUSAGE;
        *(int *)field = (int)v;
        return FP_OK;
    }
    case FP_OPT_REAL: {
        double v;
        if (parse_real(value, &v))
            return fp_usage_error("%s: --%s: expected a number, got '%s'",
                                  origin, o->name, value);
        if (check_range(o, v, origin))
            return FP_EUSAGE;
        *(double *)field = v;
        return FP_OK;
    }
    case FP_OPT_STRING: {
        char **s = (char **)field;
        char *copy = strdup(value);
        if (!copy)
            return fp_error("out of memory");
        free(*s);
        *s = copy;
        return FP_OK;
    }
    case FP_OPT_ENUM: {
        int idx = 0;
        const char *c = o->choices;
        size_t len = strlen(value);
        while (c && *c) {
            const char *bar = strchr(c, '|');
            size_t n = bar ? (size_t)(bar - c) : strlen(c);
            if (n == len && strncasecmp(c, value, n) == 0) {
                *(int *)field = idx;
                return FP_OK;
            }
            idx++;
            c = bar ? bar + 1 : NULL;
        }
        return fp_usage_error("%s: --%s: unknown value '%s' (expected %s)",
                              origin, o->name, value, o->choices);
    }
    case FP_OPT_VEC: {
        double v[8];
        int n = 0;
        char *copy = strdup(value);
        if (!copy)
            return fp_error("out of memory");
        int bad = 0;
        /* Empty components ("1,,2") are errors, so split by hand. */
        const char *s = copy;
        for (;;) {
            const char *comma = strchr(s, ',');
            size_t len = comma ? (size_t)(comma - s) : strlen(s);
            char part[64];
            if (n >= o->count || len == 0 || len >= sizeof part) {
                bad = 1;
                break;
            }
            memcpy(part, s, len);
            part[len] = 0;
            if (parse_real(part, &v[n])) {
                bad = 1;
                break;
            }
            n++;
            if (!comma)
                break;
            s = comma + 1;
        }
        free(copy);
        if (bad || n < o->min_count) {
            if (o->min_count == o->count)
                return fp_usage_error("%s: --%s: expected %d comma-separated numbers %s, got '%s'",
                                      origin, o->name, o->count, o->metavar, value);
            return fp_usage_error("%s: --%s: expected %d to %d comma-separated numbers %s, got '%s'",
                                  origin, o->name, o->min_count, o->count, o->metavar, value);
        }
        for (int i = 0; i < n; i++)
            if (check_range(o, v[i], origin))
                return FP_EUSAGE;
        /* Components the user left out keep their defaults. */
        double *dst = (double *)field;
        for (int i = 0; i < n; i++)
            dst[i] = v[i];
        return FP_OK;
    }
    }
    return fp_error("internal: option --%s has an unknown type", o->name);
}

static void mark_given(fp_params_t *p, const fp_option_t *o)
{
    for (int i = 0; i < p->num_given; i++)
        if (p->given[i] == o->name)
            return;
    if (p->num_given < FP_MAX_GIVEN)
        p->given[p->num_given++] = o->name;
}

int fp_options_defaults(fp_params_t *p)
{
    memset(p, 0, sizeof *p);
    for (const fp_option_group_t *g = fp_option_groups; g->title; g++)
        for (const fp_option_t *o = g->options; o->name; o++) {
            if (!o->def)
                continue;
            int rc;
            if (o->type == FP_OPT_VEC) {
                /* A vector default sets every component, even optional ones. */
                const fp_option_t full = { o->name, 0, FP_OPT_VEC, o->offset, o->count,
                                           o->count, NULL, o->min, o->max, NULL,
                                           o->metavar, NULL, o->set, 0 };
                rc = set_value(p, &full, o->def, "default");
            } else {
                rc = set_value(p, o, o->def, "default");
            }
            if (rc)
                return fp_error("internal: bad default for --%s", o->name);
        }
    p->num_given = 0;
    return FP_OK;
}

int fp_options_apply(fp_params_t *p, const char *name, const char *value,
                     const char *origin)
{
    const fp_option_t *o = fp_options_find(name);
    if (!o)
        return fp_usage_error("%s: unknown option --%s (see fogpipe --help)", origin, name);
    if (o->type != FP_OPT_FLAG && !value)
        return fp_usage_error("%s: --%s needs a value %s", origin, name,
                              o->metavar ? o->metavar : "");
    int rc = set_value(p, o, value, origin);
    if (rc == FP_OK)
        mark_given(p, o);
    return rc;
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s))
        s++;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1]))
        *--e = 0;
    return s;
}

/* --preset NAME (no '/', no ".preset"): presets/NAME.preset where
 * fogpipe's installed files are (src/base/install.h: beside the program or the
 * library, so a moved install works; the configured directory; the source
 * tree from a build tree).  Anything else is a file name. */
static int find_preset(const char *arg, char *path, size_t n)
{
    size_t len = strlen(arg);
    if (strchr(arg, '/') || (len > 7 && strcmp(arg + len - 7, ".preset") == 0) ||
        access(arg, F_OK) == 0) {
        snprintf(path, n, "%s", arg);
        return FP_OK;
    }
    char rel[4200], tried[8192];
    snprintf(rel, sizeof rel, "presets/%s.preset", arg);
    if (fp_install_find(rel, path, n, tried, sizeof tried) == 0)
        return FP_OK;
    return fp_usage_error("--preset %s: no such file, and no preset of that name (looked for "
                          "%s in %s; fogpipe's own: morning-valley-mist, low-sun-shafts, "
                          "night-street-lamps)", arg, rel, tried);
}

int fp_options_load_preset(fp_params_t *p, const char *arg)
{
    char path[4300];
    int rc = find_preset(arg, path, sizeof path);
    if (rc)
        return rc;
    /* Kept for -v, which is not parsed yet. */
    free(p->io.preset);
    if (!(p->io.preset = strdup(path)))
        return fp_error("out of memory");
    /* Bounded (src/base/textfile.h): --preset /dev/zero fails instead of
     * reading forever. */
    fp_text_t t;
    if ((rc = fp_text_open(&t, path, "preset", 1)))
        return rc;
    char *line;
    int got;
    while (rc == FP_OK && (got = fp_text_next(&t, &line)) > 0) {
        char *s = trim(line);
        if (!*s || *s == '#')
            continue;
        char origin[1100];
        snprintf(origin, sizeof origin, "%.1000s:%d", path, t.lineno);
        char *eq = strchr(s, '=');
        if (!eq) {
            rc = fp_usage_error("%s: expected 'name = value', got '%.200s'", origin, s);
            break;
        }
        *eq = 0;
        char *name = trim(s), *value = trim(eq + 1);
        if (strncmp(name, "--", 2) == 0)
            name += 2;
        const fp_option_t *o = fp_options_find(name);
        if (o && (o->flags & FP_OPTF_CLI_ONLY)) {
            rc = fp_usage_error("%s: --%s is a command, not allowed in a preset", origin, name);
            break;
        }
        rc = fp_options_apply(p, name, value, origin);
    }
    if (rc == FP_OK && got < 0)
        rc = t.rc;
    fp_text_close(&t);
    return rc;
}

/* The groups a look may set (fp_options_apply_look): the fog's look, not
 * what a run reads or writes. */
static int look_safe(const fp_option_t *o)
{
    static const fp_option_t *const groups[] = { fp_integrate_options, fp_scatter_options,
                                                 fp_buffers_options, fp_animate_options,
                                                 fp_ms_options };
    if (o->flags & FP_OPTF_CLI_ONLY)
        return 0;
    if (o->type == FP_OPT_STRING && strcmp(o->name, "phase") != 0)
        return 0;   /* file names and light specs: the command line's */
    for (size_t g = 0; g < FP_ARRAY_LEN(groups); g++)
        for (const fp_option_t *x = groups[g]; x->name; x++)
            if (x == o)
                return 1;
    return 0;
}

int fp_options_apply_look(fp_params_t *p, const char *text, const char *origin)
{
    const char *s = strstr(text, "fogpipe-look");
    if (!s)
        return fp_usage_error("%s: expected 'fogpipe-look 1 name=value ...'", origin);
    s += strlen("fogpipe-look");
    int first = 1, rc = FP_OK;
    const int given_before = p->num_given;
    const char *given[FP_MAX_GIVEN];
    memcpy(given, p->given, sizeof given);
    for (;;) {
        while (*s && (isspace((unsigned char)*s) || *s == ';'))
            s++;
        if (!*s)
            break;
        size_t n = 0;
        while (s[n] && !isspace((unsigned char)s[n]) && s[n] != ';')
            n++;
        char tok[512];
        if (n >= sizeof tok)
            return fp_usage_error("%s: a look entry longer than %zu characters (expected "
                                  "name=value)", origin, sizeof tok - 1);
        memcpy(tok, s, n);
        tok[n] = 0;
        s += n;
        if (first) {
            if (strcmp(tok, "1") != 0)
                return fp_usage_error("%s: 'fogpipe-look %.40s' (expected version 1)", origin,
                                      tok);
            first = 0;
            continue;
        }
        if (strncmp(tok, "fogpipe-", 8) == 0)
            break;   /* the next section */
        char *eq = strchr(tok, '=');
        if (!eq || eq == tok || !eq[1])
            return fp_usage_error("%s: look entry '%.100s' (expected name=value)", origin, tok);
        *eq = 0;
        const char *name = strncmp(tok, "--", 2) == 0 ? tok + 2 : tok;
        const fp_option_t *o = fp_options_find(name);
        if (!o)
            return fp_usage_error("%s: look: unknown option '%.100s' (see fogpipe --help)",
                                  origin, name);
        if (!look_safe(o))
            return fp_usage_error("%s: look: --%s is not part of a fog look (expected the "
                                  "fog's, light's, buffers' or animation's settings)", origin,
                                  o->name);
        /* Checked whether it is used or not (a bad look is the frame's
         * error either way), on a scratch set of parameters. */
        fp_params_t *scratch = malloc(sizeof *scratch);
        if (!scratch)
            return fp_error("out of memory");
        if ((rc = fp_options_defaults(scratch)) == FP_OK)
            rc = fp_options_apply(scratch, o->name, eq + 1, origin);
        fp_options_free(scratch);
        free(scratch);
        if (rc)
            return rc;
        /* Under the command line and --preset: set there (any alias of
         * the field) wins. */
        int taken = 0;
        for (int i = 0; i < given_before; i++) {
            const fp_option_t *g = fp_options_find(given[i]);
            taken |= g && g->offset == o->offset;
        }
        if (taken)
            continue;
        if ((rc = fp_options_apply(p, o->name, eq + 1, origin)))
            return rc;
    }
    if (first)
        return fp_usage_error("%s: expected 'fogpipe-look 1 name=value ...'", origin);
    return rc;
}

/* Split "--name=value" / "--name value" / "-x value" / "-xVALUE", and
 * bundled short options as getopt does: "-qv" is -q -v, and an option that
 * takes a value ends the bundle ("-qo out.exr", "-qoout.exr"). */
int fp_options_parse(int argc, char **argv, fp_params_t *p)
{
    int rc;
    /* Presets first, so that the command line wins over them. */
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--") == 0)
            break;
        const char *file = NULL;
        if (strcmp(a, "--preset") == 0) {
            if (i + 1 >= argc)
                return fp_usage_error("command line: --preset needs a NAME or FILE");
            file = argv[++i];
        } else if (strncmp(a, "--preset=", 9) == 0) {
            file = a + 9;
        } else if (a[0] == '-' && a[1] != '-') {
            /* A bundle's value is its own; skip it as the loop below does. */
            for (const char *c = a + 1; *c; c++) {
                const fp_option_t *o = find_short(*c);
                if (!o || o->type == FP_OPT_FLAG)
                    continue;
                if (!c[1])
                    i++;
                break;
            }
        }
        if (file && (rc = fp_options_load_preset(p, file)))
            return rc;
    }
    for (int i = 1; i < argc; i++) {
        char *a = argv[i];
        const fp_option_t *o = NULL;
        const char *value = NULL;
        char name[128];
        if (strcmp(a, "--") == 0)
            return fp_usage_error("command line: unexpected argument after --");
        if (a[0] == '-' && a[1] == '-') {
            const char *eq = strchr(a + 2, '=');
            size_t n = eq ? (size_t)(eq - a - 2) : strlen(a + 2);
            if (n >= sizeof name)
                n = sizeof name - 1;
            memcpy(name, a + 2, n);
            name[n] = 0;
            o = fp_options_find(name);
            if (!o)
                return fp_usage_error("command line: unknown option --%s (see fogpipe --help)", name);
            if (eq)
                value = eq + 1;
        } else if (a[0] == '-' && a[1]) {
            /* The bundle's flags before the last option are applied here. */
            const char *c = a + 1;
            for (;; c++) {
                o = find_short(*c);
                if (!o)
                    return fp_usage_error("command line: unknown option -%c%s%s (see fogpipe --help)",
                                          *c, a[2] ? " in " : "", a[2] ? a : "");
                if (o->type != FP_OPT_FLAG) {
                    if (c[1])
                        value = c + 1;
                    break;
                }
                if (!c[1])
                    break;
                if ((rc = fp_options_apply(p, o->name, NULL, "command line")))
                    return rc;
            }
        } else {
            return fp_usage_error("command line: unexpected argument '%s' (options start with --; "
                                  "use -i/-o for files)", a);
        }
        if (o->type != FP_OPT_FLAG && !value) {
            if (i + 1 >= argc)
                return fp_usage_error("command line: --%s needs a value %s", o->name,
                                      o->metavar ? o->metavar : "");
            value = argv[++i];
        }
        if (strcmp(o->name, "preset") == 0)
            continue;   /* applied above */
        if ((rc = fp_options_apply(p, o->name, value, "command line")))
            return rc;
    }
    return FP_OK;
}

static const char *type_metavar(const fp_option_t *o)
{
    if (o->metavar)
        return o->metavar;
    switch (o->type) {
    case FP_OPT_INT: return "N";
    case FP_OPT_REAL: return "X";
    case FP_OPT_STRING: return "TEXT";
    case FP_OPT_ENUM: return o->choices;
    default: return "";
    }
}

/* Escape '|' for Markdown tables. */
static void md_print(FILE *out, const char *s)
{
    for (; *s; s++) {
        if (*s == '|')
            fputs("\\|", out);
        else
            fputc(*s, out);
    }
}

/* The width --help wraps to: $COLUMNS when set (as GNU programs and
 * Python's argparse take it), else the terminal's when OUT is one, else 80.
 * At least 40, so the options keep a column. */
static int help_width(FILE *out)
{
    int w = 0;
    const char *env = getenv("COLUMNS");
    if (env && *env) {
        char *end;
        long v = strtol(env, &end, 10);
        if (!*end && v > 0 && v < 10000)
            w = (int)v;
    }
#ifdef TIOCGWINSZ
    struct winsize ws;
    if (!w && isatty(fileno(out)) && ioctl(fileno(out), TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0)
        w = ws.ws_col;
#endif
    if (!w)
        w = 80;
    return w < 40 ? 40 : w;
}

/* Write TEXT from column COL (the cursor is there), wrapped at WIDTH, the
 * following lines indented by INDENT; a word longer than a line is cut.
 * Ends the line. */
static void wrap(FILE *out, const char *text, int col, int indent, int width)
{
    const char *s = text;
    int fresh = 1;   /* nothing written on this line after the indent */
    while (*s) {
        while (*s == ' ')
            s++;
        if (!*s)
            break;
        int n = (int)strcspn(s, " ");
        if (!fresh && col + 1 + n > width) {
            fprintf(out, "\n%*s", indent, "");
            col = indent;
            fresh = 1;
        }
        if (!fresh) {
            fputc(' ', out);
            col++;
        }
        while (col + n > width) {
            /* A word wider than the line: cut after its last ',', ':' or
             * '|' that fits, else where the line ends. */
            int room = width - col;
            for (int k = room; k > room / 2; k--)
                if (strchr(",:|", s[k - 1])) {
                    room = k;
                    break;
                }
            fprintf(out, "%.*s\n%*s", room, s, indent, "");
            s += room;
            n -= room;
            col = indent;
        }
        fprintf(out, "%.*s", n, s);
        col += n;
        s += n;
        fresh = 0;
    }
    fputc('\n', out);
}

void fp_options_print_help(FILE *out, int markdown)
{
    const int width = markdown ? 0 : help_width(out);
    /* The descriptions' column: beside the options on a wide screen, under
     * them on a narrow one. */
    const int desc_col = width >= 72 ? 37 : 8;
    if (!markdown) {
        fputs("Usage: ", out);
        wrap(out, "fogpipe -i INPUT -o OUTPUT [--frames LIST] [options]", 7, 15, width);
        fputs("       ", out);
        wrap(out, "fogpipe [options] < in.exr > out.exr", 7, 15, width);
        wrap(out, "Adds physically based fog to color + depth OpenEXR frames.", 0, 0, width);
        wrap(out, "INPUT/OUTPUT: a file, a sequence pattern (shot.####.exr, shot.%04d.exr), "
             "or - for a stream of concatenated EXR files on stdin/stdout.", 0, 0, width);
    }
    for (const fp_option_group_t *g = fp_option_groups; g->title; g++) {
        if (markdown)
            fprintf(out, "\n### %s\n\n| option | default | range | description |\n|---|---|---|---|\n",
                    g->title);
        else
            fprintf(out, "\n%s:\n", g->title);
        for (const fp_option_t *o = g->options; o->name; o++) {
            if (o->flags & FP_OPTF_HIDDEN)
                continue;
            char opt[160], range[96] = "", def[96] = "";
            const char *mv = o->type == FP_OPT_FLAG ? "" : type_metavar(o);
            if (o->short_name)
                snprintf(opt, sizeof opt, "-%c, --%s%s%s", o->short_name, o->name,
                         *mv ? " " : "", mv);
            else
                snprintf(opt, sizeof opt, "--%s%s%s", o->name, *mv ? " " : "", mv);
            if (o->type == FP_OPT_INT || o->type == FP_OPT_REAL || o->type == FP_OPT_VEC)
                range_text(o, range, sizeof range);
            else if (o->type == FP_OPT_ENUM)
                snprintf(range, sizeof range, "%s", o->choices);
            if (o->def)
                snprintf(def, sizeof def, "%s", o->def);
            if (markdown) {
                fputs("| `", out);
                md_print(out, opt);
                fputs("` | ", out);
                md_print(out, *def ? def : (o->type == FP_OPT_FLAG ? "off" : "-"));
                fputs(" | ", out);
                md_print(out, *range ? range : "-");
                fputs(" | ", out);
                md_print(out, o->help);
                fputs(" |\n", out);
            } else {
                char text[2048];
                int n = snprintf(text, sizeof text, "%s", o->help);
                if (*def && o->type != FP_OPT_FLAG && n < (int)sizeof text)
                    n += snprintf(text + n, sizeof text - n, " [default: %s]", def);
                if (*range && o->type != FP_OPT_ENUM && n < (int)sizeof text)
                    snprintf(text + n, sizeof text - n, " [range: %s]", range);
                int col = 2 + (int)strlen(opt);
                fputs("  ", out);
                if (col > width) {
                    wrap(out, opt, 2, 4, width);
                    fprintf(out, "%*s", desc_col, "");
                } else if (col + 1 > desc_col) {
                    fprintf(out, "%s\n%*s", opt, desc_col, "");
                } else {
                    fprintf(out, "%s%*s", opt, desc_col - col, "");
                }
                wrap(out, text, desc_col, desc_col, width);
            }
        }
    }
    if (!markdown) {
        fputc('\n', out);
        wrap(out, "Environment: FOGPIPE_DEVICE (as --device), FOGPIPE_CACHE_DIR (OpenCL program "
             "cache; 'off' disables), OCIO (as --ocio).", 0, 0, width);
        fprintf(out, "%s %s\n", PACKAGE_NAME, PACKAGE_VERSION);
    }
}

void fp_options_free(fp_params_t *p)
{
    for (const fp_option_group_t *g = fp_option_groups; g->title; g++)
        for (const fp_option_t *o = g->options; o->name; o++)
            if (o->type == FP_OPT_STRING) {
                char **s = (char **)((char *)p + o->offset);
                free(*s);
                *s = NULL;
            }
    /* The lights (fp_light_append, filters/scatter.c). */
    free(p->light.lights);
    p->light.lights = NULL;
    p->light.num_lights = p->light.cap_lights = 0;
}
