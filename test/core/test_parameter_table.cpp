#include "tabletop_shapes/core/parameter_table.h"

#include <gtest/gtest.h>

#include <set>

using namespace tabletop_shapes;

TEST(ParameterTable, EveryDefaultLiesWithinItsBoundsAndNamesAreUnique) {
  PipelineParams params;
  std::set<std::string> names;
  int count = 0;
  forEachParameter(params, [&](const ParameterInfo& info, double& value) {
    ++count;
    const std::string full = std::string(info.stage) + "." + info.name;
    EXPECT_TRUE(names.insert(full).second) << full << " listed twice";
    EXPECT_GE(value, info.min) << full;
    EXPECT_LE(value, info.max) << full;
    EXPECT_GT(std::string(info.description).size(), 10u) << full;
  });
  EXPECT_GE(count, 30);
}

TEST(ParameterTable, PaperDefaults) {
  PipelineParams params;
  EXPECT_FLOAT_EQ(params.preprocess.max_range, 3.0f);
  EXPECT_FLOAT_EQ(params.table.up_tolerance_deg, 10.0f);
  EXPECT_FLOAT_EQ(params.table.hull_margin, 0.02f);  // the paper's 0.10 eats real objects
  EXPECT_EQ(params.table.outlier_k, 50);
  EXPECT_FLOAT_EQ(params.clustering.tolerance, 0.02f);
  EXPECT_EQ(params.clustering.min_size, 100);
  EXPECT_EQ(params.shapes.predictor.k, 3);
  EXPECT_FLOAT_EQ(params.shapes.cube.distance_threshold, 0.007f);
  EXPECT_NEAR(params.shapes.cube.angle_threshold, kPi / 5, 1e-6);
  EXPECT_NEAR(params.shapes.cube.min_plane_angle, kPi / 6, 1e-6);
  EXPECT_FLOAT_EQ(params.shapes.cube.min_support_fraction, 0.10f);
}

TEST(ParameterTable, SetParameterWritesTheField) {
  PipelineParams params;
  std::string error;
  ASSERT_TRUE(setParameter(params, "clustering", "tolerance", 0.03, error)) << error;
  EXPECT_FLOAT_EQ(params.clustering.tolerance, 0.03f);
  ASSERT_TRUE(setParameter(params, "clustering", "min_size", 250, error)) << error;
  EXPECT_EQ(params.clustering.min_size, 250);
  ASSERT_TRUE(setParameter(params, "predictor", "threshold", 0.05, error)) << error;
  EXPECT_FLOAT_EQ(params.shapes.predictor.threshold, 0.05f);
}

TEST(ParameterTable, AbsurdValuesAreRefusedWithAReason) {
  PipelineParams params;
  std::string error;
  EXPECT_FALSE(setParameter(params, "preprocess", "leaf_size", -0.01, error));
  EXPECT_NE(error.find("preprocess.leaf_size"), std::string::npos) << error;
  error.clear();
  EXPECT_FALSE(setParameter(params, "clustering", "min_size", 10.5, error));
  EXPECT_NE(error.find("whole number"), std::string::npos) << error;
  error.clear();
  EXPECT_FALSE(setParameter(params, "table", "hull_margin", std::nan(""), error));
  error.clear();
  EXPECT_FALSE(setParameter(params, "table", "no_such_thing", 1.0, error));
  EXPECT_NE(error.find("unknown parameter table.no_such_thing"), std::string::npos) << error;
  // Nothing was changed by the refused calls.
  EXPECT_FLOAT_EQ(params.preprocess.leaf_size, PreprocessParams().leaf_size);
  EXPECT_EQ(params.clustering.min_size, ClusteringParams().min_size);
}
