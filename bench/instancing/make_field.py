#!/usr/bin/env python3
"""Writes the field of 10,000 dragons (issue 39's benchmark) into bench/work/:
field.toml, which places the full Stanford dragon (bench/README.md) through
`[[instances]]` by field.npy, an (N, 4, 4) float32 array of world-from-object
matrices: a 100 x 100 grid 0.25 apart running away from the benchmark camera
(the grid's first dragon is the benchmark's, where it always was), every other
dragon turned about y and scaled by 0.8-1.2, from a fixed seed. The benchmark's
camera, lights and materials; its floor widened under the whole field.

    python3 bench/instancing/make_field.py [--count 10000]

Needs numpy and the dragon fetched as bench/run.sh does (bench/work/package).
"""

import argparse
import math
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
WORK = ROOT / "bench" / "work"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=10_000, help="dragons (a square number)")
    args = parser.parse_args()
    side = math.isqrt(args.count)
    if side * side != args.count:
        parser.error("--count must be a square number")
    rng = np.random.default_rng(39)
    spacing = 0.25
    matrices = np.zeros((args.count, 4, 4), dtype=np.float32)
    for k in range(args.count):
        i, j = divmod(k, side)
        x = (j - side // 2) * spacing
        z = -i * spacing
        if k == side // 2:
            angle, scale = 0.0, 1.0
        else:
            angle, scale = rng.uniform(0, 2 * math.pi), rng.uniform(0.8, 1.2)
        c, s = math.cos(angle) * scale, math.sin(angle) * scale
        matrices[k] = [[c, 0, s, x], [0, scale, 0, 0], [-s, 0, c, z], [0, 0, 0, 1]]
    WORK.mkdir(parents=True, exist_ok=True)
    np.save(WORK / "field.npy", matrices)
    half = side * spacing / 2 + 1
    depth = side * spacing + 1
    dragon = (ROOT / "bench" / "dragon.toml").read_text()
    head, _, rest = dragon.partition("# The dragon's vertices as they are (no transform).")
    _, _, lights = rest.partition("# Key light.")
    (WORK / "field.toml").write_text(
        head.replace("work/package", "package")
        + f"""# {args.count:,} dragons, each the whole 871k-triangle mesh, stored once.
[[mesh]]
file = "package/models/dragon_vrip.ply.gz"
material = "dragon"
id = "dragon"

[[instances]]
mesh = "dragon"
file = "field.npy"

[[mesh]]
file = "../floor.obj"
material = "floor"
transform = {{ scale = [{half}, 1, {depth / 2}], translate = [0, 0, {-depth / 2 + 1}] }}

# Key light."""
        + lights
    )
    print(WORK / "field.toml")


if __name__ == "__main__":
    main()
