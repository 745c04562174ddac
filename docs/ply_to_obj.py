#!/usr/bin/env python3
"""Writes the benchmark dragon scene (shared/bench/README.md) from a Stanford PLY file.

Usage: ply_to_obj.py DRAGON.ply.gz OUT_DIR

Reads a gzip-compressed (or plain) ascii PLY whose vertices have x, y, z among their
properties and whose faces are `property list ... vertex_indices`, and writes
OUT_DIR/dragon.obj and OUT_DIR/dragon.mtl in the OBJ dialect of SPEC.md: the dragon's
vertices as they are with material `dragon`, a floor square at y = 0.0525 with
material `floor`, and the two point lights of the benchmark scene.
"""

import gzip
import os
import sys

MTL = """newmtl dragon
Ka 0.01 0.01 0.01
Kd 0.8 0.2 0.2
Ks 0.3 0.3 0.3
Ns 64

newmtl floor
Ka 0.01 0.01 0.01
Kd 0.6 0.6 0.6
Ks 0 0 0
Ns 1
"""

FLOOR_Y = 0.0525


def read_header(lines):
    """Returns (vertex count, property names of a vertex, face count)."""
    if next(lines).strip() != "ply":
        sys.exit("not a PLY file")
    vertices = faces = None
    vertex_properties = []
    element = None
    for line in lines:
        words = line.split()
        if not words:
            continue
        if words[0] == "format" and words[1] != "ascii":
            sys.exit(f"only ascii PLY is supported, not {words[1]}")
        if words[0] == "element":
            element = words[1]
            if element == "vertex":
                vertices = int(words[2])
            elif element == "face":
                faces = int(words[2])
        elif words[0] == "property" and element == "vertex":
            vertex_properties.append(words[-1])
        elif words[0] == "end_header":
            return vertices, vertex_properties, faces
    sys.exit("PLY header has no end_header")


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    source, out_dir = sys.argv[1], sys.argv[2]
    opener = gzip.open if source.endswith(".gz") else open
    os.makedirs(out_dir, exist_ok=True)
    with opener(source, "rt") as ply, open(os.path.join(out_dir, "dragon.obj"), "w") as obj:
        lines = iter(ply)
        vertices, properties, faces = read_header(lines)
        xyz = [properties.index(axis) for axis in ("x", "y", "z")]
        obj.write(f"# The Stanford dragon from {os.path.basename(source)}\n")
        obj.write("mtllib dragon.mtl\nusemtl dragon\n")
        for _ in range(vertices):
            words = next(lines).split()
            obj.write("v " + " ".join(words[i] for i in xyz) + "\n")
        for _ in range(faces):
            words = next(lines).split()
            count = int(words[0])
            # PLY indices are 0-based, OBJ's 1-based.
            obj.write("f " + " ".join(str(int(w) + 1) for w in words[1 : 1 + count]) + "\n")
        obj.write("usemtl floor\n")
        for x, z in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            obj.write(f"v {x} {FLOOR_Y} {z}\n")
        # Counter-clockwise seen from above, so both triangles face +y.
        obj.write("f -4 -1 -2\nf -4 -2 -3\n")
        obj.write("P 0.5 0.9 0.6 1 1 1\nP -0.6 0.5 0.5 0.3 0.3 0.3\n")
    with open(os.path.join(out_dir, "dragon.mtl"), "w") as mtl:
        mtl.write(MTL)


if __name__ == "__main__":
    main()
