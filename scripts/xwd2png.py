#!/usr/bin/env python3
"""Converts a 24/32-bit TrueColor XWD screen dump (`xwd -root`) to PNG, optionally
cropped to the top-left WIDTHxHEIGHT: `xwd2png.py IN.xwd OUT.png [WIDTHxHEIGHT]`.

Only the standard library: no ImageMagick needed to make the README's screenshot.
"""
import struct
import sys
import zlib


def read_xwd(path):
    data = open(path, "rb").read()
    fields = struct.unpack(">25I", data[:100])
    header_size, version = fields[0], fields[1]
    if version != 7:
        sys.exit(f"{path}: not an XWD version 7 file")
    width, height = fields[4], fields[5]
    byte_order, bpp, bytes_per_line = fields[7], fields[11], fields[12]
    masks = fields[14:17]
    ncolors = fields[19]
    if bpp != 32:
        sys.exit(f"{path}: {bpp} bits per pixel; only 32 is supported")
    start = header_size + 12 * ncolors
    fmt = "<I" if byte_order == 0 else ">I"
    shifts = [(m & -m).bit_length() - 1 for m in masks]
    rows = []
    for y in range(height):
        line = data[start + y * bytes_per_line : start + y * bytes_per_line + 4 * width]
        row = bytearray()
        for (px,) in struct.iter_unpack(fmt, line):
            row += bytes(((px & m) >> s) & 0xFF for m, s in zip(masks, shifts))
        rows.append(bytes(row))
    return width, height, rows


def write_png(path, width, height, rows):
    raw = b"".join(b"\x00" + r for r in rows)

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9))
    png += chunk(b"IEND", b"")
    open(path, "wb").write(png)


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    width, height, rows = read_xwd(sys.argv[1])
    if len(sys.argv) == 4:
        w, h = (int(v) for v in sys.argv[3].split("x"))
        width, height = min(w, width), min(h, height)
        rows = [r[: 3 * width] for r in rows[:height]]
    write_png(sys.argv[2], width, height, rows)


if __name__ == "__main__":
    main()
