#!/usr/bin/env bash
# Writes docs/images/objects.png, the README's picture of map objects on the LOD terrain: the
# Presidential Range (N44W072) seen from above Bretton Woods, with peaks as labels (ranked by
# elevation, decluttered), huts and places as icons (labels when far), buildings extruded from the drawn ground and a road
# draped on it. The vector data is written here: peak and hut positions approximate the real
# ones, the buildings and the road are made up for the picture.
#
# Usage: bash scripts/objects_picture.sh [BUILD_DIR]   (default build; needs terralod built)
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
terralod="$build/apps/terralod"
dem=../shared/data/N44W072.hgt
[[ -x "$terralod" ]] || { echo "objects_picture.sh: $terralod: not built" >&2; exit 1; }
[[ -f "$dem" ]] || { echo "objects_picture.sh: $dem: no such file" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

echo "[1/4] building the terrain database (N44W072, the native lon/lat frame)"
"$terralod" build --input "$dem" --out "$work/t.db" --crs native >/dev/null

echo "[2/4] writing the layers"
feature() {  # feature NAME LON LAT ELE -> a GeoJSON point feature
  printf '{"type":"Feature","properties":{"name":"%s","ele":%s},"geometry":{"type":"Point","coordinates":[%s,%s]}}' \
    "$1" "$4" "$2" "$3"
}
{
  echo '{"type":"FeatureCollection","features":['
  first=1
  while read -r lon lat ele name; do
    ((first)) || echo ','
    first=0
    feature "$name" "$lon" "$lat" "$ele"
  done <<'PEAKS'
-71.3033 44.2706 1917 Mount Washington
-71.2914 44.3206 1760 Mount Adams
-71.3170 44.3042 1741 Mount Jefferson
-71.2778 44.3283 1636 Mount Madison
-71.3214 44.2550 1637 Mount Monroe
-71.3500 44.2406 1457 Mount Eisenhower
-71.3656 44.2272 1314 Mount Pierce
-71.4467 44.0936 1422 Mount Carrigain
PEAKS
  echo ']}'
} >"$work/peaks.geojson"
{
  echo '{"type":"FeatureCollection","features":['
  first=1
  while read -r lon lat name; do
    ((first)) || echo ','
    first=0
    feature "$name" "$lon" "$lat" 0
  done <<'HUTS'
-71.3187 44.2590 Lakes of the Clouds Hut
-71.2836 44.3275 Madison Spring Hut
-71.3697 44.2194 Mizpah Spring Hut
-71.4405 44.2548 Station
-71.4350 44.2590 Inn
-71.4290 44.2540 Trailhead
HUTS
  echo ']}'
} >"$work/huts.geojson"
# Buildings: a made-up village of 5 x 4 blocks east of the camera, 25..60 m on a side, 12..40 m high.
awk 'BEGIN {
  print "{\"type\":\"FeatureCollection\",\"features\":["
  n = 0
  for (i = 0; i < 5; ++i) for (j = 0; j < 4; ++j) {
    k = i * 4 + j
    lon = -71.4440 + i * 0.0016 + (k % 3) * 0.0002; lat = 44.2560 + j * 0.0012 + (k % 2) * 0.0002
    w = (25 + (k * 7) % 36) / 79500.0; d = (25 + (k * 11) % 30) / 111200.0; h = 12 + (k * 13) % 29
    printf "%s{\"type\":\"Feature\",\"properties\":{\"name\":\"b%d\",\"height\":%d},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[[[%.6f,%.6f],[%.6f,%.6f],[%.6f,%.6f],[%.6f,%.6f],[%.6f,%.6f]]]}}\n", (n++ ? "," : ""), k, h, lon, lat, lon + w, lat, lon + w, lat + d, lon, lat + d, lon, lat
  }
  print "]}"
}' >"$work/buildings.geojson"
cat >"$work/road.geojson" <<'ROAD'
{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"name":"Road"},"geometry":{"type":"LineString",
"coordinates":[[-71.4900,44.2530],[-71.4700,44.2545],[-71.4550,44.2555],[-71.4450,44.2585],[-71.4300,44.2600],[-71.4100,44.2560],[-71.3900,44.2480]]}}]}
ROAD
echo '{"ranges": [{"draw": "label"}], "priority_field": "ele", "label_size_px": 15}' >"$work/peaks.json"
echo '{"ranges": [{"max_distance_m": 6000, "draw": "icon"}, {"draw": "label"}], "icon_size_m": 40, "label_size_px": 12}' >"$work/huts.json"
echo '{"ranges": [{"max_distance_m": 8000, "draw": "shape"}, {"draw": "none"}]}' >"$work/buildings.json"
echo '{"ranges": [{"max_distance_m": 20000, "draw": "line"}, {"draw": "none"}], "line_width_m": 12}' >"$work/road.json"

echo "[3/4] adding the object layers"
for layer in peaks huts buildings road; do
  extra=()
  [[ "$layer" == buildings ]] && extra=(--height-field height)
  "$terralod" objects add "$work/t.db" --layer "$layer" --input "$work/$layer.geojson" --rules "$work/$layer.json" \
    "${extra[@]}" >/dev/null
done

echo "[4/4] drawing docs/images/objects.png"
# The camera: 44.2547 N, 71.4515 W (x = (lon + 72) * 1200 * 66.0916 m, y = 111195.08 - (45 - lat)
# * 1200 * 92.6626 m in the native frame of N44W072), about 150 m above the ground, looking east.
"$terralod" view --db "$work/t.db" --camera 43501,28322,640,80,-4,50 --size 1280x640 \
  --objects peaks --objects huts --objects buildings --objects road --out docs/images/objects.png
