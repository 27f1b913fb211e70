#!/bin/sh
# Regenerates the README's scene x method table: every built-in scene and every vendored
# real scene, sky and bounce light (the sun left to the engine's shadow maps), each scene's
# default grid and plate, 128 samples per node or cell, against a path-traced reference,
# every method read through lightvol's lookup, each engine's own (native), three.js's, Bevy's,
# plain trilinear and Unity APV's. Scenes that carry cameras (the Breakfast Room's glTF
# cameras) are also compared in those views, each view an entry of its own in the means;
# the views' path-traced reference takes 1,024 samples a pixel (at the default 64 its noise,
# shared by every method, is most of every method's error).
#
#   scripts/method-table.sh [OUT_DIR] [extra compare options, e.g. --seed 2]
#
# Writes OUT_DIR/<scene>/ (report.json, panels, error maps) and prints the Markdown table.
set -eu
out=${1:-method-table}
[ $# -gt 0 ] && shift
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release -q -p lightvol --manifest-path "$root/Cargo.toml"
lv="$root/target/release/lightvol"
methods=point,prefilter,doi-paper,doi-node,doi,doi+lightvol,doi+three,doi+bevy,doi+trilinear,doi+apv,point+validity,point+apv,point+vlm,point+ddgi
lookups=lightvol,native,three,bevy,trilinear,apv
dirs=""
for scene in builtin:city builtin:interior builtin:maze \
    "$root/data/scenes/breakfast_room/BreakfastRoom.gltf" \
    "$root/data/scenes/occlusion_room/room.glb" \
    "$root/data/scenes/living_room/living_room.glb" \
    "$root/data/scenes/zdm2/zdm2.glb" \
    "$root/data/scenes/cornell_original/CornellBox-Original.obj"; do
    name=$(basename "$scene" | sed 's/^builtin://; s/\.[^.]*$//')
    views=""
    [ "$name" = BreakfastRoom ] && views="--camera gltf:CameraMain --camera gltf:CameraTableTop --view-samples 1024"
    # shellcheck disable=SC2086
    "$lv" compare "$scene" --light sky+indirect --samples 128 --methods "$methods" --lookup "$lookups" \
        $views --quiet -o "$out/$name" "$@" >/dev/null
    dirs="$dirs $out/$name"
done
# shellcheck disable=SC2086
"$lv" table $dirs
