#include "json.h"
#include "fp.h"
#include "textfile.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define JSON_MAX_DEPTH 64
#define JSON_MAX_VALUES (1L << 20)

typedef struct parser_t {
    const char *s, *end;
    const char *path;
    int line;
    int depth;
    long values;
} parser_t;

static int fail(parser_t *p, const char *what)
{
    return fp_usage_error("%s:%d: %s", p->path, p->line, what);
}

static void skip_ws(parser_t *p)
{
    while (p->s < p->end && (*p->s == ' ' || *p->s == '\t' || *p->s == '\n' || *p->s == '\r')) {
        p->line += *p->s == '\n';
        p->s++;
    }
}

static int hex4(const char *s, unsigned *out)
{
    unsigned v = 0;
    for (int i = 0; i < 4; i++) {
        char c = s[i];
        v <<= 4;
        if (c >= '0' && c <= '9')
            v |= (unsigned)(c - '0');
        else if (c >= 'a' && c <= 'f')
            v |= (unsigned)(c - 'a' + 10);
        else if (c >= 'A' && c <= 'F')
            v |= (unsigned)(c - 'A' + 10);
        else
            return -1;
    }
    *out = v;
    return 0;
}

/* A string after its opening quote, into a new NUL-terminated string. */
static int parse_string(parser_t *p, char **out)
{
    size_t cap = 32, n = 0;
    char *buf = malloc(cap);
    if (!buf)
        return fp_error("%s: out of memory", p->path);
    for (;;) {
        if (p->s >= p->end) {
            free(buf);
            return fail(p, "unterminated string (expected a closing '\"')");
        }
        unsigned char c = (unsigned char)*p->s++;
        char enc[4];
        int ne = 1;
        enc[0] = (char)c;
        if (c == '"')
            break;
        if (c < 0x20) {
            free(buf);
            return fail(p, "a control character in a string (expected it escaped)");
        }
        if (c == '\\') {
            if (p->s >= p->end) {
                free(buf);
                return fail(p, "unterminated string (expected a closing '\"')");
            }
            char e = *p->s++;
            const char *simple = strchr("\"\\/bfnrt", e);
            if (e && simple) {
                static const char map[] = "\"\\/\b\f\n\r\t";
                enc[0] = map[simple - "\"\\/bfnrt"];
            } else if (e == 'u') {
                unsigned u, lo;
                if (p->end - p->s < 4 || hex4(p->s, &u)) {
                    free(buf);
                    return fail(p, "bad \\u escape (expected 4 hex digits)");
                }
                p->s += 4;
                if (u >= 0xD800 && u < 0xDC00) {
                    if (p->end - p->s < 6 || p->s[0] != '\\' || p->s[1] != 'u' ||
                        hex4(p->s + 2, &lo) || lo < 0xDC00 || lo >= 0xE000) {
                        free(buf);
                        return fail(p, "a lone UTF-16 surrogate in a \\u escape (expected a pair)");
                    }
                    p->s += 6;
                    u = 0x10000 + ((u - 0xD800) << 10) + (lo - 0xDC00);
                } else if (u >= 0xDC00 && u < 0xE000) {
                    free(buf);
                    return fail(p, "a lone UTF-16 surrogate in a \\u escape (expected a pair)");
                }
                if (u == 0) {
                    free(buf);
                    return fail(p, "\\u0000 in a string (expected no NUL character)");
                }
                if (u < 0x80) {
                    enc[0] = (char)u;
                } else if (u < 0x800) {
                    enc[0] = (char)(0xC0 | (u >> 6));
                    enc[1] = (char)(0x80 | (u & 0x3F));
                    ne = 2;
                } else if (u < 0x10000) {
                    enc[0] = (char)(0xE0 | (u >> 12));
                    enc[1] = (char)(0x80 | ((u >> 6) & 0x3F));
                    enc[2] = (char)(0x80 | (u & 0x3F));
                    ne = 3;
                } else {
                    enc[0] = (char)(0xF0 | (u >> 18));
                    enc[1] = (char)(0x80 | ((u >> 12) & 0x3F));
                    enc[2] = (char)(0x80 | ((u >> 6) & 0x3F));
                    enc[3] = (char)(0x80 | (u & 0x3F));
                    ne = 4;
                }
            } else {
                free(buf);
                return fail(p, "bad escape in a string (expected one of \\\" \\\\ \\/ \\b \\f "
                               "\\n \\r \\t \\uXXXX)");
            }
        }
        if (n + (size_t)ne + 1 > cap) {
            char *b = realloc(buf, cap * 2);
            if (!b) {
                free(buf);
                return fp_error("%s: out of memory", p->path);
            }
            buf = b;
            cap *= 2;
        }
        memcpy(buf + n, enc, (size_t)ne);
        n += (size_t)ne;
    }
    buf[n] = 0;
    *out = buf;
    return FP_OK;
}

