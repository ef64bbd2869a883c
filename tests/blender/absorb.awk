# tests/blender.sh: Cycles' own fog (a homogeneous absorbing world volume,
# tests/blender/absorb.py) against fogpipe's fog of the plate.  Input: the
# lines of `oiiotool --dumpdata` of the plate (R G B A Z), of Cycles' fogged
# render and of fogpipe's composite (R G B ...), each file's lines prefixed
# by its name: "plate|cycles|fogpipe Pixel (X, Y): R G B ...".  With tol
# set: fails when a channel of a pixel differs by more than tol between
# Cycles and fogpipe (absolute, scene-linear; the plate's values are at
# most 0.9), and prints the worst and mean errors, and the worst error of
# the transmittance (the fogged value over the plate's) over the pixels of
# geometry.
function abs(x) { return x < 0 ? -x : x }
{
    sub(/Pixel \(/, ""); sub(/,/, ""); sub(/\):/, "")
    # $1 name, $2 x, $3 y, $4.. channels
    key = $2 " " $3
    for (c = 0; c < 3; c++) v[$1, key, c] = $(4 + c)
    if ($1 == "plate") { z[key] = $8; keys[key] = 1 }
    else seen[$1, key] = 1
}
END {
    n = geo = 0; worst = sum = wt = 0; bad = 0
    for (key in keys) {
        n++
        if (!(("cycles", key) in seen) || !(("fogpipe", key) in seen)) {
            print "MISS pixel " key ": not in every image"; bad = 1; continue
        }
        if (z[key] < 1e9) geo++
        for (c = 0; c < 3; c++) {
            e = abs(v["cycles", key, c] - v["fogpipe", key, c])
            sum += e
            if (e > worst) { worst = e; wkey = key; wc = c }
            p = v["plate", key, c]
            if (p > 0.1) {
                et = abs(v["cycles", key, c] - v["fogpipe", key, c]) / p
                if (et > wt) wt = et
            }
            if (!(e <= tol)) {
                if (nbad++ < 5)
                    printf "MISS pixel %s channel %d: Cycles %.6g, fogpipe %.6g, plate %.6g, depth %.6g\n",
                           key, c, v["cycles", key, c], v["fogpipe", key, c], p, z[key]
                bad = 1
            }
        }
    }
    if (n == 0) { print "MISS no pixels"; bad = 1 }
    printf "absorb: %d pixels (%d of geometry): |Cycles - fogpipe| max %.3g (pixel %s channel %d), mean %.3g; transmittance max error %.3g; tolerance %g\n",
           n, geo, worst, wkey, wc, n ? sum / (3 * n) : 0, wt, tol
    exit bad
}
