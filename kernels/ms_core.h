/* fogpipe: the fast multiple-scattering path (issue 28), shared by the
 * OpenCL kernel (scatter.cl, float) and the C reference (filters/scatter.c,
 * double).  Include after fog_core.h and light_core.h.
 *
 * The sun in a height-profiled fog is a plane-parallel problem: the light
 * scattered once or more (the diffuse field) has a mean radiance
 *   J_ms(y) = (1 / 4 pi) int L_diffuse(y, w) dw
 * that depends on the height alone.  filters/ms.c solves for it once per
 * frame (the slab's integral equation in optical depth, exact for an
 * isotropic phase function; Henyey-Greenstein through the similarity
 * relation sigma_s' = sigma_s (1 - g)) and stores it per unit sun
 * irradiance on a uniform height grid in the light parameters
 * (FP_LT_MS_*).  Along each view ray the multiply scattered light is then
 *   S_ms = albedo int tau(O,u) sigma_t(u) E_sun J_ms(y(u)) du,
 * the same integral as the single-scattered light's with J_ms for J, over
 * FP_MS_SEGMENTS segments of exact optical depth with J_ms linear in each
 * (the closed form of scatter_core.h).  J_ms is isotropic (the diffuse
 * field's mean), so the view ray's phase function does not enter. */
#ifndef FP_MS_CORE_H
#define FP_MS_CORE_H

/* Layout in the light parameters (after light_core.h's own). */
#define FP_LT_MS_ON (FP_LT_MS + 0)   /* 1: add S_ms */
#define FP_LT_MS_YB (FP_LT_MS + 1)   /* fog-space height of the table's first node */
#define FP_LT_MS_DY (FP_LT_MS + 2)   /* spacing of the nodes */
#define FP_LT_MS_J (FP_LT_MS + 3)    /* FP_MS_NODES: J_ms per unit sun irradiance */
#define FP_MS_NODES 64
/* The casters: the sunlit share of the fog that feeds a point's diffuse
 * light, on a grid over the fog box (fog-local x, z; fog-space y), by
 * which J_ms is scaled (1 without a shadow map or a box).  Node (i, j, k)
 * (x, y, z) is FP_LT_MS_V + (k GY + j) GX + i. */
#define FP_LT_MS_GON (FP_LT_MS + 3 + FP_MS_NODES)  /* 1: the grid is used */
#define FP_LT_MS_G0 (FP_LT_MS_GON + 1)             /* 3: its first node */
#define FP_LT_MS_GD (FP_LT_MS_GON + 4)             /* 3: its spacing */
#define FP_LT_MS_V (FP_LT_MS_GON + 7)
#define FP_MS_GX 10
#define FP_MS_GY 6
#define FP_MS_GZ 10
#define FP_LT_MS_COUNT (3 + FP_MS_NODES + 7 + FP_MS_GX * FP_MS_GY * FP_MS_GZ)
/* Segments of the view ray: J_ms is smooth in height (its scale is the
 * fog's scale height or more), so few are needed. */
#define FP_MS_SEGMENTS 12

/* J_ms at fog-space height y, per unit sun irradiance: linear between the
 * nodes, constant beyond the ends. */
FP_FN fp_real fp_ms_j(FP_CONSTANT const fp_real *lt, fp_real y)
{
    fp_real u = (y - lt[FP_LT_MS_YB]) / lt[FP_LT_MS_DY];
    u = fmin(fmax(u, (fp_real)0), (fp_real)(FP_MS_NODES - 1));
    int i = (int)u;
    i = i > FP_MS_NODES - 2 ? FP_MS_NODES - 2 : i;
    fp_real f = u - (fp_real)i;
    return lt[FP_LT_MS_J + i] + f * (lt[FP_LT_MS_J + i + 1] - lt[FP_LT_MS_J + i]);
}

/* The grid's sunlit share at fog-space (x, y, z): trilinear, held at
 * the grid's faces beyond them. */
