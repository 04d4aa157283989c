#pragma once
/// @file basic_maps.hpp
/// Maps that move, repeat, insert or transform values one by one (docs/parametrizations.md):
/// gather (slice, per body to per element or per vertex), constant insertion, scale and
/// offset, exp (log-space variables).

#include "shape_opt/parametrization/parameter_map.hpp"

namespace diffipc {

/// y_j = x_{index_j}: a slice (consecutive indices), a selection, or a repetition (one value
/// per body spread to its elements: index_e = body of e). VJP: x_bar_i = sum over j with
/// index_j = i of y_bar_j. Inverse: each input from the outputs that copy it, which must agree
/// (an E per element that is not constant over a body has no per-body design).
class GatherMap : public ParameterMap {
public:
    /// @param in_size number of inputs
    /// @param index out_size entries, each in [0, in_size)
    /// @param inputs_per_body whether the inputs are one per body (a remesh keeps them)
    /// @throws InputError naming `field` for an index out of range
    GatherMap(Index in_size, std::vector<Index> index, const std::string& field, std::string name = "gather",
        bool inputs_per_body = false);
    Index in_size() const override { return m_in; }
    Index out_size() const override { return Index(m_index.size()); }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    /// Every input is copied to at least one output.
    bool invertible() const override { return m_covers; }
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return m_name; }
    bool input_survives_remesh() const override { return m_per_body; }

private:
    Index m_in;
    std::vector<Index> m_index;
    std::string m_name;
    bool m_per_body = false;
    bool m_covers = false;
};

/// y is x with constants inserted: y_{positions_k} = values_k, the other entries of y take x
/// in order. VJP drops the constants' entries; the inverse reads the others.
class InsertConstantsMap : public ParameterMap {
public:
    /// @param out_size size of y
    /// @param positions distinct entries of y in [0, out_size)
    /// @param values one per position
    /// @throws InputError naming `field` for a position out of range or listed twice
    InsertConstantsMap(
        Index out_size, const std::vector<Index>& positions, const VectorXd& values, const std::string& field);
    Index in_size() const override { return Index(m_free.size()); }
    Index out_size() const override { return m_out; }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override { return true; }
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "insert"; }

private:
    Index m_out;
    std::vector<Index> m_free; ///< entries of y that come from x, in order
    std::vector<std::pair<Index, double>> m_constants;
};

/// y = a * x + b, a and b one value for all entries or one per entry.
class ScaleOffsetMap : public ParameterMap {
public:
    /// @throws InputError naming `field` for a or b of a size other than 1 or `size`, or not finite
    ScaleOffsetMap(Index size, const VectorXd& scale, const VectorXd& offset, const std::string& field);
    Index in_size() const override { return m_size; }
    Index out_size() const override { return m_size; }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override { return (m_scale.array() != 0).all(); }
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "scale"; }

private:
    Index m_size;
    VectorXd m_scale, m_offset; ///< size m_size
};

/// y = exp(x): a positive parameter (a modulus, a density) as a log-space variable, so that
/// relative changes are what the optimizer sees and no step makes it negative.
class ExpMap : public ParameterMap {
public:
    explicit ExpMap(Index size)
        : m_size(size)
    {
    }
    Index in_size() const override { return m_size; }
    Index out_size() const override { return m_size; }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override { return true; }
    /// @throws InputError naming `field` for a y that is not positive
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "exp"; }

private:
    Index m_size;
};

} // namespace diffipc
