#!/usr/bin/env python3
"""New / old CPU rates of `raytracer bench` runs kept one JSON a line (the first line
of each file, farm-bench's warm-up, left out), pair by pair: median and range.

    python3 bench/instancing/ratios.py NEW.json OLD.json
"""

import json
import statistics
import sys


def runs(path: str) -> list[dict]:
    with open(path) as f:
        return [json.loads(line) for line in f if line.startswith("{")][1:]


def main() -> None:
    new, old = runs(sys.argv[1]), runs(sys.argv[2])
    n = min(len(new), len(old))
    print(f"{n} pairs; above 1: new faster")
    for key in new[0]:
        if not (key.endswith("mrays_per_cpu_s") or key in ("build_cpu_ms", "render_cpu_ms")):
            continue
        # Rates: new / old; times: old / new.
        ratios = [a[key] / b[key] if key.endswith("_s") else b[key] / a[key]
                  for a, b in zip(new[:n], old[:n])]
        print(f"{key:36s} new {statistics.median(a[key] for a in new[:n]):8.2f}  "
              f"old {statistics.median(b[key] for b in old[:n]):8.2f}  "
              f"{statistics.median(ratios):.3f}x ({min(ratios):.2f}-{max(ratios):.2f})")


if __name__ == "__main__":
    main()
