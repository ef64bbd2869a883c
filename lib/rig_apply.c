/* fogpipe: the rig applied to a frame's parameters (src/scene/rig.h, lib/rig_apply.h), its
 * options, and what --print-camera says of it. */
#include "rig_apply.h"
#include "fp.h"
#include "options_all.h"
#include "scatter.h"
#include "seq.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ once a run */

/* Once a run (the context's, src/base/fp_ctx.h). */
static const char warned_up = 0;

static void warn_once(const char *flag, const char *fmt, const char *a, long frame,
                      const char *b, const char *c)
{
    if (!fp_once(flag))
        return;
    fp_warn(fmt, a, frame, b, c);
}

static const char *up_name(int up) { return up == FP_UP_Z ? "z" : "y"; }

int fp_rig_prescan(fp_params_t *p, const fp_rig_file_t *file, const fp_rig_t *first,
                   const char *first_name, long first_frame)
{
    fp_rig_t run;
    memset(&run, 0, sizeof run);
    int rc = FP_OK;
    if (first && first->any)
        rc = fp_rig_merge(&run, first);
    if (rc == FP_OK && file) {
        fp_rig_t fr;
        if ((rc = fp_rig_file_frame(file, first_frame, &fr)) == FP_OK)
            rc = fp_rig_merge(&run, &fr);
        fp_rig_free(&fr);
    }
    if (rc == FP_OK && run.has_up && !fp_options_given(p, "up")) {
        p->camera.up = run.up;
        fp_info("%s: frame %ld: up axis %s from the rig", first_name, first_frame,
                up_name(run.up));
    }
    if (rc == FP_OK && run.look)
        rc = fp_options_apply_look(p, run.look, run.look_from);
    fp_rig_free(&run);
    return rc;
}

/* ------------------------------------------------------------ the run */

/* A single input file's frame number: --frame, else the number its name
 * ends with, else 1. */
long fp_rig_single_frame(const fp_params_t *p)
{
    long frame = 1;
    if (fp_options_given(p, "frame"))
        return p->io.frame;
    fp_seq_frame_of_name(p->io.input, &frame);
    return frame;
}

/* The first input frame and its number (file input): where the run's up
 * axis and look come from (fp_rig_prescan).  Non-zero when there is none
 * to read (the frame loop says why). */
static int first_input(const fp_params_t *p, char *path, size_t n, long *frame)
{
    int seq = fp_seq_has_placeholder(p->io.input);
    if (seq < 0)
        return FP_ERR;
    if (!seq) {
        if (p->io.frames)
            return FP_ERR;
        *frame = fp_rig_single_frame(p);
        snprintf(path, n, "%s", p->io.input);
        return FP_OK;
    }
    fp_frame_list_t l = { NULL, 0 };
    int rc = p->io.frames ? fp_frames_parse(p->io.frames, &l) : fp_frames_scan(p->io.input, &l);
    if (rc == FP_OK && l.count)
        rc = fp_seq_format(p->io.input, *frame = l.frames[0], path, n);
    else
        rc = FP_ERR;
    fp_frames_free(&l);
    return rc;
}

static int is_stream(const char *s) { return !s || strcmp(s, "-") == 0; }

/* --rig FILE, and the run's up axis and look: from the rig file, else the
 * first frame's rig (its header read once more here; its errors, if any,
 * are the frame loop's to report). */
int fp_rig_run_setup(fp_params_t *p, fp_rig_file_t **file, int *has_rig)
{
    int rc;
    *file = NULL;
    *has_rig = 0;
    if (p->io.rig && (rc = fp_rig_file_load(p->io.rig, file)))
        return rc;
    fp_rig_t first;
    memset(&first, 0, sizeof first);
    char path[4096] = "<stdin>";
    long frame = 1;
    if (!is_stream(p->io.input)) {
        fp_msgbuf_t quiet = { NULL, 0, 0 };
        fp_msgbuf_t *prev = fp_msg_capture(&quiet);
        fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
        sel.need_color = sel.need_depth = 0;
        fp_frame_t *f = NULL;
        if (first_input(p, path, sizeof path, &frame) == FP_OK &&
            fp_exr_read_file(path, frame, &sel, &f) == FP_OK &&
            fp_rig_from_frame(fp_frame_info(f), path, frame, &first) != FP_OK)
            memset(&first, 0, sizeof first);
        fp_frame_free(f);
        fp_msg_capture(prev);
        fp_msg_free(&quiet);
    }
    *has_rig = *file || first.any;
    rc = fp_rig_prescan(p, *file, &first, path, frame);
    fp_rig_free(&first);
    return rc;
}

