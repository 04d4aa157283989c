#pragma once
/// @file error.hpp
/// Errors a user can act on. InputError names the offending field or file
/// (for example "bodies[0].material.nu"); the CLI prints it as one line and
/// exits non-zero, the Python module raises ValueError.

#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace diffipc {

/// Longest message an InputError carries: a message quotes user input (a malformed line,
/// an expression), which may be megabytes long; the quote is cut, the message stays one line.
inline constexpr std::size_t MAX_ERROR_MESSAGE = 600;

/// `text` cut to MAX_ERROR_MESSAGE characters (with how much was left out), line breaks as spaces,
/// a NUL character as "\0" (a C string, printed with %s, would end there) and other control
/// characters as '?'.
inline std::string clip_message(std::string text)
{
    if (text.find('\0') != std::string::npos) {
        std::string shown;
        for (char c : text)
            shown += c == '\0' ? std::string("\\0") : std::string(1, c);
        text = std::move(shown);
    }
    for (char& c : text)
        if (c == '\n' || c == '\r')
            c = ' ';
        else if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7f)
            c = '?';
    if (text.size() <= MAX_ERROR_MESSAGE)
        return text;
    const std::size_t omitted = text.size() - MAX_ERROR_MESSAGE;
    return text.substr(0, MAX_ERROR_MESSAGE) + "... (" + std::to_string(omitted) + " more characters)";
}

/// `value` for a message: at most 7 significant digits ("1e+300", "0.001", "-nan", "inf"),
/// never the 300 digits std::to_string prints for a huge double or the "0.000000" of a tiny one.
inline std::string format_number(double value)
{
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.7g", value);
    return buffer;
}

class InputError : public std::runtime_error {
public:
    /// @param field  JSON path or file name the error is about
    /// @param message what is wrong, in a form the user can act on
    InputError(const std::string& field, const std::string& message)
        : std::runtime_error(clip_message(field.empty() ? message : field + ": " + message))
        , m_field(field)
        , m_message(clip_message(message))
    {
    }
    const std::string& field() const { return m_field; }
    /// What is wrong, without the field (to name the field within a larger input).
    const std::string& message() const { return m_message; }

private:
    std::string m_field;
    std::string m_message;
};

} // namespace diffipc
