/* Phase functions and their importance sampling (kernels/phase.h) and the
 * random number generator (kernels/rng.h), in the C (double) build:
 * normalization within 1e-3 by quadrature; the samplers' density
 * (fp_phase_pdf) equal to the phase function within 1e-4 relative, the
 * inverted CDFs checked against their closed forms and by differencing;
 * histograms of sampled mu, and of dot(o, d) and the azimuth of sampled
 * directions, against 2 pi p integrated over each bin (binomial, 5 sigma);
 * mean cosines within 0.01 (samples) and 1e-3 (quadrature) of the formulas. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fog_core.h"
#include "phase.h"

#define ARRAY_LEN(a) (sizeof(a) / sizeof((a)[0]))
#define TWO_PI 6.283185307179586

typedef struct {
    const char *name;
    int kind;
    double g, w;
} config_t;

static const config_t configs[] = {
    { "iso", FP_PHASE_ISO, 0, 0 },
    { "hg:-0.7", FP_PHASE_HG, -0.7, 0 },
    { "hg:0", FP_PHASE_HG, 0, 0 },
    { "hg:0.3", FP_PHASE_HG, 0.3, 0 },
    { "hg:0.9", FP_PHASE_HG, 0.9, 0 },
    { "cs:-0.7", FP_PHASE_CS, -0.7, 0 },
    { "cs:0", FP_PHASE_CS, 0, 0 },
    { "cs:0.3", FP_PHASE_CS, 0.3, 0 },
    { "cs:0.9", FP_PHASE_CS, 0.9, 0 },
    { "rayleigh", FP_PHASE_RAYLEIGH, 0, 0 },
    { "mix:0.3,0.8", FP_PHASE_MIX, 0.8, 0.3 },
    { "mixhg:0.5,0.6", FP_PHASE_MIXHG, 0.6, 0.5 },
};

/* Gauss-Legendre, 5 nodes on [-1, 1]. */
static const double glx[5] = { -0.9061798459386640, -0.5384693101056831, 0,
                               0.5384693101056831, 0.9061798459386640 };
static const double glw[5] = { 0.2369268850561891, 0.4786286704993665, 0.5688888888888889,
                               0.4786286704993665, 0.2369268850561891 };

/* 2 pi * integral over [a, b] of mu^power p(mu) (p = fp_phase, or
 * fp_phase_pdf with pdf set), composite Gauss-Legendre with panels of at
 * most 1e-4: the narrowest peak here (HG, g = 0.9, width ~ (1-g)^2 / 2g =
 * 0.0056) spans over 50 panels. */
static double integral(const config_t *c, double a, double b, int power, int pdf)
{
    int n = (int)ceil((b - a) / 1e-4);
    if (n < 1)
        n = 1;
    double h = (b - a) / n, sum = 0;
    for (int i = 0; i < n; i++) {
        double mid = a + (i + 0.5) * h;
        for (int k = 0; k < 5; k++) {
            double mu = mid + 0.5 * h * glx[k];
            double p = pdf ? fp_phase_pdf(c->kind, c->g, c->w, mu)
                           : fp_phase(c->kind, c->g, c->w, mu);
            sum += glw[k] * p * (power ? mu : 1);
        }
    }
    return TWO_PI * 0.5 * h * sum;
}

/* ------------------------------------------------------------------ rng */