/* JSON's number grammar: -?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)? */
static int parse_number(parser_t *p, double *out)
{
    const char *s = p->s, *e = p->end;
    const char *start = s;
    if (s < e && *s == '-')
        s++;
    if (s < e && *s == '0') {
        s++;
    } else if (s < e && *s >= '1' && *s <= '9') {
        while (s < e && *s >= '0' && *s <= '9')
            s++;
    } else {
        return fail(p, "bad number (expected JSON's digits)");
    }
    if (s < e && *s == '.') {
        s++;
        if (!(s < e && *s >= '0' && *s <= '9'))
            return fail(p, "bad number (expected digits after '.')");
        while (s < e && *s >= '0' && *s <= '9')
            s++;
    }
    if (s < e && (*s == 'e' || *s == 'E')) {
        s++;
        if (s < e && (*s == '+' || *s == '-'))
            s++;
        if (!(s < e && *s >= '0' && *s <= '9'))
            return fail(p, "bad number (expected digits in the exponent)");
        while (s < e && *s >= '0' && *s <= '9')
            s++;
    }
    char tmp[64];
    size_t n = (size_t)(s - start);
    if (n >= sizeof tmp)
        return fail(p, "a number of more than 63 characters (expected a shorter one)");
    memcpy(tmp, start, n);
    tmp[n] = 0;
    errno = 0;
    double v = strtod(tmp, NULL);
    if (!isfinite(v) || errno == ERANGE) {
        if (isfinite(v) && fabs(v) < 1)   /* underflow: as good as 0 */
            v = 0;
        else
            return fail(p, "a number out of range (expected a finite one)");
    }
    *out = v;
    p->s = s;
    return FP_OK;
}

static int parse_value(parser_t *p, fp_json_t *v);

static int grow(parser_t *p, fp_json_t *v, int *cap, int with_keys)
{
    if (v->n < *cap)
        return FP_OK;
    int nc = *cap ? *cap * 2 : 4;
    fp_json_t *items = realloc(v->items, (size_t)nc * sizeof *items);
    if (!items)
        return fp_error("%s: out of memory", p->path);
    v->items = items;
    if (with_keys) {
        char **keys = realloc(v->keys, (size_t)nc * sizeof *keys);
        if (!keys)
            return fp_error("%s: out of memory", p->path);
        v->keys = keys;
    }
    *cap = nc;
    return FP_OK;
}

static int parse_container(parser_t *p, fp_json_t *v, int object)
{
    char close = object ? '}' : ']';
    int cap = 0, rc;
    if (++p->depth > JSON_MAX_DEPTH)
        return fail(p, "nested more than 64 levels deep (expected a rig)");
    skip_ws(p);
    if (p->s < p->end && *p->s == close) {
        p->s++;
        p->depth--;
        return FP_OK;
    }
    for (;;) {
        if ((rc = grow(p, v, &cap, object)))
            return rc;
        char *key = NULL;
        if (object) {
            skip_ws(p);
            if (!(p->s < p->end && *p->s == '"'))
                return fail(p, "expected a \"key\" in an object");
            p->s++;
            if ((rc = parse_string(p, &key)))
                return rc;
            for (int i = 0; i < v->n; i++)
                if (strcmp(v->keys[i], key) == 0) {
                    char msg[200];
                    snprintf(msg, sizeof msg, "key \"%.100s\" twice in one object (expected "
                             "each once)", key);
                    free(key);
                    return fail(p, msg);
                }
            skip_ws(p);
            if (!(p->s < p->end && *p->s == ':')) {
                free(key);
                return fail(p, "expected ':' after a key");
            }
            p->s++;
            v->keys[v->n] = key;
        }
        memset(&v->items[v->n], 0, sizeof v->items[0]);
        v->n++;
        if ((rc = parse_value(p, &v->items[v->n - 1])))
            return rc;
        skip_ws(p);
        if (p->s < p->end && *p->s == ',') {
            p->s++;
            skip_ws(p);
            if (p->s < p->end && *p->s == close)
                return fail(p, "a trailing comma (expected another value)");
            continue;
        }
        if (p->s < p->end && *p->s == close) {
            p->s++;
            p->depth--;
            return FP_OK;
        }
        return fail(p, object ? "expected ',' or '}' in an object" : "expected ',' or ']' in "
                                                                     "an array");
    }
}

