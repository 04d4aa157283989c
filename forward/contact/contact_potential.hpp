#pragma once
/// @file contact_potential.hpp
/// IPC barrier potential B(x) = kappa sum_k m_k b(d_k^2 - dmin^2, shat) over the
/// active contacts of the collision mesh and the planes (docs/math.md "Contact").
/// The active set is rebuilt at every state it is asked about (broad phase with
/// inflation dmin + dhat, then exact classification), cached for the last state.
/// max_step() is the largest step that conservative CCD certifies.

#include "forward/common/parallel.hpp"
#include "forward/contact/collision_mesh.hpp"
#include "forward/contact/contact_set.hpp"
#include "forward/contact/surface_images.hpp"
#include "forward/potentials/potential.hpp"

#include "forward/kernels/contact_pair.hpp"

#include <functional>
#include <memory>

namespace diffipc {

struct ContactSettings {
    double dhat = 1e-3; ///< activation distance (m)
    double min_distance = 0; ///< dmin (m)
    double kappa = 1; ///< barrier stiffness
    int ccd_max_iterations = 1000000;
    double ccd_rescaling = 0.9;
    /// Penalty contact instead of the barrier (forward/contact/penalty.hpp): kappa is the
    /// penalty stiffness (N/m), min_distance must be 0, and there is no CCD.
    bool penalty = false;
};

/// A half-space obstacle: bodies stay on the side the normal points to. Its
/// point is a (kinematic) vertex of the mesh, so it moves with the state.
struct ContactPlane {
    Index vertex; ///< full-mesh index of the plane's point
    Eigen::Vector3d normal; ///< unit normal (z = 0 in 2D)
};

/// Wall time (s) spent in contact work since the last reset.
struct ContactTimes {
    double broad_phase = 0, ccd = 0, barrier = 0;
};

class ContactPotential : public Potential {
public:
    /// @param mesh           collision mesh (indices into the full mesh)
    /// @param rest_positions #V by dim (for the edge-edge mollifier thresholds)
    /// @param planes         plane obstacles (tested against every non-kinematic surface vertex)
    ContactPotential(CollisionMesh mesh, const Positions& rest_positions, std::vector<ContactPlane> planes,
        ContactSettings settings);
    ~ContactPotential() override;

    std::string name() const override { return "contact"; }
    double value(const VectorXd& x) const override;
    void add_gradient(const VectorXd& x, double weight, VectorXd& g) const override;
    void add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const override;
    /// Largest step certified by CCD (min over candidate pairs of the time of impact).
    double max_step(const VectorXd& x, const VectorXd& p) const override;
    bool step_unresolved() const override { return m_ccd_unresolved; }
    bool end_iteration(const VectorXd& x) override;
    /// @brief The normal force of a pair at distance d (m) per unit stiffness, without the
    /// mollifier: |d b/d d| = |b'(d^2 - dmin^2)| 2 d for the barrier, dhat - d for the penalty
    /// (friction's lagged normal force is kappa m times this).
    double normal_force_per_stiffness(double d) const;
    /// True for `"model": "penalty"` (forward/contact/penalty.hpp): no CCD, max_step() is 1.
    bool penalty() const { return m_settings.penalty; }
    /// Shape derivative of direction^T grad B: only the edge-edge mollifier
    /// thresholds depend on the rest positions.
    void add_shape_derivative(
        const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_rest_positions) const override;

    /// @brief The contact of a primitive pair at surface positions x (vertex indices in ContactKind's
    /// order; plane: the plane's index for VERTEX_PLANE, else -1): its closest-feature type and squared
    /// distance (-1 for a vertex behind a plane), and an edge-edge pair's mollifier threshold; whether
    /// it is active is up to the caller (contacts() keeps those with s < (dmin + dhat)^2).
    /// @param threshold compute an edge-edge pair's mollifier threshold (contacts() does it only for
    ///                  the pairs it keeps)
    Contact classify(ContactKind kind, const std::array<Index, 4>& vertices, int plane, const VectorXd& x,
        bool threshold = true) const;
    /// Active contacts at x (cached for the last x asked about).
    const ContactSet& contacts(const VectorXd& x) const;
    /// contacts() at surface positions y (surface_positions(x)); the same without images.
    const ContactSet& surface_contacts(const VectorXd& y) const;
    /// @brief Minimum distance (m) over primitive pairs within `radius` (m) of each
    /// other at x, and over vertex-plane pairs; +inf if there is none.
    double min_distance(const VectorXd& x, double radius) const;
    /// Barrier value without kappa: sum_k m_k b_k.
    double barrier_value(const VectorXd& x) const;
    /// Gradient of the barrier without kappa (#V*dim).
    VectorXd barrier_gradient(const VectorXd& x) const;

