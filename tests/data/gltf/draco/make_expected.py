#!/usr/bin/env python3
"""Writes expected.json: the triangle count and world bounding box of the
uncompressed 2CylinderEngine (glTF-Sample-Models' 2CylinderEngine-glTF-Binary, as
Debian's assimp-testmodels installs it), the independent answer the Draco test of
tests/gltf_compression.rs checks the decoded 2CylinderEngine.gltf against.

Triangles whose three corners do not have three distinct positions are not
counted: Draco's encoder merges equal vertices and drops the triangles that then
repeat one. Only the standard library is used.

    python3 make_expected.py [path/to/2CylinderEngine.glb]
"""

import json
import struct
import sys

GLB = "/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb"
# Draco's default quantisation of positions (draco_encoder -qp, COLLADA2GLTF).
POSITION_BITS = 11


def read_glb(path):
    data = open(path, "rb").read()
    assert data[:4] == b"glTF"
    (json_len,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20 : 20 + json_len])
    at = 20 + json_len
    (bin_len,) = struct.unpack_from("<I", data, at)
    return doc, data[at + 8 : at + 8 + bin_len]


def accessor(doc, blob, index):
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    fmt = {5121: "B", 5123: "H", 5125: "I", 5126: "f"}[acc["componentType"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    size = struct.calcsize(fmt)
    stride = view.get("byteStride", size * n)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return [
        struct.unpack_from("<" + fmt * n, blob, start + i * stride)
        for i in range(acc["count"])
    ]


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def local(node):
    if "matrix" in node:
        m = node["matrix"]  # column major
        return [[m[c * 4 + r] for c in range(4)] for r in range(4)]
    t = node.get("translation", [0, 0, 0])
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    s = node.get("scale", [1, 1, 1])
    r = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return [[r[i][j] * s[j] for j in range(3)] + [t[i]] for i in range(3)] + [[0, 0, 0, 1]]


def main():
    doc, blob = read_glb(sys.argv[1] if len(sys.argv) > 1 else GLB)
    triangles = 0
    lo, hi = [float("inf")] * 3, [float("-inf")] * 3
    tolerance = 0.0
    identity = [[float(i == j) for j in range(4)] for i in range(4)]

    def walk(index, parent):
        nonlocal triangles, tolerance
        node = doc["nodes"][index]
        world = matmul(parent, local(node))
        if "mesh" in node:
            scale = max(sum(world[r][c] ** 2 for r in range(3)) ** 0.5 for c in range(3))
            for prim in doc["meshes"][node["mesh"]]["primitives"]:
                assert prim.get("mode", 4) == 4
                positions = accessor(doc, blob, prim["attributes"]["POSITION"])
                indices = [i[0] for i in accessor(doc, blob, prim["indices"])]
                for t in range(0, len(indices), 3):
                    if len({positions[i] for i in indices[t : t + 3]}) == 3:
                        triangles += 1
                extent = max(
                    max(p[k] for p in positions) - min(p[k] for p in positions)
                    for k in range(3)
                )
                tolerance = max(tolerance, extent * scale / 2**POSITION_BITS)
                for i in set(indices):
                    p = positions[i]
                    w = [sum(world[r][c] * (list(p) + [1])[c] for c in range(4)) for r in range(3)]
                    for k in range(3):
                        lo[k], hi[k] = min(lo[k], w[k]), max(hi[k], w[k])
        for child in node.get("children", []):
            walk(child, world)

    scene = doc["scenes"][doc.get("scene", 0)]
    for root in scene["nodes"]:
        walk(root, identity)
    expected = {
        "source": "2CylinderEngine-glTF-Binary/2CylinderEngine.glb (uncompressed)",
        "triangles": triangles,
        "min": lo,
        "max": hi,
        "position_bits": POSITION_BITS,
        "tolerance": tolerance,
    }
    with open("expected.json", "w") as f:
        json.dump(expected, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
