#!/usr/bin/python3
"""The estimate_shapes command's contract: one JSON document on stdout, exit 0 when the
cloud was processed (also without a table), exit 2 with one clear line on stderr for bad
usage, unreadable files and clouds without x y z; real scenes give the expected objects."""
import json
import os
import re
import struct
import subprocess
import sys
import tempfile
import unittest

TOOL = sys.argv.pop(1)
DATA = sys.argv.pop(1)


def run(*args, timeout=60):
    proc = subprocess.run([TOOL, *args], capture_output=True, text=True, timeout=timeout)
    return proc.returncode, proc.stdout, proc.stderr


def write_pcd(path, fields, rows, width=None, height=1):
    width = width if width is not None else len(rows)
    with open(path, "w") as f:
        f.write("# .PCD v0.7\nVERSION 0.7\n")
        f.write("FIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\n" % (
            " ".join(fields), " ".join("4" * len(fields)), " ".join("F" * len(fields)),
            " ".join("1" * len(fields))))
        f.write("WIDTH %d\nHEIGHT %d\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA ascii\n" % (
            width, height, len(rows)))
        for row in rows:
            f.write(" ".join(str(v) for v in row) + "\n")


def lzf_decompress(data, size):
    """liblzf's format, as PCL writes it (a reference independent of the tool's reader)."""
    out = bytearray()
    i = 0
    while i < len(data):
        ctrl = data[i]
        i += 1
        if ctrl < 32:
            out += data[i:i + ctrl + 1]
            i += ctrl + 1
            continue
        length = ctrl >> 5
        if length == 7:
            length += data[i]
            i += 1
        ref = len(out) - ((ctrl & 0x1f) << 8) - data[i] - 1
        i += 1
        if ref + length + 2 <= len(out):
            out += out[ref:ref + length + 2]
        else:  # overlapping: byte by byte
            for k in range(length + 2):
                out.append(out[ref + k])
    assert len(out) == size
    return bytes(out)


