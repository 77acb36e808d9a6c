// expInPlace against std::exp, bit for bit: MLS's weights (exp(-d^2 / r^2)) come from it.
#include "tabletop_shapes/core/exp_lanes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace tabletop_shapes {
namespace {

size_t differingFromStdExp(const std::vector<double>& arguments) {
  std::vector<double> values = arguments;
  expInPlace(values.data(), values.size());
  size_t differing = 0;
  for (size_t i = 0; i < arguments.size(); ++i) {
    const double expected = std::exp(arguments[i]);
    if (std::memcmp(&expected, &values[i], sizeof expected) != 0) {
      if (differing++ < 5)
        ADD_FAILURE() << std::hexfloat << "exp(" << arguments[i] << "): " << values[i]
                      << ", std::exp " << expected;
    }
  }
  return differing;
}

TEST(ExpLanes, EveryValueIsThatOfStdExp) {
  std::printf("four lanes at a time: %s\n", expInLanes() ? "yes" : "no (std::exp)");
  std::mt19937_64 rng(5);
  // MLS's range (-d^2 / r^2 for neighbours a little beyond the radius from the projected
  // point), then the whole main path of glibc's algorithm, both signs.
  std::uniform_real_distribution<double> weights(-4.0, 0.0), wide(-511.0, 511.0);
  std::vector<double> arguments(3000001);  // not a multiple of 4: the last ones alone
  for (size_t i = 0; i < arguments.size(); ++i) arguments[i] = i % 2 ? weights(rng) : wide(rng);
  // Every table entry (k mod 128) at both ends of its interval of r.
  for (int k = -1024; k < 1024; ++k) {
    const double centre = k * std::log(2.0) / 128.0;
    for (const double r : {-0.0027, 0.0, 0.0027}) arguments.push_back(centre + r);
  }
  EXPECT_EQ(differingFromStdExp(arguments), 0u);
}

TEST(ExpLanes, ArgumentsBeyondTheMainPathAreThoseOfStdExp) {
  const double inf = std::numeric_limits<double>::infinity();
  // Each among three ordinary lanes: the whole block of four goes to std::exp.
  for (const double special : {0.0, -0.0, 0x1p-60, -0x1p-55, 512.0, -700.0, 710.0, -746.0, inf,
                               -inf, std::numeric_limits<double>::quiet_NaN()}) {
    const std::vector<double> arguments = {-0.5, special, -1.5, 2.0, special};
    std::vector<double> values = arguments;
    expInPlace(values.data(), values.size());
    for (size_t i = 0; i < values.size(); ++i) {
      const double expected = std::exp(arguments[i]);
      if (std::isnan(expected)) {
        EXPECT_TRUE(std::isnan(values[i]));
      } else {
        EXPECT_EQ(std::memcmp(&expected, &values[i], sizeof expected), 0)
            << std::hexfloat << "exp(" << arguments[i] << ") = " << values[i];
      }
    }
  }
}

}  // namespace
}  // namespace tabletop_shapes
