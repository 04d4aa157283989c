#pragma once
/// @file device_conversion.hpp
/// The CPU's contact data in the device's plain arrays (cuda/), for builds with CUDA only
/// (DIFFIPC_CUDA): device_solver.cpp and the GPU tests include it; device_solver.hpp does not, so
/// the rest of the build does not depend on whether the kernels are built.

#include "cuda/broad_phase/step_bound.hpp" // plain C++: gpu::CollisionMeshData, gpu::PlaneObstacle
#include "cuda/contact/device_contact.hpp" // plain C++: gpu::DeviceContactSettings
#include "cuda/contact/device_friction.hpp" // plain C++: gpu::FrictionPair
#include "forward/contact/contact_potential.hpp"
#include "forward/contact/friction/friction_potential.hpp"

#include <utility>
#include <vector>

namespace diffipc {

/// The CPU's CollisionMesh in cuda/broad_phase's plain arrays (field for field).
gpu::CollisionMeshData to_device(const CollisionMesh& mesh);
/// The CPU's plane obstacles as the device's (cuda/broad_phase/step_bound.hpp).
std::vector<gpu::PlaneObstacle> to_device(const std::vector<ContactPlane>& planes);
/// The barrier's settings as the device contact takes them (kappa, dhat, dmin, the CCD's).
gpu::DeviceContactSettings to_device(const ContactSettings& settings);
/// One lagged friction pair as the device takes it: its vertices (kind, vertices, plane) and its
/// frozen data (weights, tangents, mu lambda).
std::pair<gpu::BarrierPair, gpu::FrictionPair> to_device(const FrictionContact& contact);

} // namespace diffipc
