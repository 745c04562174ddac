#!/usr/bin/env bash
# Renders every file listed in LIST (one path a line) with no flags but a small size,
# in full and path modes, into OUT/N.full.png and OUT/N.path.png (N: the file's line
# in LIST), and prints one tab-separated line per file and mode: N, file, mode, exit
# status, seconds, stderr (lines joined by '|'). Then, with python3 and Pillow, draws
# contact sheets OUT/sheet-MODE-K.png of 48 images each, numbered, to look at.
# See docs/real-files.md.
#
#   bash docs/real-files-sweep.sh LIST OUT > sweep.tsv
set -uo pipefail
bin=${RAYTRACER:-raytracer}
list=$(realpath "$1")
mkdir -p "$2"
out=$(realpath "$2")
n=0
while read -r file; do
    n=$((n + 1))
    for mode in full path; do
        start=$(date +%s.%N)
        err=$(cd "$(dirname "$file")" &&
            timeout 300 "$bin" render "$(basename "$file")" -o "$out/$n.$mode.png" \
                --width 160 --height 120 --mode "$mode" 2>&1 >/dev/null)
        status=$?
        end=$(date +%s.%N)
        printf '%s\t%s\t%s\t%s\t%.2f\t%s\n' "$n" "$file" "$mode" "$status" \
            "$(echo "$end - $start" | bc)" "$(echo "$err" | tr '\n' '|')"
    done
done <"$list"
python3 - "$out" "$n" <<'PY' || echo "no contact sheets (python3 with Pillow needed)" >&2
import os, sys
from PIL import Image, ImageDraw
out, count = sys.argv[1], int(sys.argv[2])
for mode in ("full", "path"):
    for first in range(1, count + 1, 48):
        ids = range(first, min(first + 48, count + 1))
        sheet = Image.new("RGB", (8 * 162, (len(ids) + 7) // 8 * 122), (255, 0, 255))
        draw = ImageDraw.Draw(sheet)
        for k, i in enumerate(ids):
            x, y = k % 8 * 162, k // 8 * 122
            png = f"{out}/{i}.{mode}.png"
            if os.path.exists(png):
                sheet.paste(Image.open(png).convert("RGB"), (x, y))
            draw.text((x + 2, y + 2), str(i), fill=(255, 255, 0))
        sheet.save(f"{out}/sheet-{mode}-{first // 48 + 1}.png")
PY
