/* fogpipe: single scattering along one view ray, deterministic, shared by
 * the OpenCL kernel (kernels/scatter.cl, float) and the C reference
 * (filters/scatter.c, double).  Include after fog_core.h and light_core.h.
 *
 * Transmittance tau(O,P) is the exact optical depth of fog_core.h.  The
 * in-scattered light
 *   S = albedo int tau(O,u) sigma_t(u) J(u) du,
 *   J = L_amb + E_sun p(mu_sun) V(u) tau_sun(u)            (+ local lights)
 * is integrated over N segments of the ray's stretch through the fog:
 * each segment's optical depth x is exact (fp_fog_od over the segment) and
 * J is taken linear between the segment's ends, which integrates in closed
 * form against the segment's attenuation:
 *   int_seg = tau_a [ J_a (1 - e^-x) + (J_b - J_a) ((1 - e^-x)/x - e^-x) ].
 * The ambient term (J constant) is therefore exact: S_amb = albedo (1 -
 * tau) L_amb, seed 000's eq. 4.  Local lights are integrated separately,
 * with Gauss-Legendre nodes placed equiangularly as seen from the light
 * (t = t_c + D tan(theta)), which turns the 1/d^2 peak into a constant
 * (dt / d^2 = dtheta / D): halos stay clean at high g. */
#ifndef FP_SCATTER_CORE_H
#define FP_SCATTER_CORE_H

#define FP_SCATTER_MAX_STEPS_ 256
#define FP_SCATTER_DOUBLINGS 80   /* trial ends of the doubling in fp_scatter_ray_core */

#include "shafts_core.h"
#include "ms_core.h"

/* The fast rule's functions (fp_l_*, fp_light_*): the C reference.  The
 * OpenCL kernel scatter_lights runs the same rule on float16 lanes
 * (scatter_lanes.h, the same float polynomials as fp_l_*). */
#ifdef __OPENCL_VERSION__
#define FP_LFN inline __attribute__((always_inline))
#else
#define FP_LFN static inline
#endif

/* Where along o + t dir, t in [0, len], fog can be: the main fog's box and
 * top (and the fogmap's rectangle when it does not wrap), joined with the
 * haze's stretch.  Returns 0 when nowhere. */
FP_FN int fp_fog_span(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy, fp_real oz,
                      fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real *ta, fp_real *tb)
{
    fp_real a, b, lo = FP_INF, hi = -FP_INF;
    if (fp_main_span(fp, ox, oy, oz, dx, dy, dz, len, &a, &b)) {
        lo = a;
        hi = b;
    }
    if (fp_haze_span(fp, oy, dy, len, &a, &b)) {
        lo = fmin(lo, a);
        hi = fmax(hi, b);
    }
    *ta = lo;
    *tb = hi;
    return hi > lo;
}

/* J at a point: sun (phase value `ph_sun` for this ray), the extra
 * directional lights (lights after the local ones: irradiance, phase
 * toward them, screen shadows under --shadows screen and map+screen, no map; the
 * fog's own shadow exact, fp_fog_od toward them) and ambient; (dx, dy, dz)
 * the view ray's direction. */
FP_FN void fp_scatter_source(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                             FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                             FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                             FP_GLOBAL const fp_real *lights, FP_GLOBAL const float *smap,
                             FP_GLOBAL const float *grid, FP_CONSTANT const float *view,
                             FP_GLOBAL const float *depth, int width, int height, fp_real ph_sun,
                             fp_real dx, fp_real dy, fp_real dz, fp_real x, fp_real y, fp_real z,
                             fp_real *J)
{
    J[0] = lt[FP_LT_AMB];
    J[1] = lt[FP_LT_AMB + 1];
    J[2] = lt[FP_LT_AMB + 2];
    int nl = (int)lt[FP_LT_NLIGHTS], nd = (int)lt[FP_LT_NDIR];
    for (int k = nl; k < nl + nd; k++) {
        FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
        fp_real lx = row[FP_LL_POS], ly = row[FP_LL_POS + 1], lz = row[FP_LL_POS + 2];
        fp_real v = fp_phase((int)lt[FP_LT_PHASE], lt[FP_LT_PHASE + 1], lt[FP_LT_PHASE + 2],
                             dx * lx + dy * ly + dz * lz);
        if (v > 0 && ((int)lt[FP_LT_SHADOWS] == FP_SHADOWS_SCREEN ||
                      (int)lt[FP_LT_SHADOWS] == FP_SHADOWS_MAP_SCREEN))
            v *= fp_shadow_screen_dir(lt, lx, ly, lz, view, fp_ss_zpyr(lt, smap), x, y, z);
        if (v > 0 && (int)lt[FP_LT_SELF] != FP_SELF_OFF)
            v *= exp(-fp_fog_od(fp, lvi, lvf, coef, occ, x, y, z, lx, ly, lz, FP_INF, 0));
        if (!(v > 0))
            continue;
        J[0] += v * row[FP_LL_I];
        J[1] += v * row[FP_LL_I + 1];
        J[2] += v * row[FP_LL_I + 2];
    }
    if (lt[FP_LT_SUN_ON] == 0 || ph_sun <= 0)
        return;
    fp_real v = fp_sun_visibility(lt, smap, view, depth, width, height, x, y, z);
    if (v <= 0)
        return;
    v *= ph_sun * fp_sun_tau(fp, lvi, lvf, coef, occ, lt, grid, x, y, z);
    J[0] += v * lt[FP_LT_SUN_E];
    J[1] += v * lt[FP_LT_SUN_E + 1];
    J[2] += v * lt[FP_LT_SUN_E + 2];
}

/* Nodes per piece of the fast rule for local lights (4 pieces per light),
 * a constant so that the node loops unroll and every work-item runs the
 * same steps. */
#define FP_LIGHT_NODES 8

/* Math for the fast rule that the CPU device can inline and vectorise.
 * PoCL calls out of line for tan, atan, atan2, acos and expm1 (Sleef and
 * its argument reduction), and a call in a kernel keeps its work-group
 * loop scalar; exp and sqrt are inlined.  So in OpenCL these are short
 * polynomials (Cephes' single-precision atanf and sinf/cosf kernels, about
 * 1e-7 relative) written with selects, and in C (the double reference)
 * the C library's functions. */
