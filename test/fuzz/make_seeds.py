#!/usr/bin/python3
"""Writes the seed corpus of the fuzz targets into corpus/<target>/ (committed; rerun to
regenerate): small valid inputs of every kind each target reads, so that the fuzzer starts
from the formats rather than from random bytes."""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def out(target, name, data):
    folder = os.path.join(HERE, "corpus", target)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data)


def scene(n_table=120, n_box=60):
    """A table plane at y = 0.3 (camera frame, y down) with a small box standing on it."""
    points = []
    for i in range(n_table):
        points.append((-0.3 + 0.6 * (i % 12) / 11, 0.3, 0.8 + 0.4 * (i // 12) / 9))
    for i in range(n_box):
        points.append((-0.05 + 0.1 * (i % 6) / 5, 0.3 - 0.1 * (i // 6) / 9, 0.95))
    return points


def lzf_literals(data):
    """Valid LZF made of literal runs only (<= 32 bytes each)."""
    out_bytes = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i:i + 32]
        out_bytes.append(len(chunk) - 1)
        out_bytes += chunk
    return bytes(out_bytes)


def pcd(points, encoding, fields="x y z", size=4):
    n = len(points)
    names = fields.split()
    head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\n"
            "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n" % (
                fields, " ".join([str(size)] * len(names)), " ".join("F" * len(names)),
                " ".join("1" * len(names)), n, n, encoding)).encode()
    fmt = "f" if size == 4 else "d"
    rows = [p + (0.0,) * (len(names) - 3) for p in points]
    if encoding == "ascii":
        return head + "".join(" ".join("%g" % v for v in r) + "\n" for r in rows).encode()
    if encoding == "binary":
        return head + b"".join(struct.pack("<" + fmt * len(names), *r) for r in rows)
    columns = b"".join(struct.pack("<" + fmt, r[k]) for k in range(len(names)) for r in rows)
    block = lzf_literals(columns)
    return head + struct.pack("<II", len(block), len(columns)) + block


def cloud2(points, width=None, height=1):
    """A serialised sensor_msgs/PointCloud2 with x y z float32 (point_step 16)."""
    width = width if width is not None else len(points)
    frame = b"camera_rgb_optical_frame"
    msg = struct.pack("<III", 7, 100, 0) + struct.pack("<I", len(frame)) + frame
    msg += struct.pack("<II", height, width)
    msg += struct.pack("<I", 3)
    for k, name in enumerate("xyz"):
        msg += struct.pack("<I", 1) + name.encode() + struct.pack("<IBI", 4 * k, 7, 1)
    data = b"".join(struct.pack("<ffff", *p, 0.0) for p in points)
    msg += struct.pack("<BII", 0, 16, 16 * width) + struct.pack("<I", len(data)) + data
    return msg + struct.pack("<B", 0)


def oni_record(kind, node, fields=b"", payload=b""):
    """One .oni record: "NIR\\0", type, node id, header size (28 + fields), payload size, undo."""
    return struct.pack("<IIIIIQ", 0x0052494E, kind, node, 28 + len(fields), len(payload),
                       0) + fields + payload


def oni(records_end=True):
    """The skeleton of a recording as render_oni writes it: the NI10 header, a node-added
    record (13) with its name, a frame record (9) with a small payload, then END (11)."""
    head = b"NI10" + struct.pack("<HHHH", 1, 1, 0, 0) + struct.pack("<IIi", 0x8235, 0, 1)
    body = oni_record(13, 1, b"\x06\x00\x00\x00Depth\x00") + oni_record(9, 1, b"", b"\x01" * 64)
    return head + body + (oni_record(11, 0) if records_end else b"")


def main():
    points = scene()
    for encoding in ("ascii", "binary", "binary_compressed"):
        out("fuzz_pcd_reader", encoding + ".pcd", pcd(points, encoding))
    out("fuzz_pcd_reader", "float64.pcd", pcd(points[:20], "binary", size=8))
    out("fuzz_pcd_reader", "rgb_compressed.pcd", pcd(points[:30], "binary_compressed",
                                                     fields="x y z rgb"))
    out("fuzz_pcd_reader", "empty.pcd", pcd([], "ascii"))
    out("fuzz_cloud_input", "scene", cloud2(points))
    out("fuzz_cloud_input", "organised", cloud2(points[:120], width=12, height=10))
    out("fuzz_cloud_input", "empty", cloud2([], width=0))
    raw = b"".join(struct.pack("<fff", *p) for p in points)
    out("fuzz_pipeline", "scene", b"\x00" + raw)
    out("fuzz_pipeline", "scene_auto_up", b"\x80" + raw)
    out("fuzz_pipeline", "organised", b"\x0c" + raw[:12 * 120])
    out("fuzz_oni_recording", "whole.oni", oni())
    out("fuzz_oni_recording", "no_end.oni", oni(records_end=False))
    out("fuzz_pipeline", "nan", b"\x00" + struct.pack("<fff", math.nan, 0.0, math.inf) * 8)


if __name__ == "__main__":
    main()
