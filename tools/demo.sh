#!/usr/bin/env bash
# The end-to-end demo on a built-in sample: synthesize real-format inputs
# (DTED 1/2, GeoTIFF, GeoPackage), build (with the sample's built-in icons),
# validate, show info, run the sample scenario headless, fly headless, and
# say where the images, stats and event log are. Usage: tools/demo.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/demo}
st=./build/tools/sandtable
[ -x "$st" ] || tools/setup.sh

mkdir -p "$out"
echo "== synth: DTED1/DTED2 cells, dem.tif, culture.gpkg"
$st synth -o "$out/inputs" --size-km 20 --force
echo "== build: DTED2 -> UTM grid (seed location-weighted resampling), culture decaled, 1 km load modules x 4 levels, icons"
# The synthesized square's bounds, from synth.json (no JSON tool needed).
bound() { sed -n "s/.*\"$1\": *\(-\?[0-9.]*\).*/\1/p" "$out/inputs/synth.json" | head -n 1; }
extent="$(bound west) $(bound south) $(bound east) $(bound north)"
$st build --elevation "$out/inputs/dted2" --culture "$out/inputs/culture.gpkg" --extent $extent \
  --spacing 31.25 --icons samples/icons.txt -o "$out/db" --force
echo "== validate"
$st validate "$out/db"
echo "== info"
$st info "$out/db"
echo "== sim: samples/demo.scenario, 5 simulated minutes (entities, collisions, behaviours, scripts)"
$st sim "$out/db" --scenario samples/demo.scenario --duration 300 --record "$out/lead.script"
$st sim "$out/db" --scenario samples/demo.scenario --duration 300 --json > "$out/sim.json"
echo "== fly (headless EGL)"
$st fly "$out/db" --headless --png "$out/frames" --frames 60 --size 1280x720 --height 250 --heading 45 --map
echo "== fly the scenario (headless EGL), attached to a blue tank as the first missiles fly"
$st fly "$out/db" --scenario samples/demo.scenario --attach blue3 --sim-start 6 --headless --png "$out/battle" \
  --frames 60 --size 1280x720 --map
echo "== dynamic terrain: samples/terrain.scenario's craters, berm, ditch and flattened position, journaled"
rm -f "$out/terrain.journal"
$st sim "$out/db" --scenario samples/terrain.scenario --duration 5 --journal "$out/terrain.journal"
$st edits list "$out/terrain.journal"
$st fly "$out/db" --journal "$out/terrain.journal" --headless --png "$out/crater" --frames 1 --size 1280x720 \
  --at 13.355 42.2733 --height 25 --pitch -50 --heading 0 --map --map-scale sixteenth
$st export "$out/db" --journal "$out/terrain.journal" --grid -o "$out/ground-after.tif"
echo
echo "demo: database  $out/db"
echo "demo: images    $out/frames/frame_*.png"
echo "demo: stats     $out/frames/stats.json"
echo "demo: sim       $out/sim.json (summary and event log), $out/lead.script (the driven tank, Figure 71 lines)"
echo "demo: battle    $out/battle/frame_*.png, $out/battle/stats.json"
echo "demo: terrain   $out/terrain.journal (the edits), $out/crater/frame_00000.png (a crater), $out/ground-after.tif (the edited grid, GeoTIFF)"
