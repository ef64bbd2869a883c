# tests/blender_light.sh: fogpipe's lit fog of the plate against Cycles' own
# render of the fog (tests/blender/light_scene.py), one frame.  Input: the
# lines of `oiiotool --dumpdata`, each file's lines prefixed by its name:
#   A|B Pixel (X, Y): R G B A           Cycles' in-scattered light, seeds 1, 2
#   T Pixel (X, Y): R G B A             Cycles' plate through the fog (exact)
#   plate Pixel (X, Y): R G B           the plate
#   fp Pixel (X, Y): R G B  tR tG tB    fogpipe's composite and transmittance
#   light NAME X Y                      (tests/blender/light_truth.py: where
#                                        Blender projects a local light)
# and fogpipe's in-scatter (fp - transmittance x plate) per pixel.  With
# frame, maxbias (relative) and maxrms (times the noise) set.  Cycles'
# image is C = T + (A + B) / 2; its noise, per 8x8 block and channel, is
# the block mean of (A - B) / 2 (the same spread as C's own error).
# Prints:
#   frame F: bias B (mean of fogpipe - C over mean of C, all pixels and
#     channels); in-scatter bias (the same on the fog's light alone:
#     fogpipe - its transmittance x plate against (A + B) / 2); the
#     largest |T - fogpipe's transmittance x plate|; block rms of
#     fogpipe - C, Cycles' noise, and their ratio; the worst blocks;
# and fails (exit 1) when |bias| > maxbias or rms > maxrms x noise.  With
# a "light" line: the pixel of fogpipe's brightest in-scatter within 3 px of
# the light must be the light's own pixel or a neighbor (the light is where
# Blender puts it), printed with Cycles' brightest pixel there.
function abs(x) { return x < 0 ? -x : x }
$1 == "light" { lname[++nl] = $2; lx[nl] = $3; ly[nl] = $4; next }
{
    name = $1
    sub(/^[^ ]+ Pixel \(/, ""); sub(/,/, ""); sub(/\):/, "")
    # $1 x, $2 y, $3.. channels
    x = $1; y = $2
    if (x + 1 > W) W = x + 1
    if (y + 1 > H) H = y + 1
    for (c = 0; c < 3; c++) v[name, x, y, c] = $(3 + c)
    if (name == "fp") for (c = 0; c < 3; c++) tau[x, y, c] = $(6 + c)
    seen[name]++
}
END {
    bad = 0
    for (k = 1; k <= 5; k++) {
        nm = k == 1 ? "A" : k == 2 ? "B" : k == 3 ? "plate" : k == 4 ? "T" : "fp"
        if (seen[nm] != W * H || W * H == 0) {
            printf "MISS frame %s: %s: %d pixels of %d x %d\n", frame, nm, seen[nm], W, H
            exit 1
        }
    }
    sf = sc = ssf = ssc = te = 0
    for (x = 0; x < W; x++) for (y = 0; y < H; y++) for (c = 0; c < 3; c++) {
        S = (v["A", x, y, c] + v["B", x, y, c]) / 2
        C = v["T", x, y, c] + S
        F = v["fp", x, y, c]
        tp = tau[x, y, c] * v["plate", x, y, c]
        sf += F; sc += C; ssf += F - tp; ssc += S
        if (abs(tp - v["T", x, y, c]) > te) te = abs(tp - v["T", x, y, c])
    }
    bias = sc > 0 ? (sf - sc) / sc : 1
    sbias = ssc > 0 ? (ssf - ssc) / ssc : 1
    # 8x8 blocks (whole blocks only).
    nb = 0; se = sn = 0
    for (bx = 0; bx + 8 <= W; bx += 8) for (by = 0; by + 8 <= H; by += 8) for (c = 0; c < 3; c++) {
        e = n = m = 0
        for (x = bx; x < bx + 8; x++) for (y = by; y < by + 8; y++) {
            C = v["T", x, y, c] + (v["A", x, y, c] + v["B", x, y, c]) / 2
            e += v["fp", x, y, c] - C
            n += (v["A", x, y, c] - v["B", x, y, c]) / 2
            m += C
        }
        e /= 64; n /= 64; m /= 64
        nb++; se += e * e; sn += n * n
        # The worst three blocks, in units of the frame's noise later.
        for (k = 1; k <= 3; k++) if (!(k in we) || abs(e) > abs(we[k])) {
            for (j = 3; j > k; j--) if ((j - 1) in we) {
                we[j] = we[j - 1]; wm[j] = wm[j - 1]; wb[j] = wb[j - 1]
            }
            we[k] = e; wm[k] = m; wb[k] = bx "," by " ch " c
            break
        }
    }
    rms = sqrt(se / nb); noise = sqrt(sn / nb)
    ratio = noise > 0 ? rms / noise : 1e9
    printf "frame %s: bias %+.2f%% (fogpipe %.5g, Cycles %.5g mean), in-scatter bias %+.2f%%, transmitted plate within %.2g; 8x8 blocks: rms %.3g, Cycles' noise %.3g, ratio %.2f (%d blocks x 3 channels)\n",
           frame, 100 * bias, sf / (3 * W * H), sc / (3 * W * H), 100 * sbias, te, rms, noise, ratio, nb / 3
    for (k = 1; k <= 3; k++) if (k in we)
        printf "frame %s: worst block %d at %s: fogpipe - Cycles %+.3g (%+.1f%% of %.3g, %.1f x noise)\n",
               frame, k, wb[k], we[k], (wm[k] > 0 ? 100 * we[k] / wm[k] : 0), wm[k],
               (noise > 0 ? abs(we[k]) / noise : 0)
    if (!(abs(bias) <= maxbias)) {
        printf "MISS frame %s: |bias| %.2f%% > %.2f%%\n", frame, 100 * abs(bias), 100 * maxbias
        bad = 1
    }
    if (!(ratio <= maxrms)) {
        printf "MISS frame %s: block rms %.2f x Cycles' noise > %.2f\n", frame, ratio, maxrms
        bad = 1
    }
    for (k = 1; k <= nl; k++) {
        bf = bc = -1
        for (x = lx[k] - 3; x <= lx[k] + 3; x++) for (y = ly[k] - 3; y <= ly[k] + 3; y++) {
            if (x < 0 || y < 0 || x >= W || y >= H) continue
            f = c2 = 0
            for (c = 0; c < 3; c++) {
                tp = tau[x, y, c] * v["plate", x, y, c]
                f += v["fp", x, y, c] - tp
                c2 += (v["A", x, y, c] + v["B", x, y, c]) / 2
            }
            if (f > bf) { bf = f; fx = x; fy = y }
            if (c2 > bc) { bc = c2; cx = x; cy = y }
        }
        printf "frame %s: %s light: Blender's pixel %d,%d; fogpipe's brightest %d,%d, Cycles' %d,%d\n",
               frame, lname[k], lx[k], ly[k], fx, fy, cx, cy
        if (abs(fx - lx[k]) > 1 || abs(fy - ly[k]) > 1) {
            printf "MISS frame %s: %s light: fogpipe's brightest fog at %d,%d, not at Blender's %d,%d\n",
                   frame, lname[k], fx, fy, lx[k], ly[k]
            bad = 1
        }
    }
    exit bad
}
