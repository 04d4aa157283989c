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

/// Length of the valid UTF-8 sequence at text[i] (1 to 4), or 0 if the bytes there are not
/// one (a stray continuation byte, a truncated sequence, an overlong form, a surrogate).
inline std::size_t utf8_sequence_length(const std::string& text, std::size_t i)
{
    const auto byte = [&](std::size_t k) { return k < text.size() ? static_cast<unsigned char>(text[k]) : 0u; };
    const unsigned lead = byte(i);
    if (lead < 0x80)
        return 1;
    std::size_t length = 0;
    unsigned low = 0x80, high = 0xbf; // allowed range of the second byte
    if (lead >= 0xc2 && lead <= 0xdf)
        length = 2;
    else if (lead >= 0xe0 && lead <= 0xef) {
        length = 3;
        low = lead == 0xe0 ? 0xa0 : 0x80;
        high = lead == 0xed ? 0x9f : 0xbf;
    } else if (lead >= 0xf0 && lead <= 0xf4) {
        length = 4;
        low = lead == 0xf0 ? 0x90 : 0x80;
        high = lead == 0xf4 ? 0x8f : 0xbf;
    } else
        return 0;
    if (byte(i + 1) < low || byte(i + 1) > high)
        return 0;
    for (std::size_t k = 2; k < length; ++k)
        if (byte(i + k) < 0x80 || byte(i + k) > 0xbf)
            return 0;
    return length;
}

/// `text` cut to MAX_ERROR_MESSAGE characters (with how much was left out), line breaks as spaces,
/// a NUL character as "\0" (a C string, printed with %s, would end there), other control
/// characters and bytes that are not UTF-8 as '?' (the message is valid UTF-8: Python turns it
/// into a str, a terminal shows it).
inline std::string clip_message(std::string text)
{
    {
        std::string valid;
        valid.reserve(text.size());
        for (std::size_t i = 0; i < text.size();) {
            const std::size_t length = utf8_sequence_length(text, i);
            if (length == 0) {
                valid += '?';
                ++i;
            } else {
                valid.append(text, i, length);
                i += length;
            }
        }
        text = std::move(valid);
    }
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
    std::size_t cut = MAX_ERROR_MESSAGE; // not inside a multi-byte character
    while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xc0) == 0x80)
        --cut;
    const std::size_t omitted = text.size() - cut;
    return text.substr(0, cut) + "... (" + std::to_string(omitted) + " more characters)";
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
