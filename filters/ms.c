#include "ms.h"
#include "fp.h"
#include "integrate.h"
#include "scatter.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/ms_core.h"

_Static_assert(FP_LT_MS + FP_LT_MS_COUNT == FP_LT_COUNT, "light_core.h reserves the table");

#define MS(f) offsetof(fp_params_t, ms.f)
const fp_option_t fp_ms_options[] = {
    { "multiple-scattering", 0, FP_OPT_ENUM, MS(mode), 0, 0, "auto", 0, 0, "auto|on|off",
      "auto|on|off",
      "the sun's light scattered more than once in the fog, from a plane-parallel solution "
      "per frame (doc/notes/multiple-scattering.md): auto is on with a sun when the fog "
      "color is not typed (--fog-color auto), off when it is (a typed fog color is the "
      "whole of that light)", NULL, 0 },
    { "ground-albedo", 0, FP_OPT_REAL, MS(ground_albedo), 0, 0, "0", 0, 1, NULL, "A",
      "reflectance of the ground under the fog (Lambertian) for --multiple-scattering: the "
      "light it sends back up into the fog (0: none, as the surfaces' own light is the "
      "render's)", NULL, 0 },
    FP_OPT_END
};

double fp_ms_mean_cosine(int kind, double g, double w)
{
    /* Cornette-Shanks: <mu> = 3 g (4 + g^2) / (5 (2 + g^2)); Rayleigh 0. */
    double cs = 3 * g * (4 + g * g) / (5 * (2 + g * g));
    switch (kind) {
    case FP_PHASE_HG: return g;
    case FP_PHASE_CS: return cs;
    case FP_PHASE_MIX: return (1 - w) * cs;
    case FP_PHASE_MIXHG: return (1 - w) * g;
    default: return 0;
    }
}

/* E1(x), x > 0 (Numerical Recipes' expint: series below 1, continued
 * fraction above); E2 and E3 by E_{n+1} = (e^-x - x E_n) / n. */
static double e1(double x)
{
    if (x > 700)
        return 0;
    if (x <= 1) {
        double sum = 0, term = 1;
        for (int k = 1; k < 60; k++) {
            term *= -x / k;
            double d = -term / k;
            sum += d;
            if (fabs(d) < 1e-17 * fabs(sum))
                break;
        }
        return -0.5772156649015329 - log(x) + sum;
    }
    double b = x + 1, c = 1e300, d = 1 / b, h = d;
    for (int i = 1; i < 200; i++) {
        double an = -(double)i * i;
        b += 2;
        d = 1 / (an * d + b);
        c = b + an / c;
        double del = c * d;
        h *= del;
        if (fabs(del - 1) < 1e-16)
            break;
    }
    return h * exp(-x);
}

static double e2(double x)
{
    return x <= 0 ? 1 : x > 700 ? 0 : exp(-x) - x * e1(x);
}

static double e3(double x)
{
    return x <= 0 ? 0.5 : x > 700 ? 0 : 0.5 * (exp(-x) - x * e2(x));
}

/* Extinction at fog-space height y, the fog taken infinitely wide: the
 * main fog inside its box's vertical range and under its top, the haze. */
static double sigma_at(const double *fp, double y)
{
    double s = 0;
    double py = y - fp[FP_F_OFF + 1];
    if (fp[FP_F_SIGMA] > 0 && py >= fp[FP_F_BOX + 1] && py <= fp[FP_F_BOX + 4] &&
        py < fp[FP_F_TOP])
        s += fp[FP_F_SIGMA] * (py < fp[FP_F_Y0] ? 1 : exp(-(py - fp[FP_F_Y0]) / fp[FP_F_H]));
    if (fp[FP_F_HAZE] > 0 && y < fp[FP_F_HAZE + 3])
        s += fp[FP_F_HAZE] * (y < fp[FP_F_HAZE + 1] ? 1
                                                     : exp(-(y - fp[FP_F_HAZE + 1]) /
                                                           fp[FP_F_HAZE + 2]));
    return s;
}

/* The top of a profile's fog: its top, or where 25 scale heights above
 * its base leave e^-25 of it, or 40 / sigma above base for homogeneous
 * fog without a top (optically semi-infinite from there). */
static double profile_top(double base, double H, double top, double sigma)
{
    if (isfinite(top))
        return top;
    if (isfinite(H))
        return base + 25 * H;
    return base + 40 / sigma;
}

