"""Camera images: simgate's image records decoded into pixels (docs/components/cameras.md).

A record (``get_image``, ``capture``, ``get_snapshot``, a camera stream's sample) holds a PNG
file in base64: 8-bit RGB (``encoding`` ``rgb8``) or 16-bit grey in millimetres (``mono16``,
a depth camera). `decode_image` gives, with numpy installed, an ``HxWx3 uint8`` array (RGB)
or an ``HxW float32`` array of metres (depth; 0 where nothing was hit); without numpy, or
with ``numpy=False``, a `RawImage` holding the same pixels as bytes with their shape. The
PNG is read with the standard library (zlib): no imaging package is needed.
"""

from __future__ import annotations

import array
import base64
import struct
import sys
import zlib
from typing import Any, List, Mapping, NamedTuple, Optional, Tuple, Union

try:
    import numpy
except ImportError:  # the core runs without it
    numpy = None  # type: ignore[assignment]


class RawImage(NamedTuple):
    """Pixels without numpy: `data` row-major from the top row, `shape` (H, W[, 3]),
    `dtype` ``"uint8"`` (RGB) or ``"float32"`` (depth in metres, native byte order)."""

    data: bytes
    shape: Tuple[int, ...]
    dtype: str


Image = Union["numpy.ndarray", RawImage]


def decode_image(record: Mapping[str, Any], numpy_arrays: Optional[bool] = None) -> Image:
    """The pixels of an image record: a numpy array when numpy is installed (and
    `numpy_arrays` is not False), else a `RawImage`. Depth is converted to metres."""
    if record.get("format") != "png" or "image" not in record:
        raise ValueError(f"not a PNG image record (format {record.get('format')!r}; "
                         "DDS raw records have no pixels in JSON)")
    width, height, depth, channels, pixels = _read_png(base64.b64decode(record["image"]))
    use_numpy = numpy is not None if numpy_arrays is None else numpy_arrays
    if use_numpy and numpy is None:
        raise ImportError("decode_image(numpy_arrays=True): numpy is not installed "
                          "(pip install 'simgate[numpy]')")
    metres = record.get("encoding") == "mono16" or depth == 16
    scale = {"mm": 0.001, "m": 1.0}.get(record.get("depth_unit", "mm"), 0.001)
    shape: Tuple[int, ...] = (height, width) if channels == 1 else (height, width, channels)
    if use_numpy:
        if depth == 16:
            values = numpy.frombuffer(pixels, dtype=">u2").reshape(shape)
            # in double, then rounded to float32: the same numbers as without numpy
            return (values * scale).astype(numpy.float32) if metres else values
        return numpy.frombuffer(pixels, dtype=numpy.uint8).reshape(shape).copy()
    if depth == 16:
        values16 = array.array("H", pixels)
        if sys.byteorder == "little":
            values16.byteswap()  # PNG samples are big-endian
        return RawImage(array.array("f", (v * scale for v in values16)).tobytes(), shape, "float32")
    return RawImage(pixels, shape, "uint8")


_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}  # PNG colour type → samples per pixel (no palettes)


def _read_png(data: bytes) -> Tuple[int, int, int, int, bytes]:
    """(width, height, bit depth, channels, unfiltered pixel rows) of a PNG file."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG file")
    pos, idat, header = 8, [], None
    while pos + 8 <= len(data):
        (length,), kind = struct.unpack(">I", data[pos:pos + 4]), data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    if header is None:
        raise ValueError("PNG without IHDR")
    width, height, depth, colour, _, _, interlace = header
    if colour not in _CHANNELS or depth not in (8, 16) or interlace:
        raise ValueError(f"PNG colour type {colour}, depth {depth}, interlace {interlace}: "
                         "only 8/16-bit grey, RGB and RGBA without interlace are read")
    channels = _CHANNELS[colour]
    bpp = channels * depth // 8
    stride = width * bpp
    raw = zlib.decompress(b"".join(idat))
    if len(raw) != height * (stride + 1):
        raise ValueError(f"PNG data of {len(raw)} bytes, expected {height * (stride + 1)}")
    rows: List[bytes] = []
    prev = bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind = raw[start]
        row = bytearray(raw[start + 1:start + 1 + stride])
        if kind:
            _unfilter(kind, row, prev, bpp)
        rows.append(bytes(row))
        prev = row
    return width, height, depth, channels, b"".join(rows)


def _unfilter(kind: int, row: bytearray, prev: bytearray, bpp: int) -> None:
    """Undo one row's PNG filter in place (1 Sub, 2 Up, 3 Average, 4 Paeth)."""
    n = len(row)
    if kind == 1:
        for i in range(bpp, n):
            row[i] = (row[i] + row[i - bpp]) & 0xFF
    elif kind == 2:
        for i in range(n):
            row[i] = (row[i] + prev[i]) & 0xFF
    elif kind == 3:
        for i in range(n):
            left = row[i - bpp] if i >= bpp else 0
            row[i] = (row[i] + ((left + prev[i]) >> 1)) & 0xFF
    elif kind == 4:
        for i in range(n):
            a = row[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            p = a + b - c
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            row[i] = (row[i] + pred) & 0xFF
    else:
        raise ValueError(f"PNG filter type {kind} is not one of 0-4")
