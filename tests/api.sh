#!/bin/sh
# libfogpipe as hosts use it: installed with its header and pkg-config file,
# a C program built with nothing but `pkg-config --cflags --libs fogpipe`
# fogs a frame in memory and gets the command line's pixels; the Python
# module gives the same pixels, and raises on bad arrays and options; the
# layers show (the program includes only the public header).
. "${FP_SRCDIR:-.}/tests/lib.sh"
PY=${PYTHON3:-python3}
S=$FP_SAMPLES
IN="$S/scene.0003.exr"
OPTS="--density 0.05 --height 0,4 --fog-color 0.7,0.72,0.75"

check "the program includes only fogpipe.h (and system headers)" sh -c '
  ! grep -h "^#include \"" "$1"/cli/*.c | grep -v "^#include \"fogpipe.h\"$"' sh "$FP_SRCDIR"
check "nothing in the library includes the program or the Python module" sh -c '
  ! grep -rlE "#include \"(cli/|\.\./cli|python)" "$1/src" "$1/filters" "$1/kernels" "$1/lib"' sh "$FP_SRCDIR"

"$FP_BUILDDIR/tests/frame_raw" dump "$IN" "$T/frame.bin"
# shellcheck disable=SC2086
"$FOGPIPE" --float $OPTS -i "$IN" -o "$T/cli.exr"

D="$T/dest"
if env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$FP_BUILDDIR" install DESTDIR="$D" prefix=/opt/fp >"$T/install.txt" 2>&1; then
  ok "make install DESTDIR"
  check "installed: libfogpipe.so.0, libfogpipe.a, fogpipe.h, fogpipe.pc, the Python module" sh -c '
    test -f "$1/opt/fp/lib/libfogpipe.so.0" -a -f "$1/opt/fp/lib/libfogpipe.a" -a \
      -f "$1/opt/fp/include/fogpipe.h" -a -f "$1/opt/fp/lib/pkgconfig/fogpipe.pc" &&
    ls "$1"/opt/fp/lib/python3*/dist-packages/fogpipe/__init__.py &&
    grep -q "/opt/fp/lib/libfogpipe.so.0" "$1"/opt/fp/lib/python3*/dist-packages/fogpipe/_config.py' sh "$D"
  check "fogpipe.pc says prefix=/opt/fp (DESTDIR is not in it)" grep -q "^prefix=/opt/fp$" "$D/opt/fp/lib/pkgconfig/fogpipe.pc"
  check "only fogpipe_* is exported, under FOGPIPE_0" sh -c '
    nm -D --defined-only "$1/opt/fp/lib/libfogpipe.so.0" | awk "\$2 == \"T\" {print \$3}" > "$2/syms.txt" &&
    test -s "$2/syms.txt" && ! grep -v "^fogpipe_.*@@FOGPIPE_0$" "$2/syms.txt"' sh "$D" "$T"
  PC="env PKG_CONFIG_PATH=$D/opt/fp/lib/pkgconfig pkg-config --define-variable=prefix=$D/opt/fp"
  if check "a C host builds with only pkg-config --cflags --libs fogpipe" sh -c "
      cc -o '$T/api_demo' '$FP_SRCDIR/tests/api_demo.c' \$($PC --cflags --libs fogpipe)"; then
    check "the C host's frame from memory = the command line's pixels (max |d| <= 1e-5)" sh -c '
      LD_LIBRARY_PATH="$1/opt/fp/lib" "$2/api_demo" "$2/frame.bin" "$2/c.bin" \
        density=0.05 height=0,4 fog-color=0.7,0.72,0.75 &&
      "$3/tests/frame_raw" compare "$2/c.bin" "$2/cli.exr" 1e-5' sh "$D" "$T" "$FP_BUILDDIR"
    check "the C host gets the library's message, exit 2, for a bad option" sh -c '
      ! LD_LIBRARY_PATH="$1/opt/fp/lib" "$2/api_demo" "$2/frame.bin" "$2/bad.bin" density=-3 2> "$2/bad.txt" &&
      grep -q "api_demo: api_demo: --density: -3 is out of range" "$2/bad.txt" && ! test -e "$2/bad.bin"' sh "$D" "$T"
  fi
  if "$PY" -c "import numpy" 2>/dev/null; then
    check "the installed Python module loads the installed library" sh -c '
      cd / && PYTHONPATH=$(echo "$1"/opt/fp/lib/python3*/dist-packages) \
        FOGPIPE_LIBRARY="$1/opt/fp/lib/libfogpipe.so.0" "$2" -c "import fogpipe; print(fogpipe.version())"' sh "$D" "$PY"
    # The library loads the OpenImageIO module installed beside it.
    "$OIIOTOOL" --pattern constant:color=0.5 32x32 1 -d uint8 -o "$T/fm.png"
    check "the installed library reads a PNG fogmap through lib/fogpipe/fogpipe_oiio.so" sh -c '
      cd / && test -f "$1/opt/fp/lib/fogpipe/fogpipe_oiio.so" &&
      PYTHONPATH=$(echo "$1"/opt/fp/lib/python3*/dist-packages) FOGPIPE_LIBRARY="$1/opt/fp/lib/libfogpipe.so.0" \
        "$2" -c "import sys, fogpipe; fogpipe.apply_file(sys.argv[1], sys.argv[2], fogmap=sys.argv[3], quiet=True)" \
        "$3" "$4/py-fm.exr" "$4/fm.png" && test -s "$4/py-fm.exr"' sh "$D" "$PY" "$IN" "$T"
  else
    skip "python3 with numpy"
  fi
else
  not_ok "make install DESTDIR"; diag "$T/install.txt" 2>/dev/null || true
fi

if "$PY" -c "import numpy" 2>/dev/null; then
  PYTHONPATH="$FP_SRCDIR/python" FOGPIPE_LIBRARY="$FP_BUILDDIR/.libs/libfogpipe.so.0" \
    "$PY" "$FP_SRCDIR/tests/test_python.py" "$T/frame.bin" "$T" > "$T/py.tap" 2>&1
  while IFS= read -r line; do
    case $line in
      "ok "*) ok "python: ${line#ok * - }" ;;
      "not ok "*) not_ok "python: ${line#not ok * - }" ;;
    esac
  done < "$T/py.tap"
  grep -q "^1\.\." "$T/py.tap" || { not_ok "python: the test ran to its end"; diag "$T/py.tap"; }
  grep "^#" "$T/py.tap" || true
  sed -n '/<!-- example:python -->/,/<!-- example:end -->/p' "$FP_SRCDIR/doc/library.md" |
    sed '1d;$d; s/^    //' > "$T/readme_example.py"
  check "the manual's Python example runs (doc/library.md)" sh -c '
    PYTHONPATH="$1/python" FOGPIPE_LIBRARY="$2/.libs/libfogpipe.so.0" "$3" "$4" > "$5" &&
    grep -Eq "^\(270, 480, 4\) 0\.[0-9]+" "$5"' sh "$FP_SRCDIR" "$FP_BUILDDIR" "$PY" \
    "$T/readme_example.py" "$T/readme_example.txt"
  check "fogpipe.apply = the command line's pixels (max |d| <= 1e-5, same device)" \
    "$FP_BUILDDIR/tests/frame_raw" compare "$T/py.bin" "$T/cli.exr" 1e-5
else
  skip "python3 with numpy (python3-numpy)"
fi
finish
