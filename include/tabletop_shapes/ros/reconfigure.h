// dynamic_reconfigure <-> the core's parameter table. Every cfg/*.cfg parameter is a
// "stage.name" of core/parameter_table.h under the same name (unique among the stages one
// nodelet covers), so one generic function maps any generated Config onto PipelineParams.
#pragma once

#include "tabletop_shapes/core/parameter_table.h"

#include <boost/any.hpp>
#include <ros/node_handle.h>

#include <algorithm>
#include <string>
#include <vector>

namespace tabletop_shapes {
namespace bridge {

// The stage of `stages` that has a parameter called `name`; empty when none has.
inline std::string stageOfParameter(const std::vector<std::string>& stages,
                                    const std::string& name) {
  std::string found;
  PipelineParams scratch;
  forEachParameter(scratch, [&](const ParameterInfo& info, double&) {
    if (found.empty() && name == info.name) {
      for (const std::string& stage : stages) {
        if (stage == info.stage) found = stage;
      }
    }
  });
  return found;
}

// A generated Config value (int, double or bool) as a number; false for other types.
inline bool anyToNumber(const boost::any& value, double& number) {
  if (const int* i = boost::any_cast<int>(&value)) {
    number = *i;
  } else if (const double* d = boost::any_cast<double>(&value)) {
    number = *d;
  } else if (const bool* b = boost::any_cast<bool>(&value)) {
    number = *b ? 1.0 : 0.0;
  } else {
    return false;
  }
  return true;
}

// Copies every parameter of `config` into `params` (the fields of `stages` only). Returns
// false with the reasons when a name is unknown or a value is rejected by the table.
template <typename Config>
bool applyConfig(const Config& config, const std::vector<std::string>& stages,
                 PipelineParams& params, std::string& error) {
  error.clear();
  for (const auto& description : Config::__getParamDescriptions__()) {
    boost::any value;
    description->getValue(config, value);
    double number = 0.0;
    const std::string stage = stageOfParameter(stages, description->name);
    std::string why;
    if (stage.empty() || !anyToNumber(value, number)) {
      why = "parameter " + description->name + " is not in the core's parameter table";
    } else {
      setParameter(params, stage, description->name, number, why);
    }
    if (!why.empty()) error += (error.empty() ? "" : "; ") + why;
  }
  return error.empty();
}

// The core's defaults win over the cfg file's: every parameter of `stages` not set on the
// parameter server (e.g. by a launch file) is set there to the core's default before the
// dynamic_reconfigure server reads it. While the core is being tuned, a stale cfg default
// thus cannot change the results (rostest_cfg_params still reports the drift).
inline void seedCoreDefaults(ros::NodeHandle& private_node,
                             const std::vector<std::string>& stages) {
  PipelineParams defaults;
  forEachParameter(defaults, [&](const ParameterInfo& info, double& value) {
    if (std::find(stages.begin(), stages.end(), info.stage) == stages.end()) return;
    if (private_node.hasParam(info.name)) return;
    if (info.is_integer) {
      private_node.setParam(info.name, static_cast<int>(value));
    } else {
      private_node.setParam(info.name, value);
    }
  });
}

}  // namespace bridge
}  // namespace tabletop_shapes
