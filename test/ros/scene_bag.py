#!/usr/bin/python3
"""Test fixture: writes a scene bag with write_scene_bag into a fresh temporary folder (rendered
from the current renderer, so nothing large is committed), then plays it with rosbag play.

usage: scene_bag.py [--delayed-tf SECONDS] WRITER_ARGS... -- PLAY_ARGS...

--delayed-tf: broadcast the bag's /tf_static only after SECONDS of wall time (give `rosbag
play` --topics without /tf_static): the "transform appears late" scenario.
"""
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading


def main(argv):
    delayed_tf = None
    if argv[:1] == ["--delayed-tf"]:
        delayed_tf = float(argv[1])
        argv = argv[2:]
    split = argv.index("--") if "--" in argv else len(argv)
    writer_args, play_args = argv[:split], argv[split + 1:]
    folder = tempfile.mkdtemp(prefix="tabletop_shapes_bag_")
    bag = os.path.join(folder, "scene.bag")
    player = None
    try:
        subprocess.check_call(["rosrun", "tabletop_shapes", "write_scene_bag", "--out", bag]
                              + writer_args)
        if delayed_tf is not None:
            start_delayed_tf(bag, delayed_tf)
        # The bag first: a trailing --topics list would swallow it.
        player = subprocess.Popen(["rosbag", "play", bag] + play_args)
        signal.signal(signal.SIGINT, lambda *_: player.terminate())
        signal.signal(signal.SIGTERM, lambda *_: player.terminate())
        return player.wait()
    finally:
        if player and player.poll() is None:
            player.terminate()
        shutil.rmtree(folder, ignore_errors=True)


def start_delayed_tf(bag_path, seconds):
    import rosbag
    import rospy
    import tf2_ros

    with rosbag.Bag(bag_path) as bag:
        transforms = [t for _, msg, _ in bag.read_messages(topics=["/tf_static"])
                      for t in msg.transforms]
    rospy.init_node("delayed_static_tf", disable_signals=True)
    broadcaster = tf2_ros.StaticTransformBroadcaster()

    def publish():
        rospy.loginfo("delayed_static_tf: publishing %d transforms now", len(transforms))
        broadcaster.sendTransform(transforms)

    timer = threading.Timer(seconds, publish)
    timer.daemon = True
    timer.start()


if __name__ == "__main__":
    # roslaunch appends __name:= and __log:= arguments: drop them.
    sys.exit(main([a for a in sys.argv[1:] if not a.startswith("__")]))
