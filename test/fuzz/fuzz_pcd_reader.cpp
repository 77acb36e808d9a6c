// libFuzzer target: the bounded PCD reader on arbitrary bytes. Every input is read or refused
// with PcdError; a crash, a sanitizer report or a cloud that contradicts its own size fails.
#include "tabletop_shapes/core/pcd_reader.h"

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  tabletop_shapes::PcdReadOptions options;
  options.max_points = 100000;  // the cap is the reader's bound on memory: keep runs fast
  try {
    const auto cloud = tabletop_shapes::parsePcd(data, size, options);
    if (cloud.size() > options.max_points) std::abort();
    if (cloud.size() > 0 && static_cast<size_t>(cloud.width) * cloud.height != cloud.size()) {
      std::abort();
    }
  } catch (const tabletop_shapes::PcdError&) {
  }
  return 0;
}