static int literal(parser_t *p, const char *word)
{
    size_t n = strlen(word);
    if ((size_t)(p->end - p->s) < n || memcmp(p->s, word, n) != 0)
        return 0;
    p->s += n;
    return 1;
}

static int parse_value(parser_t *p, fp_json_t *v)
{
    skip_ws(p);
    v->line = p->line;
    if (++p->values > JSON_MAX_VALUES)
        return fail(p, "more than 1M values (expected a rig)");
    if (p->s >= p->end)
        return fail(p, "unexpected end (expected a value)");
    char c = *p->s;
    if (c == '{' || c == '[') {
        p->s++;
        v->type = c == '{' ? FP_JSON_OBJECT : FP_JSON_ARRAY;
        return parse_container(p, v, c == '{');
    }
    if (c == '"') {
        p->s++;
        v->type = FP_JSON_STRING;
        return parse_string(p, &v->string);
    }
    if (c == '-' || (c >= '0' && c <= '9')) {
        v->type = FP_JSON_NUMBER;
        return parse_number(p, &v->number);
    }
    if (literal(p, "true") || literal(p, "false")) {
        v->type = FP_JSON_BOOL;
        v->boolean = p->s[-1] == 'e' && p->s[-2] == 'u';
        return FP_OK;
    }
    if (literal(p, "null")) {
        v->type = FP_JSON_NULL;
        return FP_OK;
    }
    return fail(p, "unexpected character (expected a JSON value: object, array, string, "
                   "number, true, false or null)");
}

int fp_json_parse(const char *text, size_t len, const char *path, fp_json_t *out)
{
    memset(out, 0, sizeof *out);
    parser_t p = { text, text + len, path, 1, 0, 0 };
    /* A UTF-8 byte order mark is allowed before the value (RFC 8259 8.1). */
    if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0)
        p.s += 3;
    int rc = parse_value(&p, out);
    if (rc == FP_OK) {
        skip_ws(&p);
        if (p.s < p.end)
            rc = fail(&p, "text after the value (expected one JSON value)");
    }
    if (rc)
        fp_json_free(out);
    return rc;
}

int fp_json_load(const char *path, const char *what, fp_json_t *out)
{
    memset(out, 0, sizeof *out);
    char *text;
    size_t len;
    int rc = fp_text_read_all(path, what, 1, &text, &len);
    if (rc)
        return rc;
    rc = fp_json_parse(text, len, path, out);
    free(text);
    return rc;
}

const fp_json_t *fp_json_get(const fp_json_t *obj, const char *key)
{
    if (!obj || obj->type != FP_JSON_OBJECT)
        return NULL;
    for (int i = 0; i < obj->n; i++)
        if (strcmp(obj->keys[i], key) == 0)
            return &obj->items[i];
    return NULL;
}

const char *fp_json_type_name(fp_json_type_t t)
{
    static const char *const names[] = { "null", "a boolean", "a number", "a string",
                                         "an array", "an object" };
    return (unsigned)t < FP_ARRAY_LEN(names) ? names[t] : "?";
}

void fp_json_free(fp_json_t *v)
{
    if (!v)
        return;
    for (int i = 0; i < v->n; i++) {
        fp_json_free(&v->items[i]);
        if (v->keys)
            free(v->keys[i]);
    }
    free(v->items);
    free(v->keys);
    free(v->string);
    memset(v, 0, sizeof *v);
}
