#pragma once
/// @file parameter_map.hpp
/// Parametrizations (issue 12, docs/parametrizations.md): design variables x map to the
/// simulation parameters p through a chain of maps y = m(x), each with its value, its
/// vector-Jacobian product x_bar = (dm/dx)^T y_bar (the chain applies them in reverse
/// order for the gradient: dJ/dx = m_1'^T ... m_k'^T dJ/dp) and, where the map is
/// invertible, an inverse that turns an initial design p into x.
///
/// Sizes are part of every map: a chain whose sizes do not line up is an InputError
/// naming the entry, never a crash.

#include "forward/common/types.hpp"

#include <memory>
#include <string>
#include <vector>

namespace diffipc {

class RemeshableShape;

class ParameterMap {
public:
    virtual ~ParameterMap() = default;
    /// Number of inputs (the variables it reads) and outputs.
    virtual Index in_size() const = 0;
    virtual Index out_size() const = 0;
    /// @brief y = m(x).
    /// @param x in_size() values
    /// @return out_size() values
    virtual VectorXd apply(const VectorXd& x) const = 0;
    /// @brief (dm/dx at x)^T y_bar.
    /// @param x in_size() values (the point of linearization)
    /// @param y_bar out_size() values
    /// @return in_size() values
    virtual VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const = 0;
    /// Whether inverse() exists.
    virtual bool invertible() const { return false; }
    /// @brief x such that m(x) = y.
    /// @throws InputError naming `field` if y is outside the map's range (a log of a
    ///         negative value); std::logic_error if the map has no inverse
    virtual VectorXd inverse(const VectorXd& y, const std::string& field) const;
    /// What the map is, for messages and the docs ("exp", "scale", ...).
    virtual std::string name() const = 0;

    /// @name Remeshing (shape_opt/remesh.hpp): whether and how the map follows a new mesh.
    /// @{
    /// Whether the map's input keeps its meaning on another mesh of the same domain, so that a
    /// remesh keeps the design variables that reach it: values per body gathered onto elements,
    /// a free-form deformation's lattice. False by default (values per element, vertex or dof).
    virtual bool input_survives_remesh() const { return false; }
    /// The map as rest positions that any mesh of its domain can follow, or nullptr.
    virtual const RemeshableShape* remeshable_shape() const { return nullptr; }
    /// @}
};

/// A map whose output is the rest positions of whatever mesh of its domain it was built on, so
/// that a remesh rebuilds it on the new mesh and keeps its input (FreeFormDeformation).
class RemeshableShape {
public:
    virtual ~RemeshableShape() = default;
    /// @brief The rest positions that the input x moves onto `current` (#V by dim): the new
    /// mesh's rest positions when `current` is a new mesh of the domain at x.
    /// @throws std::runtime_error where the map cannot be inverted at a vertex
    virtual Positions pull_back(const Positions& current, const VectorXd& x) const = 0;
    /// The key of the map's JSON spec that says at which input its given mesh is the shape
    /// (a remesh writes the input there, with the new mesh).
    virtual std::string mesh_input_key() const = 0;
};

/// Maps applied one after the other: p = m_k(...m_2(m_1(x))).
class ParameterChain : public ParameterMap {
public:
    /// @brief Checks that out_size of each map is in_size of the next.
    /// @param fields one JSON path per map, for the messages ("design.maps[2]")
    /// @throws InputError naming the first map whose input size does not match
    ParameterChain(std::vector<std::unique_ptr<ParameterMap>> maps, std::vector<std::string> fields);
    /// A chain of no maps: the identity on `size` values.
    explicit ParameterChain(Index size);

    Index in_size() const override { return m_maps.empty() ? m_size : m_maps.front()->in_size(); }
    Index out_size() const override { return m_maps.empty() ? m_size : m_maps.back()->out_size(); }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override;
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "chain"; }
    size_t size() const { return m_maps.size(); }
    const ParameterMap& map(size_t i) const { return *m_maps[i]; }

private:
    std::vector<std::unique_ptr<ParameterMap>> m_maps;
    std::vector<std::string> m_fields;
    Index m_size = 0;
};

/// Sub-chains side by side: the input is split into consecutive blocks, one per part, and
/// the parts' outputs are concatenated (E from one block of x, a shape from another).
class Concatenation : public ParameterMap {
public:
    explicit Concatenation(std::vector<std::unique_ptr<ParameterMap>> parts);
    Index in_size() const override { return m_in; }
    Index out_size() const override { return m_out; }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override;
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "concatenate"; }

private:
    std::vector<std::unique_ptr<ParameterMap>> m_parts;
    Index m_in = 0, m_out = 0;
};

/// @brief Checks `v` has `size` entries.
/// @throws InputError naming `field` ("<what> expects N values, got M")
void check_size(const VectorXd& v, Index size, const std::string& field, const std::string& what);

} // namespace diffipc
