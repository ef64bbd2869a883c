/* The rig (src/scene/rig.h): the text form, typed attributes, the JSON rig file
 * and its reader, precedence under the flags, the look, --frame's file
 * names, and the clip start in the fog (closed form, C and OpenCL). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "camera.h"
#include "fp.h"
#include "integrate.h"
#include "json.h"
#include "options.h"
#include "rig.h"
#include "rig_apply.h"
#include "seq.h"
#include "testutil.h"

static int parse(const char *text, fp_rig_t *r, int *declared, int *complete)
{
    int d, c;
    return fp_rig_parse_text(text, "test", r, declared ? declared : &d, complete ? complete : &c);
}

static void test_text_form(void **state)
{
    (void)state;
    fp_rig_t r;
    int declared, complete;
    const char *t = "fogpipe-camera 1 worldToCamera ... ; fogpipe-rig 1 up z; clip 0.1 "
                    "shadow sun.0002.exr lights 4 sun 0 0 2 3 3 2.4 0.5 "
                    "point 1 2 3 10 8 6 0.25 spot 4 5 6 1 1 1 0.1 0 0 -1 45 0.15 "
                    "area 0 0 4 2 2 2 0 0 -1 1 0 0 2 1 1 fogpipe-look 1 density=0.1";
    assert_int_equal(parse(t, &r, &declared, &complete), FP_OK);
    assert_int_equal(declared, 4);
    assert_int_equal(complete, 1);
    assert_true(r.has_up && r.up == FP_UP_Z);
    assert_true(r.has_clip);
    assert_double_equal(r.clip, 0.1, 0);
    assert_string_equal(r.shadow, "sun.0002.exr");
    assert_int_equal(r.nlights, 4);
    assert_int_equal(r.lights[0].type, FP_RIG_SUN);
    assert_double_equal(r.lights[0].dir[2], 1, 1e-15);   /* normalized */
    assert_double_equal(r.lights[0].rgb[2], 2.4, 0);
    assert_double_equal(r.lights[0].angle, 0.5, 0);
    assert_int_equal(r.lights[1].type, FP_RIG_POINT);
    assert_double_equal(r.lights[1].radius, 0.25, 0);
    assert_int_equal(r.lights[2].type, FP_RIG_SPOT);
    assert_double_equal(r.lights[2].size, 45, 0);
    assert_double_equal(r.lights[2].blend, 0.15, 0);
    assert_double_equal(r.lights[2].dir[2], -1, 0);
    assert_int_equal(r.lights[3].type, FP_RIG_AREA);
    assert_double_equal(r.lights[3].extent[0], 2, 0);
    assert_int_equal(r.lights[3].shape, 1);
    fp_rig_free(&r);

    /* Cut off (Blender's Note holds 767 bytes): fewer lights than said,
     * also in the middle of one. */
    assert_int_equal(parse("fogpipe-rig 1 lights 3 point 0 0 0 1 1 1 0 point 1 2", &r,
                           &declared, &complete), FP_OK);
    assert_int_equal(declared, 3);
    assert_int_equal(complete, 0);
    assert_int_equal(r.nlights, 1);
    fp_rig_free(&r);
    /* No lights at all said: "lights 0" is lights given, none. */
    assert_int_equal(parse("fogpipe-rig 1 lights 0", &r, &declared, &complete), FP_OK);
    assert_true(r.has_lights && r.nlights == 0 && complete);
    fp_rig_free(&r);
}

