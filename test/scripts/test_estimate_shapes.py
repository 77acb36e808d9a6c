#!/usr/bin/python3
"""The estimate_shapes command's contract: one JSON document on stdout, exit 0 when the
cloud was processed (also without a table), exit 2 with one clear line on stderr for bad
usage, unreadable files and clouds without x y z; real scenes give the expected objects."""
import json
import re
import os
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
        self.assertUsageError([path], "has no 'x' field")

    def test_bad_config(self):
        cfg = os.path.join(self.tmp, "bad.yaml")
        with open(cfg, "w") as f:
            f.write("clustering:\n  min_size: -4\n")
        path = os.path.join(self.tmp, "one.pcd")
        write_pcd(path, ["x", "y", "z"], [(0, 0, 1)])
        self.assertUsageError(["--config", cfg, path], "clustering.min_size = -4 is outside")


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
