#!/usr/bin/env python3
"""Writes an elevation-band (hypsometric) RGBA PNG of an SRTM .hgt tile, one pixel per sample:
8 equal bands between the tile's lowest and highest valid sample, voids transparent.
Usage: elevation_bands.py N44W072.hgt bands.png   (Python 3 standard library only)"""
import math, struct, sys, zlib

src, dst = sys.argv[1], sys.argv[2]
data = open(src, "rb").read()
n = int(math.isqrt(len(data) // 2))
if n * n * 2 != len(data):
    sys.exit(f"{src}: not a square SRTM tile ({len(data)} bytes)")
h = struct.unpack(f">{n * n}h", data)
valid = [v for v in h if v != -32768]
lo, hi = min(valid), max(valid)
colours = [(38, 115, 77), (92, 158, 74), (166, 196, 92), (235, 224, 138),
           (214, 170, 102), (170, 120, 80), (150, 140, 135), (245, 245, 245)]
rows = []
for r in range(n):
    row = bytearray(b"\0")  # PNG filter type 0
    for v in h[r * n:(r + 1) * n]:
        if v == -32768:
            row += b"\0\0\0\0"
        else:
            k = min(7, int(8 * (v - lo) / max(1, hi - lo)))
            row += bytes(colours[k]) + b"\xff"
    rows.append(bytes(row))
def chunk(t, d):
    return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", n, n, 8, 6, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(b"".join(rows), 9)) + chunk(b"IEND", b"")
open(dst, "wb").write(png)
print(f"{dst}: {n} x {n}, heights {lo}..{hi} m in 8 bands of {(hi - lo) / 8:.1f} m")
