#!/usr/bin/env python3
"""Writes the fuzzers' small seed corpus (fuzz/corpus/<harness>/): tiny valid inputs of every format
the readers take, so that libFuzzer starts from the interesting structure rather than from nothing.
Run from the repository root: python3 fuzz/make_corpus.py"""
import json
import os
import struct
import zlib

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")


def put(sub, name, data):
    d = os.path.join(ROOT, sub)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def star_image(w, h, peak):
    """Background 10 with one Gaussian-ish star near the centre."""
    px = []
    for y in range(h):
        for x in range(w):
            r2 = (x - w / 2 + 0.3) ** 2 + (y - h / 2 - 0.2) ** 2
            px.append(10 + int(peak * 2.718281828 ** (-r2 / 2.0)) + (x * 7 + y * 3) % 4)
    return px


def png(w, h, px, depth, interlace=0):
    def chunk(t, data):
        c = t + data
        return struct.pack(">I", len(data)) + c + struct.pack(">I", zlib.crc32(c) & 0xFFFFFFFF)
    fmt = "B" if depth == 8 else ">H"
    raw = b"".join(b"\0" + b"".join(struct.pack(fmt, min(v, 2 ** depth - 1)) for v in px[y * w:(y + 1) * w])
                   for y in range(h))
    ihdr = struct.pack(">IIBBBBB", w, h, depth, 0, 0, 0, interlace)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def tiff(w, h, px):
    """Uncompressed 16-bit grey, little endian, one strip (TIFF 6.0 baseline)."""
    data = b"".join(struct.pack("<H", v) for v in px)
    entries = [(256, 3, 1, w), (257, 3, 1, h), (258, 3, 1, 16), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 8), (277, 3, 1, 1), (278, 3, 1, h), (279, 4, 1, len(data))]
    ifd = struct.pack("<H", len(entries))
    for tag, typ, count, value in entries:
        ifd += struct.pack("<HHI", tag, typ, count) + (struct.pack("<HH", value, 0) if typ == 3 else struct.pack("<I", value))
    ifd += struct.pack("<I", 0)
    return b"II*\0" + struct.pack("<I", 8 + len(data)) + data + ifd


def fits(w, h, px, bitpix):
    cards = ["SIMPLE  =                    T", "BITPIX  = %20d" % bitpix, "NAXIS   =                    2",
             "NAXIS1  = %20d" % w, "NAXIS2  = %20d" % h, "END"]
    header = "".join(c.ljust(80) for c in cards).ljust(2880).encode()
    fmt = {8: ">B", 16: ">h", -32: ">f"}[bitpix]
    data = b"".join(struct.pack(fmt, float(v) if bitpix < 0 else min(v, 255 if bitpix == 8 else 32767)) for v in px)
    return header + data.ljust((len(data) + 2879) // 2880 * 2880, b"\0")


px = star_image(16, 16, 3000)
def bmp(w, h, px, bits):
    """Windows BMP, BITMAPINFOHEADER, bottom-up rows padded to 4 bytes: 8-bit with a grey palette, or
    24-bit BGR (the star in blue-green-red = v, v // 2, v // 3)."""
    rows = []
    for y in reversed(range(h)):
        row = bytes(px[y * w:(y + 1) * w]) if bits == 8 else b"".join(
            bytes((v, v // 2, v // 3)) for v in px[y * w:(y + 1) * w])
        rows.append(row + b"\0" * (-len(row) % 4))
    palette = b"".join(bytes((i, i, i, 0)) for i in range(256)) if bits == 8 else b""
    data = b"".join(rows)
    off = 14 + 40 + len(palette)
    head = b"BM" + struct.pack("<IHHI", off + len(data), 0, 0, off)
    info = struct.pack("<IiiHHIIiiII", 40, w, h, 1, bits, 0, len(data), 2835, 2835, 256 if bits == 8 else 0, 0)
    return head + info + palette + data


put("image", "grey16.png", png(16, 16, px, 16))
put("image", "grey8.png", png(16, 16, [min(v, 255) for v in star_image(16, 16, 200)], 8))
put("image", "grey16.tif", tiff(16, 16, px))
put("image", "int16.fits", fits(16, 16, px, 16))
put("image", "float.fits", fits(16, 16, px, -32))
put("image", "byte.fits", fits(16, 16, [min(v, 255) for v in star_image(16, 16, 200)], 8))
put("image", "grey8.bmp", bmp(16, 16, [min(v, 255) for v in star_image(16, 16, 200)], 8))
put("image", "rgb24.bmp", bmp(16, 16, [min(v, 255) for v in star_image(16, 16, 200)], 24))
# grey8.jpg (baseline) and rgb8.jpg (progressive): 16 x 16 stars written by libjpeg-turbo at quality 90,
# kept as files (no JPEG encoder here).

put("csv", "gyro.csv", "t_s,wx_dph,wy_dph,wz_dph,temp_c\n0.01,1.5,-2,3e1,20.5\n0.02,1.4,-2.1,30,20.6\n")
put("csv", "units.csv", "t_s,g1_dph,g2_dph,azimuth_deg,bn_ut,be_ut,bh_ut\n0,1,2,90,20,0,-40\n1,1,2,180,20,0,-40\n")
put("csv", "st.csv", "\ufefft_s,qw,qx,qy,qz,sigma_cross_arcsec\n0,1,0,0,0,5\n1,0.7071,0.7071,0,0,5\n")

cam = {"width": 64, "height": 48, "focal_length_px": 200.0, "principal_point": [31.5, 23.5],
       "distortion": {"k1": -0.1, "k2": 0.01, "k3": 0, "p1": 1e-4, "p2": 0}, "gain_e_per_adu": 0.5}
put("json", "camera.json", json.dumps(cam))
put("json", "camera_mm.json", json.dumps({"width": 1392, "height": 1040, "focal_length_mm": 50, "pixel_pitch_um": 6.45}))
put("json", "heads.json", json.dumps([{"camera": cam, "q_body_sensor": [1, 0, 0, 0]}]))
put("json", "nested.json", '{"a": {"k": 1}, "b": [{"k": 2}, {"k": 3}], // comment\n "c": "s"}')

put("centroids", "centroids.csv", "x_px,y_px,flux,sigma_px\n10.5,20.25,1000,0.1\n300,400.5,250,0.2\n")
put("centroids", "xy.csv", "x_px,y_px\n1,2\n3,4\n")