#ifdef __OPENCL_VERSION__
FP_LFN float fp_l_atan(float x)
{
    float ax = fabs(x);
    int big = ax > 2.414213562373095f, mid = ax > 0.4142135623730950f;
    float y0 = big ? 1.5707963267948966f : mid ? 0.7853981633974483f : 0.0f;
    float xr = big ? -1.0f / ax : mid ? (ax - 1.0f) / (ax + 1.0f) : ax;
    float z = xr * xr;
    float y = y0 + (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
                    3.33329491539e-1f) * z * xr + xr;
    return x < 0 ? -y : y;
}

FP_LFN float fp_l_atan2(float y, float x)
{
    float a = fp_l_atan(y / x);
    float pi = 3.14159265358979323846f;
    /* x < 0: the other half-plane; x == 0: +-pi/2. */
    float r = x > 0 ? a : x < 0 ? (y >= 0 ? a + pi : a - pi) : (y > 0 ? 0.5f * pi : y < 0 ? -0.5f * pi : 0.0f);
    return r;
}

/* sin and cos of x in [-pi/4, pi/4]. */
FP_LFN void fp_l_sincos_small(float x, float *s, float *c)
{
    float z = x * x;
    *s = ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f) * z * x + x;
    *c = ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f) * z * z -
         0.5f * z + 1.0f;
}

/* sin and cos of x in [0, pi/2]: about pi/4. */
FP_LFN void fp_l_sincos(float x, float *s, float *c)
{
    float a, b;
    fp_l_sincos_small(x - 0.7853981633974483f, &a, &b);
    *s = 0.7071067811865476f * (b + a);
    *c = 0.7071067811865476f * (b - a);
}

FP_LFN float fp_l_acos(float x)
{
    /* acos x = 2 atan(sqrt((1 - x) / (1 + x))), x in [-1, 1]. */
    return 2.0f * fp_l_atan(sqrt((1.0f - x) / (1.0f + x)));
}

FP_LFN float fp_l_one_minus_exp(float x)
{
    return fp_one_minus_exp(x);
}
#else
#define fp_l_atan atan
#define fp_l_atan2 atan2
#define fp_l_acos acos
FP_LFN void fp_l_sincos(double x, double *s, double *c)
{
    *s = sin(x);
    *c = cos(x);
}
FP_LFN double fp_l_one_minus_exp(double x)
{
    return fp_one_minus_exp(x);
}
#endif

/* (1 - e^-x) / x, x >= 0, both ways computed and one selected (no branch
 * around the math). */
FP_LFN fp_real fp_light_ratio(fp_real x)
{
    fp_real series = (fp_real)1 - x * ((fp_real)0.5 - x * ((fp_real)1 / 6));
    fp_real full = fp_l_one_minus_exp(x) / fmax(x, (fp_real)1e-30);
    return x < (fp_real)1e-3 ? series : full;
}

/* Optical depth of sigma h(y) along y = oy + t dy, t in [0, len], len
 * finite: fp_height_od's closed form written without branches. */
FP_LFN fp_real fp_light_height_od(fp_real sigma, fp_real y0, fp_real H, fp_real top, fp_real oy,
                                 fp_real dy, fp_real len)
{
    fp_real ddy = fabs(dy) > (fp_real)1e-30 ? dy : (fp_real)1e-30;
    fp_real inv = 1 / ddy;
    fp_real lo = fmin(y0, top);
    /* below lo: y < lo */
    fp_real u = (lo - oy) * inv;
    fp_real a1 = ddy > 0 ? (fp_real)0 : fmax(u, (fp_real)0);
    fp_real b1 = ddy > 0 ? fmin(u, len) : len;
    fp_real below = fmax(b1 - a1, (fp_real)0);
    /* y0 <= y < top */
    fp_real u0 = (y0 - oy) * inv, u1 = (top - oy) * inv;
    fp_real a2 = fmax(fmin(u0, u1), (fp_real)0), b2 = fmin(fmax(u0, u1), len);
    fp_real w = fmax(b2 - a2, (fp_real)0);
    fp_real ya = (oy + a2 * dy - y0) / H;
    fp_real Dl = fabs(dy) * w / H;
    fp_real m = dy < 0 ? ya - Dl : ya;
    fp_real above = w > 0 ? w * exp(-m) * fp_light_ratio(Dl) : (fp_real)0;
    return sigma > 0 ? sigma * (below + above) : (fp_real)0;
}

/* Optical depth of fog without a fogmap (height fog in its box, haze)
 * along o + t d, t in [0, len], len finite: fp_fog_od's closed form. */
FP_LFN fp_real fp_light_plain_od(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy,
                                fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real len)
{
    fp_real od = fp_light_height_od(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                    fp[FP_F_HAZE + 3], oy, dy, len);
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_real o3[3] = { c * px - s * pz, py, s * px + c * pz };
    fp_real d3[3] = { c * dx - s * dz, dy, s * dx + c * dz };
    fp_real a = 0, b = len;
    for (int i = 0; i < 3; i++) {
        fp_real dd = fabs(d3[i]) > (fp_real)1e-30 ? d3[i] : (fp_real)1e-30;
        fp_real u = (fp[FP_F_BOX + i] - o3[i]) / dd, v = (fp[FP_F_BOX + 3 + i] - o3[i]) / dd;
        int inside = o3[i] >= fp[FP_F_BOX + i] && o3[i] <= fp[FP_F_BOX + 3 + i];
        fp_real lo = fabs(d3[i]) > (fp_real)1e-30 ? fmin(u, v) : inside ? -FP_INF : FP_INF;
        fp_real hi = fabs(d3[i]) > (fp_real)1e-30 ? fmax(u, v) : inside ? FP_INF : -FP_INF;
        a = fmax(a, lo);
        b = fmin(b, hi);
    }
    fp_real main = fp_light_height_od(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                      py + a * dy, dy, fmax(b - a, (fp_real)0));
    return od + (b > a ? main : (fp_real)0);
}

/* Extinction of fog without a fogmap at a point: fp_sigma_t without the
 * fogmap's branch. */
