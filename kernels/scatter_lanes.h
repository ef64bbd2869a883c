/* fogpipe: local lights by the fast rule (--light-quad fast, fog without a
 * fogmap) on FP_LN_LANES view rays at once: fp_light_ray of scatter_core.h
 * written with lanes (OpenCL: float16, one work-item computing 16 pixels;
 * C: one ray in double), every quantity computed for every lane and the
 * cases chosen among computed values (?: on vectors selects per lane).
 * Include after scatter_core.h.
 *
 * Why lanes: PoCL ran the former kernel (scatter_light, fp_light_ray per
 * work-item, one pixel each) scalar.  Its work-group loop was an outer
 * loop around the rule's node, piece and box loops (LLVM's loop vectorizer
 * only takes innermost loops; the IR that PoCL leaves with
 * POCL_LEAVE_KERNEL_COMPILER_TEMP_FILES=1 showed five inner loops inside
 * the work-item loop and the private arrays they index kept in memory);
 * with those loops unrolled by force it still emitted scalar code (xmm
 * registers, *ss instructions only) at 12.6 instead of 14.7 us/px.  With
 * explicit vectors the shape is the program's, not the vectorizer's
 * choice: scatter_lights compiles to zmm code (AVX-512) at about 1.1
 * us/px for the night-street-lamps look.
 *
 * The values are those of fp_light_ray (the C double reference, the
 * judge): the same formulas, the same pieces and nodes, the same float
 * polynomials for atan and sin/cos as scatter_core.h's fp_l_* in OpenCL
 * and the C library's functions in C.  Conditions that are the same for
 * every lane (the light's kind, the phase function, whether there is
 * haze) stay scalar branches.  tests/test_scatter.c compares this header
 * compiled in double with fp_light_ray, and the OpenCL kernel
 * (scatter_lights) with the C reference. */
#ifndef FP_SCATTER_LANES_H
#define FP_SCATTER_LANES_H

#ifdef __OPENCL_VERSION__
/* 16: one AVX-512 register of floats; filters/scatter_cl.c launches
 * scatter_lights with this many pixels per work-item. */
#define FP_LN_LANES 16
#define FP_LN_CAT_(a, b) a##b
#define FP_LN_CAT(a, b) FP_LN_CAT_(a, b)
typedef FP_LN_CAT(float, FP_LN_LANES) fp_lnr;
typedef FP_LN_CAT(int, FP_LN_LANES) fp_lni;
#define FP_LN_FN inline __attribute__((always_inline))
#else
#define FP_LN_LANES 1
typedef double fp_lnr;
typedef int fp_lni;
#define FP_LN_FN static inline
#endif
#define FP_LN(x) ((fp_lnr)(x))
#define FP_LNI(x) ((fp_lni)(x))

#ifdef __OPENCL_VERSION__
/* fp_l_atan, fp_l_atan2, fp_l_sincos, fp_l_acos, fp_l_one_minus_exp of
 * scatter_core.h on lanes. */
FP_LN_FN fp_lnr fp_ln_atan(fp_lnr x)
{
    fp_lnr ax = fabs(x);
    fp_lni big = ax > 2.414213562373095f, mid = ax > 0.4142135623730950f;
    fp_lnr y0 = big ? FP_LN(1.5707963267948966f) : mid ? FP_LN(0.7853981633974483f) : FP_LN(0.0f);
    fp_lnr xr = big ? -1.0f / ax : mid ? (ax - 1.0f) / (ax + 1.0f) : ax;
    fp_lnr z = xr * xr;
    fp_lnr y = y0 + (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
                     3.33329491539e-1f) * z * xr + xr;
    return x < 0.0f ? -y : y;
}

FP_LN_FN fp_lnr fp_ln_atan2(fp_lnr y, fp_lnr x)
{
    fp_lnr a = fp_ln_atan(y / x);
    const float pi = 3.14159265358979323846f;
    fp_lnr left = y >= 0.0f ? a + pi : a - pi;
    fp_lnr axis = y > 0.0f ? FP_LN(0.5f * pi) : y < 0.0f ? FP_LN(-0.5f * pi) : FP_LN(0.0f);
    return x > 0.0f ? a : x < 0.0f ? left : axis;
}

