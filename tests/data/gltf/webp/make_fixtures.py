"""Writes texels.webp (lossless WebP) and texels.png: the same 4x3 RGB texels,
each a different colour, for tests/gltf_extensions.rs (EXT_texture_webp).

Run with Python 3 and Pillow (made with Pillow 13.0.0): python3 make_fixtures.py
"""

from PIL import Image

WIDTH, HEIGHT = 4, 3
texels = [
    (17 + 60 * x, 200 - 70 * y, (37 * (x + 2 * y)) % 256)
    for y in range(HEIGHT)
    for x in range(WIDTH)
]
image = Image.new("RGB", (WIDTH, HEIGHT))
image.putdata(texels)
image.save("texels.webp", lossless=True, exact=True)
image.save("texels.png")
# The WebP must decode to the same texels.
assert Image.open("texels.webp").convert("RGB").tobytes() == image.tobytes()
