"""Decoding and encoding of clutterseg.label_image_t payloads (standard library only).

    from clutterseg import label_image_t
    from clutterseg.label_image_codec import decode

    labels = decode(label_image_t.decode(data))     # array('H'), width * height ids
    object_id = labels[v * msg.width + u]          # 0 = background or no measurement

The three layouts of label_image_t.compression: COMPRESSION_NONE (little-endian uint16 per
pixel, row-major), COMPRESSION_RLE ((uint16 id, uint32 run length) little-endian pairs) and
COMPRESSION_ZLIB (the uncompressed layout deflated with zlib). A malformed message raises
ValueError before anything is allocated for it.
"""

import array
import struct
import sys
import zlib

__all__ = ["decode", "encode", "MAX_PIXELS"]

MAX_PIXELS = 4096 * 4096  # the daemon's frame limit; larger images are refused
_NONE, _RLE, _ZLIB = 0, 1, 2


def _from_le16(raw, n):
    if len(raw) != 2 * n:
        raise ValueError("label_image_t: %d label bytes for %d pixels" % (len(raw), n))
    labels = array.array("H")
    labels.frombytes(raw)
    if sys.byteorder != "little":
        labels.byteswap()
    return labels


def decode(msg):
    """The ids of a label_image_t as array('H') of width * height entries, row-major."""
    width, height = msg.width, msg.height
    if width < 0 or height < 0 or width * height > MAX_PIXELS:
        raise ValueError("label_image_t: bad size %dx%d" % (width, height))
    n = width * height
    data = bytes(msg.data)
    if msg.size != len(data):
        raise ValueError("label_image_t: size %d != %d data bytes" % (msg.size, len(data)))
    if msg.compression == _NONE:
        return _from_le16(data, n)
    if msg.compression == _ZLIB:
        inflater = zlib.decompressobj()
        raw = inflater.decompress(data, 2 * n + 1)  # never more than the image needs
        if len(raw) > 2 * n or inflater.unconsumed_tail:
            raise ValueError("label_image_t: zlib data larger than the image")
        return _from_le16(raw, n)
    if msg.compression == _RLE:
        if len(data) % 6 != 0:
            raise ValueError("label_image_t: RLE data is truncated")
        labels = array.array("H", bytes(2 * n))
        pos = 0
        for label, run in struct.iter_unpack("<HI", data):
            if run > n - pos:
                raise ValueError("label_image_t: RLE runs exceed the image")
            if label:
                labels[pos:pos + run] = array.array("H", [label]) * run
            pos += run
        if pos != n:
            raise ValueError("label_image_t: RLE runs cover %d of %d pixels" % (pos, n))
        return labels
    raise ValueError("label_image_t: unknown compression %d" % msg.compression)


def encode(labels, width, height, compression=_RLE):
    """The (compression, data bytes) of ids `labels` (a sequence of width * height ints in
    0..65535), for tests and tools that publish label images."""
    n = width * height
    if len(labels) != n:
        raise ValueError("%d labels for %dx%d" % (len(labels), width, height))
    raw = array.array("H", labels)
    if sys.byteorder != "little":
        raw.byteswap()
    if compression == _NONE:
        return _NONE, raw.tobytes()
    if compression == _ZLIB:
        return _ZLIB, zlib.compress(raw.tobytes(), 1)
    if compression != _RLE:
        raise ValueError("unknown compression %d" % compression)
    out = bytearray()
    i = 0
    while i < n:
        j = i + 1
        while j < n and labels[j] == labels[i]:
            j += 1
        out += struct.pack("<HI", labels[i], j - i)
        i = j
    return _RLE, bytes(out)
