#pragma once
/// @file step_bound.hpp
/// The line search's contact step bound on the GPU: the largest alpha in [0, 1] that conservative CCD certifies
/// for the step x -> x + p, the device twin of ContactPotential::max_step (forward/contact/contact_potential.cpp)
/// without periodic images (pass the image surface's positions T x, T p for those):
///  1. x1 = x + p; tolerance = 1e-12 (max|x| + max|p|) (the CPU's on-segment tolerance);
///  2. the swept candidates of x -> x1 on boxes inflated by dmin + dhat + 4 tolerance (DeviceBroadPhase, the
///     CPU's pairs exactly);
///  3. CCD of every candidate (cuda/ccd/ccd.cuh: point_edge_ccd in 2D, point_triangle_ccd and edge_edge_ccd in 3D)
///     and of every (plane, non-kinematic surface vertex) pair (point_plane_ccd.cuh), with the CPU's settings
///     (min_distance = dmin, conservative_rescaling, max_iterations, t_max = 1), one thread per pair;
///  4. alpha = min(1, toi of every pair that reports a collision), a min-reduction (exact, so independent of the
///     order); budget_exhausted if any of those pairs ran out of iterations; unresolved when alpha is not > 0.
/// The CCD is the CPU's bit for bit (step_bound.cu is compiled with -fmad=false), and the candidate set is the
/// CPU's, so alpha is the CPU's max_step bit for bit. Not here: the penalty model (the CPU's max_step is then 1
/// without CCD; the caller skips the bound), and the CPU's reuse of the segment's candidates for the line search's
/// trial points (segment_candidates() hands them out for that). One difference on invalid input: a non-finite
/// entry of x or p anywhere (also off the contact surface) throws here, where the CPU throws only if it reaches
/// the broad phase's inflation or a surface vertex.
///
/// Layouts: x, p are #V by dim doubles, row-major (xyxy / xyzxyz), metres, over the full mesh; planes reference a
/// full-mesh vertex (the plane's point, which moves with x and p) and a normal (z = 0 in 2D).
///
/// Host code; this header compiles with a plain C++ compiler (no CUDA headers).

#include "cuda/broad_phase/device_broad_phase.hpp"

#include <cstddef>
#include <memory>
#include <vector>

namespace diffipc::gpu {

/// The contact settings the bound depends on (the CPU's ContactSettings fields of the same names).
struct StepBoundSettings {
    double dhat = 1e-3; ///< activation distance (m)
    double min_distance = 0; ///< dmin (m)
    int ccd_max_iterations = 1000000; ///< per-pair budget of the additive CCD
    double ccd_rescaling = 0.9; ///< conservative rescaling s in (0, 1)
};

/// A half-space obstacle (the CPU's ContactPlane).
struct PlaneObstacle {
    int vertex = 0; ///< full-mesh index of the plane's point
    double normal[3] = { 0, 1, 0 }; ///< finite, nonzero (the CPU's are unit normals); z = 0 in 2D
};

struct StepBoundResult {
    double alpha = 1; ///< the certified step fraction in [0, 1]
    bool unresolved = false; ///< alpha is not > 0 (the CPU's step_unresolved(): CCD_UNRESOLVED)
    bool budget_exhausted = false; ///< a colliding pair ran out of CCD iterations (the CPU's ccd_budget_exhausted())
    double inflation = 0; ///< the swept boxes' inflation dmin + dhat + 4 tolerance (m)
    std::size_t num_vertex_edge = 0, num_vertex_face = 0, num_edge_edge = 0, num_plane = 0; ///< pairs checked
    float broad_phase_ms = 0; ///< device time of x + p, the tolerance and the broad phase
    float ccd_ms = 0; ///< device time of the CCD and the reduction, to alpha on the host
    float total_ms = 0;
};

class DeviceStepBound {
public:
    /// @param mesh      collision mesh (checked and uploaded as by DeviceBroadPhase)
    /// @param planes    plane obstacles, each tested against every surface vertex of a non-kinematic group
    /// @param settings  checked with the CPU CCD's rules (check_ccd_settings) and dhat, dmin finite and >= 0
    /// @throws std::invalid_argument on an inconsistent mesh, a plane vertex out of range; InputError
    ///         (forward/common/error.hpp) on invalid settings or a zero or non-finite plane normal
    DeviceStepBound(
        const CollisionMeshData& mesh, const std::vector<PlaneObstacle>& planes, const StepBoundSettings& settings);
    ~DeviceStepBound();
    DeviceStepBound(const DeviceStepBound&) = delete;
    DeviceStepBound& operator=(const DeviceStepBound&) = delete;

    /// @brief The step bound from device data.
    /// @param d_x  device pointer, #V * dim positions at the start (m)
    /// @param d_p  device pointer, #V * dim step (m)
    /// @throws std::invalid_argument as the CPU's broad phase (non-finite positions or inflation);
    ///         std::runtime_error on a CUDA error or without a GPU
    StepBoundResult max_step(const double* d_x, const double* d_p);

    /// @brief max_step from host vectors (uploaded first).
    /// @throws std::invalid_argument also on vectors of the wrong size
    StepBoundResult max_step(const std::vector<double>& x, const std::vector<double>& p);

    /// The swept candidates of the last max_step (device views, valid until the next call): the CPU keeps them
    /// for the trial points of the line search on the same segment (ContactPotential's Segment).
    const DeviceCandidates& segment_candidates() const;
    /// x + p of the last max_step (device pointer, #V * dim).
    const double* segment_end() const;

    const StepBoundSettings& settings() const;
    /// @throws InputError on invalid settings
    void set_settings(const StepBoundSettings& settings);

    /// The broad phase it runs (for the active set's static queries at the same mesh).
    DeviceBroadPhase& broad_phase();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace diffipc::gpu