/* sin and cos of x in [0, pi/2]: about pi/4. */
FP_LN_FN void fp_ln_sincos(fp_lnr x, fp_lnr *s, fp_lnr *c)
{
    fp_lnr r = x - 0.7853981633974483f, z = r * r;
    fp_lnr a = ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f) * z * r + r;
    fp_lnr b = ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f) *
               z * z - 0.5f * z + 1.0f;
    *s = 0.7071067811865476f * (b + a);
    *c = 0.7071067811865476f * (b - a);
}

FP_LN_FN fp_lnr fp_ln_acos(fp_lnr x)
{
    return 2.0f * fp_ln_atan(sqrt((1.0f - x) / (1.0f + x)));
}

FP_LN_FN fp_lnr fp_ln_one_minus_exp(fp_lnr x)
{
    fp_lnr series = x * (1.0f - x * (0.5f - x * (1.0f / 6 - x * (1.0f / 24))));
    return x < 0.05f ? series : 1.0f - exp(-x);
}
#else
#define fp_ln_atan atan
#define fp_ln_atan2 atan2
#define fp_ln_acos acos
#define fp_ln_sincos fp_l_sincos
#define fp_ln_one_minus_exp fp_l_one_minus_exp
#endif

/* fp_light_ratio: (1 - e^-x) / x, x >= 0. */
FP_LN_FN fp_lnr fp_ln_ratio(fp_lnr x)
{
    fp_lnr series = 1 - x * ((fp_real)0.5 - x * ((fp_real)1 / 6));
    fp_lnr full = fp_ln_one_minus_exp(x) / fmax(x, (fp_real)1e-30);
    return x < (fp_real)1e-3 ? series : full;
}

/* fp_light_height_od: optical depth of sigma h(y) along y = oy + t dy,
 * t in [0, len], len finite. */
FP_LN_FN fp_lnr fp_ln_height_od(fp_real sigma, fp_real y0, fp_real H, fp_real top, fp_lnr oy,
                                fp_lnr dy, fp_lnr len)
{
    if (!(sigma > 0))
        return FP_LN(0);
    fp_lnr ddy = fabs(dy) > (fp_real)1e-30 ? dy : FP_LN((fp_real)1e-30);
    fp_lnr inv = 1 / ddy;
    fp_real lo = fmin(y0, top);
    /* below lo: y < lo */
    fp_lnr u = (lo - oy) * inv;
    fp_lnr a1 = ddy > 0 ? FP_LN(0) : fmax(u, (fp_real)0);
    fp_lnr b1 = ddy > 0 ? fmin(u, len) : len;
    fp_lnr below = fmax(b1 - a1, (fp_real)0);
    /* y0 <= y < top */
    fp_lnr u0 = (y0 - oy) * inv, u1 = (top - oy) * inv;
    fp_lnr a2 = fmax(fmin(u0, u1), (fp_real)0), b2 = fmin(fmax(u0, u1), len);
    fp_lnr w = fmax(b2 - a2, (fp_real)0);
    fp_lnr ya = (oy + a2 * dy - y0) / H;
    fp_lnr Dl = fabs(dy) * w / H;
    fp_lnr m = dy < 0 ? ya - Dl : ya;
    fp_lnr above = w > 0 ? w * exp(-m) * fp_ln_ratio(Dl) : FP_LN(0);
    return sigma * (below + above);
}

/* One axis of fp_light_plain_od's box: [a, b] cut to lo <= o + t d <= hi. */
FP_LN_FN void fp_ln_clip(fp_lnr o, fp_lnr d, fp_real lo, fp_real hi, fp_lnr *a, fp_lnr *b)
{
    fp_lni moving = fabs(d) > (fp_real)1e-30;
    fp_lnr dd = moving ? d : FP_LN((fp_real)1e-30);
    fp_lnr u = (lo - o) / dd, v = (hi - o) / dd;
    fp_lni inside = (o >= lo) & (o <= hi);
    fp_lnr still_lo = inside ? FP_LN(-FP_INF) : FP_LN(FP_INF);
    fp_lnr still_hi = inside ? FP_LN(FP_INF) : FP_LN(-FP_INF);
    *a = fmax(*a, moving ? fmin(u, v) : still_lo);
    *b = fmin(*b, moving ? fmax(u, v) : still_hi);
}

