#!/usr/bin/python3
"""scripts/benchmark_speed's arithmetic on known per-frame records: latency per stage and end to
end, frames lost per stage, frames answered with a result / refused as busy / lost, objects per answer (ours: the Objects message's size; pcl_ros: its
cluster messages, stamped input + i ms), RSS after the warm-up against the end, and a probe
line cut short by a stopped manager. No ROS needed.

usage: test_benchmark_speed.py"""
import importlib.machinery
import importlib.util
import os
import tempfile
import unittest

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts",
                      "benchmark_speed")
loader = importlib.machinery.SourceFileLoader("benchmark_speed", SCRIPT)
spec = importlib.util.spec_from_loader("benchmark_speed", loader)
bench = importlib.util.module_from_spec(spec)
loader.exec_module(bench)

NS = "/tabletop_shapes"


class FakeRss:
    def __init__(self, samples):
        self.samples = samples

    def at(self, wall_us):
        return bench.RssSampler.at(self, wall_us)


def write_probe(lines):
    handle, path = tempfile.mkstemp(suffix=".csv")
    with os.fdopen(handle, "w") as f:
        f.write("topic,stamp_us,arrival_us,size,answer\n" + "".join(line + "\n" for line in lines))
    return path


class Summary(unittest.TestCase):
    def setUp(self):
        self.paths = []

    def tearDown(self):
        for path in self.paths:
            os.remove(path)

    def probe(self, lines):
        self.paths.append(write_probe(lines))
        return self.paths[-1]

    def test_ours_latency_and_losses_per_stage(self):
        # Frame 1 and 4 pass every stage; frame 2 ends after Preprocess (lost at the table
        # stage), frame 3 never leaves Preprocess's queue. Arrivals in us after the stamp.
        lines = []
        for stamp, arrivals in ((1000000, (10000, 25000, 26000, 30000, 50000)),
                                (2000000, (12000,)), (3000000, ()),
                                (4000000, (20000, 45000, 47000, 60000, 100000))):
            for (topic, _), delay in zip(bench.OURS_TOPICS, arrivals):
                size, answer = (4, "result") if topic == "objects" else (1000, "")
                lines.append(f"{NS}/{topic},{stamp},{stamp + delay},{size},{answer}")
        lines.append(f"{NS}/objects,1000000,1090000,3,result")  # a later duplicate: the first counts
        lines.append(f"{NS}/clusters,5000000")  # cut short when the manager stopped
        first = bench.read_probe(self.probe(lines), NS)
        rss = FakeRss([(900000, 100.0), (1500000, 120.0), (4500000, 121.0)])
        cpu = {"seconds": 0.5, "frames": 10, "peak": 130.0}
        r = bench.summarise("tabletop_shapes", {"name": "VGA 4 obj", "key": "vga4"}, 30,
                            [1000000, 2000000, 3000000, 4000000], first, bench.OURS_TOPICS,
                            1200000, cpu, rss)
        self.assertEqual(r["frames"], 4)
        self.assertEqual(r["dropped"], 2)
        self.assertEqual(r["answers"], {"result": 2, "busy": 0, "reason": 0, "lost": 2})
        self.assertEqual(r["e2e"], [50.0, 100.0])
        self.assertEqual(r["lost"], {"preprocessed": 1, "table": 1, "objects_cloud": 0,
                                     "clusters": 0, "objects": 0})
        self.assertEqual(r["stages"]["preprocessed"], [10.0, 20.0])
        self.assertEqual(r["stages"]["table"], [15.0, 25.0])
        self.assertEqual(r["stages"]["objects"], [20.0, 40.0])
        # The core's four stages: table runs to objects_cloud.
        self.assertEqual(r["core_stages"]["preprocess"], [10.0, 20.0])
        self.assertEqual(r["core_stages"]["table"], [16.0, 27.0])
        self.assertEqual(r["core_stages"]["clustering"], [4.0, 13.0])
        self.assertEqual(r["core_stages"]["shapes"], [20.0, 40.0])
        self.assertEqual(r["found"], 4)
        self.assertAlmostEqual(r["cpu_ms"], 50.0)
        self.assertEqual((r["rss_warm"], r["rss_end"], r["rss_peak"]), (120.0, 121.0, 130.0))

    def test_busy_answers_are_counted_apart_from_the_latency_and_the_losses(self):
        # Frame 1 passes every stage; frame 2 is refused at Preprocess (answered at once, 1 ms
        # after its stamp); frame 3 is skipped by TableSegmentation (no transform), answered
        # with that reason; frame 4 is lost after Preprocess.
        lines = []
        for stamp, arrivals, answer in ((1000000, (10000, 25000, 26000, 30000, 50000), "result"),
                                        (2000000, (None, None, None, None, 1000), "busy"),
                                        (3000000, (10000, None, None, None, 40000), "reason"),
                                        (4000000, (10000,), "")):
            for (topic, _), delay in zip(bench.OURS_TOPICS, arrivals):
                if delay is not None:
                    size = 0 if topic == "objects" else 1000
                    lines.append(f"{NS}/{topic},{stamp},{stamp + delay},{size},"
                                 f"{answer if topic == 'objects' else ''}")
        first = bench.read_probe(self.probe(lines), NS)
        r = bench.summarise("tabletop_shapes", {"name": "VGA 4 obj", "key": "vga4"}, 30,
                            [1000000, 2000000, 3000000, 4000000], first, bench.OURS_TOPICS,
                            1000000, {"seconds": 0.1, "frames": 4, "peak": 100.0},
                            FakeRss([(0, 100.0)]))
        self.assertEqual(r["answers"], {"result": 1, "busy": 1, "reason": 1, "lost": 1})
        self.assertEqual(r["dropped"], 1)
        self.assertEqual(r["e2e"], [50.0, 40.0])  # the busy frame's 1 ms is left out
        # Three frames taken in, all three preprocessed; two left TableSegmentation's queue
        # without its table (frame 3 skipped there, frame 4 lost), frame 3 still answered.
        self.assertEqual(r["lost"], {"preprocessed": 0, "table": 2, "objects_cloud": 0,
                                     "clusters": 0, "objects": 0})

    def test_pcl_ros_counts_its_cluster_messages(self):
        topics = bench.PCL_TOPICS
        lines = [f"/pcl_ros_chain/voxel_grid/output,1000000,1020000,50000,"]
        # Three clusters of frame 1 (stamps + 0, 1, 2 ms), one of frame 2.
        for i in range(3):
            lines.append(f"/pcl_ros_chain/cluster/output,{1000000 + 1000 * i},"
                         f"{1060000 + 100 * i},{300 + i},")
        lines.append("/pcl_ros_chain/voxel_grid/output,2000000,2030000,50000,")
        lines.append("/pcl_ros_chain/cluster/output,2000000,2080000,700,")
        path = self.probe(lines)
        stamps = [1000000, 2000000]
        counts = bench.clusters_per_frame(path, "/pcl_ros_chain/cluster/output", stamps)
        self.assertEqual(counts, {1000000: 3, 2000000: 1})
        r = bench.summarise("pcl_ros", {"name": "VGA 4 obj"}, 0, stamps,
                            bench.read_probe(path, "/pcl_ros_chain"), topics, 1000000,
                            {"seconds": 0.2, "frames": 2, "peak": 200.0},
                            FakeRss([(0, 150.0)]), counts)
        self.assertEqual(r["e2e"], [60.0, 80.0])
        self.assertEqual(r["stages"]["cluster/output"], [40.0, 50.0])
        self.assertEqual(r["dropped"], 0)
        self.assertEqual(r["found"], 2)  # median of 3 and 1 clusters

    def test_quantiles_and_text(self):
        values = [float(v) for v in range(1, 101)]
        self.assertEqual(bench.three(values), "51.0/91.0/100.0")
        self.assertEqual(bench.three([]), "-")


if __name__ == "__main__":
    unittest.main()
