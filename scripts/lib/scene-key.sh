# scripts/lib/scene-key.sh: a key for files made from a scene (sourced, not
# run).
#   scene_key JSON
# prints a checksum of the scene's JSON and of the mesh and material files in
# its folder, so that a cached reference named by it is made again when the
# scene or its generated geometry changes (a reference named only by its
# sample count was reused after the scene changed).
scene_key() {
  local json=$1 dir
  dir=$(dirname "$json")
  {
    cat "$json"
    find "$dir" -maxdepth 1 -type f \( -name '*.obj' -o -name '*.mtl' -o -name '*.ply' -o -name '*.gltf' \
      -o -name '*.glb' -o -name '*.fbx' \) -print0 | sort -z | xargs -0 -r cat
  } | cksum | cut -d' ' -f1
}
