#!/usr/bin/env python3
"""Writes the seed corpus of the fuzz targets into tests/fuzz/corpus/<target>/ (committed; run
again only to change the seeds). Standard library only, plus libturbojpeg through ctypes for the
JPEG seeds. Every file is small: the fuzzers grow their own corpora from these."""
import ctypes
import ctypes.util
import os
import random
import struct
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "corpus")


def put(target, name, data):
    d = os.path.join(CORPUS, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def gradient(w, h, channels=1, maxval=255, seed=0):
    """Row-major samples: a diagonal gradient with a little deterministic texture."""
    out = []
    for y in range(h):
        for x in range(w):
            for c in range(channels):
                v = ((x * 37 + y * 23 + c * 61 + seed * 11) * maxval) // (37 * w + 23 * h + 61 * 3)
                out.append(min(maxval, v))
    return out


# ---- PNM -----------------------------------------------------------------------------------------
def pnm_seeds():
    put("pnm", "p5_8x6.pgm", b"P5\n8 6\n255\n" + bytes(gradient(8, 6)))
    put("pnm", "p2_4x3_comment.pgm",
        "P2\n# ascii gray\n4 3\n15\n" + " ".join(str(v) for v in gradient(4, 3, 1, 15)) + "\n")
    put("pnm", "p6_4x4.ppm", b"P6 4 4 255\n" + bytes(gradient(4, 4, 3)))
    put("pnm", "p3_2x2.ppm", "P3\n2 2\n255\n" + " ".join(str(v) for v in gradient(2, 2, 3)) + "\n")
    samples16 = gradient(4, 2, 1, 65535)
    put("pnm", "p5_16bit.pgm", b"P5\n4 2\n65535\n" + b"".join(struct.pack(">H", v) for v in samples16))
    samples = gradient(2, 2, 3, 1000)
    put("pnm", "p6_maxval1000.ppm", b"P6\n2 2\n1000\n" + b"".join(struct.pack(">H", v) for v in samples))


# ---- Y4M -----------------------------------------------------------------------------------------
def y4m(w, h, chroma, frames=1, extra_tags=" F25:1 Ip A1:1", frame_line="FRAME"):
    depth = 8
    planes, sx, sy, alpha = 2, 1, 1, False
    base = chroma
    for prefix, p, x, y, a in (("444alpha", 2, 0, 0, True), ("420", 2, 1, 1, False),
                               ("411", 2, 2, 0, False), ("422", 2, 1, 0, False),
                               ("444", 2, 0, 0, False), ("mono", 0, 0, 0, False)):
        if chroma.startswith(prefix):
            planes, sx, sy, alpha, base = p, x, y, a, prefix
            break
    suffix = chroma[len(base):]
    if suffix.startswith("p") and suffix[1:].isdigit():
        depth = int(suffix[1:])
    elif suffix.isdigit():
        depth = int(suffix)
    sample = 2 if depth > 8 else 1
    cw = (w + (1 << sx) - 1) >> sx
    ch = (h + (1 << sy) - 1) >> sy
    other = planes * cw * ch + (w * h if alpha else 0)
    out = ("YUV4MPEG2 W%d H%d%s C%s\n" % (w, h, extra_tags, chroma)).encode()
    for i in range(frames):
        out += (frame_line + "\n").encode()
        luma = gradient(w, h, 1, (1 << depth) - 1, seed=i)
        if sample == 1:
            out += bytes(luma) + bytes([128]) * other
        else:
            out += b"".join(struct.pack("<H", v) for v in luma) + struct.pack("<H", 1 << (depth - 1)) * other
    return out


def y4m_seeds():
    put("y4m", "420jpeg_8x6_2frames.y4m", y4m(8, 6, "420jpeg", 2))
    put("y4m", "mono_4x4.y4m", y4m(4, 4, "mono", 1, " F30000:1001"))
    put("y4m", "422p10_4x2.y4m", y4m(4, 2, "422p10", 1))
    put("y4m", "444alpha_2x2.y4m", y4m(2, 2, "444alpha", 1, " XCOMMENT=seed"))
    put("y4m", "411_8x2.y4m", y4m(8, 2, "411", 1))
    put("y4m", "mono16_3x2.y4m", y4m(3, 2, "mono16", 1))
    put("y4m", "420_frame_tags.y4m", y4m(4, 4, "420", 2, "", "FRAME Ip XTAG"))
    put("y4m", "truncated.y4m", y4m(8, 6, "420mpeg2", 2)[:-20])


# ---- PNG -----------------------------------------------------------------------------------------
def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def pack_row(samples, depth):
    if depth == 8:
        return bytes(samples)
    if depth == 16:
        return b"".join(struct.pack(">H", v) for v in samples)
    out, acc, bits = bytearray(), 0, 0
    for v in samples:
        acc = (acc << depth) | v
        bits += depth
        if bits == 8:
            out.append(acc)
            acc, bits = 0, 0
    if bits:
        out.append(acc << (8 - bits))
    return bytes(out)


ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def png(w, h, color, depth, channels, interlace=False, plte=None, trns=None, seed=0):
    maxval = (1 << depth) - 1
    pixels = gradient(w, h, channels, maxval, seed)

    def sample(x, y):
        i = (y * w + x) * channels
        return pixels[i:i + channels]

    raw = bytearray()
    passes = ADAM7 if interlace else ((0, 0, 1, 1),)
    for x0, y0, dx, dy in passes:
        xs = list(range(x0, w, dx))
        for y in range(y0, h, dy):
            if not xs:
                continue
            row = [v for x in xs for v in sample(x, y)]
            raw += b"\x00" + pack_row(row, depth)  # filter type None
    out = b"\x89PNG\r\n\x1a\n"
    out += png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, color, 0, 0, 1 if interlace else 0))
    if plte is not None:
        out += png_chunk(b"PLTE", plte)
    if trns is not None:
        out += png_chunk(b"tRNS", trns)
    out += png_chunk(b"IDAT", zlib.compress(bytes(raw), 9))
    out += png_chunk(b"IEND", b"")
    return out


