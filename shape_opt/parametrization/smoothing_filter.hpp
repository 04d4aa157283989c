#pragma once
/// @file smoothing_filter.hpp
/// A smoothing filter over element neighbourhoods (docs/parametrizations.md): per-element
/// values x become
///
///   y_e = sum_f w_ef x_f / sum_f w_ef,   w_ef = |f| max(0, r - |c_e - c_f|),
///
/// with c the element centroids, |f| the element volumes and r the radius in metres (the
/// linear "hat" filter of density-based topology optimization, Bruns and Tortorelli 2001;
/// Bourdin 2001). A constant field stays constant; features smaller than r are smoothed out,
/// which regularizes a per-element modulus fitted to noisy data. Linear: the VJP is W^T.

#include "shape_opt/parametrization/parameter_map.hpp"

namespace diffipc {

class SmoothingFilter : public ParameterMap {
public:
    /// @param centroids #E by dim element centroids (m), row per element
    /// @param volumes #E element volumes (areas in 2D), positive
    /// @param radius r > 0 (m); with r below the distance between neighbouring centroids the
    ///        filter is the identity
    /// @throws InputError naming `field` for a radius that is not positive and finite
    SmoothingFilter(const MatrixXd& centroids, const VectorXd& volumes, double radius, const std::string& field);
    Index in_size() const override { return m_weights.cols(); }
    Index out_size() const override { return m_weights.rows(); }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    std::string name() const override { return "filter"; }
    /// The row-normalized weights W (#E by #E).
    const SparseMatrixd& weights() const { return m_weights; }

private:
    SparseMatrixd m_weights;
};

} // namespace diffipc
