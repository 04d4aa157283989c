#include "shape_opt/parametrization/parameter_map.hpp"

#include "forward/common/error.hpp"

#include <stdexcept>

namespace diffipc {

VectorXd ParameterMap::inverse(const VectorXd&, const std::string&) const
{
    throw std::logic_error("ParameterMap::inverse: the map '" + name() + "' has no inverse");
}

void check_size(const VectorXd& v, Index size, const std::string& field, const std::string& what)
{
    if (v.size() != size)
        throw InputError(field, what + " expects " + std::to_string(size) + " values, got " + std::to_string(v.size()));
}

ParameterChain::ParameterChain(std::vector<std::unique_ptr<ParameterMap>> maps, std::vector<std::string> fields)
    : m_maps(std::move(maps))
    , m_fields(std::move(fields))
{
    if (m_fields.size() != m_maps.size())
        throw std::logic_error("ParameterChain: one field per map");
    for (size_t i = 1; i < m_maps.size(); ++i)
        if (m_maps[i]->in_size() != m_maps[i - 1]->out_size())
            throw InputError(m_fields[i],
                "'" + m_maps[i]->name() + "' reads " + std::to_string(m_maps[i]->in_size()) + " values, but '"
                    + m_maps[i - 1]->name() + "' before it gives " + std::to_string(m_maps[i - 1]->out_size()));
}

ParameterChain::ParameterChain(Index size)
    : m_size(size)
{
}

VectorXd ParameterChain::apply(const VectorXd& x) const
{
    check_size(x, in_size(), "design", "the parametrization");
    VectorXd y = x;
    for (const auto& m : m_maps)
        y = m->apply(y);
    return y;
}

VectorXd ParameterChain::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", "the parametrization");
    check_size(y_bar, out_size(), "design", "the parametrization's gradient");
    // The maps' inputs, forward; then their transposed Jacobians, backward.
    std::vector<VectorXd> inputs;
    inputs.reserve(m_maps.size());
    VectorXd y = x;
    for (const auto& m : m_maps) {
        inputs.push_back(y);
        y = m->apply(y);
    }
    VectorXd bar = y_bar;
    for (size_t i = m_maps.size(); i-- > 0;)
        bar = m_maps[i]->vjp(inputs[i], bar);
    return bar;
}

bool ParameterChain::invertible() const
{
    for (const auto& m : m_maps)
        if (!m->invertible())
            return false;
    return true;
}

VectorXd ParameterChain::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, out_size(), field, "the parametrization's inverse");
    VectorXd x = y;
    for (size_t i = m_maps.size(); i-- > 0;) {
        if (!m_maps[i]->invertible())
            throw InputError(m_fields[i], "'" + m_maps[i]->name() + "' has no inverse: give the design variables");
        x = m_maps[i]->inverse(x, field);
    }
    return x;
}

Concatenation::Concatenation(std::vector<std::unique_ptr<ParameterMap>> parts)
    : m_parts(std::move(parts))
{
    for (const auto& p : m_parts) {
        m_in += p->in_size();
        m_out += p->out_size();
    }
}

VectorXd Concatenation::apply(const VectorXd& x) const
{
    check_size(x, m_in, "design", "concatenate");
    VectorXd y(m_out);
    Index i = 0, o = 0;
    for (const auto& p : m_parts) {
        y.segment(o, p->out_size()) = p->apply(x.segment(i, p->in_size()));
        i += p->in_size();
        o += p->out_size();
    }
    return y;
}

VectorXd Concatenation::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, m_in, "design", "concatenate");
    check_size(y_bar, m_out, "design", "concatenate's gradient");
    VectorXd x_bar(m_in);
    Index i = 0, o = 0;
    for (const auto& p : m_parts) {
        x_bar.segment(i, p->in_size()) = p->vjp(x.segment(i, p->in_size()), y_bar.segment(o, p->out_size()));
        i += p->in_size();
        o += p->out_size();
    }
    return x_bar;
}

bool Concatenation::invertible() const
{
    for (const auto& p : m_parts)
        if (!p->invertible())
            return false;
    return true;
}

VectorXd Concatenation::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, m_out, field, "concatenate's inverse");
    VectorXd x(m_in);
    Index i = 0, o = 0;
    for (const auto& p : m_parts) {
        x.segment(i, p->in_size()) = p->inverse(y.segment(o, p->out_size()), field);
        i += p->in_size();
        o += p->out_size();
    }
    return x;
}

} // namespace diffipc