FP_LFN fp_real fp_light_plain_sigma(FP_CONSTANT const fp_real *fp, fp_real x, fp_real y, fp_real z)
{
    fp_real hy = fp[FP_F_HAZE + 1], hH = fp[FP_F_HAZE + 2];
    fp_real haze = y < fp[FP_F_HAZE + 3] ? fp[FP_F_HAZE] * exp(-fmax(y - hy, (fp_real)0) / hH)
                                         : (fp_real)0;
    fp_real c = fp[FP_F_COS], sn = fp[FP_F_SIN];
    fp_real px = x - fp[FP_F_OFF], py = y - fp[FP_F_OFF + 1], pz = z - fp[FP_F_OFF + 2];
    fp_real qx = c * px - sn * pz, qz = sn * px + c * pz;
    int in = qx >= fp[FP_F_BOX] && qx <= fp[FP_F_BOX + 3] && py >= fp[FP_F_BOX + 1] &&
             py <= fp[FP_F_BOX + 4] && qz >= fp[FP_F_BOX + 2] && qz <= fp[FP_F_BOX + 5] &&
             py < fp[FP_F_TOP];
    fp_real h = exp(-fmax(py - fp[FP_F_Y0], (fp_real)0) / fp[FP_F_H]);
    return fmax(haze, (fp_real)0) + (in ? fmax(fp[FP_F_SIGMA], (fp_real)0) * h : (fp_real)0);
}

/* fp_phase (kernels/phase.h) with every kind computed and one selected. */
FP_LFN fp_real fp_light_phase(int kind, fp_real g, fp_real w, fp_real mu)
{
    fp_real d = 1 + g * g - 2 * g * mu;
    fp_real hg = FP_INV_4PI * (1 - g * g) / (d * sqrt(d));
    fp_real cs = hg * (fp_real)1.5 * (1 + mu * mu) / (2 + g * g);
    fp_real ray = (fp_real)0.75 * FP_INV_4PI * (1 + mu * mu);
    fp_real r = kind == FP_PHASE_HG ? hg : kind == FP_PHASE_CS ? cs
              : kind == FP_PHASE_RAYLEIGH ? ray : kind == FP_PHASE_MIX ? w * ray + (1 - w) * cs
              : kind == FP_PHASE_MIXHG ? w * ray + (1 - w) * hg : FP_INV_4PI;
    return r;
}

/* fp_fog_span for fog without a fogmap, without branches: where along
 * o + t d, t in [0, len], the main fog's box below its top and the haze
 * below its top are; ta > tb when nowhere. */
FP_LFN void fp_light_span(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy, fp_real oz,
                          fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real *ta,
                          fp_real *tb)
{
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_real o3[3] = { c * px - s * pz, py, s * px + c * pz };
    fp_real d3[3] = { c * dx - s * dz, dy, s * dx + c * dz };
    fp_real lo3[3] = { fp[FP_F_BOX], fp[FP_F_BOX + 1], fp[FP_F_BOX + 2] };
    fp_real hi3[3] = { fp[FP_F_BOX + 3], fmin(fp[FP_F_BOX + 4], fp[FP_F_TOP]), fp[FP_F_BOX + 5] };
    fp_real a = 0, b = len;
    for (int i = 0; i < 3; i++) {
        int moving = fabs(d3[i]) > (fp_real)1e-30;
        fp_real dd = moving ? d3[i] : (fp_real)1e-30;
        fp_real u = (lo3[i] - o3[i]) / dd, v = (hi3[i] - o3[i]) / dd;
        int inside = o3[i] >= lo3[i] && o3[i] <= hi3[i];
        a = fmax(a, moving ? fmin(u, v) : inside ? -FP_INF : FP_INF);
        b = fmin(b, moving ? fmax(u, v) : inside ? FP_INF : -FP_INF);
    }
    int main_on = fp[FP_F_SIGMA] > 0 && b > a;
    /* the haze: below its top */
    int hmoving = fabs(dy) > (fp_real)1e-30;
    fp_real hu = (fp[FP_F_HAZE + 3] - oy) / (hmoving ? dy : (fp_real)1e-30);
    fp_real ha = hmoving && dy < 0 ? fmax(hu, (fp_real)0) : (fp_real)0;
    fp_real hb = hmoving && dy > 0 ? fmin(hu, len) : len;
    int haze_on = fp[FP_F_HAZE] > 0 && hb > ha && (hmoving || oy < fp[FP_F_HAZE + 3]);
    fp_real lo = fmin(main_on ? a : FP_INF, haze_on ? ha : FP_INF);
    fp_real hi = fmax(main_on ? b : -FP_INF, haze_on ? hb : -FP_INF);
    *ta = lo;
    *tb = hi;
}

/* Extinction at the point of [ta, tl] nearest the light (fog without a
 * fogmap): where fp_light_fast puts the start of the far fall. */
FP_LFN fp_real fp_light_sig_c(FP_CONSTANT const fp_real *fp, FP_GLOBAL const fp_real *row,
                             fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy,
                             fp_real dz, fp_real ta, fp_real tl)
{
    fp_real tc = (row[FP_LL_POS] - ox) * dx + (row[FP_LL_POS + 1] - oy) * dy +
                 (row[FP_LL_POS + 2] - oz) * dz;
    tc = fmin(fmax(tc, ta), tl);
    return fp_light_plain_sigma(fp, ox + tc * dx, oy + tc * dy, oz + tc * dz);
}

/* A local light's in-scatter over [ta, tl] of the view ray, without the
 * light's intensity, for fog without a fogmap (--light-quad fast): the
 * fewest nodes the integrand's shape allows.
 *
 * Seen from the light (t = t_c + D tan(theta)), dt / r^2 = dtheta / D
 * takes away the 1/r^2 peak (Sun et al. 2005), and what is left is
 *   int sigma(t) e^{-od_cam(t) - od_light(t)} cone(theta) p(-sin theta) dtheta / D.
 * In homogeneous fog the exponent is -sigma (t_c + D tan(pi/4 + theta/2))
 * (Sun et al.'s A1 tan(xi)): smooth, but with a steep fall toward
 * theta = pi/2 (far along the ray) when sigma D is small; height fog and
 * haze change it smoothly.  Peaked is the phase function, at e = 0, e the
 * angle from its forward peak (e = pi/2 + sgn(g) theta), where
 * 1 + g^2 - 2 g cos e is smallest.  With
 *   tan(e/2) = k tan(phi),  k = (1 - |g|) / (1 + |g|),
 * phi is the integral of (1 - g^2) / (2 (1 + g^2 - 2 g cos e)) de (a closed
 * form), so the phase function times de/dphi is
 *   sqrt(cos^2 phi + k^2 sin^2 phi) / (2 pi (1 - |g|))
 * for Henyey-Greenstein: smooth and bounded (Cornette-Shanks adds a factor
 * in [1, 2]); k = 1 (phi = e/2) for the phase functions without a peak.
 * A spot's cone is R cos(theta - theta_a) >= cos(outer) along the ray (R,
 * theta_a from the axis's parts along the ray and toward it), so its support
 * and the ends of its smooth edge are found in closed form and become the
 * pieces' ends; a point light's range is cut where the fall toward the far
 * end begins (A1 tan(xi) = 1, sigma taken at the closest point), and the
 * rest halved in phi; where the ray crosses the height fog's base (a kink
 * of the extinction) a fourth piece begins, else the widest piece is
 * halved.  Four pieces of FP_LIGHT_NODES Gauss-Legendre nodes, whatever
 * the light: one trip count for every work-item.  The optical
 * depths to the camera and to the light are exact (closed forms). */