#define NF 8192   /* fine steps of the vertical optical depth */
#define NL 48     /* layers of the slab */
#define NAZ 8     /* azimuths of the box's reach, over a quarter turn */

/* Gaussian elimination with partial pivoting: A (n x n) x = b in place. */
static int solve_linear(double *A, double *b, int n)
{
    for (int c = 0; c < n; c++) {
        int piv = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(A[r * n + c]) > fabs(A[piv * n + c]))
                piv = r;
        if (!(fabs(A[piv * n + c]) > 1e-300))
            return -1;
        if (piv != c) {
            for (int k = 0; k < n; k++) {
                double t = A[c * n + k];
                A[c * n + k] = A[piv * n + k];
                A[piv * n + k] = t;
            }
            double t = b[c];
            b[c] = b[piv];
            b[piv] = t;
        }
        for (int r = c + 1; r < n; r++) {
            double f = A[r * n + c] / A[c * n + c];
            if (f == 0)
                continue;
            for (int k = c; k < n; k++)
                A[r * n + k] -= f * A[c * n + k];
            b[r] -= f * b[c];
        }
    }
    for (int r = n - 1; r >= 0; r--) {
        double s = b[r];
        for (int k = r + 1; k < n; k++)
            s -= A[r * n + k] * b[k];
        b[r] = s / A[r * n + r];
    }
    return 0;
}

/* Distance from the fog box's center to its side along the fog-space
 * horizontal direction (hx, hz) (the box is fog-local: turned by
 * FP_F_COS, FP_F_SIN); infinite without sides. */
static double box_reach(const double *fp, double hx, double hz)
{
    double c = fp[FP_F_COS], s = fp[FP_F_SIN];
    double qx = c * hx - s * hz, qz = s * hx + c * hz;
    double a = 0.5 * (fp[FP_F_BOX + 3] - fp[FP_F_BOX]), b = 0.5 * (fp[FP_F_BOX + 5] - fp[FP_F_BOX + 2]);
    double r = INFINITY;
    if (fabs(qx) > 1e-12 && isfinite(a))
        r = fmin(r, a / fabs(qx));
    if (fabs(qz) > 1e-12 && isfinite(b))
        r = fmin(r, b / fabs(qz));
    return fp[FP_F_SIGMA] > 0 ? r : INFINITY;
}

/* Vertical optical depth from the top down to height y, from the fine
 * table tau[0..NF] over [yb, yt]. */
static double tau_at(const double *tau, double yb, double hf, int nf, double y)
{
    double u = (y - yb) / hf;
    if (!(u > 0))
        return tau[0];
    if (u >= nf)
        return 0;
    int i = (int)u;
    return tau[i] + (u - i) * (tau[i + 1] - tau[i]);
}

/* The slab's floor and top (fog space): the ground is the main fog box's
 * floor, else its base Y0 (full density below it without end: the ground
 * is where a scene puts it, at the base of a ground fog), else the haze's
 * base.  Returns -1 when there is no slab. */
static int slab_bounds(const double *fp, double *yb_out, double *yt_out)
{
    int main_on = fp[FP_F_SIGMA] > 0, haze_on = fp[FP_F_HAZE] > 0;
    if (!main_on && !haze_on)
        return -1;
    double off = fp[FP_F_OFF + 1];
    double yb = main_on ? (isfinite(fp[FP_F_BOX + 1]) ? off + fp[FP_F_BOX + 1] : off + fp[FP_F_Y0])
                        : fp[FP_F_HAZE + 1];
    double yt = -INFINITY;
    if (main_on)
        yt = off + fmin(profile_top(fmax(fp[FP_F_Y0], yb - off), fp[FP_F_H], fp[FP_F_TOP],
                                    fp[FP_F_SIGMA]), fp[FP_F_BOX + 4]);
    if (haze_on)
        yt = fmax(yt, profile_top(fmax(fp[FP_F_HAZE + 1], yb), fp[FP_F_HAZE + 2],
                                  fp[FP_F_HAZE + 3], fp[FP_F_HAZE]));
    if (!(yt > yb) || !isfinite(yt) || !isfinite(yb))
        return -1;
    *yb_out = yb;
    *yt_out = yt;
    return 0;
}