/* ------------------------------------------------------------ per frame */

/* The copy's lights start empty, without touching the base's storage. */
/* The frame's parameters own their light list (a copy of the options'):
 * appending the rig's lights must never grow the options' own array,
 * which other frames read. */
static int own_lights(fp_light_params_t *l, const fp_light_params_t *from)
{
    l->lights = NULL;
    l->num_lights = l->cap_lights = 0;
    for (int k = 0; k < from->num_lights; k++)
        if (fp_light_append(l, &from->lights[k]))
            return FP_ERR;
    return FP_OK;
}

static void detach_lights(fp_light_params_t *l)
{
    l->num_lights = 0;
}

void fp_rig_params_release(fp_params_t *q)
{
    fp_light_clear(&q->light);
    if (q->light.shadow_map_literal) {
        free(q->light.shadow_map);
        q->light.shadow_map = NULL;
        q->light.shadow_map_literal = 0;
    }
}

static void mark_given(fp_params_t *q, const char *name)
{
    const fp_option_t *o = fp_options_find(name);
    if (!o || fp_options_given(q, name) || q->num_given >= FP_MAX_GIVEN)
        return;
    q->given[q->num_given++] = o->name;
}

static void rig_to_light(const fp_rig_light_t *r, fp_light_t *li)
{
    memset(li, 0, sizeof *li);
    memcpy(li->pos, r->pos, sizeof li->pos);
    memcpy(li->color, r->rgb, sizeof li->color);
    li->intensity = 1;
    li->radius = r->radius;
    switch (r->type) {
    case FP_RIG_POINT:
        li->kind = 0;
        break;
    case FP_RIG_SPOT: {
        li->kind = 1;
        li->spot_profile = 1;
        memcpy(li->axis, r->dir, sizeof li->axis);
        li->outer = r->size / 2;
        li->blend = r->blend;
        /* Cycles' smoothstep runs over cos(outer) .. cos(outer) + spread,
         * spread = (1 - cos(outer)) * blend: the inner cone where it ends
         * (for the inner/outer profile). */
        double co = cos(li->outer * M_PI / 180);
        li->inner = acos(fmin(1, co + (1 - co) * r->blend)) * 180 / M_PI;
        break;
    }
    case FP_RIG_AREA:
        li->kind = 2;
        memcpy(li->axis, r->dir, sizeof li->axis);
        memcpy(li->u, r->u, sizeof li->u);
        li->size[0] = r->extent[0];
        li->size[1] = r->extent[1];
        li->shape = r->shape;
        break;
    case FP_RIG_SUN:
        li->kind = 3;
        memset(li->pos, 0, sizeof li->pos);
        memcpy(li->axis, r->dir, sizeof li->axis);
        break;
    }
}

