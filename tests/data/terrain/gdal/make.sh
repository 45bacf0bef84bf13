#!/bin/sh
# The compressed GeoTIFFs beside this script, written by GDAL (gdal_translate 3.6.2) from
# two ESRI ASCII grids of the same 37 x 29 samples (one real-valued, one whole metres,
# each with three voids of -9999), placed at 47.5-47.5+29/3600 N, 8.25 E, one arc-second
# apart. Re-run it where gdal-bin is installed; the tests only read its output.
set -eu
cd "$(dirname "$0")"
python3 - <<'PY'
import math
rows, cols = 29, 37
def value(r, c):
    return 412.0 + 3.17 * c - 1.91 * r + 25.0 * math.sin(r / 4.0) * math.cos(c / 5.0)
voids = {(0, 5), (14, 20), (28, 36)}
for name, fmt in (("float32.asc", "{:.3f}"), ("int16.asc", "{:.0f}")):
    with open(name, "w") as out:
        out.write(f"ncols {cols}\nnrows {rows}\nxllcorner 8.25\nyllcorner 47.5\n")
        out.write(f"cellsize {1/3600!r}\nNODATA_value -9999\n")
        for r in range(rows):
            out.write(" ".join("-9999" if (r, c) in voids else fmt.format(value(r, c))
                               for c in range(cols)) + "\n")
PY
t() { gdal_translate -q -a_srs EPSG:4326 "$@"; }
t -ot Float32 float32.asc reference_float32.tif
t -ot Int16 int16.asc reference_int16.tif
t -ot Float32 -co COMPRESS=DEFLATE -co PREDICTOR=3 -co BLOCKYSIZE=8 float32.asc deflate_fp_strips.tif
t -ot Float32 -co COMPRESS=DEFLATE -co PREDICTOR=3 -co TILED=YES -co BLOCKXSIZE=16 -co BLOCKYSIZE=16 float32.asc deflate_fp_tiled.tif
t -ot Float64 -co COMPRESS=DEFLATE -co PREDICTOR=3 float32.asc deflate_fp_float64.tif
t -ot Float32 -co COMPRESS=LZW -co PREDICTOR=3 -co TILED=YES -co BLOCKXSIZE=16 -co BLOCKYSIZE=16 float32.asc lzw_fp_tiled.tif
t -ot Int16 -co COMPRESS=LZW int16.asc lzw_int16.tif
t -ot Int16 -co COMPRESS=LZW -co PREDICTOR=2 -co BLOCKYSIZE=5 int16.asc lzw_int16_predictor2.tif
t -ot Int16 -co COMPRESS=LZW -co PREDICTOR=2 -co ENDIANNESS=BIG -co TILED=YES -co BLOCKXSIZE=16 -co BLOCKYSIZE=16 int16.asc lzw_int16_predictor2_big_endian_tiled.tif
t -ot Int16 -co COMPRESS=PACKBITS int16.asc packbits_int16.tif
rm -f float32.asc int16.asc *.prj *.aux.xml
