#!/usr/bin/env bash
# Files that are not regular files, as inputs and outputs of the programs.
# Inputs: a FIFO as scene, mesh file, camera path file, --radmesh, --mesh or
# compare input, and a folder as scene, each fail at once (a FIFO used to
# hang the loader) with exit 2 and one line naming it; a 1 GiB sparse file as
# --radmesh fails on its header without being read. Outputs: a FIFO with a
# reader gets the same bytes a regular file would and stays a FIFO; a FIFO
# without a reader and a folder are refused with one line (a folder before a
# reference image or a path's frames are traced, not after); a character device
# (root only: mknod) is written to and stays a device (the old rename turned
# it into a regular file, and /dev/null with it when run as root).
source "$(dirname "$0")/lib/common.sh"
display="$bin/corrtex-display"
SCENE_DIR="$root/tests/data/scenes"
REF=(--width 8 --height 6 --spp 1 --mode path --threads 1 --quiet)

# expect_bad WHAT NAME PROGRAM ARGS...: exit 2 within 20 s (124 = it hung)
# and exactly one error line, naming NAME.
expect_bad() {
  local what=$1 name=$2; shift 2
  echo "+ $*"
  timeout 20 "$@" >"$tmp/o" 2>"$tmp/e"; rc=$?
  sed 's/^/  stderr: /' "$tmp/e"
  ((rc == 2)) || fail "$what: exit status $rc, expected 2 (124: hung)"
  (($(grep -c '^error ' "$tmp/e") == 1)) || fail "$what: expected exactly one error line"
  grep -q -- "$name" "$tmp/e" || fail "$what: the error does not name $name"
}

# --- inputs -------------------------------------------------------------------
cp "$SCENE_DIR"/mini.* "$tmp/"
mkfifo "$tmp/fifo.json" "$tmp/fifo.obj" "$tmp/fifo.path" "$tmp/fifo.ctmesh" "$tmp/fifo.exr"
sed 's/"mini.obj"/"fifo.obj"/' "$SCENE_DIR/mini.json" >"$tmp/mesh_fifo.json"
sed 's/"mini.path"/"fifo.path"/' "$SCENE_DIR/mini.json" >"$tmp/path_fifo.json"
expect_bad "FIFO scene" fifo.json "$corrtex" info "$tmp/fifo.json"
expect_bad "folder scene" "$tmp" "$corrtex" info "$tmp"
expect_bad "FIFO mesh file" fifo.obj "$corrtex" info "$tmp/mesh_fifo.json"
expect_bad "FIFO path file" fifo.path "$corrtex" info "$tmp/path_fifo.json"
expect_bad "FIFO --radmesh" fifo.ctmesh "$corrtex" reference "$tmp/mini.json" "${REF[@]}" --mode drt \
  --radmesh "$tmp/fifo.ctmesh" -o "$tmp/x.exr"
expect_bad "FIFO compare input" fifo.exr "$corrtex" compare "$tmp/fifo.exr" "$tmp/fifo.exr"
[[ -x $display ]] && expect_bad "FIFO display --mesh" fifo.ctmesh "$display" --mesh "$tmp/fifo.ctmesh" \
  --backend osmesa --frames 1 --quiet
truncate -s 1G "$tmp/sparse.ctmesh"
start=$(date +%s.%N)
expect_bad "1 GiB sparse --radmesh" "sparse.ctmesh: not a corrtex mesh cache" "$corrtex" reference \
  "$tmp/mini.json" "${REF[@]}" --mode drt --radmesh "$tmp/sparse.ctmesh" -o "$tmp/x.exr"
secs=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.2f", e - s }')
echo "metric: a 1 GiB sparse --radmesh refused in $secs s"

# --- outputs ------------------------------------------------------------------
run_corrtex 0 reference "$tmp/mini.json" "${REF[@]}" -o "$tmp/plain.exr"
mkfifo "$tmp/out.exr"
cat "$tmp/out.exr" >"$tmp/from_fifo.exr" &
reader=$!
run_corrtex 0 reference "$tmp/mini.json" "${REF[@]}" -o "$tmp/out.exr"
wait "$reader"
cmp -s "$tmp/plain.exr" "$tmp/from_fifo.exr" || fail "the FIFO's reader did not get the EXR a file gets"
[[ -p $tmp/out.exr ]] || fail "the FIFO output was replaced by a regular file"

mkfifo "$tmp/nobody.exr"
expect_bad "FIFO output without a reader" "nobody.exr: a FIFO without a reader" \
  "$corrtex" reference "$tmp/mini.json" "${REF[@]}" -o "$tmp/nobody.exr"
mkdir "$tmp/folder.ctmesh"
expect_bad "folder as radiosity output" "folder.ctmesh: is a folder" \
  "$corrtex" radiosity "$tmp/mini.json" -o "$tmp/folder.ctmesh"
[[ -d $tmp/folder.ctmesh ]] || fail "the output folder was replaced"
# ... and before the render (it was found only once the image was traced:
# a progress line came first)
mkdir "$tmp/folder.exr" "$tmp/folder2.png"
LOUD=(--width 8 --height 6 --spp 4 --mode path --threads 1)
expect_bad "folder as reference output" "folder.exr: is a folder" \
  "$corrtex" reference "$tmp/mini.json" "${LOUD[@]}" -o "$tmp/folder.exr"
grep -q '^progress' "$tmp/e" && fail "the reference was traced before its output was refused"
expect_bad "folder as reference --png output" "folder2.png: is a folder" \
  "$corrtex" reference "$tmp/mini.json" "${LOUD[@]}" -o "$tmp/folder2.exr" --png
grep -q '^progress' "$tmp/e" && fail "the reference was traced before its --png output was refused"
[[ -e $tmp/folder2.exr ]] && fail "an EXR was written beside a --png output that cannot be"
# a path's frames into a folder: frame 2 a folder was found once frames 0
# and 1 were traced and written
mkdir -p "$tmp/frames/frame_00002.exr"
expect_bad "folder as a path frame" "frame_00002.exr: is a folder" \
  "$corrtex" reference "$tmp/mini.json" "${LOUD[@]}" --path walk --frames 3 -o "$tmp/frames"
grep -q '^progress' "$tmp/e" && fail "frames were traced before a frame's output was refused"
[[ -e $tmp/frames/frame_00000.exr ]] && fail "frame 0 was written before frame 2's output was refused"

if mknod "$tmp/null.exr" c 1 3 2>/dev/null && mknod "$tmp/null.ctmesh" c 1 3 && mknod "$tmp/null.png" c 1 3; then
  run_corrtex 0 reference "$tmp/mini.json" "${REF[@]}" -o "$tmp/null.exr"
  run_corrtex 0 radiosity "$tmp/mini.json" -o "$tmp/null.ctmesh" --image "$tmp/null.png" --width 8 --height 6 \
    --max-triangles 2000 --quiet
  for f in null.exr null.ctmesh null.png; do
    [[ -c $tmp/$f ]] || fail "$f: the character device was replaced by a regular file"
  done
else
  echo "skip: character device outputs (mknod needs root)"
fi

((fails == 0)) || { echo "special_files: $fails failure(s)"; exit 1; }
echo "special_files: ok"
