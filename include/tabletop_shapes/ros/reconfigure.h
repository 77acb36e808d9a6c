// dynamic_reconfigure <-> the core's parameter table. Every cfg/*.cfg parameter is a
// "stage.name" of core/parameter_table.h under the same name (unique among the stages one
// nodelet covers), so one generic function maps any generated Config onto PipelineParams.
#pragma once

#include "tabletop_shapes/core/parameter_table.h"

#include <boost/any.hpp>
#include <ros/console.h>
#include <ros/node_handle.h>

#include <algorithm>
#include <sstream>
#include <stdexcept>
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

// Parameters of the ROS chain itself that no core stage has (Preprocess's admission of frames
// in flight, ros/frame_admission.h): the nodelet reads them from its Config; applyConfig and
// the check against the core's table skip them, checkChainParameters checks their start-up
// values.
inline bool isChainParameter(const std::string& name) {
  return name == "max_frames_in_flight" || name == "in_flight_timeout";
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
    if (isChainParameter(description->name)) continue;
    const std::string stage = stageOfParameter(stages, description->name);
    std::string why;
    if (stage.empty() || !anyToNumber(value, number)) {
      why = "parameter " + description->name + " is not in the core's parameter table";
    } else {
      setParameter(params, stage, description->name, number, why);
    }
    if (!why.empty()) error += (error.empty() ? "" : "; ") + why;
  }
  if (error.empty()) validateParams(params, error);  // contradictory pairs
  return error.empty();
}

// The core's defaults win over the cfg file's: every parameter of `stages` not set on the
// parameter server (e.g. by a launch file) is set there to the core's default before the
// dynamic_reconfigure server reads it. While the core is being tuned, a stale cfg default
// thus cannot change the results (rostest_cfg_params still reports the drift).
//
// Parameters may also be given as in `estimate_shapes --config` (`stage: {name: value}`, e.g.
// ~predictor/threshold, from <rosparam file="params.yaml"/>): those of `stages` are copied to
// the flat name that dynamic_reconfigure uses (~threshold; moved there), which must not be set as
// well.
// Every stage.name there is checked against the table, also those of other nodes' stages, so that
// one file serves all nodes. Throws std::invalid_argument naming the parameter for an unknown
// name, a value out of range, a contradictory pair or a name given both ways (the nodelet's
// load then fails: a wrong start-up value is refused, not run with).
inline void seedCoreDefaults(ros::NodeHandle& private_node,
                             const std::vector<std::string>& stages) {
  PipelineParams defaults, given;
  std::string errors;
  auto fail = [&](const std::string& why) { errors += (errors.empty() ? "" : "; ") + why; };
  std::vector<std::string> all_stages;
  forEachParameter(defaults, [&](const ParameterInfo& info, double&) {
    if (std::find(all_stages.begin(), all_stages.end(), info.stage) == all_stages.end()) {
      all_stages.push_back(info.stage);
    }
  });
  for (const std::string& stage : all_stages) {
    XmlRpc::XmlRpcValue stage_map;
    if (!private_node.getParam(stage, stage_map) ||
        stage_map.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
      continue;
    }
    const bool ours = std::find(stages.begin(), stages.end(), stage) != stages.end();
    for (auto& [name, value] : stage_map) {
      const std::string full = private_node.resolveName(stage + "/" + name);
      const auto type = value.getType();
      if (type != XmlRpc::XmlRpcValue::TypeDouble && type != XmlRpc::XmlRpcValue::TypeInt) {
        fail(full + " is not a number");
        continue;
      }
      const double number = type == XmlRpc::XmlRpcValue::TypeInt ? static_cast<int>(value)
                                                                 : static_cast<double>(value);
      std::string why;
      if (!setParameter(given, stage, name, number, why)) {
        fail(full + ": " + why);
      } else if (ours && private_node.hasParam(name)) {
        fail(full + " and " + private_node.resolveName(name) + " are both set: give one");
      } else if (ours) {
        // Moved, not copied: dynamic_reconfigure keeps the flat name current from now on, and
        // a reloaded nodelet must not find both.
        if (type == XmlRpc::XmlRpcValue::TypeInt) {
          private_node.setParam(name, static_cast<int>(value));
        } else {
          private_node.setParam(name, number);
        }
        private_node.deleteParam(stage + "/" + name);
      }
    }
  }
  // Then the flat names of our stages: set ones are checked, missing ones get the default.
  forEachParameter(defaults, [&](const ParameterInfo& info, double& value) {
    if (std::find(stages.begin(), stages.end(), info.stage) == stages.end()) return;
    double number = 0.0;
    if (private_node.getParam(info.name, number)) {
      std::string why;
      if (!setParameter(given, info.stage, info.name, number, why)) {
        fail(private_node.resolveName(info.name) + ": " + why);
      }
    } else if (info.is_integer) {
      private_node.setParam(info.name, static_cast<int>(value));
    } else {
      private_node.setParam(info.name, value);
    }
  });
  std::string contradiction;
  if (errors.empty() && !validateParams(given, contradiction)) fail(contradiction);
  if (!errors.empty()) {
    // Logged here too: the loader's own message does not name the cause.
    ROS_FATAL_STREAM("refused start-up parameters: " << errors);
    throw std::invalid_argument(errors);
  }
}

// The chain parameters of `Config` (isChainParameter) set on the parameter server before
// start, against the cfg's bounds: dynamic_reconfigure would clamp an out-of-range value
// silently. Throws std::invalid_argument naming each value refused (the load fails), as
// seedCoreDefaults does for the core's parameters.
template <typename Config>
void checkChainParameters(ros::NodeHandle& private_node) {
  std::string errors;
  for (const auto& description : Config::__getParamDescriptions__()) {
    if (!isChainParameter(description->name)) continue;
    XmlRpc::XmlRpcValue value;
    if (!private_node.getParam(description->name, value)) continue;
    const std::string full = private_node.resolveName(description->name);
    const auto type = value.getType();
    const bool integer = description->type == "int";
    if (type != XmlRpc::XmlRpcValue::TypeInt && type != XmlRpc::XmlRpcValue::TypeDouble) {
      errors += (errors.empty() ? "" : "; ") + full + " = " + value.toXml() + " is not a number";
      continue;
    }
    const double number =
        type == XmlRpc::XmlRpcValue::TypeInt ? static_cast<int>(value) : static_cast<double>(value);
    std::ostringstream why;
    why << full << " = " << number;
    if (integer && type != XmlRpc::XmlRpcValue::TypeInt) {
      errors += (errors.empty() ? "" : "; ") + why.str() + " is not an integer";
      continue;
    }
    boost::any min, max;
    description->getValue(Config::__getMin__(), min);
    description->getValue(Config::__getMax__(), max);
    double low = 0.0, high = 0.0;
    anyToNumber(min, low);
    anyToNumber(max, high);
    if (number < low || number > high) {
      why << " is outside [" << low << ", " << high << "]";
      errors += (errors.empty() ? "" : "; ") + why.str();
    }
  }
  if (!errors.empty()) {
    ROS_FATAL_STREAM("refused start-up parameters: " << errors);
    throw std::invalid_argument(errors);
  }
}

}  // namespace bridge
}  // namespace tabletop_shapes
