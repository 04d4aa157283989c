#include "forward/scene/json_input.hpp"

#include "forward/common/error.hpp"
#include "forward/scene/json_field.hpp"

#include <filesystem>
#include <fstream>
#include <vector>

namespace diffipc {

namespace fs = std::filesystem;

namespace {
    /// nlohmann's message without its "[json.exception.parse_error.101] " tag.
    std::string without_library_tag(const std::string& what)
    {
        if (what.rfind("[json.exception.", 0) == 0)
            if (const std::size_t end = what.find("] "); end != std::string::npos)
                return what.substr(end + 2);
        return what;
    }
} // namespace

std::string read_input_file(const std::string& path, const std::string& what)
{
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (ec || !fs::exists(status))
        throw InputError(path, "cannot open " + what + " (no such file)");
    if (fs::is_directory(status))
        throw InputError(path, "cannot read " + what + ": it is a directory");
    const std::string too_large = what + " is larger than the limit of " + std::to_string(MAX_INPUT_FILE_BYTES)
        + " bytes (meshes belong in .msh or surface files)";
    if (fs::is_regular_file(status)) {
        const auto size = fs::file_size(path, ec);
        if (!ec && size > MAX_INPUT_FILE_BYTES)
            throw InputError(path, too_large);
    }
    // A pipe (process substitution) or device is read up to the limit: /dev/zero ends there.
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw InputError(path, "cannot open " + what);
    std::string text;
    std::vector<char> buffer(1 << 16);
    while (in) {
        in.read(buffer.data(), std::streamsize(buffer.size()));
        text.append(buffer.data(), size_t(in.gcount()));
        if (text.size() > MAX_INPUT_FILE_BYTES)
            throw InputError(path, too_large);
    }
    if (in.bad())
        throw InputError(path, "cannot read " + what);
    return text;
}

nlohmann::json parse_json_text(const std::string& text, const std::string& source)
{
    struct TooDeep { };
    const nlohmann::json::parser_callback_t depth_limit
        = [](int depth, nlohmann::json::parse_event_t event, nlohmann::json&) {
              if (depth > MAX_JSON_DEPTH
                  && (event == nlohmann::json::parse_event_t::object_start
                      || event == nlohmann::json::parse_event_t::array_start))
                  throw TooDeep {};
              return true;
          };
    std::string work = text;
    for (int attempt = 0;; ++attempt) {
        try {
            return nlohmann::json::parse(work, depth_limit);
        } catch (const TooDeep&) {
            throw InputError(source, "JSON nested deeper than " + std::to_string(MAX_JSON_DEPTH) + " levels");
        } catch (const nlohmann::json::parse_error& e) {
            throw InputError(source, "invalid JSON: " + without_library_tag(e.what()));
        } catch (const nlohmann::json::out_of_range& e) {
            // A number that overflows a double (1e999): mark it so that validation
            // names the field it stands in, then parse again.
            const std::string what = e.what();
            const size_t a = what.find('\''), b = what.rfind('\'');
            const size_t at = a < b ? work.find(what.substr(a + 1, b - a - 1)) : std::string::npos;
            if (at == std::string::npos || attempt > 1000)
                throw InputError(source, "invalid JSON: " + without_library_tag(what));
            work.replace(at, b - a - 1, "\"" + std::string(NON_FINITE_MARK) + what.substr(a + 1, b - a - 1) + "\"");
        }
    }
}

} // namespace diffipc
