#!/usr/bin/env bash
# `make install`, staged with DESTDIR=<tmp>, must give a package that works on its own: in a
# clean environment (no devel space, no source tree on any path) that only sources the staged
# setup.bash, rospack finds the package and its nodelet plugin in the stage, the message modules
# import from it, the installed estimate_shapes processes a real scene, and pipeline.launch
# loads the four processing nodelets from the installed library.
#   test_install.sh SOURCE_DIR BUILD_DIR
set -u
export PATH="/usr/bin:/bin:$PATH"
src="${1:?usage: test_install.sh SOURCE_DIR BUILD_DIR}"
build="${2:?usage: test_install.sh SOURCE_DIR BUILD_DIR}"
tmp=$(mktemp -d)
# Staged under DESTDIR at the build's own install prefix: installing to another prefix would
# reconfigure the build, and the next `make` would then rebuild most of it.
build_prefix=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$build/CMakeCache.txt")
prefix="$tmp/stage$build_prefix"
launch_pid=""
cleanup() {
  if [ -n "$launch_pid" ]; then  # roslaunch itself (not the shell around it) stops its nodes
    kill -TERM "$(cat "$tmp/roslaunch.pid" 2>/dev/null)" "$launch_pid" 2>/dev/null
    wait "$launch_pid" 2>/dev/null
  fi
  rm -rf "$tmp"
}
trap cleanup EXIT
failures=0
check() { if eval "$2"; then echo "PASS: $1"; else echo "FAIL: $1"; failures=$((failures + 1)); fi; }

# The Makefile's target, as a user runs it (the build is up to date: make test built it).
if ! make -C "$src" install PREFIX="$build_prefix" DESTDIR="$tmp/stage" BUILD_DIR="$build" \
    JOBS=1 >"$tmp/install.log" 2>&1; then
  echo "FAIL: make install"
  tail -n 30 "$tmp/install.log"
  exit 1
fi
echo "PASS: make install DESTDIR=$tmp/stage ($(find "$prefix" -type f | wc -l) files)"

# Everything below runs with only the prefix's setup.bash sourced.
in_prefix() {
  # shellcheck disable=SC2016  # expanded by the inner bash
  env -i HOME="$tmp" PATH=/usr/bin:/bin ROS_HOME="$tmp/ros" ROS_LOG_DIR="$tmp/log" \
    bash -c 'set +u; source "$0/setup.bash" >/dev/null; set -u; eval "$1"' "$prefix" "$1"
}
share="$prefix/share/tabletop_shapes"
check "rospack find points into the prefix" \
  "[ \"\$(in_prefix 'rospack find tabletop_shapes')\" = '$share' ]"
check "the nodelet plugin is found in the prefix" \
  "in_prefix 'rospack plugins --attrib=plugin nodelet' | grep -qx 'tabletop_shapes $share/nodelet_plugins.xml'"
check "the plugin library is installed" "[ -f '$prefix/lib/libtabletop_shapes_nodelets.so' ]"
for file in package.xml launch/pipeline.launch launch/camera.launch rviz/tabletop_shapes.rviz \
            cfg/ShapeEstimation.cfg msg/Objects.msg; do
  check "share/tabletop_shapes/$file installed" "[ -f '$share/$file' ]"
done
for tool in estimate_shapes render_oni demo_summary; do
  check "rosrun finds the installed $tool" \
    "[ \"\$(in_prefix 'catkin_find --first-only --libexec tabletop_shapes $tool')\" = '$prefix/lib/tabletop_shapes/$tool' ]"
done
check "the installed tools and libraries need nothing from the build tree" \
  "! in_prefix 'ldd $prefix/lib/tabletop_shapes/* $prefix/lib/*.so' | grep -e 'not found' -e '$build'"
# (Importing tabletop_shapes.msg needs python3-shape-msgs, which is not among the packages.)
check "the Python messages are installed" \
  "[ -f '$prefix/lib/python3/dist-packages/tabletop_shapes/msg/_Objects.py' ]"
check "the reconfigure modules import from the prefix" \
  "in_prefix '/usr/bin/python3 -c \"import tabletop_shapes.cfg.ShapeEstimationConfig as c; print(c.__file__)\"' | grep -q '^$prefix/'"

# The installed estimate_shapes on the OSD boxes scene, through the command test's own case.
check "installed estimate_shapes finds the boxes of learn0.pcd" \
  "in_prefix '/usr/bin/python3 $src/test/scripts/test_estimate_shapes.py \
     $prefix/lib/tabletop_shapes/estimate_shapes $src/test/data Processed.test_osd_boxes_scene' \
     >'$tmp/estimate.log' 2>&1 || { cat '$tmp/estimate.log'; false; }"

# pipeline.launch from the prefix on a private master: each processing nodelet must be loaded
# into the manager, which then serves its dynamic_reconfigure topics, from the installed
# library. (`rosservice call <manager>/list` would need nodelet's Python module, which Debian
# does not install.)
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])')
master="ROS_MASTER_URI=http://localhost:$port"
in_prefix "$master PYTHONUNBUFFERED=1 exec roslaunch -p $port --pid=$tmp/roslaunch.pid tabletop_shapes pipeline.launch" >"$tmp/launch.log" 2>&1 &
launch_pid=$!
manager=/tabletop_shapes/tabletop_shapes_manager
info=""
for _ in $(seq 60); do
  info=$(in_prefix "$master rosnode info $manager" 2>/dev/null)
  [ "$(grep -c '^ \* /tabletop_shapes/[a-z_]*/parameter_updates ' <<<"$info")" -eq 4 ] && break
  kill -0 "$launch_pid" 2>/dev/null || break
  sleep 0.5
done
for nodelet in preprocess table_segmentation clustering shape_estimation; do
  check "pipeline.launch loads $nodelet into the manager" \
    "grep -q '^ \* /tabletop_shapes/$nodelet/parameter_updates ' <<<\"\$info\""
done
check "ShapeEstimation advertises the objects" "grep -q '^ \* /tabletop_shapes/objects ' <<<\"\$info\""
manager_pid=$(sed -n 's/^Pid: //p' <<<"$info")
check "the manager runs the prefix's nodelet library" \
  "grep -q '$prefix/lib/libtabletop_shapes_nodelets.so' /proc/${manager_pid:-0}/maps"
if [ $failures -ne 0 ]; then
  echo "--- roslaunch said:"
  tail -n 20 "$tmp/launch.log"
fi
[ $failures -eq 0 ]
