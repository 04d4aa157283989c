#pragma once
/// @file json_field.hpp
/// A JSON value together with its path in the document ("bodies[0].material.E"),
/// so that every validation error names the field it is about.

#include "forward/common/error.hpp"
#include "forward/common/types.hpp"

#include <nlohmann/json.hpp>

#include <initializer_list>
#include <string>

namespace diffipc {

/// Stands in for a number that overflowed a double while the text was parsed.
inline constexpr const char* NON_FINITE_MARK = "<non-finite number> ";

class JsonField {
public:
    JsonField(const nlohmann::json& value, std::string path)
        : m_value(value)
        , m_path(std::move(path))
    {
    }

    const nlohmann::json& json() const { return m_value; }
    const std::string& path() const { return m_path; }
    [[noreturn]] void fail(const std::string& message) const { throw InputError(m_path, message); }

    bool is_object() const { return m_value.is_object(); }
    bool has(const std::string& key) const { return m_value.is_object() && m_value.contains(key); }
    /// Child of an object; fails if missing.
    JsonField operator[](const std::string& key) const;
    /// Element of an array.
    JsonField at(size_t i) const;
    size_t size() const { return m_value.size(); }

    /// Fails unless this is an object whose keys are all in `allowed`.
    void require_object(std::initializer_list<const char*> allowed) const;
    void require_array(size_t min_size = 0) const;

    double number() const; ///< finite number
    double positive() const; ///< finite and > 0
    int integer(int min_value) const; ///< integer >= min_value
    bool boolean() const;
    std::string string() const;
    VectorXd vector(int size) const; ///< array of `size` finite numbers
    VectorXi int_vector(int size, int min_value) const;

    double number_or(const std::string& key, double fallback) const
    {
        return has(key) ? (*this)[key].number() : fallback;
    }

private:
    const nlohmann::json& m_value;
    std::string m_path;
};

} // namespace diffipc