static void test_rng(void **state)
{
    (void)state;
    fp_rng_t r = fp_rng_seed(42, 0, 0);
    double sum = 0, sum2 = 0, lo = 1, hi = 0;
    const int n = 1000000;
    for (int i = 0; i < n; i++) {
        double u = FP_RNG_NEXT(&r);
        if (!(u >= 0 && u < 1))
            fail_msg("draw %d: %.17g outside [0, 1)", i, u);
        sum += u;
        sum2 += u * u;
        lo = fmin(lo, u);
        hi = fmax(hi, u);
    }
    double mean = sum / n, var = sum2 / n - mean * mean;
    print_message("rng: mean %.6f (|-0.5| %.2g, tolerance 1e-3), variance %.6f (1/12 = %.6f), "
                  "range [%.3g, %.9f]\n", mean, fabs(mean - 0.5), var, 1.0 / 12, lo, hi);
    assert_true(fabs(mean - 0.5) <= 1e-3);
    assert_true(fabs(var - 1.0 / 12) <= 1e-3);
    assert_true(lo < 1e-4 && hi > 1 - 1e-4);

    /* Repeatable, and different (seed, pixel, sample) give different streams. */
    const fp_u32 keys[][3] = { { 42, 0, 0 }, { 43, 0, 0 }, { 42, 1, 0 }, { 42, 0, 1 },
                               { 0, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 }, { 1, 0, 0 } };
    const int nk = (int)ARRAY_LEN(keys), len = 32;
    double streams[8][32];
    for (int k = 0; k < nk; k++) {
        fp_rng_t a = fp_rng_seed(keys[k][0], keys[k][1], keys[k][2]);
        fp_rng_t b = fp_rng_seed(keys[k][0], keys[k][1], keys[k][2]);
        for (int i = 0; i < len; i++) {
            streams[k][i] = FP_RNG_NEXT(&a);
            assert_true(streams[k][i] == FP_RNG_NEXT(&b));
        }
    }
    for (int k = 0; k < nk; k++)
        for (int m = k + 1; m < nk; m++) {
            int same = 0;
            for (int i = 0; i < len; i++)
                same += streams[k][i] == streams[m][i];
            if (same > 1)
                fail_msg("streams (%u,%u,%u) and (%u,%u,%u): %d of %d draws equal", keys[k][0],
                         keys[k][1], keys[k][2], keys[m][0], keys[m][1], keys[m][2], same, len);
        }

    /* One draw per stream, streams of consecutive samples: uniform and
     * uncorrelated (how the renderer seeds one stream per sample). */
    double s1 = 0, s11 = 0, s12 = 0, prev = 0;
    const int ns = 200000;
    for (int k = 0; k <= ns; k++) {
        fp_rng_t a = fp_rng_seed(7, 3, (fp_u32)k);
        double u = FP_RNG_NEXT(&a);
        if (k > 0) {
            s1 += u;
            s11 += u * u;
            s12 += u * prev;
        }
        prev = u;
    }
    double m1 = s1 / ns, v1 = s11 / ns - m1 * m1, corr = (s12 / ns - m1 * m1) / v1;
    print_message("rng: first draws of consecutive streams: mean %.5f, lag-1 correlation %.2g\n",
                  m1, corr);
    assert_true(fabs(m1 - 0.5) <= 3e-3);
    assert_true(fabs(corr) <= 0.01);
}

/* ------------------------------------------------------- normalization */

static void test_normalization(void **state)
{
    (void)state;
    double worst = 0;
    for (size_t i = 0; i < ARRAY_LEN(configs); i++) {
        const config_t *c = &configs[i];
        for (int pdf = 0; pdf < 2; pdf++) {
            double e = fabs(integral(c, -1, 1, 0, pdf) - 1);
            worst = fmax(worst, e);
            if (!(e <= 1e-3))
                fail_msg("%s: 2 pi int %s dmu = 1 %+.3g", c->name,
                         pdf ? "fp_phase_pdf" : "fp_phase", e);
        }
    }
    print_message("normalization: max |2 pi int p dmu - 1| = %.3g (tolerance 1e-3)\n", worst);
}

/* ------------------------------------------------ the samplers' density */

/* fp_phase_pdf (the density the samplers produce, derived from them)
 * against fp_phase (the definition), relative, on a grid of mu that
 * includes both ends. */
static void test_pdf_equals_phase(void **state)
{
    (void)state;
    double worst = 0;
    const double extra_g[] = { -0.999, -0.5, -1e-4, 1e-4, 5e-4, 2e-3, 0.5, 0.95, 0.999 };
    for (size_t i = 0; i < ARRAY_LEN(configs) + 2 * ARRAY_LEN(extra_g); i++) {
        config_t c;
        if (i < ARRAY_LEN(configs)) {
            c = configs[i];
        } else {
            size_t j = i - ARRAY_LEN(configs);
            c.name = j < ARRAY_LEN(extra_g) ? "hg (extra)" : "cs (extra)";
            c.kind = j < ARRAY_LEN(extra_g) ? FP_PHASE_HG : FP_PHASE_CS;
            c.g = extra_g[j % ARRAY_LEN(extra_g)];
            c.w = 0;
        }
        for (int k = 0; k <= 2000; k++) {
            double mu = -1 + k / 1000.0;
            double want = fp_phase(c.kind, c.g, c.w, mu);
            double got = fp_phase_pdf(c.kind, c.g, c.w, mu);
            double e = fabs(got - want) / want;
            worst = fmax(worst, e);
            if (!(e <= 1e-4))
                fail_msg("%s g %g w %g mu %g: pdf %.12g phase %.12g", c.name, c.g, c.w, mu, got,
                         want);
        }
    }
    print_message("pdf vs phase: max relative difference %.3g (tolerance 1e-4)\n", worst);
}

