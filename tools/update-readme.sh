#!/bin/sh
# Regenerate the option reference (doc/options.md, between its
# options:begin and options:end markers) from the option tables:
#   tools/update-readme.sh ./fogpipe doc/options.md
set -eu
bin=$1 readme=$2
tmp=$(mktemp)
"$bin" --help-markdown > "$tmp.opts"
awk -v opts="$tmp.opts" '
  /<!-- options:begin -->/ { print; while ((getline l < opts) > 0) print l; skip = 1; next }
  /<!-- options:end -->/ { skip = 0 }
  !skip { print }' "$readme" > "$tmp"
mv "$tmp" "$readme"
rm -f "$tmp.opts"
echo "updated the option reference in $readme"