static void test_text_errors(void **state)
{
    (void)state;
    static const char *const bad[] = {
        "no rig here",
        "fogpipe-rig 2 up z",
        "fogpipe-rig up z",
        "fogpipe-rig 1 up x",
        "fogpipe-rig 1 up",
        "fogpipe-rig 1 clip -1",
        "fogpipe-rig 1 clip nan",
        "fogpipe-rig 1 clip 1e400",
        "fogpipe-rig 1 shadow",
        "fogpipe-rig 1 lights 2.5",
        "fogpipe-rig 1 lights 5000",
        "fogpipe-rig 1 frobnicate 3",
        "fogpipe-rig 1 point 0 0 0 1 1 1",                 /* the text ends: not said cut */
        "fogpipe-rig 1 point 0 0 0 1 1 x 0",
        "fogpipe-rig 1 point 0 0 0 1 -1 1 0",
        "fogpipe-rig 1 point 0 0 0 1 1 1 -0.5",
        "fogpipe-rig 1 point 0 0 inf 1 1 1 0",
        "fogpipe-rig 1 sun 0 0 0 1 1 1 0.5",
        "fogpipe-rig 1 sun 0 1 0 1 1 1 200",
        "fogpipe-rig 1 spot 0 0 0 1 1 1 0 0 0 -1 0 0.1",
        "fogpipe-rig 1 spot 0 0 0 1 1 1 0 0 0 -1 190 0.1",
        "fogpipe-rig 1 spot 0 0 0 1 1 1 0 0 0 -1 45 1.5",
        "fogpipe-rig 1 spot 0 0 0 1 1 1 0 0 0 0 45 0.1",
        "fogpipe-rig 1 area 0 0 0 1 1 1 0 0 -1 0 0 1 1 1 0",   /* u along the normal */
        "fogpipe-rig 1 area 0 0 0 1 1 1 0 0 -1 1 0 0 0 1 0",   /* zero size */
        "fogpipe-rig 1 area 0 0 0 1 1 1 0 0 -1 1 0 0 1 1 2",   /* shape 2 */
        "fogpipe-rig 1 lights 1 point 0 0 0 1 1 1 0 point 0 0 0 1 1 1 0",
        "fogpipe-rig 1 point 0 0 0 1 1 1 0 up z",           /* keys after the lights */
        "fogpipe-rig 1 lights 2 point 0 0 0 1 1 1 0 point 0 0 0 1 1 1 x",
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(bad); i++) {
        fp_rig_t r;
        int rc = parse(bad[i], &r, NULL, NULL);
        if (rc == FP_OK)
            fail_msg("accepted: %s", bad[i]);
        assert_null(r.lights);
    }
}

static void set_attr(char **dst, const char *v)
{
    free(*dst);
    *dst = v ? strdup(v) : NULL;
}

static void free_attrs(fp_rig_attrs_t *a)
{
    free(a->text);
    free(a->rig);
    free(a->up);
    free(a->shadow_map);
    free(a->look);
    memset(a, 0, sizeof *a);
}

static void test_frame_attributes(void **state)
{
    (void)state;
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    fp_rig_attrs_t *a = &info.rig;
    fp_rig_t r;
    /* No rig: nothing. */
    assert_int_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    assert_false(r.any);
    /* Typed attributes over the text. */
    set_attr(&a->text, "fogpipe-rig 1 up y clip 0.1 shadow a.exr point 0 0 0 1 1 1 0");
    snprintf(a->text_attr, sizeof a->text_attr, "Note");
    set_attr(&a->up, "z");
    a->has_clip = 1;
    a->clip = 0.25;
    set_attr(&a->shadow_map, "b.exr");
    a->has_version = 1;
    a->version = 1;
    assert_int_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    assert_true(r.any && r.up == FP_UP_Z);
    assert_double_equal(r.clip, 0.25, 0);
    assert_string_equal(r.shadow, "b.exr");
    assert_int_equal(r.nlights, 1);
    fp_rig_free(&r);
    /* fogpipeRig's lights over the text's. */
    set_attr(&a->rig, "fogpipe-rig 1 lights 2 point 0 0 0 1 1 1 0 point 5 5 5 2 2 2 0");
    assert_int_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    assert_int_equal(r.nlights, 2);
    assert_double_equal(r.lights[1].pos[0], 5, 0);
    fp_rig_free(&r);
    /* A cut-off text: the whole rig from fogpipeRig, else an error. */
    set_attr(&a->text, "fogpipe-rig 1 lights 12 point 0 0 0 1 1 1 0 point 1");
    assert_int_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    assert_int_equal(r.nlights, 2);
    fp_rig_free(&r);
    set_attr(&a->rig, NULL);
    /* Without it the cut is kept, an error only where the lights are used
     * (fp_rig_apply: test_precedence). */
    assert_int_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    assert_non_null(r.cut);
    assert_non_null(strstr(r.cut, "f.exr: frame 3: the rig says 12 lights but carries 1 and "
                                  "there is no fogpipeRig attribute"));
    fp_rig_free(&r);
    set_attr(&a->text, NULL);
    /* fogpipeRig cut off itself, wrong version, wrong up, wrong clip, a
     * typed attribute of the wrong type. */
    set_attr(&a->rig, "fogpipe-rig 1 lights 3 point 0 0 0 1 1 1 0");
    assert_int_not_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    set_attr(&a->rig, NULL);
    a->version = 2;
    assert_int_not_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    a->version = 1;
    set_attr(&a->up, "Z-up");
    assert_int_not_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    set_attr(&a->up, "y");
    a->clip = -1;
    assert_int_not_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    a->clip = 0;
    set_attr(&a->shadow_map, "");
    assert_int_not_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    set_attr(&a->shadow_map, NULL);
    snprintf(a->bad, sizeof a->bad, "attribute 'fogpipeClipStart' is of type string");
    assert_int_not_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    a->bad[0] = 0;
    assert_int_equal(fp_rig_from_frame(&info, "f.exr", 3, &r), FP_OK);
    assert_true(r.any && r.up == FP_UP_Y && r.has_clip && r.clip == 0);
    fp_rig_free(&r);
    free_attrs(a);
}

