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

AEM = ("CCSDS_AEM_VERS = 2.0\nCREATION_DATE = 2025-01-01T00:00:00\nORIGINATOR = X\nMETA_START\nOBJECT_NAME = S\n"
       "OBJECT_ID = 2025-001A\nREF_FRAME_A = EME2000\nREF_FRAME_B = SC_BODY_1\nTIME_SYSTEM = UTC\n"
       "START_TIME = 2025-001T00:00:00\nSTOP_TIME = 2025-01-01T00:00:01.5\nATTITUDE_TYPE = QUATERNION/ANGVEL\n"
       "ANGVEL_FRAME = REF_FRAME_B\nMETA_STOP\nDATA_START\n2025-001T00:00:00 0 0 0.7071 0.7071 0.1 0 -0.2\n"
       "2025-01-01T00:00:01.5 0 0 0.7072 0.7070 0.1 0 -0.2\nDATA_STOP\n")
put("adm", "aem.kvn", AEM)
put("adm", "aem_v1.kvn", AEM.replace("2.0", "1.0", 1).replace("QUATERNION/ANGVEL", "QUATERNION\nQUATERNION_TYPE = FIRST\n"
                                      "ATTITUDE_DIR = B2A").replace("ANGVEL_FRAME = REF_FRAME_B\n", "")
    .replace(" 0.1 0 -0.2", ""))
put("adm", "acm.kvn", "CCSDS_ACM_VERS = 2.0\nCREATION_DATE = 2025-01-01T00:00:00\nORIGINATOR = X\nMETA_START\n"
    "OBJECT_NAME = S\nTIME_SYSTEM = TAI\nEPOCH_TZERO = 2025-01-01T00:00:00\nMETA_STOP\nATT_START\nREF_FRAME_A = ICRF\n"
    "REF_FRAME_B = AST_1\nNUMBER_STATES = 7\nATT_TYPE = QUATERNION\nRATE_TYPE = GYRO_BIAS\n0 0 0 0 1 1e-6 0 0\n"
    "0.5 0 0 0.01 1 1e-6 0 0\nATT_STOP\nCOV_START\nCOV_TYPE = ANGLE\n0 1e-8 1e-8 1e-6\n0.5 1e-8 1e-8 1e-6\nCOV_STOP\n"
    "AD_START\nAD_METHOD = EKF\nATTITUDE_STATES = QUATERNION\nREF_FRAME_A = ICRF\nREF_FRAME_B = AST_1\n"
    "SIGMA_U = 1e-9\nSIGMA_V = 1e-6\nSENSOR_START\nSENSOR_NUMBER = 1\nSENSOR_USED = AST_1\n"
    "NUMBER_SENSOR_NOISE_COVARIANCE = 2\nSENSOR_NOISE_STDDEV = 0.001 0.004 [deg]\nSENSOR_FREQUENCY = 2 [Hz]\n"
    "SENSOR_STOP\nAD_STOP\nPHYS_START\nWET_MASS = 1 [kg]\nPHYS_STOP\n")
put("adm", "acm.xml", '<?xml version="1.0"?>\n<!-- c -->\n<ndm><acm id="CCSDS_ACM_VERS" version="2.0"><header>'
    "<CREATION_DATE>2025-01-01T00:00:00</CREATION_DATE><ORIGINATOR>X &amp; Y</ORIGINATOR></header><body><segment>"
    "<metadata><OBJECT_NAME>S</OBJECT_NAME><TIME_SYSTEM>UTC</TIME_SYSTEM><EPOCH_TZERO>2025-01-01T00:00:00Z</EPOCH_TZERO>"
    "</metadata><data><att><REF_FRAME_A>J2000</REF_FRAME_A><REF_FRAME_B>SC_BODY_1</REF_FRAME_B><NUMBER_STATES>4"
    "</NUMBER_STATES><ATT_TYPE>QUATERNION</ATT_TYPE><attLine>0 0 0 0 1</attLine><attLine>1 0 0.1 0 1</attLine>"
    "</att></data></segment></body></acm></ndm>\n")

put("centroids", "centroids.csv", "x_px,y_px,flux,sigma_px\n10.5,20.25,1000,0.1\n300,400.5,250,0.2\n")
put("centroids", "xy.csv", "x_px,y_px\n1,2\n3,4\n")

put("flight_cfg", "flight.cfg", "# a unit\nn_heads 2\nn_gyros 4\nhead1.size_px 512 512\nhead1.focal_length_px 1754.8\n"
    "head1.principal_point_px 255.5 255.5\nhead1.psf_sigma_px 1.4\nhead1.vignetting 0.25\n"
    "head1.hot_pixels 3 10 20 511 0 7 7\nhead2.hot_pixels 0\nhead2.q_body_sensor 0.7071067811865476 0.7071067811865476 0 0\n"
    "gyro2.axis_body 0 1 0\nepoch_utc 2025-06-21T00:00:00Z\nvelocity_kms 1 2 3\ncatalog_crc32 12345\ncalibrate_unit 1\n")
put("flight_cfg", "bad.cfg", "n_heads 1\nhead1.hot_pixels 2 1 2\n")
