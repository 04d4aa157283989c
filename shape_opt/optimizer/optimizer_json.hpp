#pragma once
/// @file optimizer_json.hpp
/// A problem file's "optimizer" object (docs/optimization.md) as OptimizerSettings.

#include "forward/scene/json_field.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

namespace diffipc {

/// @brief The settings of `spec` (an object; null: the defaults), every key known and of its kind.
/// @throws InputError naming the field ("optimizer.algorithm: unknown optimizer 'bfgs' ...")
OptimizerSettings parse_optimizer_settings(const JsonField& spec);

} // namespace diffipc