static void test_json(void **state)
{
    (void)state;
    fp_json_t j;
    const char *good = "\xEF\xBB\xBF {\"a\": [1, -2.5e3, 0, true, false, null], "
                       "\"s\": \"x\\u00e9\\ud83d\\ude00\\n\", \"o\": {}}";
    assert_int_equal(fp_json_parse(good, strlen(good), "t", &j), FP_OK);
    assert_int_equal(j.type, FP_JSON_OBJECT);
    const fp_json_t *a = fp_json_get(&j, "a");
    assert_non_null(a);
    assert_int_equal(a->n, 6);
    assert_double_equal(a->items[1].number, -2500, 0);
    assert_true(a->items[3].boolean && !a->items[4].boolean);
    assert_string_equal(fp_json_get(&j, "s")->string, "x\xc3\xa9\xf0\x9f\x98\x80\n");
    fp_json_free(&j);
    static const char *const bad[] = {
        "", "{", "[1,]", "{\"a\":1,}", "{\"a\":1 \"b\":2}", "{\"a\":1,\"a\":2}", "[01]",
        "[1.]", "[.5]", "[1e]", "[+1]", "[1e999]", "[NaN]", "[Infinity]", "// c\n{}", "{} x",
        "[\"\\x\"]", "[\"\\ud800\"]", "[\"\\u0000\"]", "[\"a\tb\"]", "[\"abc", "{1:2}", "[tru]",
        "'a'",
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(bad); i++)
        if (fp_json_parse(bad[i], strlen(bad[i]), "t", &j) == FP_OK)
            fail_msg("accepted: %s", bad[i]);
    /* Nested past 64 levels. */
    char deep[200];
    memset(deep, '[', 100);
    memset(deep + 100, ']', 100);
    assert_int_not_equal(fp_json_parse(deep, sizeof deep, "t", &j), FP_OK);
    assert_int_equal(fp_json_parse(deep + 40, 120, "t", &j), FP_OK);
    fp_json_free(&j);
}

static char *write_tmp(const char *text)
{
    static char path[64];
    snprintf(path, sizeof path, "/tmp/fp_test_rig_%d.json", (int)getpid());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    return path;
}