def png_seeds():
    put("png", "gray8_8x6.png", png(8, 6, 0, 8, 1))
    put("png", "gray1_9x2.png", png(9, 2, 0, 1, 1))
    put("png", "gray_alpha16_3x3.png", png(3, 3, 4, 16, 2))
    put("png", "rgb8_4x4.png", png(4, 4, 2, 8, 3))
    put("png", "rgba16_2x2.png", png(2, 2, 6, 16, 4))
    palette = bytes(v for i in range(16) for v in (i * 16, 255 - i * 16, (i * 53) % 256))
    put("png", "palette4_trns_5x3.png", png(5, 3, 3, 4, 1, plte=palette, trns=bytes([0, 128, 255])))
    put("png", "gray8_interlaced_7x5.png", png(7, 5, 0, 8, 1, interlace=True))
    put("png", "rgb8_interlaced_5x3.png", png(5, 3, 2, 8, 3, interlace=True))


# ---- JPEG (libturbojpeg through ctypes) ----------------------------------------------------------
TJPF_RGB, TJPF_GRAY = 0, 6
TJSAMP_444, TJSAMP_422, TJSAMP_420, TJSAMP_GRAY = 0, 1, 2, 3
TJFLAG_PROGRESSIVE = 16384


class Jpeg:
    def __init__(self):
        name = ctypes.util.find_library("turbojpeg") or "libturbojpeg.so.0"
        self.tj = ctypes.CDLL(name)
        self.tj.tjInitCompress.restype = ctypes.c_void_p
        self.tj.tjCompress2.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_int,
                                        ctypes.c_int, ctypes.c_int,
                                        ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_ulong),
                                        ctypes.c_int, ctypes.c_int, ctypes.c_int]
        self.tj.tjFree.argtypes = [ctypes.c_void_p]
        self.tj.tjDestroy.argtypes = [ctypes.c_void_p]
        self.handle = self.tj.tjInitCompress()

    def encode(self, w, h, rgb, subsamp, quality, flags=0, seed=0):
        channels = 3 if rgb else 1
        pixels = bytes(gradient(w, h, channels, 255, seed))
        buf = ctypes.c_void_p()
        size = ctypes.c_ulong(0)
        rc = self.tj.tjCompress2(self.handle, pixels, w, w * channels, h, TJPF_RGB if rgb else TJPF_GRAY,
                                 ctypes.byref(buf), ctypes.byref(size), subsamp, quality, flags)
        if rc != 0:
            raise RuntimeError("tjCompress2 failed")
        data = ctypes.string_at(buf, size.value)
        self.tj.tjFree(buf)
        return data


