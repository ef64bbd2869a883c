# tests/blender.sh: compares what fogpipe understood with Blender's truth
# (tests/blender/truth.py).  Inputs, in this order:
#   mode=camera: the truth files, then `fogpipe --print-camera` output;
#   mode=pixels: the truth files, then lines "depth FRAME X Y VALUE" and
#     "tau FRAME X Y VALUE" (the render's depth and fogpipe's
#     transmittance.R at the truth's pixels), with sigma and H set (the fog
#     was --density sigma --height 0,H, up z: density sigma*exp(-z/H)).
# Prints one line per comparison and the worst errors; exits 1 on a miss.
function abs(x) { return x < 0 ? -x : x }
function miss(msg) { print "MISS " msg; bad = 1 }
# Optical depth of the exponential fog along a straight line of length L
# from height hc to height hq (both >= 0).
function od(hc, hq, L) {
    if (hq < 0) hq = 0
    if (abs(hc - hq) < 1e-6) return sigma * L * exp(-hc / H)
    return sigma * L * H / (hc - hq) * (exp(-hq / H) - exp(-hc / H))
}
$1 == "camera" && NF == 16 {
    f = $2; cam[f] = 1
    for (i = 3; i <= 16; i++) want[f, i] = $i
    next
}
$1 == "pixel" { key = $2 " " $3 " " $4; depth[key] = $5; hc[key] = $6; hq[key] = $7; len[key] = $8; label[key] = $9; next }
# --print-camera output
/: frame [0-9]+: camera / { match($0, /: frame [0-9]+:/); pf = substr($0, RSTART + 8, RLENGTH - 9) + 0; seen[pf] = 1; next }
$1 == "position" { got[pf, 3] = $2; got[pf, 4] = $3; got[pf, 5] = $4; next }
$1 == "forward" { got[pf, 6] = $2; got[pf, 7] = $3; got[pf, 8] = $4; next }
$1 == "up" { got[pf, 9] = $2; got[pf, 10] = $3; got[pf, 11] = $4; next }
$1 == "right" { got[pf, 12] = $2; got[pf, 13] = $3; got[pf, 14] = $4; next }
$1 == "vfov" { got[pf, 15] = $2; got[pf, 16] = $5; next }
$1 == "orthographic" { got[pf, 15] = 0; got[pf, 16] = 0; next }
$1 == "depth" || $1 == "tau" { key = $2 " " $3 " " $4; val[$1, key] = $5; next }
END {
    if (mode == "camera") {
        n = 0
        for (f in cam) {
            n++
            if (!(f in seen)) { miss("frame " f ": --print-camera printed no camera"); continue }
            for (i = 3; i <= 16; i++) {
                e = abs(got[f, i] - want[f, i])
                tol = i <= 5 ? 1e-4 * (1 + abs(want[f, i])) : i <= 14 ? 5e-5 : 2e-3
                kind = i <= 5 ? "position" : i <= 14 ? "direction" : "fov"
                if (e > worst[kind]) worst[kind] = e
                if (!(e <= tol))
                    miss("frame " f ": " kind " component " i - 2 ": fogpipe " got[f, i] ", Blender " want[f, i])
            }
        }
        if (n == 0) miss("no truth")
        printf "camera: %d frames, worst |error|: position %.3g, direction %.3g, fov %.3g deg\n",
               n, worst["position"], worst["direction"], worst["fov"]
    } else {
        n = 0
        for (key in depth) {
            n++
            if (!(("depth", key) in val) || !(("tau", key) in val)) { miss(key ": no value read"); continue }
            ed = abs(val["depth", key] - depth[key]) / depth[key]
            want_tau = exp(-od(hc[key], hq[key], len[key]))
            et = abs(val["tau", key] - want_tau)
            if (ed > wd) wd = ed
            if (et > wt) wt = et
            printf "frame/pixel %s (%s): depth %.6g (Blender %.6g), transmittance %.6f (exact %.6f)\n",
                   key, label[key], val["depth", key], depth[key], val["tau", key], want_tau
            if (!(ed <= 1e-3)) miss(key " " label[key] ": the render's depth is not Blender's at this pixel")
            if (!(et <= 1e-3)) miss(key " " label[key] ": transmittance " val["tau", key] ", exact " want_tau)
        }
        if (n == 0) miss("no truth")
        printf "pixels: %d, worst relative depth error %.3g, worst transmittance error %.3g\n", n, wd, wt
    }
    exit bad
}