/* HG CDF in closed form, for g != 0. */
static double hg_cdf(double g, double mu)
{
    return (1 - g * g) / (2 * g) * (1 / sqrt(1 + g * g - 2 * g * mu) - 1 / (1 + g));
}

/* The inversions: F(F^-1(u)) = u against the closed-form CDFs (including
 * g near 0, where the usual HG inversion cancels, and the ends u = 0 and
 * u -> 1); and the density of the map u -> mu, 1 / (2 pi dmu/du) by
 * central differences, equals fp_phase_pdf. */
static void test_inversion(void **state)
{
    (void)state;
    const double gs[] = { -0.99, -0.9, -0.7, -0.3, -1e-2, -1e-4, 1e-5, 1e-4, 5e-4, 1e-3,
                          3e-3, 0.1, 0.3, 0.6, 0.9, 0.99 };
    double worst_cdf = 0, worst_jac = 0;
    const double h = 1e-6;
    for (size_t i = 0; i <= ARRAY_LEN(gs); i++) {
        int ray = i == ARRAY_LEN(gs);
        double g = ray ? 0 : gs[i];
        for (int k = 0; k <= 4000; k++) {
            double u = k == 4000 ? 1 - 1.0 / 16777216 : k / 4000.0;
            double mu = ray ? fp_phase_rayleigh_invert(u) : fp_phase_hg_invert(g, u);
            if (!(mu >= -1 && mu <= 1))
                fail_msg("%s g %g: u %.17g -> mu %.17g", ray ? "rayleigh" : "hg", g, u, mu);
            double F = ray ? (mu * mu * mu + 3 * mu + 4) / 8 : hg_cdf(g, mu);
            double e = fabs(F - u);
            /* hg_cdf itself loses ~1e-16 / |g| near g = 0 */
            double tol = 1e-12 + (ray ? 0 : 1e-15 / fabs(g));
            worst_cdf = fmax(worst_cdf, e);
            if (!(e <= tol))
                fail_msg("%s g %g: F(F^-1(%.17g)) = %.17g", ray ? "rayleigh" : "hg", g, u, F);
            if (k == 0 || k == 4000)
                continue;
            double m0 = ray ? fp_phase_rayleigh_invert(u - h) : fp_phase_hg_invert(g, u - h);
            double m1 = ray ? fp_phase_rayleigh_invert(u + h) : fp_phase_hg_invert(g, u + h);
            double dens = 2 * h / (m1 - m0) / TWO_PI;
            double want = fp_phase_pdf(ray ? FP_PHASE_RAYLEIGH : FP_PHASE_HG, g, 0, mu);
            e = fabs(dens - want) / want;
            worst_jac = fmax(worst_jac, e);
            if (!(e <= 1e-4))
                fail_msg("%s g %g u %g mu %.12g: density of the map %.10g, pdf %.10g",
                         ray ? "rayleigh" : "hg", g, u, mu, dens, want);
        }
    }
    print_message("inversions: max |F(F^-1(u)) - u| %.3g; map density vs pdf: max relative "
                  "difference %.3g (tolerance 1e-4)\n", worst_cdf, worst_jac);
}

/* ------------------------------------------------------------ histograms */

#define NSAMPLES 200000
#define NBINS 50

/* Bin edges with about equal probability under 2 pi p (from a tabulated
 * CDF), so the narrow peaks are resolved; the expected counts are then
 * integrated over the actual edges, so the edges need not be exact. */
