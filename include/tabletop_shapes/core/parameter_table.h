// Every tunable of the pipeline, named once: "stage.name", bounds and meaning. The YAML
// config of estimate_shapes, the documentation and the checks of absurd values read this
// table, so a parameter's name and bounds cannot drift between them.
#pragma once

#include "tabletop_shapes/core/pipeline.h"

#include <functional>

namespace tabletop_shapes {

struct ParameterInfo {
  const char* stage;  // preprocess, table, clustering, normals, predictor, cube, ...
  const char* name;   // as in the parameter struct and dynamic_reconfigure
  double min, max;    // accepted range (inclusive)
  bool is_integer;
  const char* description;  // with the unit
};

// Calls `visit(info, value)` for every parameter of `params`; `value` refers to the field
// (float or int, widened to double: the visitor may assign to it, see setParameter).
void forEachParameter(PipelineParams& params,
                      const std::function<void(const ParameterInfo&, double& value)>& visit);

// Sets "stage.name" to value. Returns false with a reason for an unknown name, a value out
// of bounds, or a non-integer value for an integer parameter.
bool setParameter(PipelineParams& params, const std::string& stage, const std::string& name,
                  double value, std::string& error);

// Pairs that contradict each other (a low end above its high end: predictor.section_low /
// section_high, cylinder.min_radius / max_radius, clustering.min_size / max_size,
// table.min_height / max_height). Returns false with every such pair and its values named.
// Each value alone passes setParameter; the pair is checked once all are set.
bool validateParams(const PipelineParams& params, std::string& error);

}  // namespace tabletop_shapes
