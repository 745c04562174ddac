#!/usr/bin/env python3
"""Writes the EXT_meshopt_compression fixtures of tests/gltf_compression.rs.

- torus.glb: the uncompressed source (standard library only): a torus of 32 x 16
  quads with normals, texture coordinates and a 2x2 checker texture, the
  independent answer the compressed files are checked against;
- torus-*.glb: the same file through npm's gltfpack 1.3 (`npx gltfpack`), with
  EXT_meshopt_compression (`-ce ext`):
  - torus-quantized.glb (`-cc`): gltfpack's defaults, KHR_mesh_quantization's
    integer positions, octahedral-filtered 8-bit normals, 12-bit texture coordinates;
  - torus-filters.glb (`-cc -vpf -vtf -vn 12`): float positions and texture
    coordinates through the exponential filter, 12-bit octahedral normals (16-bit
    components);
  - torus-float.glb (`-c -noq`): no quantization, so no filter: plain float
    attributes through the vertex codec, indices through the index codec;
- torus-khr.glb (`-cc -ce khr`): gltfpack's defaults with KHR_meshopt_compression,
  whose vertex streams are the codec's version 1 (header byte 0xa1).

Run it from anywhere (needs Node.js and npm for gltfpack); it writes beside itself.
"""

import json
import math
import struct
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
# The PNG writer of the other glTF fixtures (tests/data/gltf/make_fixtures.py).
sys.path.insert(0, str(HERE.parent))
from make_fixtures import png  # noqa: E402
GLTFPACK = ["npx", "--yes", "gltfpack@1.3"]


def torus(major=32, minor=16, big=1.0, small=0.4):
    """Positions, normals, texture coordinates (seams duplicated) and indices."""
    positions, normals, texcoords, indices = [], [], [], []
    for i in range(major + 1):
        u = i / major
        a = 2 * math.pi * u
        for j in range(minor + 1):
            v = j / minor
            b = 2 * math.pi * v
            n = (math.cos(a) * math.cos(b), math.sin(b), math.sin(a) * math.cos(b))
            c = (big * math.cos(a), 0.0, big * math.sin(a))
            positions.append(tuple(c[k] + small * n[k] for k in range(3)))
            normals.append(n)
            texcoords.append((u * 4, v * 2))
    row = minor + 1
    for i in range(major):
        for j in range(minor):
            p, q = i * row + j, (i + 1) * row + j
            indices += [p, p + 1, q, q, p + 1, q + 1]
    return positions, normals, texcoords, indices


def glb(json_doc, binary):
    text = json.dumps(json_doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    body += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def source():
    positions, normals, texcoords, indices = torus()
    image = png(2, 2, [[(230, 40, 40), (40, 200, 40)], [(40, 40, 230), (240, 240, 240)]])
    chunks = [
        b"".join(struct.pack("<3f", *p) for p in positions),
        b"".join(struct.pack("<3f", *n) for n in normals),
        b"".join(struct.pack("<2f", *t) for t in texcoords),
        b"".join(struct.pack("<H", i) for i in indices),
        image,
    ]
    views, binary = [], b""
    for data in chunks:
        binary += b"\0" * (-len(binary) % 4)
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
        binary += data
    for view in views[:3]:
        view["target"] = 34962
    views[3]["target"] = 34963
    lo = [min(p[k] for p in positions) for k in range(3)]
    hi = [max(p[k] for p in positions) for k in range(3)]
    doc = {
        "asset": {"version": "2.0", "generator": "make_fixtures.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "rotation": [0.5, 0, 0, 0.8660254]}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                        "indices": 3,
                        "material": 0,
                    }
                ]
            }
        ],
        "materials": [
            {
                "pbrMetallicRoughness": {
                    "baseColorTexture": {"index": 0},
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.6,
                }
            }
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728}],
        "images": [{"bufferView": 4, "mimeType": "image/png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": len(normals), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": len(texcoords), "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": len(indices), "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary) + (-len(binary) % 4)}],
    }
    (HERE / "torus.glb").write_bytes(glb(doc, binary))


def pack(name, *flags, extension="ext"):
    subprocess.run(
        GLTFPACK
        + ["-i", str(HERE / "torus.glb"), "-o", str(HERE / name), "-ce", extension, *flags],
        check=True,
    )


if __name__ == "__main__":
    source()
    pack("torus-quantized.glb", "-cc")
    pack("torus-filters.glb", "-cc", "-vpf", "-vtf", "-vn", "12")
    pack("torus-float.glb", "-c", "-noq")
    pack("torus-khr.glb", "-cc", extension="khr")