static void equiprobable_edges(const config_t *c, int nb, double *edges)
{
    enum { M = 4000 };
    static double cdf[M + 1];
    cdf[0] = 0;
    for (int i = 0; i < M; i++)
        cdf[i + 1] = cdf[i] + integral(c, -1 + 2.0 * i / M, -1 + 2.0 * (i + 1) / M, 0, 0);
    edges[0] = -1;
    edges[nb] = 1;
    int j = 0;
    for (int b = 1; b < nb; b++) {
        double t = cdf[M] * b / nb;
        while (j < M - 1 && cdf[j + 1] < t)
            j++;
        double f = (t - cdf[j]) / (cdf[j + 1] - cdf[j]);
        edges[b] = -1 + 2.0 * (j + f) / M;
    }
}

static int find_bin(const double *edges, int nb, double x)
{
    int lo = 0, hi = nb; /* edges[lo] <= x < edges[hi] */
    while (hi - lo > 1) {
        int m = (lo + hi) / 2;
        if (x >= edges[m])
            lo = m;
        else
            hi = m;
    }
    return lo;
}

/* 2 pi int_bin p for each bin. */
static void bin_probs(const config_t *c, const double *edges, int nb, double *probs)
{
    for (int b = 0; b < nb; b++)
        probs[b] = integral(c, edges[b], edges[b + 1], 0, 0);
}

static double worst_chi2; /* the largest chi^2 / degrees of freedom seen */

/* Counts against N * share * 2 pi int_bin p: |obs - exp| <= 5 sigma
 * (binomial) + 3 in every bin.  For a whole histogram (share 1), also
 * Pearson's chi^2 (nb - 1 degrees of freedom) within 5 of its standard
 * deviations of its mean, which catches small deviations spread over many
 * bins.  Returns the largest |z|. */
static double check_counts(const config_t *c, const char *what, const double *edges, int nb,
                           const double *probs, const long *counts, long n, double share)
{
    double worst = 0, chi2 = 0;
    for (int b = 0; b < nb; b++) {
        double p = probs[b] * share;
        double expect = n * p, sd = sqrt(n * p * (1 - p));
        double dev = fabs((double)counts[b] - expect);
        double z = sd > 0 ? dev / sd : (dev > 0 ? INFINITY : 0);
        worst = fmax(worst, z);
        chi2 += expect > 0 ? dev * dev / expect : 0;
        if (!(dev <= 5 * sd + 3))
            fail_msg("%s, %s: bin %d [%.6f, %.6f): %ld samples, expected %.1f (z = %.2f)",
                     c->name, what, b, edges[b], edges[b + 1], counts[b], expect, z);
    }
    if (share == 1) {
        double dof = nb - 1;
        worst_chi2 = fmax(worst_chi2, chi2 / dof);
        if (!(chi2 <= dof + 5 * sqrt(2 * dof)))
            fail_msg("%s, %s: chi^2 %.1f for %.0f degrees of freedom", c->name, what, chi2,
                     dof);
    }
    return worst;
}