FP_FN fp_real fp_ms_vis(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt, fp_real x,
                        fp_real y, fp_real z)
{
    if (lt[FP_LT_MS_GON] == 0)
        return 1;
    fp_real c = fp[FP_F_COS], s = fp[FP_F_SIN];
    fp_real px = x - fp[FP_F_OFF], pz = z - fp[FP_F_OFF + 2];
    fp_real q[3] = { c * px - s * pz, y, s * px + c * pz };
    const int n[3] = { FP_MS_GX, FP_MS_GY, FP_MS_GZ };
    int i0[3];
    fp_real f[3];
    for (int a = 0; a < 3; a++) {
        fp_real u = (q[a] - lt[FP_LT_MS_G0 + a]) / lt[FP_LT_MS_GD + a];
        u = fmin(fmax(u, (fp_real)0), (fp_real)(n[a] - 1));
        int i = (int)u;
        i = i > n[a] - 2 ? n[a] - 2 : i;
        i0[a] = i;
        f[a] = u - (fp_real)i;
    }
    fp_real v = 0;
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++) {
                fp_real w = (i ? f[0] : 1 - f[0]) * (j ? f[1] : 1 - f[1]) *
                            (k ? f[2] : 1 - f[2]);
                v += w * lt[FP_LT_MS_V + ((i0[2] + k) * FP_MS_GY + i0[1] + j) * FP_MS_GX +
                            i0[0] + i];
            }
    return v;
}

/* S += the multiply scattered light along o + t d over the fog's stretch
 * [ta, tb] (tb may be infinite), od_total the ray's whole optical depth.
 * An unbounded stretch ends where the optical depth from ta reaches
 * FP_LT_OD_STOP or all but 1e-4 of od_total (doubling from 1 / sigma). */
FP_FN void fp_ms_ray(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                     FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                     FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                     fp_real ox, fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz,
                     fp_real ta, fp_real tb, fp_real od_total, fp_real *S)
{
    if (lt[FP_LT_MS_ON] == 0 || !(od_total > 0) || !(tb > ta))
        return;
    fp_real od = ta > 0 ? fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, ta, 0) : 0;
    if (!isfinite(tb)) {
        fp_real step = fmax((fp_real)1 / fmax(fp[FP_F_SIGMA] + fp[FP_F_HAZE], (fp_real)1e-12),
                            (fp_real)1e-3);
        for (int k = 0; k < 80 && step < fp[FP_F_CAP]; k++) {
            fp_real x = fp_fog_od(fp, lvi, lvf, coef, occ, ox + ta * dx, oy + ta * dy,
                                  oz + ta * dz, dx, dy, dz, step, 0);
            if (x >= lt[FP_LT_OD_STOP] || od + x >= od_total - (fp_real)1e-4 * od_total)
                break;
            step *= 2;
        }
        tb = ta + fmin(step, fp[FP_F_CAP]);
    }
    fp_real h = (tb - ta) / FP_MS_SEGMENTS, acc = 0;
    fp_real ja = fp_ms_j(lt, oy + ta * dy) * fp_ms_vis(fp, lt, ox + ta * dx, oy + ta * dy, oz + ta * dz);
    for (int i = 0; i < FP_MS_SEGMENTS; i++) {
        fp_real t0 = ta + h * (fp_real)i;
        fp_real t1 = i + 1 == FP_MS_SEGMENTS ? tb : t0 + h;
        fp_real x = fp_fog_od(fp, lvi, lvf, coef, occ, ox + t0 * dx, oy + t0 * dy, oz + t0 * dz,
                              dx, dy, dz, t1 - t0, 0);
        fp_real jb = fp_ms_j(lt, oy + t1 * dy) *
                     fp_ms_vis(fp, lt, ox + t1 * dx, oy + t1 * dy, oz + t1 * dz);
        fp_real c0 = -expm1(-x), c1 = x > 0 ? fp_expm1_ratio(x) - exp(-x) : (fp_real)0;
        acc += exp(-od) * (ja * c0 + (jb - ja) * c1);
        od += x;
        ja = jb;
    }
    /* Beyond tb (an unbounded ray's last 1e-4): the last point's J_ms. */
    acc += ja * fmax(exp(-od) - exp(-od_total), (fp_real)0);
    acc *= lt[FP_LT_ALBEDO];
    for (int c = 0; c < 3; c++)
        S[c] += acc * lt[FP_LT_SUN_E + c];
}

#endif
