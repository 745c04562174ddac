#!/usr/bin/env python3
"""Writes a mesh of an ascii PLY file (optionally gzipped: the Stanford dragon of
bench/README.md) as the MESH.bin that `embree_bench --mesh` reads, for Embree's
instancing on the field of dragons (bench/instancing/make_field.py):

    python3 bench/embree/write_mesh.py bench/work/package/models/dragon_vrip.ply.gz bench/work/mesh.bin

Little-endian: "RTMESH01", u32 vertex count, f32 x, y, z per vertex, u32 triangle
count, u32 a, b, c per triangle (polygons fanned into triangles). Needs numpy.
"""

import gzip
import sys
from pathlib import Path

import numpy as np


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as f:
        if f.readline().strip() != "ply":
            sys.exit(f"write_mesh.py: error: {path}: not a PLY file")
        counts, vertex_props = {}, []
        element = None
        for line in f:
            words = line.split()
            if not words:
                continue
            if words[0] == "format" and words[1] != "ascii":
                sys.exit(f"write_mesh.py: error: {path}: only ascii PLY files")
            if words[0] == "element":
                element = words[1]
                counts[element] = int(words[2])
            elif words[0] == "property" and element == "vertex":
                vertex_props.append(words[-1])
            elif words[0] == "end_header":
                break
        xyz = [vertex_props.index(axis) for axis in "xyz"]
        vertices = np.array(
            [[float(v) for v in f.readline().split()] for _ in range(counts["vertex"])],
            dtype=np.float64,
        )[:, xyz].astype(np.float32)
        triangles = []
        for _ in range(counts.get("face", 0)):
            face = [int(v) for v in f.readline().split()]
            corners = face[1 : 1 + face[0]]
            triangles.extend([corners[0], corners[k], corners[k + 1]] for k in range(1, len(corners) - 1))
    return vertices, np.array(triangles, dtype=np.uint32).reshape(-1, 3)


def main() -> None:
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    vertices, triangles = read_ply(Path(sys.argv[1]))
    with open(sys.argv[2], "wb") as out:
        out.write(b"RTMESH01")
        out.write(np.uint32(len(vertices)).tobytes())
        out.write(vertices.astype("<f4").tobytes())
        out.write(np.uint32(len(triangles)).tobytes())
        out.write(triangles.astype("<u4").tobytes())
    print(f"{sys.argv[2]}: {len(vertices):,} vertices, {len(triangles):,} triangles")


if __name__ == "__main__":
    main()