int fp_ms_solve(const double *fp, double albedo, double g, const double sun[3],
                double ground_albedo, double *J, double *yb_out, double *dy_out, double *jmean)
{
    double mu0 = sun[1];
    for (int i = 0; i < FP_MS_NODES; i++)
        J[i] = 0;
    *yb_out = 0;
    *dy_out = 1;
    *jmean = 0;
    if (!(mu0 > 0) || !(albedo > 0))
        return -1;
    double yb, yt;
    if (slab_bounds(fp, &yb, &yt))
        return -1;
    /* Vertical optical depth from the top down, on a fine grid (midpoint
     * rule: the profile is smooth but for the kink at Y0). */
    double *tau = malloc((NF + 1) * sizeof *tau);
    double *A = malloc((size_t)NL * NL * sizeof *A);
    if (!tau || !A) {
        free(tau);
        free(A);
        return fp_error("multiple scattering: out of memory");
    }
    double hf = (yt - yb) / NF;
    tau[NF] = 0;
    for (int i = NF - 1; i >= 0; i--)
        tau[i] = tau[i + 1] + hf * sigma_at(fp, yb + (i + 0.5) * hf);
    double tstar = tau[0];
    if (!(tstar > 1e-9)) {
        free(tau);
        free(A);
        return -1;
    }
    /* Similarity (van de Hulst): orders >= 2 isotropic with sigma_s' =
     * sigma_s (1 - g): sigma_t' = sigma_t (1 - albedo g), albedo' =
     * albedo (1 - g) / (1 - albedo g).  Exact for g = 0. */
    double sc = 1 - albedo * g, w = albedo * (1 - g) / sc;
    /* Layers: equal steps of s = (height fraction + optical depth
     * fraction) / 2, so both thin fog aloft and dense fog below get
     * them.  Boundaries in reduced optical depth from the top (a[0] = 0
     * at the top ... a[NL] = tau* at the ground), with their heights. */
    double ta[NL + 1], ya[NL + 1];
    {
        int j = NF;
        for (int k = 0; k <= NL; k++) {
            double s = 1 - (double)k / NL;  /* s at boundary k, from the top */
            while (j > 0 && 0.5 * (double)(j - 1) / NF + 0.5 * (1 - tau[j - 1] / tstar) >= s)
                j--;
            /* s between fine nodes j - 1 and j: linear. */
            int jl = j > 0 ? j - 1 : 0;
            double sl = 0.5 * (double)jl / NF + 0.5 * (1 - tau[jl] / tstar);
            double sh = 0.5 * (double)j / NF + 0.5 * (1 - tau[j] / tstar);
            double f = sh > sl ? (s - sl) / (sh - sl) : 0;
            f = fmin(fmax(f, 0), 1);
            ya[k] = yb + hf * (jl + f * (j - jl));
            ta[k] = sc * (tau[jl] + f * (tau[j] - tau[jl]));
        }
        ta[0] = 0;
        ya[0] = yt;
        ta[NL] = sc * tstar;
        ya[NL] = yb;
    }
    double ts = sc * tstar;
    /* The fog box's sides (the slab is not infinitely wide): light
     * scattered toward a side leaves the fog past it.  From the box's
     * center, a direction theta from the vertical at azimuth phi stays in
     * the fog while its horizontal travel dz tan(theta) is under R(phi),
     * i.e. mu > mu_min = dz / sqrt(dz^2 + R^2); a plane-parallel
     * layer's share int_{mu_min}^1 e^(-x/mu) dmu/mu = E1(x) - E1(x / mu_min)
     * (x the vertical optical depth between the heights, dz their
     * distance; in stratified fog a line's optical depth is the
     * vertical one over mu).  R(phi) over a quarter turn (the box is
     * symmetric about its center). */
    double reach[NAZ];
    int sides = 0;
    for (int j = 0; j < NAZ; j++) {
        double phi = (j + 0.5) * (M_PI / 2) / NAZ;
        reach[j] = box_reach(fp, cos(phi), sin(phi));
        sides |= isfinite(reach[j]);
    }
    /* The sun's beam: the optical depth toward the sun from height y,
     * to where it enters the box's side (from the center) or the top. */
    double hs = sqrt(sun[0] * sun[0] + sun[2] * sun[2]);
    double rsun = hs > 1e-9 ? box_reach(fp, sun[0] / hs, sun[2] / hs) : INFINITY;
    double rise = isfinite(rsun) ? rsun * mu0 / fmax(hs, 1e-12) : INFINITY;
    /* Layer centers (in optical depth) and their heights, the sun's mean
     * radiance over each layer (E = 1: e^(-tau_beam) / 4 pi, 4
     * Gauss-Legendre nodes), the kernel M_ik = 1/2 int_layer k [E1(|c_i - t|)
     * - E1(|c_i - t| / mu_min)] dt and the ground's terms. */
    double c[NL], jb[NL], e3k[NL], e2c[NL], rhs[NL], yc[NL];
    const double *gx = fp_gl_x + FP_GL_FIRST(4), *gw = fp_gl_w + FP_GL_FIRST(4);
    for (int k = 0; k < NL; k++) {
        double a = ta[k], b = ta[k + 1];
        c[k] = 0.5 * (a + b);
        yc[k] = 0.5 * (ya[k] + ya[k + 1]);
        double acc = 0;
        for (int q = 0; q < 4; q++) {
            double y = ya[k] + gx[q] * (ya[k + 1] - ya[k]);
            double tb = tau_at(tau, yb, hf, NF, y);
            double tt = isfinite(rise) ? tau_at(tau, yb, hf, NF, y + rise) : 0;
            acc += gw[q] * exp(-sc * (tb - tt) / mu0);
        }
        jb[k] = acc * FP_INV_4PI;
        e3k[k] = e3(ts - b) - e3(ts - a);
        e2c[k] = e2(ts - c[k]);
    }
    for (int i = 0; i < NL; i++)
        for (int k = 0; k < NL; k++) {
            double a = ta[k], b = ta[k + 1], m;
            if (k == i)
                m = 0.5 * (2 - e2(c[i] - a) - e2(b - c[i]));
            else if (a >= c[i])
                m = 0.5 * (e2(a - c[i]) - e2(b - c[i]));
            else
                m = 0.5 * (e2(c[i] - b) - e2(c[i] - a));
            if (sides) {
                /* What leaves through the sides: smooth (x / mu_min tends
                 * to sigma' R as the heights meet). */
                double cut = 0;
                for (int q = 0; q < 4; q++) {
                    double t = a + gx[q] * (b - a);
                    double y = ya[k] + gx[q] * (ya[k + 1] - ya[k]);
                    double x = fabs(c[i] - t), dz = fabs(yc[i] - y);
                    double az = 0;
                    for (int j = 0; j < NAZ; j++)
                        if (isfinite(reach[j]) && dz > 0)
                            az += e1(x * sqrt(dz * dz + reach[j] * reach[j]) / dz);
                    cut += gw[q] * az / NAZ;
                }
                m -= 0.5 * (b - a) * cut;
            }
            /* The ground (Lambertian, albedo A): its radiance A / pi times
             * the downward flux, 2 pi sum_k B_k e3_k from the fog; seen
             * from c_i as 1/2 E2(tau* - c_i) of it. */
            A[i * NL + k] = fmax(m, 0) + ground_albedo * e2c[i] * e3k[k];
        }
    /* J = G w (Jb + J) + r, r the ground's share of the direct sun. */
    for (int i = 0; i < NL; i++) {
        double s = 0;
        for (int k = 0; k < NL; k++)
            s += A[i * NL + k] * w * jb[k];
        rhs[i] = s + 0.5 * e2c[i] * ground_albedo / M_PI * mu0 * exp(-ts / mu0);
    }
    for (int i = 0; i < NL; i++)
        for (int k = 0; k < NL; k++)
            A[i * NL + k] = (i == k) - w * A[i * NL + k];
    int rc = solve_linear(A, rhs, NL);
    free(A);
    if (rc)
        return fp_error("multiple scattering: the slab's equations are singular");
    /* rhs is J at the layer centers.  Its mean over the column by optical
     * depth: */
    double jm = 0;
    for (int k = 0; k < NL; k++)
        jm += rhs[k] * (ta[k + 1] - ta[k]);
    *jmean = jm / ts;
    /* The table: heights from the ground up to where all but 1e-4 of the
     * optical depth is below (J no longer changes above the fog). */
    double ytab = yb;
    for (int k = NL; k >= 0; k--)
        if (ta[k] >= 1e-4 * ts)
            ytab = ya[k];
    if (!(ytab > yb))
        ytab = yt;
    free(tau);
    double dy = (ytab - yb) / (FP_MS_NODES - 1);
    for (int n = 0; n < FP_MS_NODES; n++) {
        double y = yb + n * dy;
        /* Linear in height between layer centers (yc decreasing with k),
         * held beyond the outermost. */
        double v;
        if (y >= yc[0])
            v = rhs[0];
        else if (y <= yc[NL - 1])
            v = rhs[NL - 1];
        else {
            int k = 0;
            while (k < NL - 1 && yc[k + 1] > y)
                k++;
            double f = (yc[k] - y) / (yc[k] - yc[k + 1]);
            v = rhs[k] + f * (rhs[k + 1] - rhs[k]);
        }
        J[n] = v;
    }
    *yb_out = yb;
    *dy_out = dy;
    return 0;
}

