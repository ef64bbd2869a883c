#!/bin/sh
# The manual page fogpipe(1), generated from the option tables (through
# `fogpipe --help-markdown`, the table the README's option reference is), so
# that it cannot drift from the program:
#   tools/gen-man.sh ./fogpipe > fogpipe.1
set -eu
bin=$1
version=$("$bin" --version | sed -n '1s/^fogpipe //p')
[ -n "$version" ] || { echo "gen-man.sh: $bin --version printed no version" >&2; exit 1; }
opts=$(mktemp)
trap 'rm -f "$opts"' EXIT
"$bin" --help-markdown > "$opts"

# roff: backslashes as \e, every '-' a minus (so options copy and paste),
# a leading '.' or "'" guarded.
cat <<EOF
.TH FOGPIPE 1 "" "fogpipe $version" "User Commands"
.SH NAME
fogpipe \\- add physically based fog to color + depth OpenEXR frames
.SH SYNOPSIS
.B fogpipe
\\fB\\-i\\fR \\fIINPUT\\fR \\fB\\-o\\fR \\fIOUTPUT\\fR
[\\fB\\-\\-frames\\fR \\fILIST\\fR] [\\fIoptions\\fR]
.br
.B fogpipe
[\\fIoptions\\fR] < \\fIin.exr\\fR > \\fIout.exr\\fR
.SH DESCRIPTION
.B fogpipe
reads rendered color + depth OpenEXR frames (a file, a sequence such as
\\fIshot.####.exr\\fR or \\fIshot.%04d.exr\\fR, or \\fB\\-\\fR for a stream of
concatenated EXR files on stdin), adds heterogeneous fog integrated exactly
along each view ray (OpenCL, or the C reference with \\fB\\-\\-cpu\\fR), and
writes the composited frames (a file, a sequence, or a stream on stdout).
A frame depends only on its number and its inputs, so a sequence split across
processes or farm nodes gives the same bytes as one run.
.PP
Options are also read from preset files (\\fB\\-\\-preset\\fR): one
\\fIname\\fR = \\fIvalue\\fR line per option, without the leading dashes; the
command line wins over a preset. Short options may be bundled
(\\fB\\-qv\\fR); an option that takes a value ends the bundle.
.SH OPTIONS
EOF

awk '
function roff(s) {
  gsub(/\\/, "\\e", s)
  gsub(/-/, "\\-", s)
  sub(/^[.'"'"']/, "\\\\\\&&", s)
  return s
}
/^### / { sub(/^### /, ""); print ".SS " roff($0); next }
/^\| `/ {
  line = $0
  gsub(/\\\|/, "\001", line)          # a "|" inside a cell
  n = split(line, c, / \| /)
  opt = c[1]; sub(/^\| `/, "", opt); sub(/`$/, "", opt)
  def = c[2]; range = c[3]; help = c[4]; sub(/ \|$/, "", help)
  for (k = 5; k <= n; k++) help = help " | " c[k]
  gsub(/\001/, "|", opt); gsub(/\001/, "|", def); gsub(/\001/, "|", range); gsub(/\001/, "|", help)
  # The option names bold, the value italic.
  sp = index(opt, " ")
  if (opt ~ /^-[A-Za-z], /) {
    rest = substr(opt, 5); sp = index(rest, " ")
    names = substr(opt, 1, 4) (sp ? substr(rest, 1, sp - 1) : rest)
    value = sp ? substr(rest, sp + 1) : ""
  } else {
    names = sp ? substr(opt, 1, sp - 1) : opt
    value = sp ? substr(opt, sp + 1) : ""
  }
  print ".TP"
  if (value != "") print "\\fB" roff(names) "\\fR \\fI" roff(value) "\\fR"
  else print "\\fB" roff(names) "\\fR"
  print roff(help)
  # As --help gives them.
  extra = ""
  if (def != "-" && def != "off") extra = "[default: " def "]"
  if (range != "-" && range != value) extra = extra (extra != "" ? " " : "") "[range: " range "]"
  if (extra != "") print roff(extra)
  next
}' "$opts"

cat <<'EOF'
.SH ENVIRONMENT
.TP
.B FOGPIPE_DEVICE
the OpenCL device, as \fB\-\-device\fR (which wins).
.TP
.B FOGPIPE_CACHE_DIR
where compiled OpenCL programs are cached (default
\fI$XDG_CACHE_HOME/fogpipe\fR, else \fI~/.cache/fogpipe\fR); \fBoff\fR
disables the cache.
.TP
.B FOGPIPE_PROGRESS
the default of \fB\-\-progress\fR, below presets and the command line.
.TP
.B OCIO
the OpenColorIO config, as \fB\-\-ocio\fR (which wins); without either,
fogpipe's own config.
.TP
.B COLUMNS
the width \fB\-\-help\fR wraps to (else the terminal's, else 80).
.SH FILES
Relative to the installation prefix, found from the program's own location
(so a moved or DESTDIR install works):
.TP
.I share/fogpipe/presets/*.preset
the named looks \fB\-\-preset\fR takes by name.
.TP
.I share/fogpipe/ocio/config.ocio
fogpipe's own OpenColorIO config.
.TP
.I share/fogpipe/farm/
scripts that split a frame range over GNU parallel or a Slurm array.
.TP
.I share/fogpipe/golden/fogpipe-golden-check
a golden-frame check to copy into a CI (see the README's
\(lqGolden-frame tests\(rq).
.TP
.I lib/fogpipe/fogpipe_oiio.so
the OpenImageIO module, loaded for images other than EXR frames.
.SH EXIT STATUS
0 on success; 1 on bad input, an I/O or device error; 2 on a usage error
(unknown option, value out of range); 128 + the signal when stopped by
SIGINT or SIGTERM.
.SH EXAMPLES
Fog a sequence with a named look:
.PP
.RS
.nf
fogpipe \-i shot.####.exr \-o fogged.####.exr \-\-preset morning\-valley\-mist
.fi
.RE
.PP
A stream through a pipe:
.PP
.RS
.nf
cat frame.exr | fogpipe \-\-density 0.05 \-\-height 0,4 > fogged.exr
.fi
.RE
.SH SEE ALSO
.BR idiff (1),
.BR oiiotool (1)
EOF
