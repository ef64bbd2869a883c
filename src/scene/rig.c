#include "rig.h"
#include "fp.h"
#include "json.h"
#include "options.h"
#include "seq.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ the rig */

void fp_rig_free(fp_rig_t *r)
{
    free(r->shadow);
    free(r->lights);
    free(r->look);
    free(r->cut);
    memset(r, 0, sizeof *r);
}

static int dup_into(char **dst, const char *src)
{
    char *c = strdup(src);
    if (!c)
        return fp_error("out of memory");
    free(*dst);
    *dst = c;
    return FP_OK;
}

int fp_rig_merge(fp_rig_t *dst, const fp_rig_t *over)
{
    if (over->has_up) {
        dst->has_up = 1;
        dst->up = over->up;
    }
    if (over->has_clip) {
        dst->has_clip = 1;
        dst->clip = over->clip;
    }
    if (over->shadow && dup_into(&dst->shadow, over->shadow))
        return FP_ERR;
    if (over->look) {
        if (dup_into(&dst->look, over->look))
            return FP_ERR;
        snprintf(dst->look_from, sizeof dst->look_from, "%s", over->look_from);
    }
    if (over->has_lights) {
        fp_rig_light_t *l = NULL;
        if (over->nlights && !(l = malloc((size_t)over->nlights * sizeof *l)))
            return fp_error("out of memory");
        if (over->nlights)
            memcpy(l, over->lights, (size_t)over->nlights * sizeof *l);
        free(dst->lights);
        dst->lights = l;
        dst->nlights = over->nlights;
        dst->has_lights = 1;
        free(dst->cut);
        dst->cut = NULL;
    }
    if (over->cut && !over->has_lights && !dst->cut && dup_into(&dst->cut, over->cut))
        return FP_ERR;
    dst->any |= over->any;
    return FP_OK;
}

