#!/usr/bin/env python3
"""Writes the glTF fixtures of tests/gltf.rs (standard library only):

- scene.gltf + scene.bin + checker.png: the scene with a separate buffer and image file;
- scene.glb: the same scene as one binary file, the image in a buffer view;
- datauri.gltf: the same scene, buffer and image as base64 data URIs.

The scene: a textured quad under two nested node transforms, a mirrored copy, an
emissive quad (KHR_materials_emissive_strength), an alpha-masked quad, a metal quad,
a perspective camera turned 45 degrees about y, and a KHR_lights_punctual point light
under a translated parent. Run it from anywhere; it writes beside itself.
"""

import base64
import json
import math
import struct
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent


def png(width, height, rows):
    """An 8-bit RGB PNG; rows of (r, g, b) tuples, top first."""
    raw = b"".join(b"\0" + bytes(c for pixel in row for c in pixel) for row in rows)

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


# Top row red, green; bottom row blue, white.
CHECKER = png(2, 2, [[(255, 0, 0), (0, 255, 0)], [(0, 0, 255), (255, 255, 255)]])

# The quad: corners counter-clockwise seen from +z; glTF texture coordinates have
# v = 0 at the top of the image.
POSITIONS = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
NORMALS = [(0, 0, 1)] * 4
TEXCOORDS = [(0, 1), (1, 1), (1, 0), (0, 0)]
INDICES = [0, 1, 2, 0, 2, 3]


def geometry():
    """The binary buffer (without the image) and its views and accessors."""
    data = b""
    views, accessors = [], []

    def add(blob, target, accessor):
        nonlocal data
        while len(data) % 4:
            data += b"\0"
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(blob), "target": target})
        data += blob
        accessor["bufferView"] = len(views) - 1
        accessors.append(accessor)

    add(
        b"".join(struct.pack("<3f", *p) for p in POSITIONS),
        34962,
        {"componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
    )
    add(b"".join(struct.pack("<3f", *n) for n in NORMALS), 34962, {"componentType": 5126, "count": 4, "type": "VEC3"})
    add(b"".join(struct.pack("<2f", *t) for t in TEXCOORDS), 34962, {"componentType": 5126, "count": 4, "type": "VEC2"})
    add(b"".join(struct.pack("<H", i) for i in INDICES), 34963, {"componentType": 5123, "count": 6, "type": "SCALAR"})
    return data, views, accessors


def document(buffer_uri, buffer_length, image):
    _, views, accessors = geometry()
    primitive = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}
    doc = {
        "asset": {"version": "2.0", "generator": "tests/data/gltf/make_fixtures.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0, 2, 3, 4, 5, 6, 8]}],
        "nodes": [
            # 0, 1: the textured quad, scaled by 2 and moved by +x, under a group moved to z = -5.
            {"name": "group", "translation": [0, 0, -5], "children": [1]},
            {"name": "quad", "mesh": 0, "translation": [1, 0, 0], "scale": [2, 2, 2]},
            # 2: mirrored in x at z = -10.
            {"name": "mirrored", "mesh": 0, "translation": [0, 0, -10], "scale": [-1, 1, 1]},
            # 3: the emitter, 4: the masked quad, 5: the metal.
            {"name": "lamp", "mesh": 1, "translation": [0, 3, -5]},
            {"name": "ghost", "mesh": 2, "translation": [0, -3, -5]},
            {"name": "metal", "mesh": 3, "translation": [5, 0, -20]},
            # 6: the camera at (5, 0, 0), turned 45 degrees about +y: it looks at (0, 0, -5).
            {
                "name": "camera",
                "camera": 0,
                "translation": [5, 0, 0],
                "rotation": [0, math.sin(math.pi / 8), 0, math.cos(math.pi / 8)],
            },
            # 7, 8: the light at (1, 2, 3) under a parent moved by z + 1.
            {"name": "light", "extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1, 2, 3]},
            {"name": "light parent", "translation": [0, 0, 1], "children": [7]},
        ],
        "meshes": [
            {"name": "quad", "primitives": [dict(primitive, material=0)]},
            {"name": "lamp", "primitives": [dict(primitive, material=1)]},
            {"name": "ghost", "primitives": [dict(primitive, material=2)]},
            {"name": "metal", "primitives": [dict(primitive, material=3)]},
        ],
        "materials": [
            {
                "name": "checker",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [1, 0.5, 0.25, 1],
                    "baseColorTexture": {"index": 0},
                    "metallicFactor": 0,
                    "roughnessFactor": 1,
                },
            },
            {
                "name": "lamp",
                "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0},
                "emissiveFactor": [1, 0.5, 0],
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}},
            },
            {
                "name": "ghost",
                "alphaMode": "MASK",
                "alphaCutoff": 0.5,
                "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.3], "metallicFactor": 0},
            },
            {
                "name": "metal",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.9, 0.6, 0.3, 1],
                    "metallicFactor": 1,
                    "roughnessFactor": 0.5,
                },
            },
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 33071, "wrapT": 10497}],
        "images": [image],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.01}}],
        "extensions": {
            "KHR_lights_punctual": {"lights": [{"type": "point", "color": [1, 0.5, 0.25], "intensity": 10}]}
        },
        "bufferViews": views,
        "accessors": accessors,
        "buffers": [dict({"byteLength": buffer_length}, **({"uri": buffer_uri} if buffer_uri else {}))],
    }
    return doc


def write_json(path, doc):
    path.write_text(json.dumps(doc, indent=1) + "\n")


def main():
    data, _, _ = geometry()
    # 1. Separate files.
    (HERE / "scene.bin").write_bytes(data)
    (HERE / "checker.png").write_bytes(CHECKER)
    write_json(HERE / "scene.gltf", document("scene.bin", len(data), {"uri": "checker.png"}))

    # 2. Data URIs.
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    image = {"uri": "data:image/png;base64," + base64.b64encode(CHECKER).decode()}
    write_json(HERE / "datauri.gltf", document(uri, len(data), image))

    # 3. GLB: the image appended to the buffer as one more view.
    padded = data + b"\0" * (-len(data) % 4)
    binary = padded + CHECKER
    binary += b"\0" * (-len(binary) % 4)
    doc = document(None, len(binary), {"bufferView": 4, "mimeType": "image/png"})
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(padded), "byteLength": len(CHECKER)})
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    (HERE / "scene.glb").write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks)


if __name__ == "__main__":
    main()