static void test_sampled_mu(void **state)
{
    (void)state;
    double worst_z = 0, worst_mean = 0, worst_quad = 0;
    worst_chi2 = 0;
    double uniform[NBINS + 1], eq[NBINS + 1];
    for (int b = 0; b <= NBINS; b++)
        uniform[b] = -1 + 2.0 * b / NBINS;
    for (size_t i = 0; i < ARRAY_LEN(configs); i++) {
        const config_t *c = &configs[i];
        equiprobable_edges(c, NBINS, eq);
        long cu[NBINS] = { 0 }, ce[NBINS] = { 0 };
        double sum = 0;
        for (long k = 0; k < NSAMPLES; k++) {
            /* one stream per sample, as a renderer seeds them */
            fp_rng_t r = fp_rng_seed(1000 + (fp_u32)i, 0, (fp_u32)k);
            double mu = fp_phase_sample_mu(c->kind, c->g, c->w, &r);
            if (!(mu >= -1 && mu <= 1))
                fail_msg("%s: sample %ld: mu = %.17g", c->name, k, mu);
            sum += mu;
            int bu = (int)floor((mu + 1) * 0.5 * NBINS);
            cu[bu < 0 ? 0 : bu >= NBINS ? NBINS - 1 : bu]++;
            ce[find_bin(eq, NBINS, mu)]++;
        }
        double pu[NBINS], pe[NBINS];
        bin_probs(c, uniform, NBINS, pu);
        bin_probs(c, eq, NBINS, pe);
        worst_z = fmax(worst_z,
                       check_counts(c, "uniform bins", uniform, NBINS, pu, cu, NSAMPLES, 1));
        worst_z = fmax(worst_z,
                       check_counts(c, "equiprobable bins", eq, NBINS, pe, ce, NSAMPLES, 1));

        double formula = fp_phase_mean_cos(c->kind, c->g, c->w);
        double mean = sum / NSAMPLES, quad = integral(c, -1, 1, 1, 0);
        worst_mean = fmax(worst_mean, fabs(mean - formula));
        worst_quad = fmax(worst_quad, fabs(quad - formula));
        if (!(fabs(mean - formula) <= 0.01))
            fail_msg("%s: sample mean of mu %.5f, formula %.5f", c->name, mean, formula);
        if (!(fabs(quad - formula) <= 1e-3))
            fail_msg("%s: 2 pi int mu p dmu = %.8f, formula %.8f", c->name, quad, formula);
    }
    print_message("sampled mu: %d samples x %zu phase functions, %d uniform + %d equiprobable "
                  "bins: worst |z| %.2f (tolerance 5 + 3 counts), worst chi^2/dof %.2f\n",
                  NSAMPLES, ARRAY_LEN(configs), NBINS, NBINS, worst_z, worst_chi2);
    print_message("mean cosine: max |sample mean - formula| %.3g (tolerance 0.01), "
                  "max |quadrature - formula| %.3g (tolerance 1e-3)\n", worst_mean, worst_quad);
}

/* Directions: unit length, dot(o, d) is the mu the same stream gives
 * fp_phase_sample_mu, and jointly (mu, azimuth) distributed as p(mu) / 2 pi
 * per steradian, the azimuth measured in a basis built independently. */
static const double dirs[][3] = { { 0, 0, 1 }, { 0, 0, -1 }, { 1, 0, 0 }, { 0, 1, 0 },
                                  { 1, 2, 3 }, { 0.3, -0.2, -0.9 }, { 1e-9, 0, -1 },
                                  { 0.01, 0.02, -1 }, { -1, -1, 1e-12 }, { 0.6, -0.8, -1e-7 } };

static void unit(double *v)
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    v[0] /= l;
    v[1] /= l;
    v[2] /= l;
}

static void cross(const double *a, const double *b, double *o)
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

#define NMU 10
#define NPHI 8

