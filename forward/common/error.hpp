#pragma once
/// @file error.hpp
/// Errors a user can act on. InputError names the offending field or file
/// (for example "bodies[0].material.nu"); the CLI prints it as one line and
/// exits non-zero, the Python module raises ValueError.

#include <stdexcept>
#include <string>

namespace diffipc {

class InputError : public std::runtime_error {
public:
    /// @param field  JSON path or file name the error is about
    /// @param message what is wrong, in a form the user can act on
    InputError(const std::string& field, const std::string& message)
        : std::runtime_error(field.empty() ? message : field + ": " + message)
        , m_field(field)
    {
    }
    const std::string& field() const { return m_field; }

private:
    std::string m_field;
};

} // namespace diffipc