def jpeg_seeds(jpeg):
    put("jpeg", "gray_16x16.jpg", jpeg.encode(16, 16, False, TJSAMP_GRAY, 75))
    put("jpeg", "gray_17x9_q95.jpg", jpeg.encode(17, 9, False, TJSAMP_GRAY, 95))
    put("jpeg", "rgb420_16x16.jpg", jpeg.encode(16, 16, True, TJSAMP_420, 60))
    put("jpeg", "rgb422_12x8.jpg", jpeg.encode(12, 8, True, TJSAMP_422, 80))
    put("jpeg", "rgb444_8x8.jpg", jpeg.encode(8, 8, True, TJSAMP_444, 50))
    put("jpeg", "gray_progressive_16x8.jpg", jpeg.encode(16, 8, False, TJSAMP_GRAY, 70, TJFLAG_PROGRESSIVE))
    put("jpeg", "rgb420_progressive_9x7.jpg", jpeg.encode(9, 7, True, TJSAMP_420, 70, TJFLAG_PROGRESSIVE))

    frames = [jpeg.encode(16, 12, False, TJSAMP_GRAY, 70, 0, seed=i) for i in range(3)]
    put("mjpeg", "three_frames.mjpeg", b"".join(frames))
    put("mjpeg", "truncated_middle.mjpeg", frames[0] + frames[1][: len(frames[1]) * 6 // 10] + frames[2])
    put("mjpeg", "junk_between.mjpeg", frames[0] + b"\x00\x11junk\xff" + frames[1])
    put("mjpeg", "size_change.mjpeg", frames[0] + jpeg.encode(8, 8, False, TJSAMP_GRAY, 70))
    put("mjpeg", "colour_frames.mjpeg",
        jpeg.encode(10, 6, True, TJSAMP_420, 60) + jpeg.encode(10, 6, True, TJSAMP_420, 60, TJFLAG_PROGRESSIVE, 1))


# ---- text ----------------------------------------------------------------------------------------
def text_seeds():
    put("text_formats", "trajectory.txt",
        "# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n1 0.1 -0.2 0.3 0.01 0.02 0.03 0.9994\n"
        "2.5 1e-3 2E2 -0 0 0 0.7071068 0.7071068\n")
    put("text_formats", "intrinsics.txt", "# fx fy cx cy width height\n525 525 319.5 239.5 640 480\n")
    put("text_formats", "intrinsics_k.txt", "700.5,700.5,351.2,288.7,704,576,-0.12,0.03\r\n")
    put("text_formats", "tracks.csv", "frame,track_id,x,y\n0,1,10.500,20.250\n0,2,33.000,4.125\n1,1,11.000,20.000\n")
    put("colmap", "model.txt",
        "# Camera list\n1 PINHOLE 640 480 525 525 319.5 239.5\n\f"
        "# Image list\n1 1 0 0 0 0 0 0 1 frame000000.jpg\n100.5 200.5 7 300 20 -1\n"
        "2 0.9998 0.0175 0 0 0.1 0 0 1 frame000001.jpg\n101.5 201.5 7\n\f"
        "# 3D points\n7 0.5 0.25 4 128 128 128 0.3 1 0 2 0\n")
    put("colmap", "opencv_camera.txt", "3 OPENCV 704 576 700 700 352 288 -0.1 0.01 0 0\n\f\f")
    put("device_config", "v4l2_full.txt",
        "v4l2:/dev/video0?width=640&height=480&fps=29.97&format=mjpeg&buffers=4&timeout_ms=500")
    put("device_config", "v4l2_plain.txt", "v4l2:/dev/video2")
    put("device_config", "size.txt", "704x576")
    put("device_config", "list.txt", "0.1,-0.02,3e-4")


def binary_seeds():
    rng = random.Random(9)
    for n in (16, 96, 400, 1500):
        put("v4l2_capture", "random_%d.bin" % n, bytes(rng.randrange(256) for _ in range(n)))
    put("v4l2_capture", "zeros_64.bin", bytes(64))


def main():
    pnm_seeds()
    y4m_seeds()
    png_seeds()
    jpeg_seeds(Jpeg())
    text_seeds()
    binary_seeds()
    for target in sorted(os.listdir(CORPUS)):
        files = os.listdir(os.path.join(CORPUS, target))
        total = sum(os.path.getsize(os.path.join(CORPUS, target, f)) for f in files)
        print("%-14s %2d files %6d bytes" % (target, len(files), total))
    return 0


if __name__ == "__main__":
    sys.exit(main())
