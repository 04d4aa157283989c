#pragma once
/// @file device_contact.hpp
/// The IPC contact potential on the GPU for DeviceNewton (cuda/solver/device_newton.hpp): the
/// device twin of ContactPotential (forward/contact/contact_potential.hpp) for the barrier model
/// without periodic images. It ties together the device building blocks:
///  - the active set at a state x (the CPU's contacts(x)): the static candidates of a broad phase
///    (DeviceBroadPhase) on boxes inflated by dmin + dhat, then every candidate and every
///    (plane, non-kinematic surface vertex) pair classified at x and kept if its squared distance
///    is below (dmin + dhat)^2 (a plane pair if its signed distance is below dmin + dhat), in the
///    CPU's order (vertex-edge, vertex-face, edge-edge, planes; a stable compaction on the GPU);
///    the kept pairs go to a DeviceBarrier, prepared there on the GPU (set_pairs_device: the contact
///    pattern and the gathers' incidence lists by stable radix sorts; only the pattern comes back);
///  - the barrier's gradient and projected Hessian of that set (DeviceBarrier), the Hessian on the
///    contact pattern (hessian(), to be added to the elastic matrix by a SumOperator);
///  - the energy kappa sum_k m_k b_k at any state y without building a pair list: every candidate
///    contributes its barrier if it is active at y, zero otherwise, summed by a fixed-order tree; a
///    point on the last max_step() segment reuses that segment's swept candidates (as the CPU's
///    line search does), any other point runs the static broad phase;
///  - the line search's step bound (DeviceStepBound: the CPU's max_step bit for bit);
///  - the minimum distance within a radius (the CPU's min_distance) and the smallest active gap
///    (the adaptive stiffness' doubling rule).
///
/// Layouts: positions, gradients and steps are #V * dim doubles in GPU memory, flattened
/// vertex-major (xyzxyz), metres; rest positions likewise on the host.
///
/// Not here (yet): periodic images, the shape derivative. Friction is DeviceFriction
/// (device_friction.hpp), a potential of its own on the lagged pairs.
/// Host code; this header compiles with a plain C++ compiler (no CUDA headers).

#include "cuda/broad_phase/device_broad_phase.hpp"
#include "cuda/broad_phase/step_bound.hpp"
#include "cuda/contact/device_barrier.hpp"
#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"

#include <memory>
#include <vector>

namespace diffipc::gpu {

/// ContactSettings' fields (forward/contact/contact_potential.hpp) for the barrier model.
struct DeviceContactSettings {
    double kappa = 1; ///< barrier stiffness
    double dhat = 1e-3; ///< activation distance (m)
    double min_distance = 0; ///< dmin (m)
    int ccd_max_iterations = 1000000;
    double ccd_rescaling = 0.9;
    /// The penalty baseline (ContactSettings::penalty; kappa is then its stiffness, N/m): pair energies of
    /// pair_barrier.cuh's PairModel, finite for intersecting pairs; max_step() certifies every step (no CCD).
    bool penalty = false;
};

/// Wall time (s) of the contact work since the last reset_times() (the CPU's ContactTimes).
struct DeviceContactTimes {
    double broad_phase = 0; ///< static broad phases (active sets, energies off the segment, min_distance)
    double ccd = 0; ///< max_step: swept broad phase and CCD
    double barrier = 0; ///< classification, compaction, barrier energies, gradients and Hessians
    /// Of `barrier`: rebuilding the active pair list (classification, compaction, the host's preparation
    /// of the pairs and the contact pattern, their upload) and the energies; and how often each ran.
    double active_sets = 0, energies = 0;
    long active_set_count = 0, energy_count = 0;
};

class DeviceContact {
public:
    /// @param mesh     the collision mesh (checked and uploaded as by DeviceBroadPhase)
    /// @param rest     #V * dim rest positions (m), for the edge-edge mollifier thresholds
    /// @param planes   plane obstacles (unit normals; each against every non-kinematic surface vertex)
    /// @throws std::invalid_argument on an inconsistent mesh or rest positions of the wrong size;
    ///         InputError on invalid settings (as DeviceStepBound)
    DeviceContact(const CollisionMeshData& mesh, const std::vector<double>& rest,
        const std::vector<PlaneObstacle>& planes, const DeviceContactSettings& settings);
    ~DeviceContact();
    DeviceContact(const DeviceContact&) = delete;
    DeviceContact& operator=(const DeviceContact&) = delete;

    int dim() const;
    int num_dofs() const;
    const DeviceContactSettings& settings() const;
    double kappa() const;
    void set_kappa(double kappa);

    /// @brief kappa sum_k m_k b_k over the pairs active at y (ContactPotential::value); +inf if an
    /// active pair is at or below dmin (or a vertex is behind a plane).
    /// @param on_segment y lies on the segment x -> x + p of the last max_step(x, p): its swept
    ///                   candidates (a superset of y's static ones) are reused
    double energy(const double* d_y, bool on_segment);

    /// @brief Builds the active set at x (ContactPotential::contacts(x)) and a zero Hessian matrix on
    /// its pattern. @return the number of active pairs
    int update_active(const double* d_x);
    int num_active() const;
    /// The active pairs (host copy, in the CPU's order).
    const std::vector<BarrierPair>& active_pairs() const;
    /// min over the active pairs of (sqrt(max(s, 0)) - dmin)^2 at the last update_active() (+inf if
    /// none): ContactPotential::end_iteration's gap.
    double min_active_gap_squared() const;

    /// @name The active set's barrier at x (update_active(x) first). Asynchronous.
    /// @{
    /// d_g += weight kappa dB/dx
    void add_gradient(const double* d_x, double weight, double* d_g) const;
    /// d_g += weight dB/dx without kappa (the adaptive stiffness' balancing rule)
    void add_barrier_gradient(const double* d_x, double weight, double* d_g) const;
    /// hessian() = weight kappa sum_k H_k, each projected to PSD if `project`
    void assemble_hessian(const double* d_x, double weight, bool project);
    /// @}
    /// The contact Hessian on the active set's pattern (#V block rows).
    const DeviceBsrMatrix& hessian() const;

    /// @brief The CCD step bound of x -> x + p (DeviceStepBound::max_step); remembers the segment.
    StepBoundResult max_step(const double* d_x, const double* d_p);

    /// @brief ContactPotential::min_distance: the smallest distance (m) over the pairs within
    /// max(radius, dmin + dhat) at x (0 for a vertex behind a plane); +inf if none.
    double min_distance(const double* d_x, double radius);

    const DeviceContactTimes& times() const;
    void reset_times();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace diffipc::gpu