static double norm3(const double v[3])
{
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* NULL, or what is wrong with a light (after its numbers were read, all
 * finite); directions are normalized here. */
static const char *check_light(fp_rig_light_t *l)
{
    for (int c = 0; c < 3; c++)
        if (!(l->rgb[c] >= 0) || !(l->rgb[c] < 1e30))
            return "color x strength must be finite and >= 0";
    for (int c = 0; c < 3; c++)
        if (!(fabs(l->pos[c]) < 1e30))
            return "its position must be below 1e30";
    double n = norm3(l->dir);
    if (!(n > 0) || !(n < 1e300))
        return l->type == FP_RIG_SUN ? "the direction toward the sun must be non-zero"
               : l->type == FP_RIG_AREA ? "the normal must be non-zero"
                                        : "the spot's direction must be non-zero";
    for (int c = 0; c < 3; c++)
        l->dir[c] /= n;
    switch (l->type) {
    case FP_RIG_SUN:
        if (!(l->angle >= 0 && l->angle <= 180))
            return "the sun's angular diameter must be 0..180 degrees";
        break;
    case FP_RIG_SPOT:
        if (!(l->size > 0 && l->size <= 180))
            return "the spot's SIZE (full cone angle) must be in (0, 180] degrees";
        if (!(l->blend >= 0 && l->blend <= 1))
            return "the spot's BLEND must be 0..1";
        /* fall through */
    case FP_RIG_POINT:
        if (!(l->radius >= 0 && l->radius < 1e30))
            return "the radius must be finite and >= 0";
        break;
    case FP_RIG_AREA: {
        double un = norm3(l->u);
        if (!(un > 0) || !(un < 1e300))
            return "the area's U axis must be non-zero";
        for (int c = 0; c < 3; c++)
            l->u[c] /= un;
        double d = l->u[0] * l->dir[0] + l->u[1] * l->dir[1] + l->u[2] * l->dir[2];
        if (fabs(d) > 1e-3)
            return "the area's U axis must be perpendicular to its normal";
        for (int k = 0; k < 2; k++)
            if (!(l->extent[k] > 0 && l->extent[k] < 1e30))
                return "the area's sizes SU SV must be finite and > 0";
        if (l->shape != 0 && l->shape != 1)
            return "the area's SHAPE must be 0 (rectangle) or 1 (ellipse)";
        break;
    }
    }
    return NULL;
}

static int add_light(fp_rig_t *r, const fp_rig_light_t *l, int *cap)
{
    if (r->nlights >= *cap) {
        int nc = *cap ? *cap * 2 : 8;
        fp_rig_light_t *n = realloc(r->lights, (size_t)nc * sizeof *n);
        if (!n)
            return fp_error("out of memory");
        r->lights = n;
        *cap = nc;
    }
    r->lights[r->nlights++] = *l;
    return FP_OK;
}

/* ------------------------------------------------------------ text form */

typedef struct tok_t {
    const char *s;
    char buf[4096];
} tok_t;

/* The next token (whitespace or ';' separate them): 1, or 0 at the end. */
static int next_tok(tok_t *t)
{
    while (*t->s && (isspace((unsigned char)*t->s) || *t->s == ';'))
        t->s++;
    t->buf[0] = 0;
    if (!*t->s)
        return 0;
    size_t n = 0;
    while (*t->s && !isspace((unsigned char)*t->s) && *t->s != ';') {
        if (n + 1 < sizeof t->buf)
            t->buf[n++] = *t->s;
        t->s++;
    }
    t->buf[n] = 0;
    return 1;
}

static int tok_number(const char *s, double *v)
{
    char *end;
    errno = 0;
    *v = strtod(s, &end);
    return end != s && !*end && isfinite(*v) && errno != ERANGE ? 0 : -1;
}

static int light_numbers(int type)
{
    return type == FP_RIG_SUN ? 7 : type == FP_RIG_POINT ? 7 : type == FP_RIG_SPOT ? 12 : 15;
}

static void light_from_numbers(int type, const double *v, fp_rig_light_t *l)
{
    memset(l, 0, sizeof *l);
    l->type = type;
    const double *p = v;
    if (type == FP_RIG_SUN) {
        memcpy(l->dir, p, 3 * sizeof *p);
        memcpy(l->rgb, p + 3, 3 * sizeof *p);
        l->angle = p[6];
        return;
    }
    memcpy(l->pos, p, 3 * sizeof *p);
    memcpy(l->rgb, p + 3, 3 * sizeof *p);
    if (type == FP_RIG_POINT) {
        l->radius = p[6];
        l->dir[2] = -1;   /* unused; valid for the check */
    } else if (type == FP_RIG_SPOT) {
        l->radius = p[6];
        memcpy(l->dir, p + 7, 3 * sizeof *p);
        l->size = p[10];
        l->blend = p[11];
    } else {
        memcpy(l->dir, p + 6, 3 * sizeof *p);
        memcpy(l->u, p + 9, 3 * sizeof *p);
        l->extent[0] = p[12];
        l->extent[1] = p[13];
        l->shape = p[14] == 0 ? 0 : p[14] == 1 ? 1 : -1;
    }
}

static const char *const light_names[] = { "sun", "point", "spot", "area" };
static const char *const light_forms[] = {
    "sun DX DY DZ R G B ANGLE", "point X Y Z R G B RADIUS",
    "spot X Y Z R G B RADIUS AX AY AZ SIZE BLEND",
    "area X Y Z R G B NX NY NZ UX UY UZ SU SV SHAPE"
};

int fp_rig_parse_text(const char *text, const char *what, fp_rig_t *out, int *declared,
                      int *complete)
{
    memset(out, 0, sizeof *out);
    *declared = -1;
    *complete = 1;
    const char *s = strstr(text, "fogpipe-rig");
    int cap = 0, rc = FP_OK;
    tok_t t;
    if (!s)
        return fp_error("%s: expected 'fogpipe-rig 1 ...'", what);
    t.s = s + strlen("fogpipe-rig");
    double v;
    if (!next_tok(&t) || tok_number(t.buf, &v) || v != 1)
        return fp_error("%s: expected 'fogpipe-rig 1' (version 1 of the rig schema), got "
                        "'fogpipe-rig %.40s'", what, t.s ? t.buf : "");
    out->any = 1;
    int in_lights = 0;
    while (next_tok(&t)) {
        const char *k = t.buf;
        if (strncmp(k, "fogpipe-", 8) == 0)
            break;   /* the next section (fogpipe-camera, fogpipe-look) */
        int type = -1;
        for (int i = 0; i < 4; i++)
            if (strcmp(k, light_names[i]) == 0)
                type = i;
        if (type >= 0) {
            double num[16];
            int need = light_numbers(type), got = 0;
            while (got < need && next_tok(&t) && tok_number(t.buf, &num[got]) == 0)
                got++;
            if (got < need) {
                /* The text ends in the middle of a light: cut off
                 * (Blender's Note holds 767 bytes) when it said how many
                 * lights there are; malformed otherwise. */
                if (*declared >= 0 && !t.buf[0]) {
                    *complete = 0;
                    break;
                }
                rc = fp_error("%s: light %d: expected '%s' (%d numbers), got %d number%s%s%.40s%s",
                              what, out->nlights + 1, light_forms[type], need, got,
                              got == 1 ? "" : "s", t.buf[0] ? " then '" : " and the end",
                              t.buf, t.buf[0] ? "'" : "");
                goto fail;
            }
            fp_rig_light_t l;
            light_from_numbers(type, num, &l);
            const char *why = check_light(&l);
            if (why) {
                rc = fp_error("%s: light %d (%s): %s", what, out->nlights + 1, light_names[type],
                              why);
                goto fail;
            }
            if (out->nlights >= FP_RIG_MAX_LIGHTS) {
                rc = fp_error("%s: more than %d lights (expected at most %d)", what,
                              FP_RIG_MAX_LIGHTS, FP_RIG_MAX_LIGHTS);
                goto fail;
            }
            if ((rc = add_light(out, &l, &cap)))
                goto fail;
            out->has_lights = 1;
            in_lights = 1;
            t.buf[0] = 0;
            continue;
        }
        if (in_lights) {
            rc = fp_error("%s: '%.40s' after the lights (expected sun, point, spot or area)",
                          what, k);
            goto fail;
        }
        char key[16];
        snprintf(key, sizeof key, "%.15s", k);
        int have = next_tok(&t);
        if (strcmp(key, "up") == 0) {
            if (!have || (strcmp(t.buf, "y") && strcmp(t.buf, "z"))) {
                rc = fp_error("%s: 'up %.40s' (expected up y or up z)", what, have ? t.buf : "");
                goto fail;
            }
            out->has_up = 1;
            out->up = t.buf[0] == 'z' ? FP_UP_Z : FP_UP_Y;
        } else if (strcmp(key, "clip") == 0) {
            if (!have || tok_number(t.buf, &v) || !(v >= 0 && v < 1e9)) {
                rc = fp_error("%s: 'clip %.40s' (expected the clip start, a number 0..1e9)",
                              what, have ? t.buf : "");
                goto fail;
            }
            out->has_clip = 1;
            out->clip = v;
        } else if (strcmp(key, "shadow") == 0) {
            if (!have || strncmp(t.buf, "fogpipe-", 8) == 0) {
                rc = fp_error("%s: 'shadow' without a PATH (expected shadow PATH)", what);
                goto fail;
            }
            if ((rc = dup_into(&out->shadow, t.buf)))
                goto fail;
        } else if (strcmp(key, "lights") == 0) {
            if (!have || tok_number(t.buf, &v) || v != floor(v) || v < 0 ||
                v > FP_RIG_MAX_LIGHTS) {
                rc = fp_error("%s: 'lights %.40s' (expected the number of lights, 0..%d)", what,
                              have ? t.buf : "", FP_RIG_MAX_LIGHTS);
                goto fail;
            }
            *declared = (int)v;
            out->has_lights = 1;
        } else {
            rc = fp_error("%s: unknown key '%.40s' (expected up, clip, shadow, lights, or a "
                          "light: sun, point, spot, area)", what, key);
            goto fail;
        }
    }
    if (*declared >= 0 && out->nlights < *declared)
        *complete = 0;
    if (*declared >= 0 && out->nlights > *declared) {
        rc = fp_error("%s: the rig says %d lights but carries %d (expected as many as it says)",
                      what, *declared, out->nlights);
        goto fail;
    }
    return FP_OK;
fail:
    fp_rig_free(out);
    return rc ? rc : FP_ERR;
}

int fp_rig_from_frame(const fp_frame_info_t *info, const char *where_file, long frame,
                      fp_rig_t *out)
{
    memset(out, 0, sizeof *out);
    const fp_rig_attrs_t *a = &info->rig;
    char what[600];
    int rc = FP_OK, declared, complete;
    fp_rig_t typed;
    memset(&typed, 0, sizeof typed);
    if (a->bad[0])
        return fp_error("%s: frame %ld: %s", where_file, frame, a->bad);
    if (a->has_version && a->version != 1)
        return fp_error("%s: frame %ld: attribute 'fogpipeRigVersion' is %d (expected 1, the "
                        "rig schema this fogpipe reads)", where_file, frame, a->version);
    if (a->text) {
        snprintf(what, sizeof what, "%.400s: frame %ld: attribute '%.100s'", where_file, frame,
                 a->text_attr);
        if ((rc = fp_rig_parse_text(a->text, what, out, &declared, &complete)))
            return rc;
        if (!complete && !(a->rig && strstr(a->rig, "fogpipe-rig"))) {
            /* An error only if the lights are used: --lights none, or
             * flags for both the sun and the local lights, need none. */
            char msg[800];
            snprintf(msg, sizeof msg, "%.400s: frame %ld: the rig says %d lights but carries %d "
                     "and there is no fogpipeRig attribute (expected the whole rig there when "
                     "the text is cut off)", where_file, frame, declared, out->nlights);
            if (!(out->cut = strdup(msg))) {
                rc = fp_error("out of memory");
                goto fail;
            }
        }
    }
    if (a->rig) {
        snprintf(what, sizeof what, "%.400s: frame %ld: attribute 'fogpipeRig'", where_file,
                 frame);
        if ((rc = fp_rig_parse_text(a->rig, what, &typed, &declared, &complete)))
            goto fail;
        if (!complete) {
            rc = fp_error("%s: the rig says %d lights but carries %d (expected all of them)",
                          what, declared, typed.nlights);
            goto fail;
        }
    }
    if (a->up) {
        if (strcmp(a->up, "y") && strcmp(a->up, "z")) {
            rc = fp_error("%s: frame %ld: attribute 'fogpipeUp' is '%.40s' (expected \"y\" or "
                          "\"z\")", where_file, frame, a->up);
            goto fail;
        }
        typed.has_up = 1;
        typed.up = a->up[0] == 'z' ? FP_UP_Z : FP_UP_Y;
        typed.any = 1;
    }
    if (a->has_clip) {
        if (!(a->clip >= 0 && a->clip < 1e9)) {
            rc = fp_error("%s: frame %ld: attribute 'fogpipeClipStart' is %g (expected a clip "
                          "start 0..1e9)", where_file, frame, a->clip);
            goto fail;
        }
        typed.has_clip = 1;
        typed.clip = a->clip;
        typed.any = 1;
    }
    if (a->shadow_map) {
        if (!a->shadow_map[0]) {
            rc = fp_error("%s: frame %ld: attribute 'fogpipeShadowMap' is empty (expected a "
                          "file name)", where_file, frame);
            goto fail;
        }
        if ((rc = dup_into(&typed.shadow, a->shadow_map)))
            goto fail;
        typed.any = 1;
    }
    if (a->look) {
        if ((rc = dup_into(&typed.look, a->look)))
            goto fail;
        snprintf(typed.look_from, sizeof typed.look_from, "%.200s: frame %ld: attribute '%.60s'",
                 where_file, frame, a->look_attr);
        typed.any = 1;
    }
    if (a->has_version)
        typed.any = 1;
    rc = fp_rig_merge(out, &typed);
fail:
    fp_rig_free(&typed);
    if (rc)
        fp_rig_free(out);
    return rc;
}

/* ------------------------------------------------------------ JSON file */

struct fp_rig_file_t {
    char *path;
    fp_rig_t base;
    int nframes;
    long *frame_nums;
    fp_rig_t *frames;
};

/* n finite numbers from a JSON array. */
static int json_vec(const fp_json_t *v, int n, double *out)
{
    if (!v || v->type != FP_JSON_ARRAY || v->n != n)
        return -1;
    for (int i = 0; i < n; i++) {
        if (v->items[i].type != FP_JSON_NUMBER)
            return -1;
        out[i] = v->items[i].number;
    }
    return 0;
}

static int json_light(const char *path, int idx, const fp_json_t *j, fp_rig_light_t *l)
{
    memset(l, 0, sizeof *l);
    const fp_json_t *t = fp_json_get(j, "type");
    if (j->type != FP_JSON_OBJECT || !t || t->type != FP_JSON_STRING)
        return fp_usage_error("%s:%d: light %d: expected an object with \"type\": \"sun\", "
                              "\"point\", \"spot\" or \"area\"", path, j->line, idx + 1);
    l->type = -1;
    for (int i = 0; i < 4; i++)
        if (strcmp(t->string, light_names[i]) == 0)
            l->type = i;
    if (l->type < 0)
        return fp_usage_error("%s:%d: light %d: unknown type \"%.40s\" (expected sun, point, "
                              "spot or area)", path, j->line, idx + 1, t->string);
    /* Every key the type takes, and only those. */
    static const char *const keys[4][8] = {
        { "type", "direction", "irradiance", "angle", NULL },
        { "type", "position", "intensity", "radius", NULL },
        { "type", "position", "intensity", "radius", "direction", "size", "blend", NULL },
        { "type", "position", "intensity", "normal", "u", "size", "shape", NULL },
    };
    const char *const *want = keys[l->type];
    int nwant = 0;
    while (want[nwant])
        nwant++;
    for (int i = 0; i < j->n; i++) {
        int ok = 0;
        for (int k = 0; k < nwant; k++)
            ok |= strcmp(j->keys[i], want[k]) == 0;
        if (!ok)
            return fp_usage_error("%s:%d: light %d (%s): unknown key \"%.40s\"", path,
                                  j->items[i].line, idx + 1, light_names[l->type], j->keys[i]);
    }
    for (int k = 1; k < nwant; k++) {
        const char *key = want[k];
        const fp_json_t *v = fp_json_get(j, key);
        int bad;
        const char *expect = "3 numbers";
        if (!v) {
            return fp_usage_error("%s:%d: light %d (%s): no \"%s\" (expected %s)", path, j->line,
                                  idx + 1, light_names[l->type], key, light_forms[l->type]);
        } else if (!strcmp(key, "direction") || !strcmp(key, "normal")) {
            bad = json_vec(v, 3, l->dir);
        } else if (!strcmp(key, "irradiance") || !strcmp(key, "intensity")) {
            bad = json_vec(v, 3, l->rgb);
        } else if (!strcmp(key, "position")) {
            bad = json_vec(v, 3, l->pos);
        } else if (!strcmp(key, "u")) {
            bad = json_vec(v, 3, l->u);
        } else if (!strcmp(key, "size") && l->type == FP_RIG_AREA) {
            bad = json_vec(v, 2, l->extent);
            expect = "2 numbers [su, sv]";
        } else if (!strcmp(key, "shape")) {
            bad = v->type != FP_JSON_STRING ||
                  (strcmp(v->string, "rectangle") && strcmp(v->string, "ellipse"));
            l->shape = !bad && !strcmp(v->string, "ellipse");
            expect = "\"rectangle\" or \"ellipse\"";
        } else {
            double *dst = !strcmp(key, "angle") ? &l->angle : !strcmp(key, "radius") ? &l->radius
                          : !strcmp(key, "size") ? &l->size : &l->blend;
            bad = v->type != FP_JSON_NUMBER;
            if (!bad)
                *dst = v->number;
            expect = "a number";
        }
        if (bad)
            return fp_usage_error("%s:%d: light %d (%s): \"%s\" is %s (expected %s)", path,
                                  v->line, idx + 1, light_names[l->type], key,
                                  fp_json_type_name(v->type), expect);
    }
    if (l->type == FP_RIG_POINT)
        l->dir[2] = -1;
    const char *why = check_light(l);
    if (why)
        return fp_usage_error("%s:%d: light %d (%s): %s", path, j->line, idx + 1,
                              light_names[l->type], why);
    return FP_OK;
}

/* One object of rig keys (the file's top level or a frame's). */
static int json_rig(const char *path, const fp_json_t *j, int top, fp_rig_t *out)
{
    memset(out, 0, sizeof *out);
    int rc = FP_OK, cap = 0;
    if (j->type != FP_JSON_OBJECT)
        return fp_usage_error("%s:%d: expected an object of rig keys", path, j->line);
    for (int i = 0; i < j->n && rc == FP_OK; i++) {
        const char *k = j->keys[i];
        const fp_json_t *v = &j->items[i];
        if (top && (!strcmp(k, "fogpipe_rig") || !strcmp(k, "frames")))
            continue;
        if (!strcmp(k, "up")) {
            if (v->type != FP_JSON_STRING || (strcmp(v->string, "y") && strcmp(v->string, "z")))
                rc = fp_usage_error("%s:%d: \"up\" (expected \"y\" or \"z\")", path, v->line);
            else {
                out->has_up = 1;
                out->up = v->string[0] == 'z' ? FP_UP_Z : FP_UP_Y;
            }
        } else if (!strcmp(k, "clip_start")) {
            if (v->type != FP_JSON_NUMBER || !(v->number >= 0 && v->number < 1e9))
                rc = fp_usage_error("%s:%d: \"clip_start\" (expected a number 0..1e9)", path,
                                    v->line);
            else {
                out->has_clip = 1;
                out->clip = v->number;
            }
        } else if (!strcmp(k, "shadow_map")) {
            if (v->type != FP_JSON_STRING || !v->string[0])
                rc = fp_usage_error("%s:%d: \"shadow_map\" (expected a file name or pattern)",
                                    path, v->line);
            else
                rc = dup_into(&out->shadow, v->string);
        } else if (!strcmp(k, "look")) {
            if (v->type != FP_JSON_STRING)
                rc = fp_usage_error("%s:%d: \"look\" (expected a string 'fogpipe-look 1 "
                                    "name=value ...')", path, v->line);
            else if ((rc = dup_into(&out->look, v->string)) == FP_OK)
                snprintf(out->look_from, sizeof out->look_from, "%.200s:%d", path, v->line);
        } else if (!strcmp(k, "lights")) {
            if (v->type != FP_JSON_ARRAY)
                rc = fp_usage_error("%s:%d: \"lights\" (expected an array)", path, v->line);
            else if (v->n > FP_RIG_MAX_LIGHTS)
                rc = fp_usage_error("%s:%d: %d lights (expected at most %d)", path, v->line,
                                    v->n, FP_RIG_MAX_LIGHTS);
            out->has_lights = 1;
            for (int m = 0; rc == FP_OK && m < v->n; m++) {
                fp_rig_light_t l;
                if ((rc = json_light(path, m, &v->items[m], &l)) == FP_OK)
                    rc = add_light(out, &l, &cap);
            }
        } else {
            rc = fp_usage_error("%s:%d: unknown key \"%.40s\" (expected fogpipe_rig, up, "
                                "clip_start, shadow_map, lights, look, frames)", path, v->line, k);
        }
        out->any = 1;
    }
    if (rc)
        fp_rig_free(out);
    return rc;
}

void fp_rig_file_free(fp_rig_file_t *f)
{
    if (!f)
        return;
    fp_rig_free(&f->base);
    for (int i = 0; i < f->nframes; i++)
        fp_rig_free(&f->frames[i]);
    free(f->frames);
    free(f->frame_nums);
    free(f->path);
    free(f);
}

int fp_rig_file_load(const char *path, fp_rig_file_t **out)
{
    *out = NULL;
    fp_json_t j;
    int rc = fp_json_load(path, "rig file (JSON)", &j);
    if (rc)
        return rc;
    fp_rig_file_t *f = calloc(1, sizeof *f);
    if (!f || !(f->path = strdup(path))) {
        rc = fp_error("out of memory");
        goto done;
    }
    const fp_json_t *ver = fp_json_get(&j, "fogpipe_rig");
    if (j.type != FP_JSON_OBJECT || !ver || ver->type != FP_JSON_NUMBER || ver->number != 1) {
        rc = fp_usage_error("%s: expected an object with \"fogpipe_rig\": 1 (version 1 of the "
                            "rig schema)", path);
        goto done;
    }
    if ((rc = json_rig(path, &j, 1, &f->base)))
        goto done;
    const fp_json_t *fr = fp_json_get(&j, "frames");
    if (fr) {
        if (fr->type != FP_JSON_OBJECT) {
            rc = fp_usage_error("%s:%d: \"frames\" (expected an object {\"12\": {...}})", path,
                                fr->line);
            goto done;
        }
        f->frames = calloc(fr->n ? (size_t)fr->n : 1, sizeof *f->frames);
        f->frame_nums = calloc(fr->n ? (size_t)fr->n : 1, sizeof *f->frame_nums);
        if (!f->frames || !f->frame_nums) {
            rc = fp_error("out of memory");
            goto done;
        }
        for (int i = 0; i < fr->n; i++) {
            char *end;
            errno = 0;
            long n = strtol(fr->keys[i], &end, 10);
            if (end == fr->keys[i] || *end || errno == ERANGE || n < -1000000000L ||
                n > 1000000000L) {
                rc = fp_usage_error("%s:%d: \"frames\": key \"%.40s\" (expected a frame "
                                    "number)", path, fr->items[i].line, fr->keys[i]);
                goto done;
            }
            for (int k = 0; k < f->nframes; k++)
                if (f->frame_nums[k] == n) {
                    rc = fp_usage_error("%s:%d: \"frames\": frame %ld twice (expected each "
                                        "once)", path, fr->items[i].line, n);
                    goto done;
                }
            if ((rc = json_rig(path, &fr->items[i], 0, &f->frames[i])))
                goto done;
            f->frame_nums[i] = n;
            f->nframes++;
        }
    }
    *out = f;
    f = NULL;
done:
    fp_rig_file_free(f);
    fp_json_free(&j);
    return rc;
}

int fp_rig_file_frame(const fp_rig_file_t *f, long frame, fp_rig_t *out)
{
    memset(out, 0, sizeof *out);
    int rc = fp_rig_merge(out, &f->base);
    for (int i = 0; rc == FP_OK && i < f->nframes; i++)
        if (f->frame_nums[i] == frame)
            rc = fp_rig_merge(out, &f->frames[i]);
    if (rc == FP_OK && out->shadow && fp_seq_has_placeholder(out->shadow) == 1) {
        char path[4096];
        if ((rc = fp_seq_format(out->shadow, frame, path, sizeof path)) == FP_OK)
            rc = dup_into(&out->shadow, path);
    }
    if (rc)
        fp_rig_free(out);
    return rc;
}

int fp_rig_frame(const fp_rig_file_t *file, const fp_frame_info_t *info,
                 const char *where_file, long frame, fp_rig_t *out)
{
    memset(out, 0, sizeof *out);
    int rc = info ? fp_rig_from_frame(info, where_file, frame, out) : FP_OK;
    if (rc == FP_OK && file) {
        fp_rig_t fr;
        if ((rc = fp_rig_file_frame(file, frame, &fr)) == FP_OK)
            rc = fp_rig_merge(out, &fr);
        fp_rig_free(&fr);
    }
    if (rc)
        fp_rig_free(out);
    return rc;
}
