# tests/blender_light.sh: the lights fogpipe reads from a plate's rig
# (`fogpipe --print-camera`) are Blender's (tests/blender/light_truth.py's
# flags for the same frame).  Input, in this order:
#   flags F OPTIONS...        light_truth.py's line: --sun D --sun-color C
#                             --sun-intensity E, --light point:P:I:1,
#                             --light spot:P:I:1:A:INNER,OUTER
#   fogpipe's --print-camera lines (rig, sun toward ..., light K
#                             sun/point/spot ...).
# Every truth light must be matched, in order per kind, by one light of the
# rig with the same kind, position, direction (1e-4), intensity or
# irradiance (relative 1e-4) and cone (0.01 degree); the rig's up axis z
# and clip start CLIP (set with -v clip=); the rig's light count the
# truth's.  Prints one line per light and exits 1 on any difference.
function abs(x) { return x < 0 ? -x : x }
function near(a, b, tol) { return abs(a - b) <= tol * (abs(b) > 1 ? abs(b) : 1) }
function acos(c) { return atan2(sqrt(1 - c * c), c) }
function vec3(s, v,   n, p) { n = split(s, p, ","); v[1] = p[1]; v[2] = p[2]; v[3] = p[3]; return n }
function unit(v,   n) { n = sqrt(v[1] * v[1] + v[2] * v[2] + v[3] * v[3]); v[1] /= n; v[2] /= n; v[3] /= n }
BEGIN { pi = atan2(0, -1); bad = 0 }
$1 == "flags" {
    for (i = 3; i <= NF; i++) {
        if ($i == "--sun") { vec3($(++i), d); unit(d); nt++; tk[nt] = "sun"
            for (c = 1; c <= 3; c++) tdir[nt, c] = d[c] }
        else if ($i == "--sun-color") { vec3($(++i), col) }
        else if ($i == "--sun-intensity") { e = $(++i)
            for (c = 1; c <= 3; c++) tval[nt, c] = col[c] * e }
        else if ($i == "--light") {
            split($(++i), s, ":"); nt++; tk[nt] = s[1]
            vec3(s[2], p); vec3(s[3], I)
            for (c = 1; c <= 3; c++) { tpos[nt, c] = p[c]; tval[nt, c] = I[c] }
            if (s[1] == "spot") {
                vec3(s[5], d); unit(d); split(s[6], cone, ",")
                for (c = 1; c <= 3; c++) tdir[nt, c] = d[c]
                tin[nt] = cone[1]; tout[nt] = cone[2]
            }
        }
    }
    next
}
/^ *rig / {
    line = $0; gsub(/,/, "", line); split(line, w, " ")
    # rig up z (rig) clip start 0.1 (rig) lights from the frame
    rigline = 1
    if (w[3] != "z" || w[4] != "(rig)") { print "MISS rig: up " w[3] " " w[4] ", Blender z (rig)"; bad = 1 }
    if (!near(w[7], clip, 1e-6) || w[8] != "(rig)") {
        print "MISS rig: clip start " w[7] " " w[8] ", Blender " clip " (rig)"; bad = 1 }
    next
}
# The rig's first sun, shown as --sun would be.
/^ *sun +toward / {
    line = $0; gsub(/,/, "", line); split(line, w, " ")
    nr++; rk[nr] = "sun"
    for (c = 1; c <= 3; c++) { rdir[nr, c] = w[2 + c]; rval[nr, c] = w[6 + c] }
    next
}
/^ *light +[0-9]+ / {
    line = $0; gsub(/,/, "", line); n = split(line, w, " ")
    nr++; rk[nr] = w[3]
    if (w[3] == "sun") { for (c = 1; c <= 3; c++) { rdir[nr, c] = w[4 + c]; rval[nr, c] = w[8 + c] } }
    else {
        for (c = 1; c <= 3; c++) { rpos[nr, c] = w[4 + c]; rval[nr, c] = w[8 + c] }
        if (w[3] == "spot") {
            for (c = 1; c <= 3; c++) rdir[nr, c] = w[15 + c]
            size = w[20]; blend = w[23]
            rout[nr] = size / 2
            co = cos(rout[nr] * pi / 180)
            ci = co + (1 - co) * blend; if (ci > 1) ci = 1
            rin[nr] = acos(ci) * 180 / pi
        }
    }
    next
}
END {
    if (!rigline) { print "MISS no rig line in --print-camera's output"; bad = 1 }
    if (nr != nt) { print "MISS the rig has " nr " lights, Blender " nt; bad = 1 }
    for (k = 1; k <= nt; k++) {
        # The k-th truth light of its kind against the k-th rig light of it.
        m = 0; seen = 0
        for (j = 1; j <= k; j++) if (tk[j] == tk[k]) seen++
        for (j = 1; j <= nr && !m; j++) if (rk[j] == tk[k] && ++cnt[k] == seen) m = j
        if (!m) { print "MISS " tk[k] ": not in the rig"; bad = 1; continue }
        ok = 1; msg = tk[k] ":"
        if (tk[k] != "sun") {
            msg = msg sprintf(" at %g %g %g (Blender %g %g %g)", rpos[m, 1], rpos[m, 2], rpos[m, 3],
                              tpos[k, 1], tpos[k, 2], tpos[k, 3])
            for (c = 1; c <= 3; c++) if (!near(rpos[m, c], tpos[k, c], 1e-4)) ok = 0
        }
        if (tk[k] != "point") {
            msg = msg sprintf(" toward %g %g %g (Blender %g %g %g)", rdir[m, 1], rdir[m, 2], rdir[m, 3],
                              tdir[k, 1], tdir[k, 2], tdir[k, 3])
            for (c = 1; c <= 3; c++) if (!near(rdir[m, c], tdir[k, c], 1e-4)) ok = 0
        }
        msg = msg sprintf(" %s %g %g %g (Blender %g %g %g)", tk[k] == "sun" ? "irradiance" : "intensity",
                          rval[m, 1], rval[m, 2], rval[m, 3], tval[k, 1], tval[k, 2], tval[k, 3])
        for (c = 1; c <= 3; c++) if (abs(rval[m, c] - tval[k, c]) > 1e-4 * abs(tval[k, c]) + 1e-9) ok = 0
        if (tk[k] == "spot") {
            msg = msg sprintf(" cone %.4g..%.4g deg (Blender %.4g..%.4g)", rin[m], rout[m], tin[k], tout[k])
            if (abs(rin[m] - tin[k]) > 0.01 || abs(rout[m] - tout[k]) > 0.01) ok = 0
        }
        print (ok ? "" : "MISS ") msg
        if (!ok) bad = 1
    }
    exit bad
}
