#!/usr/bin/env python3
"""Seeds fuzz/corpus/{ply,toml,gltf,textures} (called by seed.sh): the project's small
PLY, TOML and glTF test files, and tiny images (PNG, BMP, TGA) written here, laid out
as each target reads its input (see tests/support/fuzz_checks.rs)."""
import os
import re
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "tests", "data")
GLTF_SEPARATOR = b"\n#FILE#\n"


def put(target, name, data):
    folder = os.path.join(HERE, "corpus", target)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data)


def read(*path):
    with open(os.path.join(DATA, *path), "rb") as f:
        return f.read()


def png(width, height, channels, depth=8):
    colour = {1: 0, 2: 4, 3: 2, 4: 6}[channels]
    bpp = channels * depth // 8
    rows = b"".join(
        b"\0" + bytes((x * 37 + y * 91 + c * 13) % 256 for x in range(width) for c in range(bpp))
        for y in range(height)
    )

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")


def bmp(width, height):
    row = bytes((x * 50 + c * 80) % 256 for x in range(width) for c in range(3))
    row += b"\0" * ((4 - len(row) % 4) % 4)
    pixels = row * height
    header = b"BM" + struct.pack("<IHHI", 54 + len(pixels), 0, 0, 54)
    info = struct.pack("<IiiHHIIiiII", 40, width, height, 1, 24, 0, len(pixels), 2835, 2835, 0, 0)
    return header + info + pixels


def tga(width, height, rle=False):
    header = struct.pack("<BBBHHBHHHHBB", 0, 0, 10 if rle else 2, 0, 0, 0, 0, 0, width, height, 32, 8)
    if rle:
        body = (bytes([0x80 | (width - 1)]) + b"\x10\x80\xf0\xff") * height
    else:
        body = bytes((x * 30 + c * 70) % 256 for x in range(width * height) for c in range(4))
    return header + body


# PLY: the project's small files, and one of each binary byte order with normals and
# texture coordinates.
put("ply", "cube.ply", read("real", "assimp", "cube.ply"))
put("ply", "cube_binary.ply", read("real", "assimp", "cube_binary.ply"))
put("ply", "created-by.ply", read("forgiving", "created-by.ply"))
for order, fmt in (("little", "<"), ("big", ">")):
    header = (
        "ply\nformat binary_%s_endian 1.0\ncomment seed\nelement vertex 4\n" % order
        + "".join("property float %s\n" % p for p in ("x", "y", "z", "nx", "ny", "nz", "s", "t"))
        + "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    body = b"".join(struct.pack(fmt + "8f", x, y, z, 0, 0, 1, x, y) for x, y, z in corners)
    body += struct.pack(fmt + "B3i", 3, 0, 1, 2) + struct.pack(fmt + "B4i", 4, 0, 1, 2, 3)
    put("ply", "quad_%s.ply" % order, header + body)
put("ply", "polygon_ascii.ply", (
    "ply\nformat ascii 1.0\nelement vertex 6\nproperty double x\nproperty double y\nproperty double z\n"
    "element face 1\nproperty list uchar uint vertex_indices\nelement edge 1\nproperty int a\nproperty int b\nend_header\n"
    "0 0 0\n2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n6 0 1 2 3 4 5\n0 1\n").encode())

# TOML: scenes naming the fixed meshes a.obj and b.ply.
put("toml", "cornell.toml", re.sub(rb'file = "[^"]*"', b'file = "a.obj"',
                                     open(os.path.join(HERE, "..", "examples", "cornell-box", "scene.toml"), "rb").read()))
put("toml", "missing-mtl.toml", read("forgiving", "missing-mtl.toml").replace(b"missing-mtl.obj", b"b.ply"))
put("toml", "everything.toml", b"""[camera]
look_from = [0.5, 0.5, 3]
look_to = [0.5, 0.5, 0]
up = [0, 1, 0]
fov = 45
width = 32
height = 24

[render]
mode = "path"
depth = 4
spp = 2

[[mesh]]
file = "a.obj"
transform = { translate = [1, 0, -2], rotate = [0, 90, 0], scale = 0.5 }

[[mesh]]
file = "b.ply"
material = "clay"
[mesh.transform]
scale = [1, 2, 1]

[[sphere]]
center = [0.15, 0.1, -0.1]
radius = 0.05
material = "mirror"

[[light]]
position = [0.5, 0.9, 0.6]
intensity = [1.0, 1.0, 1.0]

[materials.clay]
Kd = [0.8, 0.5, 0.3]
Ns = 10

[materials.mirror]
Ks = [1, 1, 1]
d = 1
al = [0.2, 0.8, 0]
""")

# glTF: the test scenes with their buffer and image renamed to b.bin and t.png.
gltf = read("gltf", "scene.gltf").replace(b"scene.bin", b"b.bin").replace(b"checker.png", b"t.png")
put("gltf", "scene", gltf + GLTF_SEPARATOR + read("gltf", "scene.bin") + GLTF_SEPARATOR + read("gltf", "checker.png"))
put("gltf", "glb", read("gltf", "scene.glb"))
put("gltf", "datauri", read("gltf", "datauri.gltf"))

# Textures: MTL maps naming t.png, a NUL byte, the image.
mtl = b"""newmtl a
Kd 1 1 1
map_Kd -s 2 2 1 -o 0.5 0 0 t.png
map_d -imfchan m t.png
newmtl b
Ks 0.5 0.5 0.5
Ns 20
map_Ns -mm 0.1 2 t.png
bump -bm 2 -clamp on t.png
newmtl c
norm t.png
map_Ke t.png
"""
images = {
    "png-grey": png(2, 2, 1),
    "png-grey-alpha": png(3, 1, 2),
    "png-rgb": png(2, 3, 3),
    "png-rgba": png(2, 2, 4),
    "png-rgb16": png(2, 2, 3, 16),
    "bmp": bmp(3, 2),
    "tga": tga(2, 2),
    "tga-rle": tga(3, 2, rle=True),
}
for name, image in images.items():
    put("textures", name, mtl + b"\0" + image)
put("textures", "checker", mtl + b"\0" + read("gltf", "checker.png"))