FP_LFN fp_real fp_light_fast(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt,
                            FP_GLOBAL const fp_real *row, fp_real sig_c, fp_real ox, fp_real oy,
                            fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real ta, fp_real tl)
{
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    int kind = (int)ph[0];
    fp_real g = ph[1];
    fp_real lx = row[FP_LL_POS], ly = row[FP_LL_POS + 1], lz = row[FP_LL_POS + 2];
    fp_real qx = lx - ox, qy = ly - oy, qz = lz - oz;
    fp_real tc = qx * dx + qy * dy + qz * dz;
    fp_real rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
    fp_real rl = sqrt(rx * rx + ry * ry + rz * rz);
    fp_real D = fmax(rl, (fp_real)1e-6 * (1 + fabs(tc)));
    /* n: unit, from the light to the ray's closest point. */
    fp_real inv = rl > 0 ? -1 / rl : (fp_real)0;
    fp_real nx = rx * inv, ny = ry * inv, nz = rz * inv;
    fp_real th0 = fp_l_atan((ta - tc) / D), th1 = fp_l_atan((tl - tc) / D);
    const fp_real pi = (fp_real)3.14159265358979323846, hp = (fp_real)1.5707963267948966;
    /* The spot's cone along the ray: cos(angle to the axis) =
     * R cos(theta - theta_a).  Cones up to 90 degrees are one interval
     * of theta (the copy of theta_a nearest the range's middle). */
    fp_real na = nx * row[FP_LL_AXIS] + ny * row[FP_LL_AXIS + 1] + nz * row[FP_LL_AXIS + 2];
    fp_real da = dx * row[FP_LL_AXIS] + dy * row[FP_LL_AXIS + 1] + dz * row[FP_LL_AXIS + 2];
    fp_real co = row[FP_LL_COS_OUT], ci = row[FP_LL_COS_IN];
    int type = (int)row[FP_LL_TYPE];
    int spot = type == FP_LIGHT_SPOT;
    /* An area light is one-sided: its "cone" is the half-space in front
     * (cos_out 0), with no inner cone; so is a Cycles spot without blend. */
    int cut = (spot || type == FP_LIGHT_AREA) && co >= 0;
    int inner = spot && (row[FP_LL_PROFILE] == 0 || ci > co);
    fp_real R = fmax(sqrt(na * na + da * da), (fp_real)1e-30);
    fp_real tha = fp_l_atan2(da, na);
    tha += 2 * pi * floor(((fp_real)0.5 * (th0 + th1) - tha) / (2 * pi) + (fp_real)0.5);
    fp_real ao = fp_l_acos(fmin(fmax(co / R, (fp_real)-1), (fp_real)1));
    fp_real ai = fp_l_acos(fmin(fmax(ci / R, (fp_real)-1), (fp_real)1));
    /* A spot whose inner cone holds the whole range is a point light.
     * (Spots wider than 90 degrees take the panels path: filters/scatter.c.) */
    int clip = cut && inner && !(tha - ai <= th0 && tha + ai >= th1);
    int range = cut && !(tha - ao <= th0 && tha + ao >= th1);
    fp_real c0 = clip || range ? fmax(th0, tha - ao) : th0;
    fp_real c1 = clip || range ? fmax(c0, fmin(th1, tha + ao)) : th1;
    /* A point light (or a spot wider than 90 degrees): the far fall
     * begins where sigma D tan(pi/4 + theta/2) = 1. */
    fp_real thf = 2 * fp_l_atan(1 / fmax(sig_c * D, (fp_real)1e-30)) - hp;
    thf = fmin(fmax(thf, c0), c1);
    fp_real b1 = fmin(fmax(tha - ai, c0), c1);
    fp_real b2 = clip ? fmin(fmax(tha + ai, c0), c1) : thf;
    /* Map to phi: tan(e/2) = k tan(phi). */
    int peaked = (kind == FP_PHASE_HG || kind == FP_PHASE_CS || kind == FP_PHASE_MIX ||
                  kind == FP_PHASE_MIXHG) && fabs(g) > (fp_real)0.2;
    fp_real sgn = g < 0 && peaked ? (fp_real)-1 : (fp_real)1;
    fp_real k = peaked ? (1 - fabs(g)) / (1 + fabs(g)) : (fp_real)1;
    fp_real bt[4] = { c0, b1, b2, c1 }, bp[4];
    for (int i = 0; i < 4; i++) {
        fp_real sb, cb;
        fp_l_sincos((fp_real)0.5 * (hp + sgn * bt[i]), &sb, &cb);
        bp[i] = fp_l_atan2(sb, k * cb);
    }
    /* Without a cone: [phi0, phi_f] halved, then [phi_f, phi1], phi_f at
     * least a third of the way (phi runs backward when sgn < 0). */
    fp_real lam = (bp[2] - bp[0]) / (bp[3] - bp[0]);
    lam = lam >= (fp_real)1 / 3 && lam <= 1 ? lam : (fp_real)1 / 3;
    fp_real pf = bp[0] + lam * (bp[3] - bp[0]);
    bp[1] = clip ? bp[1] : (fp_real)0.5 * (bp[0] + pf);
    bp[2] = clip ? bp[2] : pf;
    /* A fourth piece: the extinction has a kink where the ray crosses the
     * height fog's base Y0 (h = 1 below, exponential above); cut there,
     * else halve the widest piece.  Ends in increasing phi, then x sorted
     * in. */
    int up = bp[3] >= bp[0];
    fp_real a0 = up ? bp[0] : bp[3], a1 = up ? bp[1] : bp[2], a2 = up ? bp[2] : bp[1],
            a3 = up ? bp[3] : bp[0];
    fp_real yl = oy - fp[FP_F_OFF + 1];
    fp_real tk = (fp[FP_F_Y0] - yl) / (fabs(dy) > (fp_real)1e-30 ? dy : (fp_real)1e-30);
    fp_real thk = fp_l_atan((tk - tc) / D);
    fp_real sk, ck;
    fp_l_sincos((fp_real)0.5 * (hp + sgn * fmin(fmax(thk, th0), th1)), &sk, &ck);
    fp_real xk = fp_l_atan2(sk, k * ck);
    int kink = fp[FP_F_SIGMA] > 0 && fabs(dy) > (fp_real)1e-30 && thk > th0 && thk < th1 &&
               xk > a0 && xk < a3;
    fp_real w0 = a1 - a0, w1 = a2 - a1, w2 = a3 - a2;
    fp_real xw = w0 >= w1 && w0 >= w2 ? (fp_real)0.5 * (a0 + a1)
               : w1 >= w2 ? (fp_real)0.5 * (a1 + a2) : (fp_real)0.5 * (a2 + a3);
    fp_real x = kink ? xk : xw;
    fp_real pe[5] = { fmin(a0, x), fmin(a1, fmax(a0, x)), fmin(a2, fmax(a1, x)),
                      fmin(a3, fmax(a2, x)), fmax(a3, x) };
    fp_real acc = 0;
    for (int piece = 0; piece < 4; piece++) {
        fp_real pa = pe[piece], pb = pe[piece + 1];
        for (int q = 0; q < FP_LIGHT_NODES; q++) {
            fp_real phi = pa + (pb - pa) * fp_gl_x[FP_GL_FIRST(FP_LIGHT_NODES) + q];
            /* tan(e/2) = k tan(phi), from sin and cos of phi: */
            fp_real sp, cp;
            fp_l_sincos(phi, &sp, &cp);
            fp_real ks = k * sp, den = 1 / (cp * cp + ks * ks);
            fp_real ce = (cp * cp - ks * ks) * den, se = 2 * ks * cp * den;
            fp_real jac = 2 * k * den;
            /* theta = sgn (e - pi/2): sin theta = -sgn cos e, cos theta = sin e. */
            fp_real s = -sgn * ce, c = se;
            fp_real ic = 1 / c;
            fp_real t = tc + D * s * ic, r = D * ic;
            fp_real px = ox + t * dx, py = oy + t * dy, pz = oz + t * dz;
            /* u: unit, from the light to the point. */
            fp_real ux = c * nx + s * dx, uy = c * ny + s * dy, uz = c * nz + s * dz;
            fp_real cu = c * na + s * da;
            fp_real cone = fp_light_gain_cos(row, cu, ux, uy, uz, r);
            fp_real sig = fp_light_plain_sigma(fp, px, py, pz);
            fp_real od = fp_light_plain_od(fp, ox, oy, oz, dx, dy, dz, t) +
                         fp_light_plain_od(fp, px, py, pz, -ux, -uy, -uz, r);
            fp_real f = sig * exp(-od) * cone * fp_light_phase(kind, g, ph[2], -s) * jac;
            acc += fp_gl_w[FP_GL_FIRST(FP_LIGHT_NODES) + q] * (pb - pa) *
                   (f > 0 && t >= ta && t <= tl ? f : (fp_real)0);
        }
    }
    return acc * lt[FP_LT_ALBEDO] / D;
}

