#pragma once
/// @file output.hpp
/// Writers for a simulated trajectory: HDF5 (docs/output_format.md), VTU
/// files with a .pvd index for ParaView, and summary.json.

#include "forward/io/trajectory_writer.hpp"
#include "forward/simulation/simulator.hpp"

#include <nlohmann/json_fwd.hpp>

#include <string>

namespace diffipc {

/// @brief One VTU (XML, ASCII) file of the mesh at positions x with point data
/// displacement and velocity and cell data body, volume_ratio and von_mises.
void write_vtu(const std::string& path, const Simulator& simulator, const VectorXd& x, const VectorXd& v);

/// @brief ParaView collection index of (time, file) pairs.
void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries);

/// @brief The run's summary: status, counts, per-phase wall times.
nlohmann::json summary_json(const Simulator& simulator);
void write_json(const std::string& path, const nlohmann::json& value);

} // namespace diffipc