/* The casters and the box's sides (kernels/ms_core.h FP_LT_MS_V).  The
 * light scattered once toward a point p comes from the fog around it,
 * weighted (the second order) by sigma(q), the sun's beam at q's height
 * and e^-tau(p, q) per unit length along each direction (the 1/r^2 and
 * r^2 dr cancel), to the box's side, floor or top; only sunlit fog
 * (V(q), the sun's map) sends it.  The slab's J_ms took that sum from
 * the box's center at p's height, unshadowed; the grid holds the ratio
 * of p's own sum, V included and paths ended by the casters, to it.
 * FP_MS_DIRS directions, FP_MS_STEPS steps each.  Without a box with sides: no grid (1). */
#define FP_MS_DIRS 32
#define FP_MS_STEPS 96

/* How far behind the surface the sun's map sees the fog-space point is
 * (map units of depth; <= 0: lit, or outside the map). */
static double map_behind(const double *lt, const float *smap, double x, double y, double z)
{
    const double *mm = lt + FP_LT_SM_NDC, *cz = lt + FP_LT_SM_Z;
    int W = (int)lt[FP_LT_SM_W], H = (int)lt[FP_LT_SM_H];
    double u = (x * mm[0] + y * mm[4] + z * mm[8] + mm[12]) * W;
    double v = (x * mm[1] + y * mm[5] + z * mm[9] + mm[13]) * H;
    if (!(u >= 0 && v >= 0 && u < W && v < H))
        return 0;
    double pz = x * cz[0] + y * cz[1] + z * cz[2] + cz[3];
    int i = (int)floor(u), j = (int)floor(v);
    i = i > W - 1 ? W - 1 : i;
    j = j > H - 1 ? H - 1 : j;
    return pz - smap[j * W + i];
}