/* One local light's in-scatter along the view ray o + t d, t in [0, len]
 * (fast rule, fog without a fogmap), over the ray's stretch through the
 * fog: S (3).  The C reference calls it from fp_scatter_ray_core; the
 * OpenCL side runs it on lanes (fp_ln_light_ray, kernel scatter_lights). */
FP_LFN void fp_light_ray(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt,
                        FP_GLOBAL const fp_real *lights, int k, fp_real ox, fp_real oy,
                        fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real *S)
{
    FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
    fp_real ta, tb;
    fp_light_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb);
    int any = tb > ta;
    ta = any ? ta : (fp_real)0;
    tb = any ? tb : (fp_real)0;
    fp_real acc = fp_light_fast(fp, lt, row, fp_light_sig_c(fp, row, ox, oy, oz, dx, dy, dz, ta, tb),
                                ox, oy, oz, dx, dy, dz, ta, tb);
    acc = any ? acc : (fp_real)0;
    for (int c = 0; c < 3; c++)
        S[c] = acc * row[FP_LL_I + c];
}

#include "lamp_shadow_core.h"

/* S += the ambient light's closed form (seed 000 eq. 4) and the local
 * lights of the fast rule (when fast; in OpenCL they run apart), each
 * pixel paying only for the lights that reach it: a light is left out
 * while the bounds (fp_light_bound) of those left out add up to at most
 * FP_LT_CULL; returns tau. */
FP_FN fp_real fp_scatter_ambient_lights(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt,
                                        FP_GLOBAL const fp_real *lights, fp_real ox, fp_real oy,
                                        fp_real oz, fp_real dx, fp_real dy, fp_real dz,
                                        fp_real len, fp_real od_total, int fast, fp_real *S)
{
    for (int c = 0; c < 3; c++)
        S[c] += lt[FP_LT_ALBEDO] * -expm1(-od_total) * lt[FP_LT_AMB + c];
#ifndef FP_LIGHTS_APART
    fp_real budget = lt[FP_LT_CULL], ta, tb;
    fp_light_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb);
    fp_real smax = fp_light_sigma_span(fp, oy, dy, ta, tb), omt = -expm1(-od_total);
    for (int k = 0; fast && tb > ta && k < (int)lt[FP_LT_NLIGHTS]; k++) {
        if (budget > 0) {
            fp_real b = fp_light_bound(lt, lights + k * FP_LL_STRIDE, smax, omt, ox, oy, oz, dx, dy,
                                       dz, ta, tb);
            if (b <= budget) {
                budget -= b;
                continue;
            }
        }
        fp_real Sk[3];
        fp_light_ray(fp, lt, lights, k, ox, oy, oz, dx, dy, dz, len, Sk);
        for (int c = 0; c < 3; c++)
            S[c] += Sk[c];
    }