int fp_rig_apply(const fp_params_t *base, const fp_rig_t *rig, const char *where_file,
                 long frame, fp_params_t *q)
{
    *q = *base;
    q->light.shadow_map_literal = 0;
    if (own_lights(&q->light, &base->light))
        return fp_error("%s: frame %ld: the options' lights could not be copied", where_file,
                        frame);
    int none = base->light.lights_from == FP_LIGHTS_NONE;
    if (rig->has_up && rig->up != base->camera.up) {
        if (fp_options_given(base, "up"))
            warn_once(&warned_up, "%s: frame %ld: the rig says up %s; --up %s is used",
                      where_file, frame, up_name(rig->up), up_name(base->camera.up));
        else
            warn_once(&warned_up, "%s: frame %ld: the rig says up %s, the run's up axis is %s "
                      "(from the first frame or --rig; give --up for this sequence)",
                      where_file, frame, up_name(rig->up), up_name(base->camera.up));
    }
    if (rig->has_clip && !fp_options_given(base, "clip-start"))
        q->camera.clip_start = rig->clip;
    if (rig->cut && !none &&
        !(fp_options_given(base, "light") &&
          (fp_options_given(base, "sun") || fp_options_given(base, "sun-color") ||
           fp_options_given(base, "sun-intensity"))))
        return fp_error("%s", rig->cut);
    if (none || !rig->has_lights)
        goto shadow;
    int sun_flags = fp_options_given(base, "sun") || fp_options_given(base, "sun-color") ||
                    fp_options_given(base, "sun-intensity");
    int local = !fp_options_given(base, "light");
    int bright = -1;
    double best = -1;
    for (int k = 0; !sun_flags && k < rig->nlights; k++) {
        const fp_rig_light_t *l = &rig->lights[k];
        double e = l->rgb[0] + l->rgb[1] + l->rgb[2];
        if (l->type == FP_RIG_SUN && e > best) {
            best = e;
            bright = k;
        }
    }
    if (bright >= 0) {
        /* The brightest sun is --sun (its shadow map, its self-shadowing
         * grid): color x intensity = irradiance, the color at most 1. */
        const fp_rig_light_t *l = &rig->lights[bright];
        double e = fmax(l->rgb[0], fmax(l->rgb[1], l->rgb[2]));
        memcpy(q->light.sun, l->dir, sizeof q->light.sun);
        q->light.sun_intensity = e;
        for (int c = 0; c < 3; c++)
            q->light.sun_color[c] = e > 0 ? l->rgb[c] / e : 1;
        mark_given(q, "sun");
    }
    if (local)
        detach_lights(&q->light);
    for (int k = 0; k < rig->nlights; k++) {
        const fp_rig_light_t *l = &rig->lights[k];
        if (l->type == FP_RIG_SUN ? (sun_flags || k == bright) : !local)
            continue;
        fp_light_t li;
        rig_to_light(l, &li);
        if (fp_light_append(&q->light, &li))
            return fp_error("%s: frame %ld: the rig's light %d could not be added", where_file,
                            frame, k + 1);
    }
shadow:
    if (!none && rig->shadow && !fp_options_given(base, "shadow-map") &&
        fp_options_given(q, "sun")) {
        /* Relative to the frame file's directory. */
        const char *slash = strrchr(where_file, '/');
        int dir = rig->shadow[0] != '/' && slash && strcmp(where_file, "<stdin>") != 0;
        size_t n = (dir ? (size_t)(slash - where_file) + 1 : 0) + strlen(rig->shadow) + 1;
        char *path = malloc(n);
        if (!path)
            return fp_error("%s: frame %ld: out of memory", where_file, frame);
        snprintf(path, n, "%.*s%s", dir ? (int)(slash - where_file) + 1 : 0, where_file,
                 rig->shadow);
        q->light.shadow_map = path;
        q->light.shadow_map_literal = 1;
    }
    return FP_OK;
}

/* FNV-1a over the numbers the light stage is committed from. */
static void mix(uint64_t *h, const void *v, size_t n)
{
    const unsigned char *b = v;
    for (size_t i = 0; i < n; i++) {
        *h ^= b[i];
        *h *= 0x100000001b3ULL;
    }
}

static void mixd(uint64_t *h, const double *v, int n)
{
    for (int i = 0; i < n; i++) {
        double x = v[i] == 0 ? 0 : v[i];   /* -0 as 0 */
        mix(h, &x, sizeof x);
    }
}

int fp_rig_seen(fp_rig_seen_t *s, const char *text, int len)
{
    uint64_t h = 0xcbf29ce484222325ULL;
    mix(&h, text, (size_t)len);
    for (int i = 0; i < s->n; i++)
        if (s->h[i] == h)
            return 1;
    if (s->n < FP_RIG_SEEN_MAX)
        s->h[s->n++] = h;
    return 0;
}

uint64_t fp_rig_light_key(const fp_params_t *q)
{
    uint64_t h = 0xcbf29ce484222325ULL;
    const fp_light_params_t *l = &q->light;
    int ints[5] = { q->camera.up, fp_options_given(q, "sun"), l->num_lights,
                    l->shadow_map_literal, l->shadow_map != NULL };
    mix(&h, ints, sizeof ints);
    mixd(&h, l->sun, 3);
    mixd(&h, l->sun_color, 3);
    mixd(&h, &l->sun_intensity, 1);
    for (int k = 0; k < l->num_lights; k++) {
        const fp_light_t *li = &l->lights[k];
        int ki[3] = { li->kind, li->spot_profile, li->shape };
        mix(&h, ki, sizeof ki);
        mixd(&h, li->pos, 3);
        mixd(&h, li->color, 3);
        mixd(&h, &li->intensity, 1);
        mixd(&h, li->axis, 3);
        mixd(&h, &li->inner, 1);
        mixd(&h, &li->outer, 1);
        mixd(&h, &li->blend, 1);
        mixd(&h, &li->radius, 1);
        mixd(&h, li->u, 3);
        mixd(&h, li->size, 2);
    }
    if (l->shadow_map)
        mix(&h, l->shadow_map, strlen(l->shadow_map));
    return h;
}

