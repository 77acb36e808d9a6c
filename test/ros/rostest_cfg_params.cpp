// Every cfg/*.cfg parameter is the core parameter of the same name, with the same default and
// bounds (core/parameter_table.h), and every core parameter is in exactly one cfg: the two
// cannot drift apart.
#include "rostest_common.h"

#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ClusteringConfig.h"
#include "tabletop_shapes/PreprocessConfig.h"
#include "tabletop_shapes/ShapeEstimationConfig.h"
#include "tabletop_shapes/TableSegmentationConfig.h"

#include <map>
#include <set>

namespace {

using tabletop_shapes::ParameterInfo;
using tabletop_shapes::PipelineParams;
using tabletop_shapes::bridge::anyToNumber;

struct Entry {
  ParameterInfo info;
  double default_value;
};

// "stage.name" -> table entry with the default of PipelineParams{}.
std::map<std::string, Entry> coreTable() {
  std::map<std::string, Entry> table;
  PipelineParams defaults;
  tabletop_shapes::forEachParameter(defaults, [&](const ParameterInfo& info, double& value) {
    table[std::string(info.stage) + "." + info.name] = Entry{info, value};
  });
  return table;
}

double valueOf(const boost::any& value) {
  double number = NAN;
  EXPECT_TRUE(anyToNumber(value, number)) << "a cfg parameter is not a number";
  return number;
}

// Checks one generated Config against the table; collects the "stage.name"s it covers.
template <typename Config>
void checkConfig(const std::string& config_name, const std::vector<std::string>& stages,
                 std::multiset<std::string>& covered) {
  const auto table = coreTable();
  for (const auto& description : Config::__getParamDescriptions__()) {
    SCOPED_TRACE(config_name + "." + description->name);
    if (tabletop_shapes::bridge::isChainParameter(description->name)) continue;  // ROS-only
    const std::string stage = tabletop_shapes::bridge::stageOfParameter(stages, description->name);
    ASSERT_FALSE(stage.empty()) << "not a core parameter of " << config_name;
    const Entry& entry = table.at(stage + "." + description->name);
    covered.insert(stage + "." + description->name);
    boost::any value, min, max;
    description->getValue(Config::__getDefault__(), value);
    description->getValue(Config::__getMin__(), min);
    description->getValue(Config::__getMax__(), max);
    // float defaults widened to double: relative 1e-6
    const double tolerance = 1e-6 * std::max(1.0, std::abs(entry.default_value));
    EXPECT_NEAR(valueOf(value), entry.default_value, tolerance);
    EXPECT_NEAR(valueOf(min), entry.info.min, 1e-9 * std::max(1.0, std::abs(entry.info.min)));
    EXPECT_NEAR(valueOf(max), entry.info.max, 1e-9 * std::max(1.0, std::abs(entry.info.max)));
    EXPECT_EQ(description->type == "int", entry.info.is_integer) << description->type;
    // The cfg files stay ASCII: the table's section sign is left out.
    std::string expected = entry.info.description;
    for (size_t at; (at = expected.find("\u00a7")) != std::string::npos;) expected.erase(at, 2);
    EXPECT_EQ(description->description, expected);
  }
}

TEST(CfgParams, EveryCfgParameterMatchesTheCoreTableAndEveryCoreParameterIsReconfigurable) {
  std::multiset<std::string> covered;
  checkConfig<tabletop_shapes::PreprocessConfig>("Preprocess", {"preprocess"}, covered);
  checkConfig<tabletop_shapes::TableSegmentationConfig>("TableSegmentation", {"table"}, covered);
  checkConfig<tabletop_shapes::ClusteringConfig>("Clustering", {"clustering"}, covered);
  checkConfig<tabletop_shapes::ShapeEstimationConfig>(
      "ShapeEstimation", {"normals", "predictor", "cube", "cylinder", "cone", "shapes"}, covered);
  for (const auto& [key, entry] : coreTable()) {
    EXPECT_EQ(covered.count(key), 1u) << key << " must be in exactly one cfg";
  }
}

TEST(CfgParams, ApplyConfigCopiesEveryValueIntoThePipelineParameters) {
  tabletop_shapes::ClusteringConfig config = tabletop_shapes::ClusteringConfig::__getDefault__();
  config.min_size = 12345;
  config.tolerance = 0.031;
  PipelineParams params;
  std::string error;
  ASSERT_TRUE(tabletop_shapes::bridge::applyConfig(config, {"clustering"}, params, error)) << error;
  EXPECT_EQ(params.clustering.min_size, 12345);
  EXPECT_FLOAT_EQ(params.clustering.tolerance, 0.031f);
  EXPECT_EQ(params.table.min_inliers, PipelineParams().table.min_inliers);  // untouched

  config.min_size = 0;  // below the table's minimum of 1
  EXPECT_FALSE(tabletop_shapes::bridge::applyConfig(config, {"clustering"}, params, error));
  EXPECT_NE(error.find("min_size"), std::string::npos) << error;
}

}  // namespace