static void test_rig_file(void **state)
{
    (void)state;
    const char *text =
        "{ \"fogpipe_rig\": 1, \"up\": \"z\", \"clip_start\": 0.1, \"shadow_map\": "
        "\"sun.####.exr\",\n \"lights\": [\n"
        "  {\"type\": \"sun\", \"direction\": [0, 0, 1], \"irradiance\": [3, 3, 3], \"angle\": 0.5},\n"
        "  {\"type\": \"point\", \"position\": [1, 2, 3], \"intensity\": [1, 1, 1], \"radius\": 0.1},\n"
        "  {\"type\": \"spot\", \"position\": [0, 0, 5], \"intensity\": [2, 2, 2], \"radius\": 0,\n"
        "   \"direction\": [0, 0, -1], \"size\": 45, \"blend\": 0.15},\n"
        "  {\"type\": \"area\", \"position\": [0, 0, 3], \"intensity\": [1, 1, 1], \"normal\": "
        "[0, 0, -1], \"u\": [1, 0, 0], \"size\": [2, 1], \"shape\": \"rectangle\"} ],\n"
        " \"frames\": { \"12\": { \"clip_start\": 0.5, \"lights\": [] } } }";
    char *path = write_tmp(text);
    fp_rig_file_t *f;
    assert_int_equal(fp_rig_file_load(path, &f), FP_OK);
    fp_rig_t r;
    assert_int_equal(fp_rig_file_frame(f, 3, &r), FP_OK);
    assert_true(r.up == FP_UP_Z && r.clip == 0.1 && r.nlights == 4);
    assert_string_equal(r.shadow, "sun.0003.exr");
    assert_int_equal(r.lights[3].type, FP_RIG_AREA);
    fp_rig_free(&r);
    assert_int_equal(fp_rig_file_frame(f, 12, &r), FP_OK);
    assert_true(r.clip == 0.5 && r.has_lights && r.nlights == 0);
    assert_string_equal(r.shadow, "sun.0012.exr");
    fp_rig_free(&r);
    /* The file over the frame's own. */
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.rig.text = strdup("fogpipe-rig 1 up y clip 2 point 9 9 9 1 1 1 0");
    assert_int_equal(fp_rig_frame(f, &info, "x.exr", 12, &r), FP_OK);
    assert_true(r.up == FP_UP_Z && r.clip == 0.5 && r.nlights == 0);
    fp_rig_free(&r);
    free(info.rig.text);
    fp_rig_file_free(f);

    static const char *const bad[] = {
        "{}",
        "{\"fogpipe_rig\": 2}",
        "{\"fogpipe_rig\": 1, \"up\": \"x\"}",
        "{\"fogpipe_rig\": 1, \"clip_start\": -1}",
        "{\"fogpipe_rig\": 1, \"clip_start\": \"0.1\"}",
        "{\"fogpipe_rig\": 1, \"shadow_map\": \"\"}",
        "{\"fogpipe_rig\": 1, \"lights\": {}}",
        "{\"fogpipe_rig\": 1, \"colour\": 1}",
        "{\"fogpipe_rig\": 1, \"lights\": [{\"type\": \"laser\"}]}",
        "{\"fogpipe_rig\": 1, \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], "
        "\"intensity\": [1,1,1]}]}",
        "{\"fogpipe_rig\": 1, \"lights\": [{\"type\": \"point\", \"position\": [0,0], "
        "\"intensity\": [1,1,1], \"radius\": 0}]}",
        "{\"fogpipe_rig\": 1, \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], "
        "\"intensity\": [1,1,1], \"radius\": 0, \"size\": 3}]}",
        "{\"fogpipe_rig\": 1, \"lights\": [{\"type\": \"sun\", \"direction\": [0,0,0], "
        "\"irradiance\": [1,1,1], \"angle\": 0}]}",
        "{\"fogpipe_rig\": 1, \"lights\": [{\"type\": \"area\", \"position\": [0,0,0], "
        "\"intensity\": [1,1,1], \"normal\": [0,0,1], \"u\": [1,0,0], \"size\": [1,1], "
        "\"shape\": \"hexagon\"}]}",
        "{\"fogpipe_rig\": 1, \"frames\": []}",
        "{\"fogpipe_rig\": 1, \"frames\": {\"x\": {}}}",
        "{\"fogpipe_rig\": 1, \"frames\": {\"1\": {\"up\": 3}}}",
        "{\"fogpipe_rig\": 1, \"frames\": {\"1\": {}, \"01\": {}}}",
        "{\"fogpipe_rig\": 1, \"frames\": {\"1\": {\"frames\": {}}}}",
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(bad); i++) {
        path = write_tmp(bad[i]);
        if (fp_rig_file_load(path, &f) == FP_OK) {
            fp_rig_file_free(f);
            fail_msg("accepted: %s", bad[i]);
        }
    }
    unlink(path);
    assert_int_not_equal(fp_rig_file_load("/nonexistent/rig.json", &f), FP_OK);
}

