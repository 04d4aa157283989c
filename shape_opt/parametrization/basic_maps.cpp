#include "shape_opt/parametrization/basic_maps.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cmath>

namespace diffipc {

GatherMap::GatherMap(
    Index in_size, std::vector<Index> index, const std::string& field, std::string name, bool inputs_per_body)
    : m_in(in_size)
    , m_index(std::move(index))
    , m_name(std::move(name))
    , m_per_body(inputs_per_body)
{
    std::vector<char> used(size_t(std::max<Index>(in_size, 0)), 0);
    for (size_t j = 0; j < m_index.size(); ++j) {
        if (m_index[j] < 0 || m_index[j] >= in_size)
            throw InputError(field,
                "entry " + std::to_string(j) + " reads value " + std::to_string(m_index[j]) + " of "
                    + std::to_string(in_size));
        used[size_t(m_index[j])] = 1;
    }
    m_covers = std::all_of(used.begin(), used.end(), [](char u) { return u != 0; });
}

VectorXd GatherMap::apply(const VectorXd& x) const
{
    check_size(x, m_in, "design", m_name);
    VectorXd y(out_size());
    for (size_t j = 0; j < m_index.size(); ++j)
        y[Index(j)] = x[m_index[j]];
    return y;
}

VectorXd GatherMap::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, m_in, "design", m_name);
    check_size(y_bar, out_size(), "design", m_name + "'s gradient");
    VectorXd x_bar = VectorXd::Zero(m_in);
    for (size_t j = 0; j < m_index.size(); ++j)
        x_bar[m_index[j]] += y_bar[Index(j)];
    return x_bar;
}

VectorXd GatherMap::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, out_size(), field, m_name);
    if (!m_covers)
        throw std::logic_error("GatherMap::inverse: not every input is read");
    VectorXd x = VectorXd::Constant(m_in, std::nan(""));
    for (size_t j = 0; j < m_index.size(); ++j) {
        double& v = x[m_index[j]];
        if (std::isnan(v))
            v = y[Index(j)];
        else if (std::abs(y[Index(j)] - v) > 1e-12 * std::max(std::abs(v), std::abs(y[Index(j)])))
            throw InputError(field,
                "values " + format_number(v) + " and " + format_number(y[Index(j)]) + " of one design variable ("
                    + std::to_string(m_index[j]) + ") differ: '" + m_name + "' cannot give them");
    }
    return x;
}

InsertConstantsMap::InsertConstantsMap(
    Index out_size, const std::vector<Index>& positions, const VectorXd& values, const std::string& field)
    : m_out(out_size)
{
    if (Index(positions.size()) != values.size())
        throw InputError(field,
            "one value per position: " + std::to_string(positions.size()) + " positions, "
                + std::to_string(values.size()) + " values");
    std::vector<char> constant(size_t(std::max<Index>(out_size, 0)), 0);
    for (size_t k = 0; k < positions.size(); ++k) {
        const Index p = positions[k];
        if (p < 0 || p >= out_size)
            throw InputError(
                field, "position " + std::to_string(p) + " is outside [0, " + std::to_string(out_size) + ")");
        if (constant[size_t(p)])
            throw InputError(field, "position " + std::to_string(p) + " is listed twice");
        if (!std::isfinite(values[Index(k)]))
            throw InputError(field, "non-finite value");
        constant[size_t(p)] = 1;
        m_constants.emplace_back(p, values[Index(k)]);
    }
    for (Index i = 0; i < out_size; ++i)
        if (!constant[size_t(i)])
            m_free.push_back(i);
}

VectorXd InsertConstantsMap::apply(const VectorXd& x) const
{
    check_size(x, in_size(), "design", "insert");
    VectorXd y(m_out);
    for (size_t i = 0; i < m_free.size(); ++i)
        y[m_free[i]] = x[Index(i)];
    for (const auto& [p, v] : m_constants)
        y[p] = v;
    return y;
}

VectorXd InsertConstantsMap::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", "insert");
    check_size(y_bar, m_out, "design", "insert's gradient");
    VectorXd x_bar(in_size());
    for (size_t i = 0; i < m_free.size(); ++i)
        x_bar[Index(i)] = y_bar[m_free[i]];
    return x_bar;
}

VectorXd InsertConstantsMap::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, m_out, field, "insert");
    VectorXd x(in_size());
    for (size_t i = 0; i < m_free.size(); ++i)
        x[Index(i)] = y[m_free[i]];
    return x;
}

namespace {
    VectorXd per_entry(const VectorXd& v, Index size, const std::string& field, const char* what)
    {
        if (!v.allFinite())
            throw InputError(field, std::string(what) + ": non-finite value");
        if (v.size() == 1)
            return VectorXd::Constant(size, v[0]);
        if (v.size() != size)
            throw InputError(field,
                std::string(what) + ": give one value or " + std::to_string(size) + ", got "
                    + std::to_string(v.size()));
        return v;
    }
} // namespace

ScaleOffsetMap::ScaleOffsetMap(Index size, const VectorXd& scale, const VectorXd& offset, const std::string& field)
    : m_size(size)
    , m_scale(per_entry(scale, size, field, "scale"))
    , m_offset(per_entry(offset, size, field, "offset"))
{
}

VectorXd ScaleOffsetMap::apply(const VectorXd& x) const
{
    check_size(x, m_size, "design", "scale");
    return m_scale.cwiseProduct(x) + m_offset;
}

VectorXd ScaleOffsetMap::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, m_size, "design", "scale");
    check_size(y_bar, m_size, "design", "scale's gradient");
    return m_scale.cwiseProduct(y_bar);
}

VectorXd ScaleOffsetMap::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, m_size, field, "scale");
    return (y - m_offset).cwiseQuotient(m_scale);
}

VectorXd ExpMap::apply(const VectorXd& x) const
{
    check_size(x, m_size, "design", "exp");
    return x.array().exp().matrix();
}

VectorXd ExpMap::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, m_size, "design", "exp");
    check_size(y_bar, m_size, "design", "exp's gradient");
    return x.array().exp().matrix().cwiseProduct(y_bar);
}

VectorXd ExpMap::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, m_size, field, "exp");
    for (Index i = 0; i < y.size(); ++i)
        if (!(y[i] > 0) || !std::isfinite(y[i]))
            throw InputError(field,
                "a log-space variable needs a positive value, got " + format_number(y[i]) + " (entry "
                    + std::to_string(i) + ")");
    return y.array().log().matrix();
}

} // namespace diffipc
