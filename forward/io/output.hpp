#pragma once
/// @file output.hpp
/// Writers for a simulated trajectory: HDF5 (docs/output_format.md), VTU
/// files with a .pvd index for ParaView, and summary.json.

#include "forward/simulation/simulator.hpp"

#include <nlohmann/json_fwd.hpp>

#include <string>

namespace diffipc {

/// @brief Writes trajectory.h5 layout: datasets time [T+1], positions [T+1,N,d],
/// velocities [T+1,N,d], status [T], newton_iterations [T], residual [T],
/// newton_step [T], min_volume_ratio [T], wall_time [T]; group mesh with
/// rest_positions [N,d], elements [E,d+1], body [N], element_body [E]. With
/// `contact`: min_distance [T] (m, +inf if no pair is within 1e-2 of the bbox
/// diagonal), active_contacts [T], kappa [T].
/// @throws InputError naming the file if it cannot be written.
void write_hdf5(const std::string& path, const Mesh& mesh, const Trajectory& trajectory, bool contact = false);

/// @brief One VTU (XML, ASCII) file of the mesh at positions x with point data
/// displacement and velocity and cell data body, volume_ratio and von_mises.
void write_vtu(const std::string& path, const Simulator& simulator, const VectorXd& x, const VectorXd& v);

/// @brief ParaView collection index of (time, file) pairs.
void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries);

/// @brief The run's summary: status, counts, per-phase wall times.
nlohmann::json summary_json(const Simulator& simulator);
void write_json(const std::string& path, const nlohmann::json& value);

} // namespace diffipc
