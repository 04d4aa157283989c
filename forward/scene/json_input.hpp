#pragma once
/// @file json_input.hpp
/// Reading scene and problem files: limits checked before anything is allocated for
/// them, and JSON parsed so that every failure is an InputError naming the file.

#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>

namespace diffipc {

/// Largest scene or problem file read (bytes).
inline constexpr std::size_t MAX_INPUT_FILE_BYTES = std::size_t(64) << 20;
/// Deepest JSON nesting accepted (scenes and problems use fewer than 10 levels).
inline constexpr int MAX_JSON_DEPTH = 64;

/// @brief The contents of `path` (a file, or a pipe or device read up to the limit), at most
/// MAX_INPUT_FILE_BYTES.
/// @param what what the file is, in words ("scene file", "problem file")
/// @throws InputError naming the file (missing, a directory, too large, unreadable)
std::string read_input_file(const std::string& path, const std::string& what);

/// @brief Parses JSON text. Nesting deeper than MAX_JSON_DEPTH is refused; a number that
/// overflows a double becomes a string marked with NON_FINITE_MARK (json_field.hpp), so
/// that validation names the field it stands in.
/// @throws InputError naming `source`
nlohmann::json parse_json_text(const std::string& text, const std::string& source);

} // namespace diffipc