/* fp_light_plain_od: optical depth of fog without a fogmap along
 * o + t d, t in [0, len], len finite. */
FP_LN_FN fp_lnr fp_ln_plain_od(FP_CONSTANT const fp_real *fp, fp_lnr ox, fp_lnr oy, fp_lnr oz,
                               fp_lnr dx, fp_lnr dy, fp_lnr dz, fp_lnr len)
{
    fp_lnr od = fp_ln_height_od(fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                                fp[FP_F_HAZE + 3], oy, dy, len);
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_lnr px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_lnr a = FP_LN(0), b = len;
    fp_ln_clip(c * px - s * pz, c * dx - s * dz, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_ln_clip(py, dy, fp[FP_F_BOX + 1], fp[FP_F_BOX + 4], &a, &b);
    fp_ln_clip(s * px + c * pz, s * dx + c * dz, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a, &b);
    fp_lnr main = fp_ln_height_od(fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP],
                                  py + a * dy, dy, fmax(b - a, (fp_real)0));
    return od + (b > a ? main : FP_LN(0));
}

/* fp_light_plain_sigma: extinction of fog without a fogmap at a point. */
FP_LN_FN fp_lnr fp_ln_plain_sigma(FP_CONSTANT const fp_real *fp, fp_lnr x, fp_lnr y, fp_lnr z)
{
    fp_lnr haze = FP_LN(0);
    if (fp[FP_F_HAZE] > 0) {
        fp_lnr e = fp[FP_F_HAZE] * exp(-fmax(y - fp[FP_F_HAZE + 1], (fp_real)0) / fp[FP_F_HAZE + 2]);
        haze = y < fp[FP_F_HAZE + 3] ? e : FP_LN(0);
    }
    if (!(fp[FP_F_SIGMA] > 0))
        return haze;
    fp_real c = fp[FP_F_COS], sn = fp[FP_F_SIN];
    fp_lnr px = x - fp[FP_F_OFF], py = y - fp[FP_F_OFF + 1], pz = z - fp[FP_F_OFF + 2];
    fp_lnr qx = c * px - sn * pz, qz = sn * px + c * pz;
    fp_lni in = (qx >= fp[FP_F_BOX]) & (qx <= fp[FP_F_BOX + 3]) & (py >= fp[FP_F_BOX + 1]) &
                (py <= fp[FP_F_BOX + 4]) & (qz >= fp[FP_F_BOX + 2]) & (qz <= fp[FP_F_BOX + 5]) &
                (py < fp[FP_F_TOP]);
    fp_lnr h = exp(-fmax(py - fp[FP_F_Y0], (fp_real)0) / fp[FP_F_H]);
    return haze + (in ? fp[FP_F_SIGMA] * h : FP_LN(0));
}

/* fp_light_phase: the kind is the same for every lane, so only its
 * formula is computed. */
FP_LN_FN fp_lnr fp_ln_phase(int kind, fp_real g, fp_real w, fp_lnr mu)
{
    if (kind == FP_PHASE_ISO || kind < FP_PHASE_ISO || kind > FP_PHASE_MIXHG)
        return FP_LN(FP_INV_4PI);
    fp_lnr ray = (fp_real)0.75 * FP_INV_4PI * (1 + mu * mu);
    if (kind == FP_PHASE_RAYLEIGH)
        return ray;
    fp_lnr d = 1 + g * g - 2 * g * mu;
    fp_lnr hg = FP_INV_4PI * (1 - g * g) / (d * sqrt(d));
    fp_lnr cs = hg * (fp_real)1.5 * (1 + mu * mu) / (2 + g * g);
    return kind == FP_PHASE_HG ? hg : kind == FP_PHASE_CS ? cs
         : kind == FP_PHASE_MIX ? w * ray + (1 - w) * cs : w * ray + (1 - w) * hg;
}

/* fp_light_span: where along o + t d, t in [0, len], the main fog's box
 * below its top and the haze below its top are; ta > tb when nowhere. */