    /// The squared distance s of a contact at x for its classified type (0 for a
    /// vertex on the wrong side of a plane), the mollifier m (1 unless edge-edge),
    /// and, if asked, their local gradients and Hessians (vertex-major, dim per vertex).
    struct LocalDistance {
        double s = 0, m = 1;
        Eigen::VectorXd gs, gm; ///< gm empty unless edge-edge
        Eigen::MatrixXd Hs, Hm;
    };
    LocalDistance local_distance(const Contact& c, const VectorXd& x, bool derivatives) const;
    /// d eps_x / d(rest positions) of an edge-edge contact: 12 (xyz per vertex; z unused in 2D).
    Eigen::Matrix<double, 12, 1> mollifier_threshold_gradient(const Contact& c) const;

    const ContactSettings& settings() const { return m_settings; }
    void set_kappa(double kappa) { m_settings.kappa = kappa; }
    double kappa() const { return m_settings.kappa; }
    /// Adaptive stiffness: enable doubling (IPC's rule) up to kappa_max after each Newton iteration.
    /// `rule(x)` returns IPC's balancing stiffness at x; it is applied (kappa only
    /// grows) after the first Newton iteration of a step that ends with active
    /// contacts, unless the step started with some (the caller applied it then).
    /// Call at the start of every step.
    void set_adaptive(
        double kappa_max, double bbox_diagonal, std::function<double(const VectorXd&)> rule, bool rule_applied)
    {
        m_adaptive = true;
        m_kappa_max = kappa_max;
        m_bbox_diagonal = bbox_diagonal;
        m_previous_min_distance_squared = -1;
        m_rule = std::move(rule);
        m_rule_applied = rule_applied;
    }
    /// @brief Periodic images (forward/periodic/contact_images.hpp): the collision mesh then indexes
    /// the image surface x_s = T x (#S dim by #V dim) and every method still takes and returns the
    /// mesh's positions x, gradients T^T g_s, Hessians T^T H_s T. Contacts (contacts(),
    /// local_distance(), mollifier_threshold_gradient()) index the surface: the first #V of its
    /// vertices are the mesh's own.
    void set_images(SparseMatrixd T);
    bool has_images() const { return !m_images.empty(); }
    /// T (empty without images).
    const SparseMatrixd& images() const { return m_images.matrix(); }
    /// The positions the collision mesh indexes: x, or T x with images.
    VectorXd surface_positions(const VectorXd& x) const
    {
        VectorXd storage;
        return m_images.surface(x, storage);
    }
    const CollisionMesh& collision_mesh() const { return m_mesh; }
    const std::vector<ContactPlane>& planes() const { return m_planes; }

    const ContactTimes& times() const { return m_times; }
    void reset_times() { m_times = {}; }
    bool ccd_budget_exhausted() const { return m_ccd_budget_exhausted; }

private:
    void build_contacts(const VectorXd& x, ContactSet& out, double radius) const;
    /// x, or T x (in `storage`) with images.
    const VectorXd& surface(const VectorXd& x, VectorXd& storage) const { return m_images.surface(x, storage); }
    /// Adds scale * grad(sum_k m_k b_k) at mesh positions x into g (#V dim).
    void add_barrier_gradient(const VectorXd& x, double scale, VectorXd& g) const;
    /// Adds scale * grad(sum_k m_k b_k) into g (no full-size temporary).
    void scatter_gradient(const VectorXd& x, double scale, VectorXd& g) const;
    /// Energy (without kappa), gradient and Hessian of one contact at x; local
    /// dofs are the contact's vertices in order, dim each.
    double local_barrier(const Contact& c, const VectorXd& x, Eigen::VectorXd* grad, Eigen::MatrixXd* hess) const;
    /// The energy of one pair without kappa and the mollifier, and its derivatives in z = s - dmin^2
    /// (the second only if asked): IPC's barrier b(z, shat), or the penalty P(sqrt(z)). For the
    /// barrier z must be positive.
    struct PairEnergy {
        double value = 0, first = 0, second = 0;
    };
    PairEnergy pair_energy(double z, bool second) const;
    /// The settings' pair model for the kernels (forward/kernels/contact_pair.hpp).
    kernels::PairModel pair_model() const;

    CollisionMesh m_mesh;
    Positions m_rest;
    std::vector<ContactPlane> m_planes;
    std::vector<Index> m_plane_vertices;
    ContactSettings m_settings;
    bool m_adaptive = false;
    double m_kappa_max = 0, m_bbox_diagonal = 1, m_previous_min_distance_squared = -1;
    std::function<double(const VectorXd&)> m_rule;
    bool m_rule_applied = false;

    // The last line-search segment x0 -> x0 + p and its swept candidates
    // (inflated by dmin + dhat): every trial point on it reuses them instead of
    // running the broad phase again.
    struct Segment;
    std::unique_ptr<Segment> m_segment;
    bool on_segment(const VectorXd& y) const;

    SurfaceImages m_images; ///< empty without periodic images

    mutable VectorXd m_cache_x;
    mutable ContactSet m_cache;
    mutable bool m_cache_valid = false;
    mutable ContactTimes m_times;
    mutable std::vector<double> m_gradient_buffer; ///< per-contact local gradients (4 vertices x dim each)
    mutable VertexScatter m_scatter; ///< gathers them per vertex in contact order
    mutable bool m_ccd_unresolved = false, m_ccd_budget_exhausted = false;
};

} // namespace diffipc
