#pragma once
/// @file friction_potential.hpp
/// Lagged smoothed Coulomb friction (Li et al. 2020, "Incremental Potential
/// Contact", Sec. 5; docs/math.md "Friction"). For every contact active at the
/// lagged state the normal force magnitude lambda_k, the tangent basis T_k and
/// the closest-point weights gamma_k are frozen; the potential is
///   D(x) = sum_k mu_k lambda_k f0(|u_k|),  u_k = T_k^T sum_i gamma_ki (x_i - x0_i),
/// with x0 the positions at the start of the time step and
///   f0(y) = -y^3/(3 eps^2) + y^2/eps + eps/3 (y < eps), y (y >= eps),  eps = eps_v h.
/// Its Hessian is positive semi-definite (a congruence of PSD 1x1 or 2x2 blocks),
/// so the search matrix and the true Hessian coincide.

#include "forward/common/parallel.hpp"
#include "forward/contact/contact_set.hpp"
#include "forward/contact/surface_images.hpp"
#include "forward/kernels/friction_pair.hpp"
#include "forward/potentials/potential.hpp"

#include <vector>

namespace diffipc {

class ContactPotential;

/// The frozen data of one frictional contact.
struct FrictionContact {
    ContactKind kind = ContactKind::VERTEX_FACE;
    std::array<Index, 4> vertices { -1, -1, -1, -1 };
    int num_vertices = 0;
    std::array<double, 4> weights { 0, 0, 0, 0 }; ///< gamma: relative position p - q = sum_i gamma_i x_i
    Eigen::Vector3d normal = Eigen::Vector3d::Zero(); ///< unit contact normal at the lagged state
    Eigen::Matrix<double, 3, 2> tangent
        = Eigen::Matrix<double, 3, 2>::Zero(); ///< T: orthonormal columns (2D: one column)
    double normal_force = 0; ///< lambda (N): kappa m |d(b)/d(d)| at the lagged state
    double coefficient = 0; ///< mu of the pair
    std::array<int, 2> groups { -1, -1 }; ///< contact groups of the two sides (mu = sqrt(mu_a mu_b))
    Contact source; ///< the barrier contact it was lagged from (type, plane, mollifier threshold)
};

/// @brief Weights gamma with p - q = sum_i gamma_i x_i, where p, q are the closest
/// points of the contact's classified feature pair at x (edge parameters clamped to [0, 1]).
/// @param x #V*dim positions
std::array<double, 4> closest_point_weights(const Contact& c, const VectorXd& x, int dim);

/// @brief The lagged pair in the layout of the shared kernel (forward/kernels/friction_pair.hpp),
/// which the CPU's FrictionPotential and the GPU's DeviceFriction both evaluate.
kernels::FrictionPair friction_pair(const FrictionContact& c);

class FrictionPotential : public Potential {
public:
    /// @param dim          2 or 3
    /// @param group_coefficient  mu per contact group (bodies, then obstacles)
    /// @param vertex_group #V group of each vertex (the mesh's vertex_body)
    /// @param eps_v        velocity below which friction is smoothed (m/s)
    FrictionPotential(int dim, std::vector<double> group_coefficient, VectorXi vertex_group, double eps_v);

    std::string name() const override { return "friction"; }
    double value(const VectorXd& x) const override;
    void add_gradient(const VectorXd& x, double weight, VectorXd& g) const override;
    void add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const override;

    /// @brief Freezes normal forces, tangents and weights from the contacts active at x_lagged.
    /// @param contact   the barrier (its stiffness, dhat and dmin give the normal forces)
    /// @param x_lagged  #V*dim state the data is taken from
    void lag(const ContactPotential& contact, const VectorXd& x_lagged);
    /// @brief lag() from a given active set at x_lagged (the GPU path's: DeviceSolver::contacts, the
    /// same pairs as contact.contacts(x_lagged)); the contact gives kappa, dhat, dmin and the planes.
    void lag(const ContactPotential& contact, const ContactSet& set, const VectorXd& x_lagged);
    /// @brief Sets the start-of-step positions x0 and the time step h (eps = eps_v h).
    void set_step(const VectorXd& x_start, double dt);

    /// @brief Periodic images (forward/periodic/contact_images.hpp, as ContactPotential::set_images):
    /// the lagged contacts index the image surface x_s = T x; every method still takes the mesh's
    /// positions and returns T^T g_s, T^T H_s T.
    /// @param surface_group the contact group of each surface vertex (-1 off the surface)
    void set_images(SparseMatrixd T, VectorXi surface_group);
    bool has_images() const { return !m_images.empty(); }
    /// The contact group of each vertex the lagged contacts index (the surface's with images).
    const VectorXi& vertex_groups() const { return m_vertex_group; }

    const std::vector<FrictionContact>& lagged() const { return m_contacts; }
    /// @brief Restores lagged data recorded earlier (StepRecord::friction).
    void set_lagged(std::vector<FrictionContact> contacts) { m_contacts = std::move(contacts); }
    /// Start-of-step positions x0 (#V*dim; with images the surface's, T x0).
    const VectorXd& step_start() const { return m_x_start; }
    /// Friction coefficient per contact group.
    const std::vector<double>& group_coefficients() const { return m_group_coefficient; }
    double eps() const { return m_eps; }

    /// f0, f1 = f0' and f1' of the mollified speed (exposed for tests).
    static double f0(double y, double eps);
    static double f1(double y, double eps);
    static double f1_derivative(double y, double eps);

private:
    /// x, or T x (in `storage`) with images.
    const VectorXd& surface(const VectorXd& x, VectorXd& storage) const { return m_images.surface(x, storage); }
    /// One pair's energy, gradient (n) and Hessian (n by n, row-major; n = #vertices * dim) at the
    /// surface positions x (forward/kernels/friction_pair.hpp); either pointer may be null.
    double pair(const FrictionContact& c, const VectorXd& x, double* gradient, double* hessian) const;

    int m_dim;
    std::vector<double> m_group_coefficient;
    VectorXi m_vertex_group;
    double m_eps_v;
    double m_eps = 0;
    VectorXd m_x_start;
    SurfaceImages m_images; ///< empty without periodic images
    std::vector<FrictionContact> m_contacts;
    mutable std::vector<double> m_gradient_buffer; ///< per-contact local forces (4 vertices x dim each)
    mutable VertexScatter m_scatter; ///< gathers them per vertex in contact order
};

} // namespace diffipc
