#include "cli/json_path.hpp"

#include "forward/common/error.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace diffipc {

void set_path(json& document, const std::string& path, const json& value, const std::string& field)
{
    json* at = &document;
    std::string where;
    size_t i = 0;
    if (path.empty()) { // the whole document: a point that is a problem or scene of its own
        if (!value.is_object())
            throw InputError(field, "the path \"\" (the whole document) takes an object");
        document = value;
        return;
    }
    while (i < path.size()) {
        if (path[i] == '[') {
            const size_t close = path.find(']', i);
            const std::string digits = close == std::string::npos ? "" : path.substr(i + 1, close - i - 1);
            if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos)
                throw InputError(field, "\"" + path + "\": a list index is [digits]");
            if (digits.size() > 9)
                throw InputError(field, "\"" + path + "\": index " + digits + " is out of range");
            const size_t k = std::stoul(digits);
            if (!at->is_array())
                throw InputError(
                    field, "\"" + path + "\": " + (where.empty() ? "the document" : where) + " is not a list");
            if (k >= at->size())
                throw InputError(field,
                    "\"" + path + "\": index " + digits + " is out of range (" + where + " has "
                        + std::to_string(at->size()) + " entries)");
            at = &(*at)[k];
            where += "[" + digits + "]";
            i = close + 1;
            if (i < path.size() && path[i] == '.')
                ++i;
            continue;
        }
        const size_t end = path.find_first_of(".[", i);
        const std::string key = path.substr(i, end == std::string::npos ? std::string::npos : end - i);
        if (key.empty())
            throw InputError(field, "\"" + path + "\": an empty key");
        if (!at->is_object())
            throw InputError(field,
                "\"" + path + "\": " + (where.empty() ? "the document" : where) + " is not an object"
                    + (at->is_string() ? " (a file name: put the file's content there)" : ""));
        at = &(*at)[key]; // made (null) if missing
        where += (where.empty() ? "" : ".") + key;
        i = end == std::string::npos ? path.size() : end;
        if (i < path.size() && path[i] == '.')
            ++i;
    }
    *at = value;
}

void absolute_paths(json& node, const fs::path& folder)
{
    if (node.is_array())
        for (json& item : node)
            absolute_paths(item, folder);
    if (!node.is_object())
        return;
    for (auto& [key, value] : node.items()) {
        if ((key == "file" || key == "scene") && value.is_string()) {
            const fs::path file = value.get<std::string>();
            if (file.is_relative())
                value = fs::absolute(folder / file).lexically_normal().string();
        } else
            absolute_paths(value, folder);
    }
}

} // namespace diffipc
