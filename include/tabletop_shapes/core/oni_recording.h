// The checks of an OpenNI .oni recording that we own (OpenNI2's file driver refuses a damaged
// recording without saying why, or plays it until it crashes): ROS-free and OpenNI2-free, so
// that the driver, the unit tests and a fuzz target share them.
#pragma once

#include <cstdint>
#include <istream>
#include <string>

namespace tabletop_shapes {

// True when a device_id names a recording (ends with .oni, any case) rather than a device.
bool looksLikeRecording(const std::string& device_id);

// Walks the records of a recording of `size` bytes (the NI10 header, then "NIR\0" records up
// to the END record) and names the first problem: "<name> is not an .oni file (...)", "<name>
// is truncated: ...", "<name> is damaged: ...". Empty when the recording looks whole.
std::string oniRecordingProblem(std::istream& in, uint64_t size, const std::string& name);

// The same for a file; also names a file that does not exist or cannot be read.
std::string oniRecordingProblem(const std::string& path);

}  // namespace tabletop_shapes