typedef struct ms_column_t {
    const double *fp, *lt, *tau, *box;
    const float *smap;
    double yb, yt, hf, mu0;
    double dir[FP_MS_DIRS][3];
} ms_column_t;

/* p's sum: fog-local x, z; fog-space y; vis: with V(q). */
static double source_sum(const ms_column_t *m, const double p[3], int vis)
{
    enum { NT = 2048 };
    const double *fp = m->fp, *box = m->box;
    double c = fp[FP_F_COS], sn = fp[FP_F_SIN];
    double tp = tau_at(m->tau, m->yb, m->hf, NT, p[1]), sum = 0;
    for (int d = 0; d < FP_MS_DIRS; d++) {
        const double *w = m->dir[d];
        double rmax = INFINITY;
        for (int a = 0; a < 3; a += 2)
            if (fabs(w[a]) > 1e-9)
                rmax = fmin(rmax, ((w[a] > 0 ? box[3 + a] : box[a]) - p[a]) / w[a]);
        if (fabs(w[1]) > 1e-9)
            rmax = fmin(rmax, ((w[1] > 0 ? m->yt : m->yb) - p[1]) / w[1]);
        if (!(rmax > 0) || !isfinite(rmax))
            continue;
        double dr = rmax / FP_MS_STEPS;
        for (int st = 0; st < FP_MS_STEPS; st++) {
            double r = (st + 0.5) * dr;
            double q[3] = { p[0] + r * w[0], p[1] + r * w[1], p[2] + r * w[2] };
            double tq = tau_at(m->tau, m->yb, m->hf, NT, q[1]);
            double od = fabs(w[1]) > 1e-6 ? fabs(tp - tq) / fabs(w[1]) : sigma_at(fp, p[1]) * r;
            double wt = sigma_at(fp, q[1]) * exp(-tq / m->mu0 - od) * dr;
            if (vis && m->smap) {
                /* fog-local -> fog space for the map */
                double x = c * q[0] + sn * q[2] + fp[FP_F_OFF];
                double z = -sn * q[0] + c * q[2] + fp[FP_F_OFF + 2];
                double behind = map_behind(m->lt, m->smap, x, q[1], z);
                /* Within 1.5 steps behind the surface the map sees: in a
                 * caster (a wall, a pillar, the ground), which no step
                 * can pass over; the path ends there (black surfaces, as
                 * the reference's --ref-geometry).  Farther behind: fog
                 * in the caster's shadow. */
                if (behind > 0 && behind < 1.5 * dr)
                    break;
                wt *= behind > 0 ? 0 : 1;
            }
            if (wt > 0)
                sum += wt;
        }
    }
    return sum;
}