static void test_sampled_dir(void **state)
{
    (void)state;
    const int nd = (int)ARRAY_LEN(dirs);
    const long per_dir = NSAMPLES / 4;
    double worst_z = 0, worst_len = 0, worst_dot = 0, worst_mean = 0, worst_pdf = 0;
    worst_chi2 = 0;
    double eq[NBINS + 1], eqj[NMU + 1];
    for (size_t i = 0; i < ARRAY_LEN(configs); i++) {
        const config_t *c = &configs[i];
        equiprobable_edges(c, NBINS, eq);
        equiprobable_edges(c, NMU, eqj);
        double pe[NBINS], pj[NMU];
        bin_probs(c, eq, NBINS, pe);
        bin_probs(c, eqj, NMU, pj);
        long cm[NBINS] = { 0 };
        double sum = 0;
        long n = 0;
        for (int di = 0; di < nd; di++) {
            double d[3] = { dirs[di][0], dirs[di][1], dirs[di][2] }, e1[3], e2[3], ax[3] = { 0 };
            unit(d);
            int m = fabs(d[0]) < fabs(d[1]) ? (fabs(d[0]) < fabs(d[2]) ? 0 : 2)
                                            : (fabs(d[1]) < fabs(d[2]) ? 1 : 2);
            ax[m] = 1;
            cross(d, ax, e1);
            unit(e1);
            cross(d, e1, e2);
            long joint[NMU][NPHI] = { { 0 } }, phi_count[NPHI] = { 0 };
            fp_rng_t r = fp_rng_seed(2000 + (fp_u32)i, (fp_u32)di, 0);
            for (long k = 0; k < per_dir; k++) {
                fp_rng_t r2 = r;
                double mu = fp_phase_sample_mu(c->kind, c->g, c->w, &r2);
                double o[3];
                fp_phase_sample_dir(c->kind, c->g, c->w, d[0], d[1], d[2], &r, &o[0], &o[1],
                                    &o[2]);
                double len = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
                double dot = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
                worst_len = fmax(worst_len, fabs(len - 1));
                worst_dot = fmax(worst_dot, fabs(dot - mu));
                if (!(fabs(len - 1) <= 1e-9))
                    fail_msg("%s d (%g,%g,%g): |o| = %.17g", c->name, d[0], d[1], d[2], len);
                if (!(fabs(dot - mu) <= 1e-9))
                    fail_msg("%s d (%g,%g,%g): dot(o, d) = %.17g, sampled mu %.17g", c->name,
                             d[0], d[1], d[2], dot, mu);
                /* the density the sampler intends at this direction */
                double want = fp_phase(c->kind, c->g, c->w, dot);
                double e = fabs(fp_phase_pdf(c->kind, c->g, c->w, dot) - want) / want;
                worst_pdf = fmax(worst_pdf, e);
                if (!(e <= 1e-4))
                    fail_msg("%s: pdf at dot %.12g off by %.3g", c->name, dot, e);
                double phi = atan2(o[0] * e2[0] + o[1] * e2[1] + o[2] * e2[2],
                                   o[0] * e1[0] + o[1] * e1[1] + o[2] * e1[2]);
                if (phi < 0)
                    phi += TWO_PI;
                int bp = (int)(phi / TWO_PI * NPHI);
                bp = bp < 0 ? 0 : bp >= NPHI ? NPHI - 1 : bp;
                joint[find_bin(eqj, NMU, dot)][bp]++;
                phi_count[bp]++;
                cm[find_bin(eq, NBINS, dot)]++;
                sum += dot;
                n++;
            }
            /* the azimuth alone: uniform */
            for (int b = 0; b < NPHI; b++) {
                double p = 1.0 / NPHI, expect = per_dir * p, sd = sqrt(per_dir * p * (1 - p));
                double z = fabs(phi_count[b] - expect) / sd;
                worst_z = fmax(worst_z, z);
                if (!(fabs(phi_count[b] - expect) <= 5 * sd + 3))
                    fail_msg("%s d (%g,%g,%g): azimuth bin %d: %ld, expected %.1f (z %.2f)",
                             c->name, d[0], d[1], d[2], b, phi_count[b], expect, z);
            }
            /* (mu, azimuth) jointly: p(mu) / 2 pi per steradian */
            for (int b = 0; b < NPHI; b++) {
                long col[NMU];
                for (int a = 0; a < NMU; a++)
                    col[a] = joint[a][b];
                char what[96];
                snprintf(what, sizeof what, "d (%g,%g,%g), azimuth bin %d", d[0], d[1], d[2], b);
                worst_z = fmax(worst_z, check_counts(c, what, eqj, NMU, pj, col, per_dir,
                                                     1.0 / NPHI));
            }
        }
        worst_z = fmax(worst_z, check_counts(c, "dot(o, d)", eq, NBINS, pe, cm, n, 1));
        double formula = fp_phase_mean_cos(c->kind, c->g, c->w), mean = sum / n;
        worst_mean = fmax(worst_mean, fabs(mean - formula));
        if (!(fabs(mean - formula) <= 0.01))
            fail_msg("%s: mean of dot(o, d) %.5f, formula %.5f", c->name, mean, formula);
    }
    print_message("sampled directions: %d directions x %ld samples x %zu phase functions: "
                  "max ||o| - 1| %.3g, max |dot(o,d) - mu| %.3g, max pdf mismatch %.3g, "
                  "max |mean dot - formula| %.3g, worst |z| %.2f (dot, azimuth, joint), "
                  "worst chi^2/dof %.2f\n",
                  nd, per_dir, ARRAY_LEN(configs), worst_len, worst_dot, worst_pdf, worst_mean,
                  worst_z, worst_chi2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rng),
        cmocka_unit_test(test_normalization),
        cmocka_unit_test(test_pdf_equals_phase),
        cmocka_unit_test(test_inversion),
        cmocka_unit_test(test_sampled_mu),
        cmocka_unit_test(test_sampled_dir),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