FP_LN_FN void fp_ln_span(FP_CONSTANT const fp_real *fp, fp_lnr ox, fp_lnr oy, fp_lnr oz,
                         fp_lnr dx, fp_lnr dy, fp_lnr dz, fp_lnr len, fp_lnr *ta, fp_lnr *tb)
{
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_lnr px = ox - fp[FP_F_OFF], py = oy - fp[FP_F_OFF + 1], pz = oz - fp[FP_F_OFF + 2];
    fp_lnr a = FP_LN(0), b = len;
    fp_ln_clip(c * px - s * pz, c * dx - s * dz, fp[FP_F_BOX], fp[FP_F_BOX + 3], &a, &b);
    fp_ln_clip(py, dy, fp[FP_F_BOX + 1], fmin(fp[FP_F_BOX + 4], fp[FP_F_TOP]), &a, &b);
    fp_ln_clip(s * px + c * pz, s * dx + c * dz, fp[FP_F_BOX + 2], fp[FP_F_BOX + 5], &a, &b);
    fp_lni main_on = b > a;
    if (!(fp[FP_F_SIGMA] > 0))
        main_on = FP_LNI(0);
    /* the haze: below its top */
    fp_lni hmoving = fabs(dy) > (fp_real)1e-30;
    fp_lnr hu = (fp[FP_F_HAZE + 3] - oy) / (hmoving ? dy : FP_LN((fp_real)1e-30));
    fp_lnr ha = (hmoving & (dy < 0)) ? fmax(hu, (fp_real)0) : FP_LN(0);
    fp_lnr hb = (hmoving & (dy > 0)) ? fmin(hu, len) : len;
    fp_lni haze_on = (hb > ha) & (hmoving | (oy < fp[FP_F_HAZE + 3]));
    if (!(fp[FP_F_HAZE] > 0))
        haze_on = FP_LNI(0);
    *ta = fmin(main_on ? a : FP_LN(FP_INF), haze_on ? ha : FP_LN(FP_INF));
    *tb = fmax(main_on ? b : FP_LN(-FP_INF), haze_on ? hb : FP_LN(-FP_INF));
}

/* fp_tri_solid on lanes: the points differ per lane, the triangle's
 * edges do not. */
FP_LN_FN fp_lnr fp_ln_tri_solid(fp_lnr ax, fp_lnr ay, fp_lnr az, fp_real ex, fp_real ey, fp_real ez,
                                fp_real fx, fp_real fy, fp_real fz)
{
    fp_lnr bx = ax + ex, by = ay + ey, bz = az + ez, cx = ax + fx, cy = ay + fy, cz = az + fz;
    fp_lnr num = ax * (ey * fz - ez * fy) + ay * (ez * fx - ex * fz) + az * (ex * fy - ey * fx);
    fp_lnr la = sqrt(ax * ax + ay * ay + az * az), lb = sqrt(bx * bx + by * by + bz * bz),
           lc = sqrt(cx * cx + cy * cy + cz * cz);
    fp_lnr den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc +
                 (ax * cx + ay * cy + az * cz) * lb + (bx * cx + by * cy + bz * cz) * la;
    return 2 * fabs(fp_ln_atan2(num, den));
}

/* fp_area_solid on lanes. */
FP_LN_FN fp_lnr fp_ln_area_solid(FP_GLOBAL const fp_real *row, fp_lnr wx, fp_lnr wy, fp_lnr wz)
{
    FP_GLOBAL const fp_real *U = row + FP_LL_U, *V = row + FP_LL_V;
    if ((int)row[FP_LL_SHAPE] == 0) {
        fp_lnr ax = wx - U[0] - V[0], ay = wy - U[1] - V[1], az = wz - U[2] - V[2];
        return fp_ln_tri_solid(ax, ay, az, 2 * U[0], 2 * U[1], 2 * U[2], 2 * (U[0] + V[0]),
                               2 * (U[1] + V[1]), 2 * (U[2] + V[2])) +
               fp_ln_tri_solid(ax, ay, az, 2 * (U[0] + V[0]), 2 * (U[1] + V[1]),
                               2 * (U[2] + V[2]), 2 * V[0], 2 * V[1], 2 * V[2]);
    }
    fp_lnr om = FP_LN(0);
    fp_real s = (fp_real)FP_AREA_OCT_SCALE, h = (fp_real)0.70710678118654752;
    fp_real cs[FP_AREA_OCT_SIDES + 1] = { 1, h, 0, -h, -1, -h, 0, h, 1 };
    fp_real sn[FP_AREA_OCT_SIDES + 1] = { 0, h, 1, h, 0, -h, -1, -h, 0 };
    for (int k = 0; k < FP_AREA_OCT_SIDES; k++) {
        fp_real c0 = s * cs[k], s0 = s * sn[k], c1 = s * cs[k + 1], s1 = s * sn[k + 1];
        om += fp_ln_tri_solid(wx, wy, wz, c0 * U[0] + s0 * V[0], c0 * U[1] + s0 * V[1],
                              c0 * U[2] + s0 * V[2], c1 * U[0] + s1 * V[0], c1 * U[1] + s1 * V[1],
                              c1 * U[2] + s1 * V[2]);
    }
    return om;
}

