#include "forward/scene/expression.hpp"

#include "forward/common/error.hpp"

#include <muParser.h>

#include <cmath>
#include <mutex>

namespace diffipc {

namespace {

    /// Position of an '=' that assigns (muparser's "=", "+=", "-=", "*=", "/="), or npos: only the
    /// comparisons "==", "!=", "<=" and ">=" may contain one. Expressions must not change t, x, y or z.
    std::size_t assignment_position(const std::string& text)
    {
        for (std::size_t i = 0; i < text.size(); ++i) {
            if (text[i] != '=')
                continue;
            const char before = i > 0 ? text[i - 1] : ' ';
            if (before == '!' || before == '<' || before == '>')
                continue;
            if (i + 1 < text.size() && text[i + 1] == '=') {
                ++i; // "==": skip its second '='
                continue;
            }
            return i;
        }
        return std::string::npos;
    }

} // namespace

struct Expression::Impl {
    mu::Parser parser;
    double t = 0, x = 0, y = 0, z = 0;
    std::mutex mutex; // muparser keeps evaluation state in the parser object
    explicit Impl(const std::string& text)
    {
        parser.DefineVar("t", &t);
        parser.DefineVar("x", &x);
        parser.DefineVar("y", &y);
        parser.DefineVar("z", &z);
        parser.SetExpr(text);
    }
};

Expression::Expression(const std::string& text, const std::string& field)
    : m_text(text)
    , m_field(field)
    , m_constant(false)
{
    if (text.find('\0') != std::string::npos)
        throw InputError(field, "expression contains a NUL character");
    if (const std::size_t at = assignment_position(text); at != std::string::npos)
        throw InputError(field,
            "invalid expression '" + text + "': '=' at position " + std::to_string(at + 1)
                + " assigns a variable (compare with ==)");
    int results = 0;
    try {
        m_impl = std::make_unique<Impl>(text);
        m_impl->parser.Eval();
        results = m_impl->parser.GetNumResults();
    } catch (const mu::Parser::exception_type& e) {
        throw InputError(field, "invalid expression '" + text + "': " + e.GetMsg());
    }
    if (results != 1)
        throw InputError(field,
            "invalid expression '" + text + "': it has " + std::to_string(results)
                + " comma-separated values, expected one (write decimals with a point)");
    (*this)(0.0);
}

Expression::Expression(double value)
    : m_text(std::to_string(value))
    , m_constant(true)
    , m_value(value)
{
}

Expression::Expression(const Expression& other)
    : m_text(other.m_text)
    , m_field(other.m_field)
    , m_constant(other.m_constant)
    , m_value(other.m_value)
{
    if (other.m_impl)
        m_impl = std::make_unique<Impl>(m_text);
}

Expression& Expression::operator=(const Expression& other)
{
    if (this != &other) {
        m_text = other.m_text;
        m_field = other.m_field;
        m_constant = other.m_constant;
        m_value = other.m_value;
        m_impl = other.m_impl ? std::make_unique<Impl>(m_text) : nullptr;
    }
    return *this;
}

Expression::~Expression() = default;

double Expression::operator()(double t, double x, double y, double z) const
{
    if (m_constant)
        return m_value;
    double value;
    {
        std::lock_guard<std::mutex> lock(m_impl->mutex);
        m_impl->t = t;
        m_impl->x = x;
        m_impl->y = y;
        m_impl->z = z;
        try {
            value = m_impl->parser.Eval();
        } catch (const mu::Parser::exception_type& e) {
            throw InputError(m_field, "cannot evaluate '" + m_text + "': " + e.GetMsg());
        }
    }
    if (!std::isfinite(value))
        throw InputError(m_field, "expression '" + m_text + "' is not finite at t = " + format_number(t));
    return value;
}

} // namespace diffipc
