#!/usr/bin/env python3
"""Puts the same crop of several 8-bit RGB PNGs side by side, enlarged with nearest
neighbour so single pixels stay visible. Standard library only.

Usage: zoom.py X Y WIDTH HEIGHT FACTOR OUT.png IN.png [IN.png ...]
"""

import struct
import sys
import zlib

GAP = 4  # pixels of white between the crops


def read_png(path):
    """Returns (width, height, rows of bytes) of a non-interlaced 8-bit RGB PNG."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG file")
    pos, idat = 8, b""
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (8, 2, 0):
                sys.exit(f"{path}: only 8-bit RGB non-interlaced PNGs are supported")
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride, bpp = width * 3, 3
    rows, previous = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind, line = raw[start], bytearray(raw[start + 1 : start + 1 + stride])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = previous[i]
            c = previous[i - bpp] if i >= bpp else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                predictor = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + predictor) & 255
        rows.append(line)
        previous = line
    return width, height, rows


def write_png(path, width, height, rows):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    raw = b"".join(b"\x00" + bytes(row) for row in rows)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def main():
    if len(sys.argv) < 8:
        sys.exit(__doc__)
    x, y, w, h, factor = map(int, sys.argv[1:6])
    out, inputs = sys.argv[6], sys.argv[7:]
    crops = []
    for path in inputs:
        width, height, rows = read_png(path)
        if x + w > width or y + h > height:
            sys.exit(f"{path}: the crop does not fit in {width}x{height}")
        crops.append([row[3 * x : 3 * (x + w)] for row in rows[y : y + h]])
    out_w = len(crops) * w * factor + (len(crops) - 1) * GAP
    out_rows = []
    for r in range(h * factor):
        line = bytearray()
        for n, crop in enumerate(crops):
            if n:
                line += b"\xff" * (3 * GAP)
            for px in range(w):
                line += bytes(crop[r // factor][3 * px : 3 * px + 3]) * factor
        out_rows.append(line)
    write_png(out, out_w, h * factor, out_rows)


if __name__ == "__main__":
    main()