/* fp_light_gain_cos on lanes (the light's kind is the same for every
 * lane): cu the cosine of u to the light's axis. */
FP_LN_FN fp_lnr fp_ln_gain(FP_GLOBAL const fp_real *row, int type, fp_lnr cu, fp_lnr ux,
                           fp_lnr uy, fp_lnr uz, fp_lnr r)
{
    if (type == FP_LIGHT_AREA)
        return cu > 0 ? r * r * fp_ln_area_solid(row, -r * ux, -r * uy, -r * uz) / row[FP_LL_AREA]
                      : FP_LN(0);
    fp_lnr g = FP_LN(1);
    if (type == FP_LIGHT_SPOT) {
        fp_real co = row[FP_LL_COS_OUT], ci = row[FP_LL_COS_IN];
        if (row[FP_LL_PROFILE] == 0) {
            fp_lnr sm = fmin(fmax((cu - co) / fmax(ci - co, (fp_real)1e-30), (fp_real)0),
                             (fp_real)1);
            g = cu >= ci ? FP_LN(1) : sm * sm * (3 - 2 * sm);
        } else {
            fp_real sp = row[FP_LL_SPREAD];
            fp_lnr sm = fmin(fmax((cu - co) / fmax(sp, (fp_real)1e-30), (fp_real)0), (fp_real)1);
            fp_lnr v = sp > 0 ? cu * (sm * sm * (3 - 2 * sm)) : cu;
            g = cu <= co ? FP_LN(0) : v;
        }
    }
    fp_real R = row[FP_LL_RADIUS];
    if (R > 0) {
        fp_lnr s = sqrt(r * r + R * R);
        g *= 2 * r * r / (s * (s + r));
    }
    return g;
}

#include "cull_lanes.h"
#include "light_band_lanes.h"

/* fp_light_bound on lanes. */
FP_LN_FN fp_lnr fp_ln_bound(FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *row,
                            fp_lnr sigma_max, fp_lnr one_minus_tau, fp_lnr ox, fp_lnr oy,
                            fp_lnr oz, fp_lnr dx, fp_lnr dy, fp_lnr dz, fp_lnr ta, fp_lnr tb)
{
    fp_lnr qx = row[FP_LL_POS] - ox, qy = row[FP_LL_POS + 1] - oy, qz = row[FP_LL_POS + 2] - oz;
    fp_lnr tc = qx * dx + qy * dy + qz * dz;
    fp_lnr rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
    fp_lnr D = sqrt(rx * rx + ry * ry + rz * rz);
    fp_real rho = row[FP_LL_REACH];
    fp_lni near = !((D > rho) & (D > (fp_real)1e-6 * (1 + fabs(tc))));
    fp_lnr Ds = near ? FP_LN(1) : D;
    const fp_real pi = (fp_real)3.14159265358979323846;
    fp_lnr th0 = fp_ln_atan((ta - tc) / Ds), th1 = fp_ln_atan((tb - tc) / Ds);
    int type = (int)row[FP_LL_TYPE];
    fp_real co = row[FP_LL_COS_OUT];
    fp_lni miss = FP_LNI(0);
    if ((type == FP_LIGHT_SPOT || type == FP_LIGHT_AREA) && co >= 0) {
        fp_lnr na = -(rx * row[FP_LL_AXIS] + ry * row[FP_LL_AXIS + 1] + rz * row[FP_LL_AXIS + 2]) / Ds;
        fp_lnr da = dx * row[FP_LL_AXIS] + dy * row[FP_LL_AXIS + 1] + dz * row[FP_LL_AXIS + 2];
        fp_lnr R = sqrt(na * na + da * da);
        fp_lnr tha = fp_ln_atan2(da, na);
        tha += 2 * pi * floor(((fp_real)0.5 * (th0 + th1) - tha) / (2 * pi) + (fp_real)0.5);
        fp_lnr ao = fp_ln_acos(fmin(co / fmax(R, (fp_real)1e-30), (fp_real)1));
        miss = (R <= co) | (tha + ao < th0) | (tha - ao > th1);
    }
    fp_lnr f = Ds / (Ds - rho);
    f *= f;
    fp_lnr b = fmin(one_minus_tau * f / (Ds * Ds), sigma_max * (th1 - th0) * f / Ds);
    b *= lt[FP_LT_ALBEDO] * row[FP_LL_IMAX];
    b *= rho > 0 ? FP_LN(lt[FP_LT_PMAX]) : fp_ln_phase_span(lt, Ds, tc, ta, tb);
    b = miss ? FP_LN(0) : b;
    return near ? FP_LN(FP_INF) : b;
}

