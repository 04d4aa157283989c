#include "forward/scene/json_field.hpp"

#include <cmath>

namespace diffipc {

namespace {
    std::string type_name(const nlohmann::json& v)
    {
        if (v.is_null())
            return "null";
        return v.type_name();
    }
} // namespace

JsonField JsonField::operator[](const std::string& key) const
{
    if (!m_value.is_object())
        fail("expected an object, got " + type_name(m_value));
    if (!m_value.contains(key))
        throw InputError(m_path.empty() ? key : m_path + "." + key, "missing required field");
    return JsonField(m_value.at(key), m_path.empty() ? key : m_path + "." + key);
}

JsonField JsonField::at(size_t i) const { return JsonField(m_value.at(i), m_path + "[" + std::to_string(i) + "]"); }

void JsonField::require_object(std::initializer_list<const char*> allowed) const
{
    if (!m_value.is_object())
        fail("expected an object, got " + type_name(m_value));
    for (auto it = m_value.begin(); it != m_value.end(); ++it) {
        bool known = false;
        std::string list;
        for (const char* a : allowed) {
            known = known || it.key() == a;
            list += list.empty() ? a : std::string(", ") + a;
        }
        if (!known) {
            const std::string key = it.key().empty() ? "\"\"" : it.key(); // an empty key, shown as such
            throw InputError(m_path.empty() ? key : m_path + "." + key, "unknown field (allowed here: " + list + ")");
        }
    }
}

void JsonField::require_array(size_t min_size) const
{
    if (!m_value.is_array())
        fail("expected an array, got " + type_name(m_value));
    if (m_value.size() < min_size)
        fail("expected at least " + std::to_string(min_size) + " entries, got " + std::to_string(m_value.size()));
}

double JsonField::number() const
{
    if (m_value.is_string() && m_value.get<std::string>().rfind(NON_FINITE_MARK, 0) == 0)
        fail("number " + m_value.get<std::string>().substr(std::string(NON_FINITE_MARK).size()) + " is not finite");
    if (!m_value.is_number())
        fail("expected a number, got " + type_name(m_value));
    const double v = m_value.get<double>();
    if (!std::isfinite(v))
        fail("must be finite");
    return v;
}

double JsonField::positive() const
{
    const double v = number();
    if (!(v > 0))
        fail("must be positive, got " + m_value.dump());
    return v;
}

int JsonField::integer(int min_value) const
{
    if (!m_value.is_number_integer())
        fail("expected an integer, got " + (m_value.is_number() ? m_value.dump() : type_name(m_value)));
    const long long v = m_value.get<long long>();
    if (v < min_value)
        fail("must be at least " + std::to_string(min_value) + ", got " + std::to_string(v));
    if (v > 2000000000LL)
        fail("is too large");
    return int(v);
}

bool JsonField::boolean() const
{
    if (!m_value.is_boolean())
        fail("expected true or false, got " + type_name(m_value));
    return m_value.get<bool>();
}

std::string JsonField::string() const
{
    if (!m_value.is_string())
        fail("expected a string, got " + type_name(m_value));
    std::string text = m_value.get<std::string>();
    // No name, path, expression or keyword has one; a path would end there for the system.
    if (text.find('\0') != std::string::npos)
        fail("contains a NUL character (\\u0000)");
    return text;
}

VectorXd JsonField::vector(int size) const
{
    require_array();
    if (int(m_value.size()) != size)
        fail("expected " + std::to_string(size) + " numbers, got " + std::to_string(m_value.size()));
    VectorXd v(size);
    for (int i = 0; i < size; ++i)
        v[i] = at(size_t(i)).number();
    return v;
}

VectorXi JsonField::int_vector(int size, int min_value) const
{
    require_array();
    if (int(m_value.size()) != size)
        fail("expected " + std::to_string(size) + " integers, got " + std::to_string(m_value.size()));
    VectorXi v(size);
    for (int i = 0; i < size; ++i)
        v[i] = at(size_t(i)).integer(min_value);
    return v;
}

} // namespace diffipc