static void shadow_grid(const double *fp, double *lt, const float *smap)
{
    enum { NT = 2048 };
    lt[FP_LT_MS_GON] = 0;
    int mode = (int)lt[FP_LT_SHADOWS];
    const double *box = fp + FP_F_BOX;
    double yb, yt, mu0 = lt[FP_LT_SUN_DIR + 1];
    if (!(fp[FP_F_SIGMA] > 0) || !isfinite(box[0]) || !isfinite(box[2]) || !isfinite(box[3]) ||
        !isfinite(box[5]) || !(mu0 > 0) || slab_bounds(fp, &yb, &yt))
        return;
    double tau[NT + 1], hf = (yt - yb) / NT;
    tau[NT] = 0;
    for (int i = NT - 1; i >= 0; i--)
        tau[i] = tau[i + 1] + hf * sigma_at(fp, yb + (i + 0.5) * hf);
    if (!(tau[0] > 0))
        return;
    /* The grid's height: to where 90% of the optical depth is below. */
    double ytop = yb;
    for (int i = NT; i >= 0 && ytop == yb; i--)
        if (tau[i] >= 0.1 * tau[0])
            ytop = yb + i * hf;
    if (!(ytop > yb))
        return;
    ms_column_t m = { fp, lt, tau, box,
                      (mode == FP_SHADOWS_MAP || mode == FP_SHADOWS_MAP_SCREEN) ? smap : NULL,
                      yb, yt, hf, mu0, { { 0 } } };
    for (int d = 0; d < FP_MS_DIRS; d++) {
        /* a Fibonacci sphere */
        double z = 1 - (2.0 * d + 1) / FP_MS_DIRS, r = sqrt(fmax(1 - z * z, 0));
        double ph = d * M_PI * (3 - sqrt(5.0));
        m.dir[d][0] = r * cos(ph);
        m.dir[d][1] = z;
        m.dir[d][2] = r * sin(ph);
    }
    double g0[3] = { box[0], yb, box[2] };
    double gd[3] = { (box[3] - box[0]) / (FP_MS_GX - 1), (ytop - yb) / (FP_MS_GY - 1),
                     (box[5] - box[2]) / (FP_MS_GZ - 1) };
    for (int j = 0; j < FP_MS_GY; j++) {
        double pc[3] = { 0.5 * (box[0] + box[3]), g0[1] + j * gd[1], 0.5 * (box[2] + box[5]) };
        double ref = source_sum(&m, pc, 0);
        for (int k = 0; k < FP_MS_GZ; k++)
            for (int i = 0; i < FP_MS_GX; i++) {
                double p[3] = { g0[0] + i * gd[0], pc[1], g0[2] + k * gd[2] };
                lt[FP_LT_MS_V + (k * FP_MS_GY + j) * FP_MS_GX + i] =
                    ref > 0 ? source_sum(&m, p, 1) / ref : 1;
            }
    }
    for (int a = 0; a < 3; a++) {
        lt[FP_LT_MS_G0 + a] = g0[a];
        lt[FP_LT_MS_GD + a] = gd[a];
    }
    lt[FP_LT_MS_GON] = 1;
}

/* The grid depends on the fog, the sun and its map alone: a sequence with
 * still fog and a still sun (its map one file, or the same map each
 * frame) fills it once.  One entry for the process, keyed by those values
 * and a 64-bit FNV-1a hash of the map's texels. */
