#pragma once
/// @file json_path.hpp
/// Fields of a JSON document named by paths ("scenes[1].scene.time.dt"), and a document's file paths made
/// absolute: what `diffipc sweep` (cli/sweep.cpp) does to its base document at each point.

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace diffipc {

/// @brief Sets the value at `path`: keys joined by '.', list entries by [i]; missing object keys are made, list
/// indices must exist; the empty path replaces the whole document (an object).
/// @throws InputError naming `field` for a path that does not fit the document
void set_path(nlohmann::json& document, const std::string& path, const nlohmann::json& value, const std::string& field);

/// @brief Every relative "file" (meshes, marker data) and "scene" (a scene file) path in the document made
/// absolute against `folder`.
void absolute_paths(nlohmann::json& node, const std::filesystem::path& folder);

} // namespace diffipc