static fp_params_t base_params(const char *const *args)
{
    fp_params_t p;
    fp_options_defaults(&p);
    for (; args && *args; args += 2)
        assert_int_equal(fp_options_apply(&p, args[0], args[1], "test"), FP_OK);
    return p;
}

static void test_precedence(void **state)
{
    (void)state;
    fp_rig_t r;
    assert_int_equal(parse("fogpipe-rig 1 clip 0.3 shadow maps/sun.exr "
                           "sun 0 0 2 1 2 4 0.5 sun 1 0 0 0.1 0.1 0.1 0 "
                           "point 1 2 3 10 8 6 0.1 spot 0 0 5 2 2 2 0 0 0 -1 60 0.5",
                           &r, NULL, NULL), FP_OK);
    fp_params_t q;
    /* Nothing given: everything from the rig. */
    fp_params_t p = base_params(NULL);
    assert_int_equal(fp_rig_apply(&p, &r, "shots/a.0001.exr", 1, &q), FP_OK);
    assert_double_equal(q.camera.clip_start, 0.3, 0);
    assert_true(fp_options_given(&q, "sun"));
    assert_double_equal(q.light.sun[2], 1, 1e-15);
    assert_double_equal(q.light.sun_intensity, 4, 0);
    assert_double_equal(q.light.sun_color[0], 0.25, 0);
    assert_int_equal(q.light.num_lights, 3);   /* the second sun, the point, the spot */
    assert_int_equal(q.light.lights[0].kind, 3);
    assert_double_equal(q.light.lights[0].axis[0], 1, 0);
    assert_int_equal(q.light.lights[1].kind, 0);
    assert_double_equal(q.light.lights[1].color[0] * q.light.lights[1].intensity, 10, 0);
    assert_int_equal(q.light.lights[2].kind, 1);
    assert_int_equal(q.light.lights[2].spot_profile, 1);
    assert_double_equal(q.light.lights[2].outer, 30, 1e-12);
    assert_double_equal(q.light.lights[2].blend, 0.5, 0);
    /* The inner cone where Cycles' smoothstep ends. */
    double co = cos(30 * M_PI / 180);
    assert_double_equal(cos(q.light.lights[2].inner * M_PI / 180), co + (1 - co) * 0.5, 1e-12);
    assert_string_equal(q.light.shadow_map, "shots/maps/sun.exr");
    assert_true(q.light.shadow_map_literal);
    assert_false(fp_options_given(&p, "sun"));   /* the base is untouched */
    assert_int_equal(p.light.num_lights, 0);
    fp_rig_params_release(&q);
    fp_options_free(&p);

    /* Flags win, each for its own part. */
    static const char *const flags[] = { "clip-start", "0", "sun", "0,1,0", "light",
                                         "point:0,0,0:1,1,1:5", "shadow-map", "mine.####.exr",
                                         NULL };
    p = base_params(flags);
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q), FP_OK);
    assert_double_equal(q.camera.clip_start, 0, 0);
    assert_double_equal(q.light.sun[1], 1, 0);
    assert_double_equal(q.light.sun_intensity, 3, 0);   /* the default, not the rig's */
    assert_int_equal(q.light.num_lights, 1);            /* --light only: suns are --sun's */
    assert_double_equal(q.light.lights[0].intensity, 5, 0);
    assert_string_equal(q.light.shadow_map, "mine.####.exr");
    assert_false(q.light.shadow_map_literal);
    fp_rig_params_release(&q);
    fp_options_free(&p);

    /* --sun-intensity alone drops the rig's suns, keeps its local lights. */
    static const char *const si[] = { "sun-intensity", "7", NULL };
    p = base_params(si);
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q), FP_OK);
    assert_false(fp_options_given(&q, "sun"));
    assert_int_equal(q.light.num_lights, 2);
    assert_null(q.light.shadow_map);   /* no sun: no sun shadow map */
    fp_rig_params_release(&q);
    fp_options_free(&p);

    /* --lights none: no suns, lights or map; the clip still applies. */
    static const char *const none[] = { "lights", "none", NULL };
    p = base_params(none);
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q), FP_OK);
    assert_false(fp_options_given(&q, "sun"));
    assert_int_equal(q.light.num_lights, 0);
    assert_null(q.light.shadow_map);
    assert_double_equal(q.camera.clip_start, 0.3, 0);
    /* Equal inputs, equal keys; another light, another key. */
    fp_params_t q2;
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q2), FP_OK);
    assert_true(fp_rig_light_key(&q) == fp_rig_light_key(&q2));
    fp_options_free(&p);
    p = base_params(NULL);
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q2), FP_OK);
    assert_true(fp_rig_light_key(&q) != fp_rig_light_key(&q2));
    fp_rig_params_release(&q2);
    fp_options_free(&p);
    /* A cut-off rig: an error where its lights are used, none with
     * --lights none, or with both --light and --sun. */
    r.cut = strdup("a.exr: frame 1: the rig says 9 lights but carries 4");
    p = base_params(NULL);
    assert_int_not_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q2), FP_OK);
    fp_rig_params_release(&q2);
    fp_options_free(&p);
    p = base_params(none);
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q2), FP_OK);
    fp_rig_params_release(&q2);
    fp_options_free(&p);
    p = base_params(flags);
    assert_int_equal(fp_rig_apply(&p, &r, "a.exr", 1, &q2), FP_OK);
    fp_rig_params_release(&q2);
    fp_options_free(&p);
    fp_rig_free(&r);

    /* The run's up axis from the first frame, unless --up. */
    assert_int_equal(parse("fogpipe-rig 1 up z", &r, NULL, NULL), FP_OK);
    p = base_params(NULL);
    assert_int_equal(fp_rig_prescan(&p, NULL, &r, "a.exr", 1), FP_OK);
    assert_int_equal(p.camera.up, FP_UP_Z);
    fp_options_free(&p);
    static const char *const upy[] = { "up", "y", NULL };
    p = base_params(upy);
    assert_int_equal(fp_rig_prescan(&p, NULL, &r, "a.exr", 1), FP_OK);
    assert_int_equal(p.camera.up, FP_UP_Y);
    fp_options_free(&p);
    fp_rig_free(&r);
}

