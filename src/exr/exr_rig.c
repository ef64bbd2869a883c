#include "exr_internal.h"
#include "fp.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* 1 when the string attribute's value holds `word`. */
static int attr_has(const exr_attribute_t *a, const char *word)
{
    size_t n = strlen(word), len = a->string->length > 0 ? (size_t)a->string->length : 0;
    for (size_t i = 0; i + n <= len; i++)
        if (memcmp(a->string->str + i, word, n) == 0)
            return 1;
    return 0;
}

/* 1 when a text starts (after white space) with "fogpipe-". */
static int starts_fogpipe(const char *s)
{
    while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r')
        s++;
    return strncmp(s, "fogpipe-", 8) == 0;
}

static int attr_starts_fogpipe(const exr_attribute_t *a)
{
    int i = 0, n = a->string->length;
    const char *s = a->string->str;
    while (i < n && (s[i] == ' ' || s[i] == '\t' || s[i] == '\n' || s[i] == '\r'))
        i++;
    return n - i >= 8 && memcmp(s + i, "fogpipe-", 8) == 0;
}

/* A string attribute's value as a new string (NULL: out of memory, or an
 * empty or too long one: 16 MiB, the most a rig of 4096 lights needs many
 * times over). */
static char *attr_strdup(const exr_attribute_t *a)
{
    int len = a->string->length;
    if (len <= 0 || len > (16 << 20))
        return NULL;
    char *s = malloc((size_t)len + 1);
    if (s) {
        memcpy(s, a->string->str, (size_t)len);
        s[len] = '\0';
    }
    return s;
}

/* The rig's typed attributes (src/scene/rig.h, "fogpipe rig schema"): the
 * first of each name over the parts; the wrong type is kept as an error
 * for the rig's reader to report with the frame. */
static int read_rig_attr(const exr_attribute_t *a, fp_rig_attrs_t *r)
{
    static const char *const names[] = { "fogpipeRigVersion", "fogpipeClipStart", "fogpipeUp",
                                         "fogpipeShadowMap", "fogpipeRig", "fogpipeLook" };
    int k = -1;
    for (int i = 0; i < (int)FP_ARRAY_LEN(names); i++)
        if (strcmp(a->name, names[i]) == 0)
            k = i;
    if (k < 0)
        return 0;
    int str = a->type == EXR_ATTR_STRING && a->string && a->string->str;
    const char *want = k == 0 ? "int" : k == 1 ? "float" : "string";
    int ok = k == 0 ? a->type == EXR_ATTR_INT
             : k == 1 ? a->type == EXR_ATTR_FLOAT || a->type == EXR_ATTR_DOUBLE
                      : str;
    if (!ok) {
        if (!r->bad[0])
            snprintf(r->bad, sizeof r->bad, "attribute '%s' is of type %s (expected %s)",
                     a->name, a->type_name ? a->type_name : "?", want);
        return 1;
    }
    char **dst[6] = { NULL, NULL, &r->up, &r->shadow_map, &r->rig, &r->look };
    if (k == 0 && !r->has_version) {
        r->has_version = 1;
        r->version = a->i;
    } else if (k == 1 && !r->has_clip) {
        r->has_clip = 1;
        r->clip = a->type == EXR_ATTR_FLOAT ? a->f : a->d;
    } else if (k == 5 && r->look && strcmp(r->look_attr, a->name) != 0) {
        /* The typed attribute over a text found before it. */
        char *v = attr_strdup(a);
        if (v) {
            free(r->look);
            r->look = v;
            snprintf(r->look_attr, sizeof r->look_attr, "%s", a->name);
        }
    } else if (k >= 2 && !*dst[k]) {
        *dst[k] = attr_strdup(a);
        if (k == 5 && *dst[k])
            snprintf(r->look_attr, sizeof r->look_attr, "%s", a->name);
    }
    return 1;
}

/* A string attribute holding the rig's or the look's text: the first one,
 * or a later one that starts with it (a tool's history, oiiotool's
 * Exif:ImageHistory, may quote the command that wrote it). */
static void read_rig_text(const exr_attribute_t *a, fp_rig_attrs_t *rg)
{
    if (a->type != EXR_ATTR_STRING || !a->string || !a->string->str)
        return;
    if (attr_has(a, "fogpipe-rig") &&
        (!rg->text || (!starts_fogpipe(rg->text) && attr_starts_fogpipe(a)))) {
        free(rg->text);
        if ((rg->text = attr_strdup(a)))
            snprintf(rg->text_attr, sizeof rg->text_attr, "%s", a->name);
    }
    if (attr_has(a, "fogpipe-look") && strcmp(rg->look_attr, "fogpipeLook") != 0 &&
        (!rg->look || (!starts_fogpipe(rg->look) && attr_starts_fogpipe(a)))) {
        free(rg->look);
        if ((rg->look = attr_strdup(a)))
            snprintf(rg->look_attr, sizeof rg->look_attr, "%s", a->name);
    }
}

int fp_exr_rig_attr(const exr_attribute_t *a, fp_rig_attrs_t *r)
{
    if (read_rig_attr(a, r))
        return 1;
    read_rig_text(a, r);
    return 0;
}

void fp_exr_rig_attrs_free(fp_rig_attrs_t *r)
{
    free(r->text);
    free(r->rig);
    free(r->up);
    free(r->shadow_map);
    free(r->look);
    memset(r, 0, sizeof *r);
}