enum { KEY_N = FP_F_COUNT + 3 + 3 + 16 + 4 + 1,
       GRID_N = FP_LT_COUNT - FP_LT_MS_GON };
static pthread_mutex_t grid_lock = PTHREAD_MUTEX_INITIALIZER;
static struct {
    int valid;
    double key[KEY_N];
    unsigned long long hash;
    double grid[GRID_N];
} grid_cache;

static void grid_key(const double *fp, const double *lt, const float *smap, double *key,
                     unsigned long long *hash)
{
    int n = 0;
    for (int i = 0; i < FP_F_COUNT; i++)
        key[n++] = fp[i];
    for (int i = 0; i < 3; i++)
        key[n++] = lt[FP_LT_SUN_DIR + i];
    key[n++] = lt[FP_LT_SHADOWS];
    key[n++] = lt[FP_LT_SM_W];
    key[n++] = lt[FP_LT_SM_H];
    for (int i = 0; i < 16; i++)
        key[n++] = lt[FP_LT_SM_NDC + i];
    for (int i = 0; i < 4; i++)
        key[n++] = lt[FP_LT_SM_Z + i];
    key[n++] = smap != NULL;
    unsigned long long h = 1469598103934665603ULL;
    size_t nt = smap ? (size_t)lt[FP_LT_SM_W] * (size_t)lt[FP_LT_SM_H] : 0;
    const unsigned char *b = (const unsigned char *)smap;
    for (size_t i = 0; i < nt * sizeof *smap; i++)
        h = (h ^ b[i]) * 1099511628211ULL;
    *hash = h;
}

static void shadow_grid_cached(const double *fp, double *lt, const float *smap)
{
    double key[KEY_N];
    unsigned long long h;
    grid_key(fp, lt, smap, key, &h);
    pthread_mutex_lock(&grid_lock);
    int hit = grid_cache.valid && grid_cache.hash == h &&
              memcmp(grid_cache.key, key, sizeof key) == 0;
    if (hit)
        memcpy(lt + FP_LT_MS_GON, grid_cache.grid, sizeof grid_cache.grid);
    pthread_mutex_unlock(&grid_lock);
    if (hit)
        return;
    shadow_grid(fp, lt, smap);
    pthread_mutex_lock(&grid_lock);
    memcpy(grid_cache.key, key, sizeof key);
    grid_cache.hash = h;
    memcpy(grid_cache.grid, lt + FP_LT_MS_GON, sizeof grid_cache.grid);
    grid_cache.valid = 1;
    pthread_mutex_unlock(&grid_lock);
}

int fp_ms_frame(const fp_params_t *p, double *lt, const double *fp, const float *smap)
{
    const fp_ms_params_t *m = &p->ms;
    int sun = lt[FP_LT_SUN_ON] != 0;
    int on = m->mode == FP_MS_ON || (m->mode == FP_MS_AUTO && sun && !m->color_typed);
    lt[FP_LT_MS_ON] = 0;
    lt[FP_LT_MS_GON] = 0;
    if (!m->color_typed)
        for (int c = 0; c < 3; c++)
            lt[FP_LT_AMB + c] = sun ? 0 : p->fog.color[c];
    if (!sun)
        return FP_OK;
    double J[FP_MS_NODES], yb, dy, jmean;
    double g = fp_ms_mean_cosine((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1], lt[FP_LT_PHASE + 2]);
    int rc = fp_ms_solve(fp, lt[FP_LT_ALBEDO], g, lt + FP_LT_SUN_DIR, m->ground_albedo, J, &yb,
                         &dy, &jmean);
    if (rc > 0)
        return rc;
    if (rc < 0)
        return FP_OK;
    if (on) {
        lt[FP_LT_MS_ON] = 1;
        lt[FP_LT_MS_YB] = yb;
        lt[FP_LT_MS_DY] = dy;
        for (int i = 0; i < FP_MS_NODES; i++)
            lt[FP_LT_MS_J + i] = J[i];
        shadow_grid_cached(fp, lt, smap);
    } else if (!m->color_typed) {
        /* --fog-color auto without the fast path: the constant that gives
         * the column's multiply scattered light on average. */
        for (int c = 0; c < 3; c++)
            lt[FP_LT_AMB + c] = jmean * lt[FP_LT_SUN_E + c];
    }
    return FP_OK;
}