static void test_look(void **state)
{
    (void)state;
    static const char *const cli[] = { "visibility", "100", NULL };
    fp_params_t p = base_params(cli);
    double sigma = p.fog.density;
    assert_int_equal(fp_options_apply_look(&p, "fogpipe-look 1 density=0.5 height=0,inf,15 "
                                                "fog-color=0.1,0.2,0.3;phase=hg:0.3 albedo=0.8 "
                                                "fog-box=-1,-2,-3,1,2,3 fogpipe-rig 1",
                                           "f.exr: frame 1: attribute 'Note'"), FP_OK);
    assert_double_equal(p.fog.density, sigma, 0);   /* --visibility (the same field) wins */
    assert_double_equal(p.fog.height[2], 15, 0);
    assert_true(isinf(p.fog.height[1]));
    assert_double_equal(p.fog.color[2], 0.3, 0);
    assert_double_equal(p.light.albedo, 0.8, 0);
    assert_double_equal(p.light.phase_g, 0.3, 1e-12);
    assert_double_equal(p.fog.box[5], 3, 0);
    static const char *const bad[] = {
        "density=0.1",                      /* no header */
        "fogpipe-look 2 density=0.1",
        "fogpipe-look 1 density",
        "fogpipe-look 1 density=",
        "fogpipe-look 1 albedo=2",
        "fogpipe-look 1 frobnicate=1",
        "fogpipe-look 1 output=/tmp/x.exr",  /* not a look */
        "fogpipe-look 1 shadow-map=x.exr",
        "fogpipe-look 1 light=point:0,0,0:1,1,1:1",
        "fogpipe-look 1 help=1",
        "fogpipe-look 1 up=z",
        "fogpipe-look",
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(bad); i++)
        if (fp_options_apply_look(&p, bad[i], "test") == FP_OK)
            fail_msg("accepted: %s", bad[i]);
    fp_options_free(&p);
}

