#include "objectives/objective_json.hpp"

#include "forward/common/error.hpp"
#include "objective_fd.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

using namespace diffipc;
using nlohmann::json;

namespace {

std::string read_text(const std::filesystem::path& path)
{
    std::ifstream in(path);
    EXPECT_TRUE(in.good()) << "cannot read " << path;
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

std::string trim(const std::string& s)
{
    const size_t a = s.find_first_not_of(" \t");
    const size_t b = s.find_last_not_of(" \t");
    return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

using TypeKeys = std::map<std::string, std::set<std::string>>;

/// The rows "| `type` | `key`, `key` | J |" of the "## Objective types" table of `markdown`, as
/// type -> keys. A type listed twice is a test failure (each type has one row).
TypeKeys documented_types(const std::string& markdown)
{
    TypeKeys types;
    std::istringstream in(markdown);
    std::string line;
    bool in_section = false;
    bool in_table = false;
    while (std::getline(in, line)) {
        if (line.rfind("## ", 0) == 0) {
            if (in_section)
                break;
            in_section = line == "## Objective types";
            continue;
        }
        if (!in_section)
            continue;
        if (line.rfind("|", 0) != 0) {
            if (in_table)
                break; // the table ended
            continue;
        }
        in_table = true;
        std::vector<std::string> cells;
        std::stringstream row(line.substr(1));
        for (std::string cell; std::getline(row, cell, '|');)
            cells.push_back(trim(cell));
        if (cells.size() < 2 || cells[0] == "type" || cells[0].rfind("---", 0) == 0)
            continue; // the header and the separator
        const std::regex name_re("^`([a-z_]+)`$");
        std::smatch name;
        if (!std::regex_match(cells[0], name, name_re)) {
            ADD_FAILURE() << "a row of \"Objective types\" whose first cell is not one `type`: " << line;
            continue;
        }
        std::set<std::string> keys;
        const std::regex key_re("`([a-z_]+)`");
        for (auto it = std::sregex_iterator(cells[1].begin(), cells[1].end(), key_re); it != std::sregex_iterator();
             ++it)
            keys.insert((*it)[1]);
        EXPECT_TRUE(types.emplace(name[1], keys).second) << "type " << name[1] << " listed twice";
    }
    return types;
}

TypeKeys registered()
{
    TypeKeys types;
    for (const ObjectiveType& t : registered_objective_types()) {
        EXPECT_TRUE(types.emplace(t.name, std::set<std::string>(t.keys.begin(), t.keys.end())).second)
            << "type " << t.name << " registered twice";
        EXPECT_EQ(t.keys.size(), types[t.name].size()) << t.name << " lists a key twice";
    }
    return types;
}

std::set<std::string> names(const TypeKeys& types)
{
    std::set<std::string> n;
    for (const auto& [name, keys] : types)
        n.insert(name);
    return n;
}

std::string objectives_md() { return read_text(std::filesystem::path(DIFFIPC_SOURCE_DIR) / "docs" / "objectives.md"); }

/// Every string captured by `pattern`'s first group in `text`.
std::set<std::string> matches(const std::string& text, const std::regex& pattern)
{
    std::set<std::string> found;
    for (auto it = std::sregex_iterator(text.begin(), text.end(), pattern); it != std::sregex_iterator(); ++it)
        found.insert((*it)[1]);
    return found;
}

} // namespace

TEST(ObjectiveRegistry, DocumentedTypesAreTheRegisteredOnes)
{
    const TypeKeys documented = documented_types(objectives_md());
    ASSERT_FALSE(documented.empty()) << "docs/objectives.md has no \"## Objective types\" table";
    EXPECT_EQ(names(documented), names(registered()));
}

TEST(ObjectiveRegistry, DocumentedKeysAreTheAcceptedOnes)
{
    const TypeKeys documented = documented_types(objectives_md());
    for (const auto& [name, keys] : registered()) {
        const auto d = documented.find(name);
        if (d != documented.end())
            EXPECT_EQ(d->second, keys) << "keys of objective type " << name;
    }
}

/// The page's examples, and the objectives written in the other docs and the README, use only
/// registered types.
TEST(ObjectiveRegistry, ExamplesInTheDocsUseRegisteredTypes)
{
    const std::set<std::string> known = names(registered());
    for (const std::string& type : matches(objectives_md(), std::regex("\"type\": *\"([a-z_]+)\"")))
        EXPECT_TRUE(known.count(type)) << "docs/objectives.md uses objective type " << type;
    const std::filesystem::path root(DIFFIPC_SOURCE_DIR);
    std::vector<std::filesystem::path> pages = { root / "README.md" };
    for (const auto& entry : std::filesystem::directory_iterator(root / "docs"))
        if (entry.path().extension() == ".md")
            pages.push_back(entry.path());
    const std::regex objective("\"objective\": *\\{ *\"type\": *\"([a-z_]+)\"");
    for (const auto& page : pages)
        for (const std::string& type : matches(read_text(page), objective))
            EXPECT_TRUE(known.count(type)) << page << " uses objective type " << type;
}

TEST(ObjectiveRegistry, UnknownTypeListsTheRegisteredNames)
{
    const Simulator sim(test::make_scene(test::cantilever_scene(2)));
    std::string expected;
    const auto& types = registered_objective_types();
    for (size_t i = 0; i < types.size(); ++i)
        expected += (i == 0 ? "" : i + 1 == types.size() ? " or " : ", ") + types[i].name;
    EXPECT_EQ(test::objective_error({ { "type", "stress_max" } }, sim),
        "objective.type: unknown objective type \"stress_max\" (expected " + expected + ")");
    for (const char* name : { "stress_norm", "body_force", "constraint" })
        EXPECT_NE(expected.find(name), std::string::npos) << name;
}

/// The factory checks each type's keys against its own entry: every listed key gets past the
/// key check (a wrong value is refused later, by another message), any other is refused with the list.
TEST(ObjectiveRegistry, EachTypeAcceptsExactlyItsKeys)
{
    const Simulator sim(test::make_scene(test::cantilever_scene(2)));
    for (const ObjectiveType& type : registered_objective_types()) {
        std::string allowed = "type";
        for (const std::string& key : type.keys) {
            allowed += ", " + key;
            const std::string error = test::objective_error({ { "type", type.name }, { key, nullptr } }, sim);
            EXPECT_EQ(error.find("unknown field"), std::string::npos) << type.name << "." << key << ": " << error;
        }
        EXPECT_EQ(test::objective_error({ { "type", type.name }, { "colour", 1 } }, sim),
            "objective.colour: unknown field (allowed here: " + allowed + ")");
    }
}

/// markers has one key list for its two forms; each form refuses the other's keys.
TEST(ObjectiveRegistry, MarkersRefuseTheOtherFormsKeys)
{
    const Simulator sim(test::make_scene(test::cantilever_scene(2)));
    EXPECT_EQ(test::objective_error(json::parse(R"({"type": "markers", "vertices": [0], "targets": [[[0, 0]]],
                                                  "steps": [3], "vertex_tolerance": 1e-6})"),
                  sim),
        "objective.vertex_tolerance: only applies with \"file\"");
    EXPECT_EQ(test::objective_error(json::parse(R"({"type": "markers", "file": "m.txt", "vertices": [0]})"), sim),
        "objective.vertices: not with \"file\": the file gives the markers and their positions");
}
