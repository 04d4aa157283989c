#pragma once
/// @file expression.hpp
/// Scalar expressions of time t and rest coordinates x, y, z (muparser syntax),
/// used for Dirichlet displacements and Neumann tractions in scene files.

#include <memory>
#include <string>

namespace diffipc {

class Expression {
public:
    /// @brief Parses `text` ("0", "0.1*sin(2*_pi*t)", "-1e3*t*y").
    /// @param field JSON path named in errors
    /// @throws InputError if the text does not parse or evaluates to a non-finite value at t = 0.
    Expression(const std::string& text, const std::string& field);
    /// A constant expression.
    explicit Expression(double value = 0.0);
    Expression(const Expression& other);
    Expression& operator=(const Expression& other);
    ~Expression();

    /// @brief Value at time t (s) and rest position (x, y, z) (m).
    /// @throws InputError naming the field if the value is not finite.
    double operator()(double t, double x = 0, double y = 0, double z = 0) const;
    const std::string& text() const { return m_text; }
    bool is_constant() const { return m_constant; }

private:
    struct Impl;
    std::string m_text;
    std::string m_field;
    bool m_constant = true;
    double m_value = 0;
    std::unique_ptr<Impl> m_impl;
};

} // namespace diffipc