static void test_frame_of_name(void **state)
{
    (void)state;
    long f = -1;
    assert_true(fp_seq_frame_of_name("shots/shot.0002.exr", &f) && f == 2);
    assert_true(fp_seq_frame_of_name("render_v0017.exr", &f) && f == 17);
    assert_true(fp_seq_frame_of_name("render_17.exr", &f) && f == 17);
    assert_false(fp_seq_frame_of_name("huge_b44.exr", &f));
    assert_false(fp_seq_frame_of_name("p3.exr", &f));
    assert_true(fp_seq_frame_of_name("0100.exr", &f) && f == 100);
    assert_false(fp_seq_frame_of_name("shot.exr", &f));
    assert_false(fp_seq_frame_of_name("v2.0/shot", &f));
    assert_false(fp_seq_frame_of_name("shot.1234567890.exr", &f));
}

/* The clip start in the fog: homogeneous fog over [clip, depth] of each
 * ray, tau = exp(-sigma * (d - clip) / cos) for planar depth d, 1 where the
 * surface is nearer than the clip; the same on the device. */
static void test_clip_closed_form(void **state)
{
    (void)state;
    fp_params_t p;
    fp_options_defaults(&p);
    p.fog.density = 0.2;
    p.fog.height[1] = INFINITY;
    fp_integrate_data_t d;
    assert_int_equal(fp_integrate_commit(&p, &d), FP_OK);
    fp_view_t v0, v;
    assert_int_equal(make_view(&v0, 24, 16, 1.5, -10), FP_OK);
    v = v0;
    v.clip = 0.7;
    enum { W = 24, H = 16, N = W * H };
    float depth[N], fog0[4 * N], fog[4 * N], fcl[4 * N];
    for (int i = 0; i < N; i++)
        depth[i] = i % 7 == 0 ? 0.5f : i % 11 == 0 ? INFINITY : (float)(1 + 0.1 * (i % 50));
    assert_int_equal(fp_integrate_pixels(&d, &v0, depth, NULL, N, fog0), FP_OK);
    assert_int_equal(fp_integrate_pixels(&d, &v, depth, NULL, N, fog), FP_OK);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int i = y * W + x;
            if (isinf(depth[i]))
                continue;
            double dir[3], len;
            fp_view_ray(&v0, x, y, depth[i], dir, &len);
            double inv_cos = len / depth[i];   /* distance per unit of planar depth */
            double want = depth[i] < 0.7 ? 1 : exp(-0.2 * (depth[i] - 0.7) * inv_cos);
            assert_double_equal(fog[4 * i + 3], want, 2e-6);
            /* Without the clip: from the camera. */
            assert_double_equal(fog0[4 * i + 3], exp(-0.2 * len), 2e-6);
        }
    /* Clip 0 is the camera's start, to the bit. */
    fp_view_t vz = v0;
    vz.clip = 0;
    float fz[4 * N];
    assert_int_equal(fp_integrate_pixels(&d, &vz, depth, NULL, N, fz), FP_OK);
    assert_memory_equal(fz, fog0, sizeof fz);
    /* OpenCL against the C reference. */
    fp_cl_t *cl;
    if (fp_cl_open(NULL, &cl) != FP_OK) {
        fp_options_free(&p);
        skip();
    }
    fp_integrate_cl_t s;
    assert_int_equal(fp_integrate_cl_init(cl, &s), FP_OK);
    assert_int_equal(fp_integrate_pixels_cl(&s, &d, &v, depth, NULL, N, fcl), FP_OK);
    for (int i = 0; i < 4 * N; i++)
        assert_double_equal(fcl[i], fog[i], 2e-5);
    fp_integrate_cl_release(&s);
    fp_cl_close(cl);
    fp_options_free(&p);
}

int main(void)
{
    fp_quiet = 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_text_form),
        cmocka_unit_test(test_text_errors),
        cmocka_unit_test(test_frame_attributes),
        cmocka_unit_test(test_json),
        cmocka_unit_test(test_rig_file),
        cmocka_unit_test(test_precedence),
        cmocka_unit_test(test_look),
        cmocka_unit_test(test_frame_of_name),
        cmocka_unit_test(test_clip_closed_form),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
