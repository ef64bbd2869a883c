/* bench_light's section on what issue 26's many-lamps goal asks of any
 * cut whose error is bounded (a light tree, Lightcuts, culling): on the
 * street of lamps_section, the C reference (fp_light_ray, the judge) on
 * every 37th pixel, per pixel
 *   - the lamps --light-cull 1e-4 computes (the others' bounds sum to at
 *     most 1e-4: what the kernels do);
 *   - the fewest lamps that carry 95% and 99% of the pixel's lamp light
 *     (the largest channel of each lamp's in-scatter, sorted): a cut whose
 *     error is at most 5% or 1% of that light and whose bounds cost no
 *     more than the light they stand for must compute at least those
 *     (a group stands for its lamps only within its bound, and a bound is
 *     never below the light it bounds);
 *   - how far fp_light_bound (kernels/light_core.h) is above each lamp's
 *     in-scatter (geometric mean over lamp-pixel pairs that get light);
 * and the cost a cut computing only the 99% lamps would have at the
 * per-lamp cost lamps_section measured (its CPU ns/px less one lamp's,
 * over the lamps computed less one), against one lamp: below the goal or
 * not.  Included by tests/bench_light.c after its helpers (look_setup,
 * street_opts). */
#ifndef FP_BENCH_LAMP_FLOOR_H
#define FP_BENCH_LAMP_FLOOR_H

static int floor_desc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? 1 : x > y ? -1 : 0;
}

/* cost: lamps_section's CPU ns/px for 1, 8, 64, 256 lamps (NaN: not
 * measured). */
static void floor_section(bench_t *b, const double cost[4])
{
    static const int counts[] = { 64, 256 }, ci_of[] = { 2, 3 };
    const size_t stride = 37;
    printf("\n### Many lamps: what a cut with a bounded error must compute (issue 26)\n\n"
           "The street above, the C reference on every %zuth pixel: per pixel the lamps that "
           "--light-cull 1e-4 computes, the fewest lamps carrying 95%% and 99%% of the pixel's "
           "lamp light (a cut whose error is within 5%% or 1%% of that light, a group standing "
           "for its lamps within its bound, must compute at least those: a bound is never "
           "below the light it bounds), means over the pixels; the culling bound over each "
           "lamp's in-scatter (geometric mean); and the cost against one lamp of a cut that "
           "computes only the 99%% lamps, at the per-lamp cost measured above.\n\n", stride);
    printf("| lamps | pixels | computed (cull 1e-4) | carrying 95%% | carrying 99%% | bound / "
           "in-scatter | 99%% cut against one lamp | goal |\n|---|---|---|---|---|---|---|---|\n");
    for (size_t ci = 0; ci < FP_ARRAY_LEN(counts); ci++) {
        int n = counts[ci], m;
        char **opts = street_opts(n, &m);
        double *c = malloc((size_t)n * sizeof *c);
        look_t l;
        if (!opts || !c) {
            free(c);
            return;
        }
        opts[m] = strdup("light-cull=1e-4");
        if (look_setup(b, &l, (const char *const *)opts)) {
            printf("| %d | failed | | | | | | |\n", n);
        } else {
            const double *fp = l.fog.fp, *lt = l.light.lt, *lights = l.light.lights;
            const double *o = b->view.origin;
            long px = 0, computed = 0, k95 = 0, k99 = 0, pairs = 0;
            double logr = 0;
            for (size_t i = 0; i < b->n; i += stride) {
                int x = (int)(i % (size_t)b->view.width), y = (int)(i / (size_t)b->view.width);
                double d[3], len, ta, tb;
                fp_view_ray(&b->view, x, y, b->depth[i], d, &len);
                fp_light_span(fp, o[0], o[1], o[2], d[0], d[1], d[2], len, &ta, &tb);
                if (!(tb > ta))
                    continue;
                double od = fp_fog_od(fp, NULL, NULL, NULL, NULL, o[0], o[1], o[2], d[0], d[1],
                                      d[2], len, 0);
                double omt = -expm1(-od), smax = fp_light_sigma_span(fp, o[1], d[1], ta, tb);
                double budget = lt[FP_LT_CULL], total = 0;
                for (int k = 0; k < n; k++) {
                    const double *row = lights + (size_t)k * FP_LL_STRIDE;
                    double S[3];
                    fp_light_ray(fp, lt, lights, k, o[0], o[1], o[2], d[0], d[1], d[2], len, S);
                    c[k] = fmax(S[0], fmax(S[1], S[2]));
                    total += c[k];
                    double bd = fp_light_bound(lt, row, smax, omt, o[0], o[1], o[2], d[0], d[1],
                                               d[2], ta, tb);
                    if (bd <= budget)
                        budget -= bd;
                    else
                        computed++;
                    if (c[k] > 0 && isfinite(bd)) {
                        logr += log(bd / c[k]);
                        pairs++;
                    }
                }
                qsort(c, (size_t)n, sizeof *c, floor_desc);
                double acc = 0;
                int a95 = 0, a99 = 0;
                for (int k = 0; k < n && total > 0 && acc < 0.99 * total; k++) {
                    acc += c[k];
                    a95 += acc - c[k] < 0.95 * total;
                    a99++;
                }
                k95 += a95;
                k99 += a99;
                px++;
            }
            double pc = (double)computed / (double)(px ? px : 1);
            double p95 = (double)k95 / (double)(px ? px : 1), p99 = (double)k99 / (double)(px ? px : 1);
            /* The per-lamp cost: what n lamps add to one, over the lamps
             * computed beyond the first. */
            double one = cost[0], per = (cost[ci_of[ci]] - one) / fmax(pc - 1, 1);
            double ratio = (one + per * fmax(p99 - 1, 0)) / one, goal = n == 64 ? 3 : 4;
            printf("| %d | %ld | %.1f | %.1f | %.1f | %.0fx | %.1fx | <= %gx (%s) |\n", n, px, pc,
                   p95, p99, exp(logr / (double)(pairs ? pairs : 1)), ratio, goal,
                   isnan(ratio) ? "not measured" : ratio <= goal ? "met" : "not met");
            look_release(&l);
        }
        for (int k = 0; k <= m; k++)
            free(opts[k]);
        free(opts);
        free(c);
    }
}

#endif
