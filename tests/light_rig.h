/* fogpipe tests: the fog and light stages committed from option pairs
 * (test_lights, test_cull, test_light_band, test_ms).  Include after
 * testutil.h, integrate.h and scatter.h. */
#ifndef FP_TEST_LIGHT_RIG_H
#define FP_TEST_LIGHT_RIG_H

typedef struct rig_t {
    fp_params_t p;
    fp_integrate_data_t fog;
    fp_scatter_data_t sd;
} rig_t;

/* opts: NULL-ended pairs of an option's name and value. */
static void rig_open(rig_t *r, const char *const *opts)
{
    memset(r, 0, sizeof *r);
    fp_options_defaults(&r->p);
    for (int i = 0; opts[i]; i += 2)
        if (fp_options_apply(&r->p, opts[i], opts[i + 1], "test"))
            fail_msg("option --%s %s refused", opts[i], opts[i + 1]);
    assert_int_equal(fp_integrate_commit(&r->p, &r->fog), FP_OK);
    assert_int_equal(fp_scatter_commit(&r->p, &r->sd), FP_OK);
}

static void rig_close(rig_t *r)
{
    fp_scatter_release(&r->sd);
    fp_options_free(&r->p);
}

#endif
