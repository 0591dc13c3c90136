#!/usr/bin/env bash
# corrtex montage: the contact sheet's size follows tiles, columns and gaps;
# a tile is the area average of its image (a flat image stays flat, labels
# off); --max-tiles picks evenly spaced inputs; bad input (a sheet in a
# missing folder too) gives one error line and exit 2 and writes nothing.
source "$(dirname "$0")/lib/common.sh"
c=$corrtex
data="$root/tests/data"
run() { echo "+ $*"; "$@"; }
[[ -x $c ]] || { echo "error: $c not built"; exit 1; }

# png_size FILE: "W H" from the PNG header (IHDR).
png_size() { od -An -tu1 -j16 -N8 "$1" | awk '{ print $1 * 16777216 + $2 * 65536 + $3 * 256 + $4, $5 * 16777216 + $6 * 65536 + $7 * 256 + $8 }'; }

run "$c" montage -q -o "$tmp/a.png" --tile 32 --gap 2 "$data/compare-ref.exr" "$data/compare-test.exr" "$data/compare-ref.exr" \
  || fail "3 tiles: exit $?"
# 3 tiles -> 2 columns (about square), 2 rows: 2*32 + 3*2 = 70 wide, 2*32 + 3*2 = 70 high
[[ $(png_size "$tmp/a.png") == "70 70" ]] || fail "3 tiles of 32 with gap 2: size $(png_size "$tmp/a.png"), want 70 70"
run "$c" montage -q -o "$tmp/b.png" --tile 16 --gap 0 --columns 3 "$data/compare-ref.exr" "$data/compare-ref.exr" "$data/compare-ref.exr" \
  || fail "one row: exit $?"
[[ $(png_size "$tmp/b.png") == "48 16" ]] || fail "3 columns of 16, no gap: size $(png_size "$tmp/b.png"), want 48 16"
# a tile at the image's own size, no gap, no labels: the sheet is the image
run "$c" montage -q -o "$tmp/same.png" --tile 16 --gap 0 --no-labels "$data/compare-ref.exr" || fail "one tile: exit $?"
run "$c" montage -q -o "$tmp/ref16.png" --tile 16 --gap 0 --no-labels "$tmp/same.png" || fail "png input: exit $?"
cmp -s "$tmp/same.png" "$tmp/ref16.png" || fail "a 16x16 tile of a 16x16 PNG is not the PNG itself"
# --max-tiles 2 of 5 inputs: 2 tiles in one row
run "$c" montage -q -o "$tmp/m.png" --tile 16 --gap 1 --max-tiles 2 "$data"/compare-{ref,test,ref,test,ref}.exr || fail "max-tiles: exit $?"
[[ $(png_size "$tmp/m.png") == "35 18" ]] || fail "--max-tiles 2: size $(png_size "$tmp/m.png"), want 35 18"

bad() {  # bad WANT ARGS...
  local want=$1; shift
  echo "+ $c montage $*"
  "$c" montage "$@" >"$tmp/out" 2>"$tmp/all"; local rc=$?
  grep -v '^progress ' "$tmp/all" >"$tmp/err"   # progress lines are not errors
  sed 's/^/  stderr: /' "$tmp/err"
  ((rc == 2)) || fail "exit $rc, want 2: $*"
  [[ $(grep -c '^error corrtex montage: ' "$tmp/err") -eq 1 && $(wc -l <"$tmp/err") -eq 1 ]] || fail "want one error line: $*"
  grep -qF -- "$want" "$tmp/err" || fail "message lacks '$want': $*"
}
bad "no output file" "$data/compare-ref.exr"
bad "no input images" -o "$tmp/x.png"
bad "missing.exr" -o "$tmp/x.png" "$tmp/missing.exr"
bad "not a .png or .exr" -o "$tmp/x.png" "$root/tests/data/scenes/mini.json"
bad "aspect" -o "$tmp/x.png" "$data/compare-ref.exr" "$tmp/b.png"
bad "--tile" -o "$tmp/x.png" --tile 3 "$data/compare-ref.exr"
bad "-o $tmp/x.exr: the sheet is written as PNG" -o "$tmp/x.exr" "$data/compare-ref.exr"
# A sheet in a missing folder: refused before the images are read (a missing
# one here), as every output file whose folder is missing; it used to be
# found only once the sheet was made.
bad "$tmp/no/dir/x.png: cannot create: its folder $tmp/no/dir does not exist" -o "$tmp/no/dir/x.png" \
  "$tmp/missing.exr"
[[ ! -e $tmp/no ]] || fail "a folder was made for the sheet"
[[ ! -e $tmp/x.png ]] || fail "a sheet was written despite an error"
((fails == 0)) || { echo "$fails failure(s)"; exit 1; }
echo "ok: montage sizes, identity tile, --max-tiles, errors"
