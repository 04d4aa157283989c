#pragma once
/// @file vtu_frame.hpp
/// What a VTU frame of a simulation shows (docs/output_format.md "VTU frames"): the
/// bodies with their fields, and the obstacles (plane patches and obstacle meshes)
/// at the same time, as two parts of one ParaView time step.

#include "forward/io/vtu_writer.hpp"
#include "forward/simulation/simulator.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// The committed state a frame shows, with the nodal forces at it (#V*dim each, N).
struct FrameState {
    VectorXd positions, velocities;
    VectorXd contact_forces; ///< -dB/dx (Simulator::contact_forces()); empty without contact
    VectorXd friction_forces; ///< -dD/dx (Simulator::friction_forces()); empty without friction
};

/// @brief The simulator's committed state and its contact and friction forces.
FrameState frame_state(const Simulator& simulator);

/// @brief The bodies: their vertices (the first Scene::body_vertices of the mesh) and
/// elements. Point data displacement, velocity (m, m/s), contact_force and friction_force
/// (N, when the scene has contact, friction); cell data body, volume_ratio, stress (the
/// Cauchy stress, 9 components, row-major 3 by 3, zero-padded in 2D) and von_mises (of it).
VtuGrid body_grid(const Simulator& simulator, const FrameState& state);

/// @brief The obstacles: each plane as a square patch (a segment in 2D) of side
/// plane_patch_size() centred at the foot of the scene's rest bounding-box centre on
/// the plane, moving with the plane, plus the plane's point as a vertex cell; each
/// obstacle mesh as its triangles (segments in 2D) at their current positions. Cell
/// data obstacle (index in the scene's obstacles); point data contact_force and
/// friction_force (N): the reactions on obstacle-mesh vertices and, at a plane's point,
/// on the whole plane (zero at the patch corners). Empty if the scene has no obstacles.
VtuGrid obstacle_grid(const Simulator& simulator, const FrameState& state);

/// @brief Side (m) of the patch that shows a plane: twice the diagonal of the rest bounding
/// box of the bodies and obstacle meshes (planes' points excluded).
double plane_patch_size(const Scene& scene);

/// @brief Writes frame `index` of the simulator's committed state at `time` into
/// `directory`: frame_<index>.vtu and, if the scene has obstacles, obstacles_<index>.vtu.
/// @return the files' .pvd entries (parts 0 and 1)
/// @throws InputError naming a file that cannot be written
std::vector<PvdEntry> write_vtu_frame(
    const std::string& directory, int index, double time, const Simulator& simulator, VtuEncoding encoding);

/// File names of frame `index`: the bodies' and the obstacles'.
std::string body_frame_name(int index);
std::string obstacle_frame_name(int index);

} // namespace diffipc
