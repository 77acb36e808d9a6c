#!/usr/bin/python3
"""pipeline.launch refuses, before any node starts, what would otherwise run wrongly or
silently: a malformed up, up given twice, and a namespace where a pipeline already runs (a
second one would shut the first down); the TableSegmentation nodelet refuses a malformed ~up
set without the launch file. Each refusal ends the launch with a message naming the value.

usage: test_launch_checks.py   (in a catkin environment: devel/env.sh)"""
import os
import signal
import socket
import subprocess
import time
import unittest

UP_ERROR = "up must be auto, X,Y,Z or [x, y, z] (a non-zero vector in the cloud frame), got '%s'"


def free_port():
    with socket.socket() as s:
        s.bind(("", 0))
        return s.getsockname()[1]


class LaunchChecks(unittest.TestCase):
    def setUp(self):
        # A private master address: nothing of anybody else's is seen or disturbed.
        self.port = free_port()
        self.env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % self.port,
                        PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""))
        self.started = []

    def tearDown(self):
        for proc in reversed(self.started):
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(15)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()

    def launch(self, *args, timeout=60):
        """roslaunch pipeline.launch ARGS on the private port; returns (exit code, output).
        A launch that is not refused is stopped after `timeout` s (exit code None)."""
        proc = subprocess.Popen(["roslaunch", "-p", str(self.port), "tabletop_shapes",
                                 "pipeline.launch", *args], env=self.env, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        try:
            out, _ = proc.communicate(timeout=timeout)
            return proc.returncode, out
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)
            out, _ = proc.communicate()
            return None, out

    def assertRefused(self, args, message):
        code, out = self.launch(*args)
        self.assertIsNotNone(code, "the launch kept running:\n" + out)
        self.assertNotEqual(code, 0, out)
        self.assertIn("*** pipeline.launch refused: " + message, out)
        self.assertNotIn("process[", out, "no node may start")

    def test_malformed_up_stops_the_launch(self):
        for bad in ("0,0", "[0, -1]", "0 -1 0", "0,0,0", "upwards"):
            with self.subTest(up=bad):
                self.assertRefused(["up:=" + bad], UP_ERROR % bad)

    def test_up_twice_stops_the_launch(self):
        self.assertRefused(["up:=0,-1,0", "up_frame:=base_link"],
                           "up:=0,-1,0 and up_frame:=base_link both given: give one of them")
        self.assertRefused(["up:=[0, -1, 0]", "auto_up:=true"],
                           "up:=[0, -1, 0] and auto_up:=true both given: give one of them")

    def check(self, *args):
        proc = subprocess.run(["rosrun", "tabletop_shapes", "check_pipeline_launch", *args],
                              env=self.env, text=True, capture_output=True, timeout=30)
        return proc.returncode, proc.stdout, proc.stderr

    def test_both_syntaxes_give_the_same_up(self):
        for text in ("0,-0.8,-0.6", "[0, -0.8, -0.6]", " [0.0,-0.8 , -0.6] "):
            self.assertEqual(self.check("--up", text), (0, "[0.000, -0.800, -0.600]", ""), text)
        self.assertEqual(self.check("--up", ""), (0, "auto", ""))
        self.assertEqual(self.check("--up", "auto"), (0, "auto", ""))

    def start_master_with_node(self, name):
        self.started.append(subprocess.Popen(["rosmaster", "--core", "-p", str(self.port)],
                                             env=self.env, stdout=subprocess.DEVNULL,
                                             stderr=subprocess.DEVNULL))
        node = subprocess.Popen(
            ["/usr/bin/python3", "-c",
             "import rospy; rospy.init_node('%s'); rospy.spin()" % name],
            env=dict(self.env, ROS_NAMESPACE="/tabletop_shapes"),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.started.append(node)
        deadline = time.time() + 30
        while time.time() < deadline:
            out = subprocess.run(["rosnode", "list"], env=self.env, text=True,
                                 capture_output=True).stdout
            if "/tabletop_shapes/" + name in out:
                return node
            time.sleep(0.3)
        self.fail("the stand-in node never registered")

    def test_busy_namespace_stops_the_second_launch(self):
        node = self.start_master_with_node("preprocess")
        self.assertRefused([], "namespace /tabletop_shapes is busy: /tabletop_shapes/preprocess "
                               "already run on http://localhost:%d" % self.port)
        self.assertEqual(node.poll(), None, "the first pipeline's node still runs")
        # Another namespace is free.
        self.assertEqual(self.check("--ns", "tabletop_shapes_2"), (0, "auto", ""))
        # A node killed without unregistering (still listed by the master) blocks nothing.
        node.kill()
        node.wait()
        self.assertEqual(self.check("--ns", "tabletop_shapes"), (0, "auto", ""))

    def test_nodelet_refuses_a_malformed_up_parameter(self):
        self.started.append(subprocess.Popen(["rosmaster", "--core", "-p", str(self.port)],
                                             env=self.env, stdout=subprocess.DEVNULL,
                                             stderr=subprocess.DEVNULL))
        proc = subprocess.run(["rosrun", "nodelet", "nodelet", "standalone",
                               "tabletop_shapes/TableSegmentation", "__name:=table_segmentation",
                               "_up:=0,0"], env=self.env, text=True, capture_output=True,
                              timeout=60)
        self.assertNotEqual(proc.returncode, 0, proc.stdout + proc.stderr)
        self.assertIn("/table_segmentation/up: " + UP_ERROR % "0,0", proc.stdout + proc.stderr)

    def test_nodelets_refuse_out_of_range_start_up_parameters(self):
        # Each stage nodelet, one value outside the core's bounds set before it starts: the load
        # fails with the value named (it once crashed in the failed nodelet's destructor first,
        # silently), never a clamped value run with.
        self.started.append(subprocess.Popen(["rosmaster", "--core", "-p", str(self.port)],
                                             env=self.env, stdout=subprocess.DEVNULL,
                                             stderr=subprocess.DEVNULL))
        cases = [("Preprocess", "preprocess", "_leaf_size:=0.5",
                  "/preprocess/leaf_size: preprocess.leaf_size = 0.5 is outside [0, 0.1]"),
                 # the chain's own admission parameters, checked against the cfg's bounds (a
                 # node name each: private parameters stay on the master between the cases)
                 ("Preprocess", "preprocess_a", "_max_frames_in_flight:=17",
                  "/preprocess_a/max_frames_in_flight = 17 is outside [0, 16]"),
                 ("Preprocess", "preprocess_b", "_in_flight_timeout:=0.01",
                  "/preprocess_b/in_flight_timeout = 0.01 is outside [0.1, 60]"),
                 ("Preprocess", "preprocess_c", "_max_frames_in_flight:=1.5",
                  "/preprocess_c/max_frames_in_flight = 1.5 is not an integer"),
                 ("TableSegmentation", "table_segmentation", "_min_inliers:=2",
                  "/table_segmentation/min_inliers: table.min_inliers = 2 is outside [3, 1e+07]"),
                 ("Clustering", "clustering", "_min_size:=0",
                  "/clustering/min_size: clustering.min_size = 0 is outside [1, 1e+07]"),
                 ("ShapeEstimation", "shape_estimation", "_threshold:=-1",
                  "/shape_estimation/threshold: predictor.threshold = -1 is outside [0, 4]")]
        for nodelet, name, argument, message in cases:
            with self.subTest(nodelet=nodelet, argument=argument):
                proc = subprocess.run(["rosrun", "nodelet", "nodelet", "standalone",
                                       "tabletop_shapes/" + nodelet, "__name:=" + name, argument],
                                      env=self.env, text=True, capture_output=True, timeout=60)
                out = proc.stdout + proc.stderr
                self.assertIn(proc.returncode, (1, 255), out)  # refused, not crashed (139)
                self.assertIn("refused start-up parameters: " + message, out)


if __name__ == "__main__":
    unittest.main(verbosity=2)
