"""Readers that pathwave did not write, to check its files against: EXR through the OpenEXR package, PNG decoded here
from the specification (zlib and the five scanline filters), and the film statistics' fixed-point words."""

from __future__ import annotations

import json
import os
import struct
import zlib
from fractions import Fraction
from typing import Dict, Tuple

import numpy as np
import OpenEXR

# The exact film's units (docs/guide/many-machines.md): sums in 2^-64, squares in 2^-48.
SUM_UNIT_BITS = 64
SQUARE_UNIT_BITS = 48


def read_exr(path: "os.PathLike[str] | str") -> Tuple[Dict[str, np.ndarray], dict]:
    """Every channel of the EXR's first part by name (each a (height, width) array of the file's own type), and its
    header."""
    f = OpenEXR.File(os.fspath(path), separate_channels=True)
    part = f.parts[0]
    channels = {name: np.asarray(c.pixels) for name, c in part.channels.items()}
    return channels, dict(part.header)


def exr_layer(channels: Dict[str, np.ndarray], names) -> np.ndarray:
    """The named channels stacked on a last axis: (height, width, len(names))."""
    return np.stack([channels[n] for n in names], axis=-1)


def film_meta(header: dict) -> dict:
    """The film file's `pathwave` header attribute (JSON)."""
    return json.loads(header["pathwave"])


def exact_sums(channels: Dict[str, np.ndarray]):
    """From a film file's u32 words (`pathwave.count`, `pathwave.sum0.R` .. `sum3.B`, least significant first, and
    `pathwave.square0.R` .. `square4.B`): per pixel the count, and per pixel and channel the exact sum and sum of
    squares as Fractions. Returns (count (h, w) int array, sums, squares) with sums/squares nested lists [y][x][c]."""
    count = channels["pathwave.count"].astype(np.int64)
    h, w = count.shape

    def wide(prefix: str, words: int, unit_bits: int):
        out = [[[None] * 3 for _ in range(w)] for _ in range(h)]
        for c, name in enumerate("RGB"):
            ws = [channels[f"pathwave.{prefix}{k}.{name}"] for k in range(words)]
            for y in range(h):
                for x in range(w):
                    v = 0
                    for k in range(words):
                        v |= int(ws[k][y, x]) << (32 * k)
                    out[y][x][c] = Fraction(v, 1 << unit_bits)
        return out

    return count, wide("sum", 4, SUM_UNIT_BITS), wide("square", 5, SQUARE_UNIT_BITS)


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_png(path: "os.PathLike[str] | str") -> np.ndarray:
    """An 8-bit, non-interlaced PNG (grey, grey+alpha, RGB or RGBA) as uint8 (height, width, channels)."""
    with open(path, "rb") as f:
        data = f.read()
    assert data[:8] == PNG_SIGNATURE, f"{path}: not a PNG"
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + n]
        crc = struct.unpack(">I", data[pos + 8 + n : pos + 12 + n])[0]
        assert zlib.crc32(kind + body) == crc, f"{path}: bad CRC in {kind!r}"
        pos += 12 + n
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    assert ihdr is not None, f"{path}: no IHDR"
    w, h, depth, colour, _, _, interlace = ihdr
    assert depth == 8 and interlace == 0, f"{path}: bit depth {depth}, interlace {interlace} not supported here"
    ch = {0: 1, 4: 2, 2: 3, 6: 4}[colour]
    raw = zlib.decompress(idat)
    stride = w * ch
    assert len(raw) == h * (stride + 1), f"{path}: {len(raw)} bytes of scanlines for {w}x{h}x{ch}"
    out = np.zeros((h, stride), np.uint8)
    prev = np.zeros(stride, np.int64)
    for y in range(h):
        kind = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int64)
        cur = np.zeros(stride, np.int64)
        if kind in (0, 2):  # None, Up: no dependence within the row
            cur = (line + (prev if kind == 2 else 0)) & 255
        else:
            for x in range(stride):
                a = cur[x - ch] if x >= ch else 0
                b = prev[x]
                c = prev[x - ch] if x >= ch else 0
                if kind == 1:
                    p = a
                elif kind == 3:
                    p = (a + b) // 2
                elif kind == 4:
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                else:
                    raise AssertionError(f"{path}: filter type {kind}")
                cur[x] = (line[x] + p) & 255
        out[y] = cur
        prev = cur
    return out.reshape(h, w, ch)


def srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB clipped to [0, 1] through the sRGB curve (IEC 61966-2-1), to 8 bits rounded."""
    x = np.clip(linear.astype(np.float64), 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(s * 255.0)
