// libFuzzer target: the .oni record walk we own (oniRecordingProblem) on arbitrary bytes. Every
// input ends with a verdict: empty (whole) or a problem that names the recording.
#include "tabletop_shapes/core/oni_recording.h"

#include <cstdlib>
#include <sstream>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  const std::string problem = tabletop_shapes::oniRecordingProblem(in, size, "fuzz");
  if (!problem.empty() && problem.compare(0, 5, "fuzz ") != 0) std::abort();
  return 0;
}