class BadInput(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp()

    def assertUsageError(self, args, expected):
        code, out, err = run(*args)
        self.assertEqual(code, 2, err)
        self.assertEqual(out, "")
        self.assertIn(expected, err.splitlines()[0])

    def test_no_arguments(self):
        self.assertUsageError([], "no cloud given")

    def test_unknown_option(self):
        self.assertUsageError(["--frobnicate", "x.pcd"], "unknown option --frobnicate")

    def test_bad_up(self):
        for bad in ("0,0", "0,0,0", "[0, -1, 0", "0 -1 0", "up", "0,-1,0,1", "0,x,1"):
            self.assertUsageError(["--up", bad, "x.pcd"],
                                  "up must be auto, X,Y,Z or [x, y, z] (a non-zero vector in "
                                  "the cloud frame), got '%s'" % bad)

    def test_contradictory_config(self):
        cfg = os.path.join(self.tmp, "contradictory.yaml")
        with open(cfg, "w") as f:
            f.write("predictor:\n  section_low: 0.8\n  section_high: 0.6\n"
                    "cylinder:\n  min_radius: 0.4\n  max_radius: 0.2\n")
        path = os.path.join(self.tmp, "one.pcd")
        write_pcd(path, ["x", "y", "z"], [(0, 0, 1)])
        self.assertUsageError(["--config", cfg, path],
                              "predictor.section_low = 0.8 must be below predictor.section_high"
                              " = 0.6; cylinder.min_radius = 0.4 must be below "
                              "cylinder.max_radius = 0.2")

    def test_missing_file(self):
        self.assertUsageError([os.path.join(self.tmp, "nope.pcd")], "cannot read PCD file")

    def test_garbage_file(self):
        path = os.path.join(self.tmp, "garbage.pcd")
        with open(path, "wb") as f:
            f.write(os.urandom(5000))
        self.assertUsageError([path], "cannot read PCD file")

    def test_truncated_file(self):
        src = os.path.join(DATA, "learn0.pcd")
        path = os.path.join(self.tmp, "truncated.pcd")
        with open(src, "rb") as f, open(path, "wb") as g:
            g.write(f.read(3000))
        code, out, err = run(path)
        self.assertEqual(code, 2, err)

    def test_cloud_without_xyz(self):
        path = os.path.join(self.tmp, "noxyz.pcd")
        write_pcd(path, ["a", "b", "c"], [(1, 2, 3)] * 5)
        self.assertUsageError([path], "no 'x' field")

    def test_bad_config(self):
        cfg = os.path.join(self.tmp, "bad.yaml")
        with open(cfg, "w") as f:
            f.write("clustering:\n  min_size: -4\n")
        path = os.path.join(self.tmp, "one.pcd")
        write_pcd(path, ["x", "y", "z"], [(0, 0, 1)])
        self.assertUsageError(["--config", cfg, path], "clustering.min_size = -4 is outside")


def compressed_parts(path):
    """The header, the two size fields and the LZF block of a binary_compressed PCD."""
    data = open(path, "rb").read()
    body = data.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n")
    compressed, uncompressed = struct.unpack("<II", data[body:body + 8])
    return data[:body], compressed, uncompressed, data[body + 8:]


def with_header(header, **values):
    for key, value in values.items():
        header = re.sub(rb"\n%s [^\n]*\n" % key.encode(), b"\n%s %s\n" % (key.encode(), value),
                        header)
    return header


class BadFiles(unittest.TestCase):
    """Issue 16: files that made PCL's reader overread, allocate gigabytes or answer wrongly.
    Every one is refused with exit 2 and one line naming the problem."""

    def setUp(self):
        self.tmp = tempfile.mkdtemp()
        self.header, self.compressed, self.uncompressed, self.block = compressed_parts(
            os.path.join(DATA, "learn0.pcd"))

    def write(self, name, data):
        path = os.path.join(self.tmp, name)
        with open(path, "wb") as f:
            f.write(data)
        return path

    def assertRefused(self, path, expected):
        code, out, err = run("--up", "auto", path)
        self.assertEqual(code, 2, err)
        self.assertEqual(out, "")
        self.assertIn("cannot read PCD file", err.splitlines()[0])
        self.assertIn(expected, err.splitlines()[0])

    def test_compressed_declaring_more_points(self):
        # finding 1: valgrind showed 3025 invalid reads, then SIGSEGV or garbage objects
        header = with_header(self.header, HEIGHT=b"960", POINTS=b"614400")
        path = self.write("more.pcd", header + struct.pack("<II", self.compressed,
                                                           self.uncompressed) + self.block)
        self.assertRefused(path, "decompresses to 6144000 bytes, but POINTS 614400")

    def test_compressed_declaring_fewer_points(self):
        # finding 4: "no table" and exit 0
        header = with_header(self.header, HEIGHT=b"240", POINTS=b"153600")
        path = self.write("fewer.pcd", header + struct.pack("<II", self.compressed,
                                                            self.uncompressed) + self.block)
        self.assertRefused(path, "but POINTS 153600")

    def test_corrupted_compressed_size(self):
        # finding 2: 9 corrupted bytes made PCL allocate 8.2 GB
        path = self.write("size.pcd", self.header + b"\xf0\xff\xff\xff" +
                          struct.pack("<I", self.uncompressed) + self.block)
        self.assertRefused(path, "(truncated)")
        path = self.write("usize.pcd", self.header + struct.pack("<I", self.compressed) +
                          b"\xff\xff\xff\xf0" + self.block)
        self.assertRefused(path, "compressed block decompresses to 4043309055 bytes")

    def test_points_above_the_cap(self):
        # finding 2: POINTS 99,999,999 cost 3.6 GB (compressed) and 1.24 GB (ascii), exit 0
        header = with_header(self.header, WIDTH=b"99999999", HEIGHT=b"1", POINTS=b"99999999")
        path = self.write("huge.pcd", header + struct.pack("<II", self.compressed,
                                                           self.uncompressed) + self.block)
        self.assertRefused(path, "POINTS 99999999 is above the limit of 4000000 (--max-points)")
        ascii_path = os.path.join(self.tmp, "huge_ascii.pcd")
        write_pcd(ascii_path, ["x", "y", "z"], [(0, 0, 1)] * 3)
        with open(ascii_path) as f:
            text = f.read().replace("POINTS 3", "POINTS 99999999").replace("WIDTH 3",
                                                                           "WIDTH 99999999")
        self.assertRefused(self.write("huge_ascii.pcd", text.encode()), "above the limit")

    def test_max_points_option(self):
        code, out, err = run("--max-points", "1000", os.path.join(DATA, "learn0.pcd"))
        self.assertEqual(code, 2, err)
        self.assertIn("POINTS 307200 is above the limit of 1000", err)
        code, out, err = run("--max-points", "lots", os.path.join(DATA, "learn0.pcd"))
        self.assertEqual(code, 2, err)
        self.assertIn("--max-points wants a positive integer, got 'lots'", err)

    def test_ascii_garbage_line(self):
        # finding 4: garbage lines were skipped without a word
        path = os.path.join(self.tmp, "garbage_line.pcd")
        write_pcd(path, ["x", "y", "z"], [(0, 0, 1), ("hello", "world", "!"), (1, 0, 1)])
        self.assertRefused(path, "data line 2: 'hello' is not a number")

    def test_truncated_binary(self):
        path = os.path.join(self.tmp, "binary.pcd")
        rows = [(0.1 * i, 0.0, 1.0) for i in range(10)]
        with open(path, "wb") as f:
            f.write(b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 10\nPOINTS 10\nDATA binary\n")
            f.write(b"".join(struct.pack("<fff", *r) for r in rows)[:-7])
        self.assertRefused(path, "binary data of 113 bytes, but POINTS 10 x 12 bytes = 120")


class Processed(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp()

    def run_json(self, *args):
        code, out, err = run(*args)
        self.assertEqual(code, 0, err)
        return json.loads(out)

    def test_empty_cloud_is_no_table(self):
        path = os.path.join(self.tmp, "empty.pcd")
        write_pcd(path, ["x", "y", "z"], [])
        doc = self.run_json(path)
        self.assertEqual(doc["status"], "no table")
        self.assertIsNone(doc["table"])
        self.assertEqual(doc["objects"], [])

    def test_all_nan_organised_cloud_is_no_table(self):
        path = os.path.join(self.tmp, "nan.pcd")
        write_pcd(path, ["x", "y", "z", "rgb"], [("nan", "nan", "nan", 0)] * 12, width=4,
                  height=3)
        for up in ("0,-1,0", "auto"):
            doc = self.run_json("--up", up, path)
            self.assertEqual(doc["status"], "no table")

    def test_osd_boxes_scene(self):
        doc = self.run_json("--up", "auto", os.path.join(DATA, "learn0.pcd"))
        self.assertEqual(doc["status"], "ok")
        self.assertGreaterEqual(doc["table"]["inliers"], 1000)
        cubes = [o for o in doc["objects"] if o["type"] == "cube"]
        self.assertGreaterEqual(len(cubes), 1, doc["objects"])
        for cube in cubes:
            self.assertEqual(len(cube["dimensions"]), 3)
            self.assertTrue(all(0.01 < d < 0.5 for d in cube["dimensions"]), cube)
            self.assertIn(cube["faces_seen"], (1, 2, 3))
        for key in ("preprocess", "table", "clustering", "shapes", "total"):
            self.assertGreaterEqual(doc["timing_ms"][key], 0.0)

    def test_pcl_mug_scene_gives_one_cylinder(self):
        doc = self.run_json("--up", "auto",
                            os.path.join(DATA, "table_scene_mug_stereo_textured.pcd"))
        self.assertEqual(doc["status"], "ok")
        round_objects = [o for o in doc["objects"] if o["type"] in ("cylinder", "cone")]
        self.assertEqual(len(round_objects), 1, doc["objects"])
        mug = round_objects[0]
        radius = mug.get("radius", (mug.get("radius_bottom", 0) + mug.get("radius_top", 0)) / 2)
        self.assertGreater(radius, 0.035, mug)
        self.assertLess(radius, 0.045, mug)

    def test_float64_coordinates_are_read(self):
        # finding 4: float64 x y z gave "no table" and exit 0; now they are converted, and the
        # scene's boxes come out as from the float32 file
        header, compressed, uncompressed, block = compressed_parts(os.path.join(DATA,
                                                                                "learn0.pcd"))
        float32 = self.run_json("--up", "auto", os.path.join(DATA, "learn0.pcd"))
        # rewrite learn0's x y z as float64 in an uncompressed binary file
        path = os.path.join(self.tmp, "learn0_f64.pcd")
        lzf = lzf_decompress(block[:compressed], uncompressed)
        n = 307200
        columns = [lzf[i * 4 * n:(i + 1) * 4 * n] for i in range(5)]  # label x y z rgba
        xyz = [struct.unpack("<%df" % n, columns[i]) for i in (1, 2, 3)]
        packed = struct.pack("<%dd" % (3 * n), *[v for p in zip(*xyz) for v in p])
        with open(path, "wb") as f:
            f.write(b"VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\n"
                    b"WIDTH 640\nHEIGHT 480\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 307200\n"
                    b"DATA binary\n")
            f.write(packed)
        float64 = self.run_json("--up", "auto", path)
        self.assertEqual(float64["status"], "ok")
        self.assertEqual(float64["table"], float32["table"])
        self.assertEqual(len(float64["objects"]), len(float32["objects"]))
    def test_without_up_the_tilted_scene_gets_the_estimated_up(self):
        # learn0's camera looks ~37 deg down: the old default [0, -1, 0] found a wrong table.
        path = os.path.join(DATA, "learn0.pcd")
        default, estimated = self.run_json(path), self.run_json("--up", "auto", path)
        self.assertEqual(default["status"], "ok")
        self.assertEqual(default["up"], estimated["up"])
        self.assertEqual(default["table"], estimated["table"])
        self.assertEqual(default["warnings"], [])
        self.assertLess(default["up"][1], -0.5, default["up"])  # tilted: not [0, -1, 0]
        self.assertLess(default["up"][2], -0.4, default["up"])

    def test_a_wrong_up_is_warned_about_with_its_angle(self):
        path = os.path.join(DATA, "learn0.pcd")
        code, out, err = run("--up", "[0, -1, 0]", path)
        self.assertEqual(code, 0, err)
        doc = json.loads(out)
        self.assertEqual(len(doc["warnings"]), 1, doc)
        match = re.match(r"up \[0.000, -1.000, 0.000\] is (\d+) deg from the scene's up",
                         doc["warnings"][0])
        self.assertIsNotNone(match, doc["warnings"])
        self.assertGreater(int(match.group(1)), 30)
        self.assertLess(int(match.group(1)), 45)
        self.assertIn("warning: " + doc["warnings"][0], err)
        # the scene's own up (both syntaxes) gives no warning
        up = tuple(self.run_json(path)["up"])
        for text in ("%g,%g,%g" % up, "[%g, %g, %g]" % up):
            self.assertEqual(self.run_json("--up", text, path)["warnings"], [], text)

    def test_config_changes_the_result(self):
        cfg = os.path.join(self.tmp, "huge_min_cluster.yaml")
        with open(cfg, "w") as f:
            f.write("clustering:\n  min_size: 1000000\n  max_size: 2000000\n")
        doc = self.run_json("--up", "auto", "--config", cfg, os.path.join(DATA, "learn0.pcd"))
        self.assertEqual(doc["status"], "ok")
        self.assertEqual(doc["objects"], [])


class Documentation(unittest.TestCase):
    def test_readme_parameter_table_is_current(self):
        code, out, err = run("--parameters")
        self.assertEqual(code, 0, err)
        self.assertIn("| `table.hull_margin` |", out)
        readme = open(os.path.join(DATA, "..", "..", "README.md")).read()
        self.assertIn(out.strip(), readme,
                      "README's parameter table differs from `estimate_shapes --parameters`")


if __name__ == "__main__":
    unittest.main(verbosity=2)