/* e in [0, pi] (theta's angle from the phase peak, halved about pi/4) to
 * phi: tan(e/2) = k tan(phi). */
FP_LN_FN fp_lnr fp_ln_phi(fp_lnr half_e, fp_real k)
{
    fp_lnr sb, cb;
    fp_ln_sincos(half_e, &sb, &cb);
    return fp_ln_atan2(sb, k * cb);
}

/* fp_light_fast on lanes: a local light's in-scatter over [ta, tl] of the
 * view ray, without the light's intensity (the comments of fp_light_fast
 * say why each step is there). */
FP_LN_FN fp_lnr fp_ln_fast(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt,
                           FP_GLOBAL const fp_real *row, fp_lnr sig_c, fp_lnr ox, fp_lnr oy,
                           fp_lnr oz, fp_lnr dx, fp_lnr dy, fp_lnr dz, fp_lnr ta, fp_lnr tl)
{
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    int kind = (int)ph[0];
    fp_real g = ph[1];
    fp_lnr qx = row[FP_LL_POS] - ox, qy = row[FP_LL_POS + 1] - oy, qz = row[FP_LL_POS + 2] - oz;
    fp_lnr tc = qx * dx + qy * dy + qz * dz;
    fp_lnr rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
    fp_lnr rl = sqrt(rx * rx + ry * ry + rz * rz);
    fp_lnr D = fmax(rl, (fp_real)1e-6 * (1 + fabs(tc)));
    fp_lnr inv = rl > 0 ? -1 / rl : FP_LN(0);
    fp_lnr nx = rx * inv, ny = ry * inv, nz = rz * inv;
    fp_lnr th0 = fp_ln_atan((ta - tc) / D), th1 = fp_ln_atan((tl - tc) / D);
    const fp_real pi = (fp_real)3.14159265358979323846, hp = (fp_real)1.5707963267948966;
    fp_lnr na = nx * row[FP_LL_AXIS] + ny * row[FP_LL_AXIS + 1] + nz * row[FP_LL_AXIS + 2];
    fp_lnr da = dx * row[FP_LL_AXIS] + dy * row[FP_LL_AXIS + 1] + dz * row[FP_LL_AXIS + 2];
    fp_real co = row[FP_LL_COS_OUT], ci = row[FP_LL_COS_IN];
    int type = (int)row[FP_LL_TYPE];
    int spot = type == FP_LIGHT_SPOT;
    int cut = (spot || type == FP_LIGHT_AREA) && co >= 0;
    int inner = spot && (row[FP_LL_PROFILE] == 0 || ci > co);
    fp_lnr R = fmax(sqrt(na * na + da * da), (fp_real)1e-30);
    fp_lnr tha = fp_ln_atan2(da, na);
    tha += 2 * pi * floor(((fp_real)0.5 * (th0 + th1) - tha) / (2 * pi) + (fp_real)0.5);
    fp_lnr ao = fp_ln_acos(fmin(fmax(co / R, (fp_real)-1), (fp_real)1));
    fp_lnr ai = fp_ln_acos(fmin(fmax(ci / R, (fp_real)-1), (fp_real)1));
    fp_lni clip = !((tha - ai <= th0) & (tha + ai >= th1));
    if (!cut || !inner)
        clip = FP_LNI(0);
    fp_lni range = !((tha - ao <= th0) & (tha + ao >= th1));
    if (!cut)
        range = FP_LNI(0);
    fp_lnr c0 = (clip | range) ? fmax(th0, tha - ao) : th0;
    fp_lnr c1 = (clip | range) ? fmax(c0, fmin(th1, tha + ao)) : th1;
    fp_lnr thf = 2 * fp_ln_atan(1 / fmax(sig_c * D, (fp_real)1e-30)) - hp;
    thf = fmin(fmax(thf, c0), c1);
    fp_lnr b1 = fmin(fmax(tha - ai, c0), c1);
    fp_lnr b2 = clip ? fmin(fmax(tha + ai, c0), c1) : thf;
    int peaked = (kind == FP_PHASE_HG || kind == FP_PHASE_CS || kind == FP_PHASE_MIX ||
                  kind == FP_PHASE_MIXHG) && fabs(g) > (fp_real)0.2;
    fp_real sgn = g < 0 && peaked ? (fp_real)-1 : (fp_real)1;
    fp_real k = peaked ? (1 - fabs(g)) / (1 + fabs(g)) : (fp_real)1;
    fp_lnr bp0 = fp_ln_phi((fp_real)0.5 * (hp + sgn * c0), k);
    fp_lnr bp1 = fp_ln_phi((fp_real)0.5 * (hp + sgn * b1), k);
    fp_lnr bp2 = fp_ln_phi((fp_real)0.5 * (hp + sgn * b2), k);
    fp_lnr bp3 = fp_ln_phi((fp_real)0.5 * (hp + sgn * c1), k);
    fp_lnr lam = (bp2 - bp0) / (bp3 - bp0);
    lam = ((lam >= (fp_real)1 / 3) & (lam <= 1)) ? lam : FP_LN((fp_real)1 / 3);
    fp_lnr pf = bp0 + lam * (bp3 - bp0);
    bp1 = clip ? bp1 : (fp_real)0.5 * (bp0 + pf);
    bp2 = clip ? bp2 : pf;
    fp_lni up = bp3 >= bp0;
    fp_lnr a0 = up ? bp0 : bp3, a1 = up ? bp1 : bp2, a2 = up ? bp2 : bp1, a3 = up ? bp3 : bp0;
    fp_lnr yl = oy - fp[FP_F_OFF + 1];
    fp_lnr tk = (fp[FP_F_Y0] - yl) / (fabs(dy) > (fp_real)1e-30 ? dy : FP_LN((fp_real)1e-30));
    fp_lnr thk = fp_ln_atan((tk - tc) / D);
    fp_lnr xk = fp_ln_phi((fp_real)0.5 * (hp + sgn * fmin(fmax(thk, th0), th1)), k);
    fp_lni kink = (fabs(dy) > (fp_real)1e-30) & (thk > th0) & (thk < th1) & (xk > a0) & (xk < a3);
    if (!(fp[FP_F_SIGMA] > 0))
        kink = FP_LNI(0);
    fp_lnr w0 = a1 - a0, w1 = a2 - a1, w2 = a3 - a2;
    fp_lnr xw = ((w0 >= w1) & (w0 >= w2)) ? (fp_real)0.5 * (a0 + a1)
              : w1 >= w2 ? (fp_real)0.5 * (a1 + a2) : (fp_real)0.5 * (a2 + a3);
    fp_lnr x = kink ? xk : xw;
    fp_lnr pe[5] = { fmin(a0, x), fmin(a1, fmax(a0, x)), fmin(a2, fmax(a1, x)),
                     fmin(a3, fmax(a2, x)), fmax(a3, x) };
    /* Fog without a box: the nodes' optical depths from the heights of
     * their ends (light_band_lanes.h). */
    int plain = 1;
    for (int i = 0; i < 6; i++)
        plain &= isinf(fp[FP_F_BOX + i]) != 0;
    int main_on = fp[FP_F_SIGMA] > 0, haze_on = fp[FP_F_HAZE] > 0;
    fp_real yoff = fp[FP_F_OFF + 1];
    fp_ln_band_t bm = { 0 }, bh = { 0 };
    if (plain && main_on)
        fp_ln_band_init(&bm, fp[FP_F_SIGMA], fp[FP_F_Y0], fp[FP_F_H], fp[FP_F_TOP], oy - yoff, dy,
                        row[FP_LL_POS + 1] - yoff);
    if (plain && haze_on)
        fp_ln_band_init(&bh, fp[FP_F_HAZE], fp[FP_F_HAZE + 1], fp[FP_F_HAZE + 2],
                        fp[FP_F_HAZE + 3], oy, dy, row[FP_LL_POS + 1]);
    fp_lnr acc = FP_LN(0);
    for (int piece = 0; piece < 4; piece++) {
        fp_lnr pa = pe[piece], pw = pe[piece + 1] - pe[piece];
        for (int q = 0; q < FP_LIGHT_NODES; q++) {
            fp_lnr phi = pa + pw * fp_gl_x[FP_GL_FIRST(FP_LIGHT_NODES) + q];
            fp_lnr sp, cp;
            fp_ln_sincos(phi, &sp, &cp);
            /* den = 1 / (cp^2 + ks^2) and 1 / c = (cp^2 + ks^2) / (2 ks cp)
             * from one division. */
            fp_lnr ks = k * sp, qq = cp * cp + ks * ks, m2 = ks * cp;
            fp_lnr iv = 1 / (qq * m2);
            fp_lnr den = m2 * iv;
            fp_lnr ce = (cp * cp - ks * ks) * den, se = 2 * m2 * den;
            fp_lnr jac = 2 * k * den;
            fp_lnr s = -sgn * ce, c = se;
            fp_lnr ic = (fp_real)0.5 * qq * qq * iv;
            fp_lnr t = tc + D * s * ic, r = D * ic;
            fp_lnr px = ox + t * dx, py = oy + t * dy, pz = oz + t * dz;
            fp_lnr ux = c * nx + s * dx, uy = c * ny + s * dy, uz = c * nz + s * dz;
            fp_lnr cone = FP_LN(1);
            if (type != FP_LIGHT_POINT || row[FP_LL_RADIUS] > 0)
                cone = fp_ln_gain(row, type, c * na + s * da, ux, uy, uz, r);
            fp_lnr sig, od;
            if (plain) {
                fp_ln_band_node(&bm, main_on, &bh, haze_on, t, py - yoff, py, uy, r, &sig, &od);
            } else {
                sig = fp_ln_plain_sigma(fp, px, py, pz);
                od = fp_ln_plain_od(fp, ox, oy, oz, dx, dy, dz, t) +
                     fp_ln_plain_od(fp, px, py, pz, -ux, -uy, -uz, r);
            }
            fp_lnr f = sig * exp(-od) * cone * fp_ln_phase(kind, g, ph[2], -s) * jac;
            fp_lni keep = (f > 0) & (t >= ta) & (t <= tl);
            acc += fp_gl_w[FP_GL_FIRST(FP_LIGHT_NODES) + q] * pw * (keep ? f : FP_LN(0));
        }
    }
    return acc * lt[FP_LT_ALBEDO] / D;
}