#else
    (void)lights;
    (void)fp;
    (void)ox;
    (void)oy;
    (void)oz;
    (void)dx;
    (void)dy;
    (void)dz;
    (void)len;
    (void)fast;
#endif
    return exp(-od_total);
}

/* The fog layer of one view ray: S (3) and returns tau. */
FP_FN fp_real fp_scatter_ray_core(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                             FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                             FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                             FP_GLOBAL const fp_real *lights, FP_GLOBAL const float *smap,
                             FP_GLOBAL const float *grid, FP_CONSTANT const float *view,
                             FP_GLOBAL const float *depth, int width, int height, fp_real ox,
                             fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz,
                             fp_real len, fp_real offset, fp_real *S)
{
    S[0] = S[1] = S[2] = 0;
    fp_real ta, tb;
    int in_fog = fp_fog_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb);
    /* The doubling below (where the fog stops mattering) tries ends
     * ta + step0 2^k.  With a fogmap one walk along the ray (fp_fog_cur_t)
     * gives the optical depth to ta, to each of those ends and to len. */
    fp_real step0 = fmax((fp_real)1 / fmax(fp[FP_F_SIGMA] + fp[FP_F_HAZE], (fp_real)1e-12),
                         (fp_real)1e-3);
    fp_real od_ta = 0, od_try[FP_SCATTER_DOUBLINGS];
    fp_fog_cur_t cur;
    fp_fog_cur_init(&cur, fp, lvi, ox, oy, oz, dx, dy, dz, len);
    fp_real od_total;
    if (cur.walk && in_fog) {
        od_ta = fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, ta);
        od_total = od_ta;
        fp_real step = step0;
        for (int k = 0; k < FP_SCATTER_DOUBLINGS && step < tb - ta && step < fp[FP_F_CAP];
             k++) {
            od_total += fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, ta + step);
            od_try[k] = od_total;
            step *= 2;
        }
        od_total += fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, len);
    } else {
        od_total = fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, len, 0);
    }
    fp_real tau = exp(-od_total);
    if (!(od_total > 0) || !in_fog)
        return tau;
    fp_real albedo = lt[FP_LT_ALBEDO];
    int nd = (int)lt[FP_LT_NDIR];
    if (lt[FP_LT_SUN_ON] == 0 && lt[FP_LT_NLIGHTS] == 0 && nd == 0) {
        /* Ambient light alone: the closed form (seed 000 eq. 4). */
        for (int c = 0; c < 3; c++)
            S[c] = albedo * -expm1(-od_total) * lt[FP_LT_AMB + c];
        return tau;
    }
    /* The light scattered more than once (kernels/ms_core.h). */
    fp_ms_ray(fp, lvi, lvf, coef, occ, lt, ox, oy, oz, dx, dy, dz, ta, tb, od_total, S);
    /* Local lights by the fast rule need no segments: without a sun the
     * ambient term is the closed form and the lights are done. */
    int nl = (int)lt[FP_LT_NLIGHTS];
    int fast_lights = lt[FP_LT_LIGHT_QUAD] != 0 && fp[FP_F_HAS_MAP] == 0;
    if (fast_lights && lt[FP_LT_SUN_ON] == 0 && nd == 0)
        return fp_scatter_ambient_lights(fp, lt, lights, ox, oy, oz, dx, dy, dz, len, od_total, 1,
                                         S);
    /* The sun with its shadow map: the exact runs of kernels/shafts_core.h
     * (the segments below then carry only the ambient light and the local
     * lights that need them).  In fog of height alone C is a closed form
     * to the span's end, infinite or not. */
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    FP_CONSTANT const fp_real *l = lt + FP_LT_SUN_DIR;
    int kind = (int)ph[0];
    fp_real ph_sun = fp_phase(kind, ph[1], ph[2], dx * l[0] + dy * l[1] + dz * l[2]);
    int shafts = lt[FP_LT_SUN_ON] != 0 && (int)lt[FP_LT_SHADOWS] != FP_SHADOWS_NONE;
    int self = (int)lt[FP_LT_SELF] != FP_SELF_OFF;
    int sides = !(isinf(fp[FP_F_BOX]) && isinf(fp[FP_F_BOX + 2]) && isinf(fp[FP_F_BOX + 3]) &&
                  isinf(fp[FP_F_BOX + 5]));
    int layered = fp[FP_F_HAS_MAP] == 0 && (!self || (!sides && l[1] > (fp_real)1e-3));
    if (shafts && layered) {
        if (ph_sun > 0)
            fp_shafts_add(fp, lvi, lvf, coef, occ, lt, smap, grid, view, depth, width, height, ox,
                          oy, oz, dx, dy, dz, ta, tb, 1, 0, od_total, albedo * ph_sun, S);
        ph_sun = 0;
        if ((nl == 0 || fast_lights) && nd == 0)
            return fp_scatter_ambient_lights(fp, lt, lights, ox, oy, oz, dx, dy, dz, len,
                                             od_total, fast_lights, S);
    }
    fp_real od_stop = lt[FP_LT_OD_STOP];
    {
        /* Go only as far as the fog still matters: until its optical depth
         * from ta passes od_stop, or nearly all of it is behind (a sky
         * ray, or geometry far beyond the fog), found by doubling. */
        fp_real span = tb - ta, step = step0;
        if (step < span) {
            /* Without the walk: a cursor of fp_fog_od per stretch, here. */
            int tried = cur.walk;
            if (!tried) {
                fp_fog_cur_init(&cur, fp, lvi, ox, oy, oz, dx, dy, dz, len);
                od_ta = fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, ta);
            }
            fp_real od = od_ta;
            for (int k = 0; k < FP_SCATTER_DOUBLINGS && step < span && step < fp[FP_F_CAP]; k++) {
                od = tried ? od_try[k]
                           : od + fp_fog_cur_advance(&cur, fp, lvi, lvf, coef, occ, ta + step);
                if (od - od_ta >= od_stop ||
                    (isfinite(od_total) && od_total - od <= (fp_real)1e-4 * od_total))
                    break;
                step *= 2;
            }
            tb = ta + fmin(fmin(step, fp[FP_F_CAP]), span);
        }
    }
    int n = (int)lt[FP_LT_STEPS];
    n = n < 1 ? 1 : n > FP_SCATTER_MAX_STEPS_ / 2 ? FP_SCATTER_MAX_STEPS_ / 2 : n;
    /* The sun with its shadow map where C is carried (a fogmap, a box
     * with sides): to where the fog stops mattering, as the segments. */
    if (shafts && !layered) {
        if (ph_sun > 0)
            fp_shafts_add(fp, lvi, lvf, coef, occ, lt, smap, grid, view, depth, width, height, ox,
                          oy, oz, dx, dy, dz, ta, tb, 0, (tb - ta) / FP_SHAFT_STEPS,
                          od_total, albedo * ph_sun, S);
        ph_sun = 0;
        if ((nl == 0 || fast_lights) && nd == 0)
            return fp_scatter_ambient_lights(fp, lt, lights, ox, oy, oz, dx, dy, dz, len,
                                             od_total, fast_lights, S);
    }
    /* Interleaved sampling: the first segment is `offset` of one long,
     * which shifts every later end along the ray. */
    fp_real h0 = (tb - ta) / n, xmax = lt[FP_LT_SEG_OD];
    fp_real h = offset > 0 ? offset * h0 : h0;
    /* Segment ends and the optical depth from the camera there (for the
     * lights).  Segments are at most (tb - ta) / n long and hold at most
     * xmax of optical depth (halved until they do, down to h0 / 256), so
     * dense fog gets more of them; MAX_STEPS bounds the count. */
    fp_real segt[FP_SCATTER_MAX_STEPS_ + 1], odc[FP_SCATTER_MAX_STEPS_ + 1];
    fp_real Ja[3], Jb[3];
    fp_real od = cur.walk ? od_ta
                 : ta > 0 ? fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, ta, 0)
                          : 0;
    fp_scatter_source(fp, lvi, lvf, coef, occ, lt, lights, smap, grid, view, depth, width, height,
                      ph_sun, dx, dy, dz, ox + ta * dx, oy + ta * dy, oz + ta * dz, Ja);
    segt[0] = ta;
    odc[0] = od;
    int last = 0;
    fp_real t0 = ta;
    for (int guard = 0; t0 < tb && last < FP_SCATTER_MAX_STEPS_ && guard < 4 * FP_SCATTER_MAX_STEPS_;
         guard++) {
        int final_seg = last + 1 == FP_SCATTER_MAX_STEPS_;
        fp_real hs = final_seg ? tb - t0 : fmin(h, tb - t0);
        fp_real t1 = hs >= tb - t0 ? tb : t0 + hs;
        fp_real x = fp_fog_od(fp, lvi, lvf, coef, occ, ox + t0 * dx, oy + t0 * dy, oz + t0 * dz,
                              dx, dy, dz, t1 - t0, 0);
        if (x > xmax && !final_seg && hs > h0 * (fp_real)(1.0 / 256)) {
            h = hs * fmax((fp_real)0.8 * xmax / x, (fp_real)0.1);
            continue;
        }
        fp_scatter_source(fp, lvi, lvf, coef, occ, lt, lights, smap, grid, view, depth, width,
                          height, ph_sun, dx, dy, dz, ox + t1 * dx, oy + t1 * dy, oz + t1 * dz, Jb);
        fp_real e = exp(-x), ta_w = exp(-od) * albedo;
        fp_real c0 = -expm1(-x), c1 = x > 0 ? fp_expm1_ratio(x) - e : 0;
        /* The light changes fast here (a shadow's edge): halve the segment
         * while the change, weighted by what the segment adds to the pixel,
         * is above FP_LT_SEG_JUMP of the light. */
        fp_real jump = 0, jscale = (fp_real)1e-12;
        for (int c = 0; c < 3; c++) {
            jump = fmax(jump, fabs(Jb[c] - Ja[c]));
            jscale = fmax(jscale, (fp_real)0.5 * (Ja[c] + Jb[c]));
        }
        if (jump * c0 * exp(-od) > lt[FP_LT_SEG_JUMP] * jscale && !final_seg &&
            hs > h0 * (fp_real)(1.0 / 256)) {
            h = (fp_real)0.5 * hs;
            continue;
        }
        for (int c = 0; c < 3; c++) {
            S[c] += ta_w * (Ja[c] * c0 + (Jb[c] - Ja[c]) * c1);
            Ja[c] = Jb[c];
        }
        od += x;
        t0 = t1;
        last++;
        segt[last] = t1;
        odc[last] = od;
        if (od > od_stop)
            break;
        if (x < (fp_real)0.25 * xmax && jump * c0 < (fp_real)0.25 * lt[FP_LT_SEG_JUMP] * jscale)
            h = fmin(2 * h, h0);
    }
    /* Beyond tb (an unbounded ray stops with 1e-4 of its optical depth
     * left): that fog with the light of the last point. */
    for (int c = 0; c < 3; c++)
        S[c] += albedo * Ja[c] * fmax(exp(-od) - tau, (fp_real)0);
    /* Local lights over [ta, t_last]. */
    fp_real tl = segt[last];
    int panels = (int)lt[FP_LT_PANELS];
    if (fast_lights) {
        /* The fast rule's own stretch and culling (the ambient term is in
         * the segments already). */
#ifndef FP_LIGHTS_APART
        fp_real budget = lt[FP_LT_CULL], la, lb;
        fp_light_span(fp, ox, oy, oz, dx, dy, dz, len, &la, &lb);
        fp_real smax = fp_light_sigma_span(fp, oy, dy, la, lb), omt = -expm1(-od_total);
        for (int k = 0; lb > la && k < nl; k++) {
            if (budget > 0) {
                fp_real b = fp_light_bound(lt, lights + k * FP_LL_STRIDE, smax, omt, ox, oy, oz, dx,
                                           dy, dz, la, lb);
                if (b <= budget) {
                    budget -= b;
                    continue;
                }
            }
            fp_real Sk[3];
            fp_light_ray(fp, lt, lights, k, ox, oy, oz, dx, dy, dz, len, Sk);
            for (int c = 0; c < 3; c++)
                S[c] += Sk[c];
        }
#endif
        return tau;
    }
    fp_real budget = lt[FP_LT_CULL], omt = -expm1(-od_total);
    fp_real smax = fp_light_sigma_span(fp, oy, dy, ta, tl);
    for (int k = 0; k < nl; k++) {
        FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
        if (budget > 0) {
            fp_real b = fp_light_bound(lt, row, smax, omt, ox, oy, oz, dx, dy, dz, ta, tl);
            if (b <= budget) {
                budget -= b;
                continue;
            }
        }
        fp_real qx = row[FP_LL_POS] - ox, qy = row[FP_LL_POS + 1] - oy, qz = row[FP_LL_POS + 2] - oz;
        fp_real tc = qx * dx + qy * dy + qz * dz;
        fp_real rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
        fp_real D = fmax(sqrt(rx * rx + ry * ry + rz * rz), (fp_real)1e-6 * (1 + fabs(tc)));
        fp_real th0 = atan2(ta - tc, D), th1 = atan2(tl - tc, D);
        /* A Cycles spot's cone and an area light's front half-space: the
         * panels cover only their support along the ray (its hard edge a
         * panel's end, not inside one), |theta - theta_a| <= acos(cos_out
         * / R) as in fp_light_fast.  (fogpipe's spots keep the whole range.) */
        int ty = (int)row[FP_LL_TYPE];
        if ((ty == FP_LIGHT_AREA || (ty == FP_LIGHT_SPOT && row[FP_LL_PROFILE] != 0)) &&
            row[FP_LL_COS_OUT] >= 0) {
            fp_real na = -(rx * row[FP_LL_AXIS] + ry * row[FP_LL_AXIS + 1] +
                           rz * row[FP_LL_AXIS + 2]) / D;
            fp_real da = dx * row[FP_LL_AXIS] + dy * row[FP_LL_AXIS + 1] + dz * row[FP_LL_AXIS + 2];
            fp_real R = sqrt(na * na + da * da), co = row[FP_LL_COS_OUT];
            const fp_real tpi = (fp_real)6.283185307179586;
            fp_real tha = atan2(da, na);
            tha += tpi * floor(((fp_real)0.5 * (th0 + th1) - tha) / tpi + (fp_real)0.5);
            fp_real ao = acos(fmin(co / fmax(R, (fp_real)1e-30), (fp_real)1));
            th0 = fmax(th0, tha - ao);
            th1 = fmin(th1, tha + ao);
            if (!(R > co) || !(th1 > th0))
                continue;
        }
        /* The phase function's peak (mu = -sin(theta) -> 1 for g > 0, at
         * theta = -pi/2; mirrored for g < 0) is about 1 - |g| wide in
         * theta: with e the angle from the peak, panels grow
         * geometrically away from it, starting at (1 - |g|) / 4. */
        fp_real g = ph[1];
        int peaked = (kind == FP_PHASE_HG || kind == FP_PHASE_CS || kind == FP_PHASE_MIX ||
                      kind == FP_PHASE_MIXHG) && fabs(g) > (fp_real)0.2;
        fp_real sgn = g < 0 ? (fp_real)-1 : (fp_real)1, hp = (fp_real)1.5707963267948966;
        fp_real ea = hp + sgn * (sgn > 0 ? th0 : th1), eb = hp + sgn * (sgn > 0 ? th1 : th0);
        fp_real es = fmax(ea, (fp_real)0.25 * (1 - fabs(g)));
        int geo = peaked && panels > 1 && es < eb && ea >= 0;
        int first = geo && ea < es;   /* a uniform panel before the geometric ones */
        fp_real ratio = geo ? pow(eb / es, (fp_real)1 / (panels - first)) : 1;
        fp_real acc = 0, ls_iv[2 * FP_SS_MAX_IV];   /* the lamp's screen shadows: nodes in them skipped */
        int ls_n = fp_ls_ray_iv(lt, row, view, smap, ox, oy, oz, dx, dy, dz, ta, tl, ls_iv);
        for (int q = 0; q < panels; q++) {
            fp_real pa, pb;
            if (!geo) {
                pa = ea + (eb - ea) * q / panels;
                pb = ea + (eb - ea) * (q + 1) / panels;
            } else if (first && q == 0) {
                pa = ea;
                pb = es;
            } else {
                pa = es * pow(ratio, (fp_real)(q - first));
                pb = q + 1 == panels ? eb : es * pow(ratio, (fp_real)(q + 1 - first));
            }
            for (int gq = 0; gq < 4; gq++) {
                fp_real e = pa + (pb - pa) * fp_gl_x[FP_GL_FIRST(4) + gq];
                fp_real th = sgn * (e - hp);
                fp_real t = tc + D * tan(th);
                fp_real px = ox + t * dx, py = oy + t * dy, pz = oz + t * dz;
                fp_real sig = fp_sigma_t(fp, lvi, lvf, coef, px, py, pz);
                if (sig <= 0 || (ls_n && fp_ls_in(ls_iv, ls_n, t)))
                    continue;
                fp_real vx = row[FP_LL_POS] - px, vy = row[FP_LL_POS + 1] - py,
                        vz = row[FP_LL_POS + 2] - pz;
                fp_real r = sqrt(vx * vx + vy * vy + vz * vz);
                vx /= r;
                vy /= r;
                vz /= r;
                fp_real cone = fp_light_gain(row, -vx, -vy, -vz, r);
                if (cone <= 0)
                    continue;
                /* Camera-side optical depth: linear between segment ends. */
                int lo = 0, hi = last;
                while (hi - lo > 1) {
                    int mid = (lo + hi) / 2;
                    if (segt[mid] <= t)
                        lo = mid;
                    else
                        hi = mid;
                }
                fp_real f = fmin(fmax((t - segt[lo]) / fmax(segt[hi] - segt[lo], (fp_real)1e-30),
                                      (fp_real)0), (fp_real)1);
                fp_real odt = odc[lo] + f * (odc[hi] - odc[lo]);
                fp_real odl = fp_fog_od(fp, lvi, lvf, coef, occ, px, py, pz, vx, vy, vz, r, 0);
                acc += fp_gl_w[FP_GL_FIRST(4) + gq] * (pb - pa) * sig * exp(-odt - odl) * cone *
                       fp_phase(kind, ph[1], ph[2], vx * dx + vy * dy + vz * dz);
            }
        }
        acc *= albedo / D;
        for (int c = 0; c < 3; c++)
            S[c] += acc * row[FP_LL_I + c];
    }
    return tau;
}

#endif