/* ------------------------------------------------------------ printing */

void fp_rig_print(FILE *out, const fp_rig_t *rig, const fp_params_t *q)
{
    const fp_light_params_t *l = &q->light;
    fprintf(out, "  rig       up %s%s, clip start %.6g%s, lights %s\n", up_name(q->camera.up),
            fp_options_given(q, "up") ? " (--up)" : rig->has_up ? " (rig)" : "",
            q->camera.clip_start,
            fp_options_given(q, "clip-start") ? " (--clip-start)" : rig->has_clip ? " (rig)" : "",
            l->lights_from == FP_LIGHTS_NONE ? "none (--lights none)" : "from the frame");
    if (fp_options_given(q, "sun")) {
        double n = sqrt(l->sun[0] * l->sun[0] + l->sun[1] * l->sun[1] + l->sun[2] * l->sun[2]);
        fprintf(out, "  sun       toward %.6f %.6f %.6f, irradiance %.6g %.6g %.6g (color %.6g "
                "%.6g %.6g x %.6g)\n", l->sun[0] / n, l->sun[1] / n, l->sun[2] / n,
                l->sun_color[0] * l->sun_intensity, l->sun_color[1] * l->sun_intensity,
                l->sun_color[2] * l->sun_intensity, l->sun_color[0], l->sun_color[1],
                l->sun_color[2], l->sun_intensity);
    }
    for (int k = 0; k < l->num_lights; k++) {
        const fp_light_t *li = &l->lights[k];
        double I[3] = { li->color[0] * li->intensity, li->color[1] * li->intensity,
                        li->color[2] * li->intensity };
        const double *a = li->axis;
        switch (li->kind) {
        case 0:
            fprintf(out, "  light %-3d point at %.6g %.6g %.6g, intensity %.6g %.6g %.6g W/sr, "
                    "radius %.6g\n", k + 1, li->pos[0], li->pos[1], li->pos[2], I[0], I[1], I[2],
                    li->radius);
            break;
        case 1:
            fprintf(out, "  light %-3d spot at %.6g %.6g %.6g, intensity %.6g %.6g %.6g W/sr, "
                    "radius %.6g, pointing %.6f %.6f %.6f, ", k + 1, li->pos[0], li->pos[1],
                    li->pos[2], I[0], I[1], I[2], li->radius, a[0], a[1], a[2]);
            if (li->spot_profile)
                fprintf(out, "size %.6g deg, blend %.6g\n", 2 * li->outer, li->blend);
            else
                fprintf(out, "cone %.6g..%.6g deg\n", li->inner, li->outer);
            break;
        case 2:
            fprintf(out, "  light %-3d area at %.6g %.6g %.6g, intensity %.6g %.6g %.6g W/sr, "
                    "normal %.6f %.6f %.6f, u %.6f %.6f %.6f, size %.6g x %.6g %s\n", k + 1,
                    li->pos[0], li->pos[1], li->pos[2], I[0], I[1], I[2], a[0], a[1], a[2],
                    li->u[0], li->u[1], li->u[2], li->size[0], li->size[1],
                    li->shape ? "ellipse" : "rectangle");
            break;
        default:
            fprintf(out, "  light %-3d sun toward %.6f %.6f %.6f, irradiance %.6g %.6g %.6g\n",
                    k + 1, a[0], a[1], a[2], I[0], I[1], I[2]);
            break;
        }
    }
    if (l->shadow_map)
        fprintf(out, "  shadow map %s%s\n", l->shadow_map,
                l->shadow_map_literal ? " (rig)" : " (--shadow-map)");
    if (rig->look)
        fprintf(out, "  look      from %s\n", rig->look_from);
}