/* fp_light_ray on lanes: light k's in-scatter along the view rays
 * o + t d, t in [0, len] (len finite or infinite): S (3). */
FP_LN_FN void fp_ln_light_ray(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt,
                              FP_GLOBAL const fp_real *lights, int k, fp_lnr ox, fp_lnr oy,
                              fp_lnr oz, fp_lnr dx, fp_lnr dy, fp_lnr dz, fp_lnr len, fp_lnr *S)
{
    FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
    fp_lnr ta, tb;
    fp_ln_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb);
    fp_lni any = tb > ta;
    ta = any ? ta : FP_LN(0);
    tb = any ? tb : FP_LN(0);
    /* fp_light_sig_c: the extinction at the point of [ta, tb] nearest the
     * light. */
    fp_lnr tc = (row[FP_LL_POS] - ox) * dx + (row[FP_LL_POS + 1] - oy) * dy +
                (row[FP_LL_POS + 2] - oz) * dz;
    tc = fmin(fmax(tc, ta), tb);
    fp_lnr sig_c = fp_ln_plain_sigma(fp, ox + tc * dx, oy + tc * dy, oz + tc * dz);
    fp_lnr acc = fp_ln_fast(fp, lt, row, sig_c, ox, oy, oz, dx, dy, dz, ta, tb);
    acc = any ? acc : FP_LN(0);
    for (int c = 0; c < 3; c++)
        S[c] = acc * row[FP_LL_I + c];
}

#endif
