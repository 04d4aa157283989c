// shape_opt/optimizer/optimizer.hpp's table of algorithms against docs/optimization.md: the page's table of
// optimizers (names, what each takes, the library) is the registry's, row for row, and every algorithm the
// page names in the `optimizer` key table is registered; minimize()'s refusals list the algorithms the table
// says take what the problem has.

#include "shape_opt/optimizer/optimizer.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

using namespace diffipc;

namespace {

std::string read_page()
{
    const std::string path = std::string(DIFFIPC_SOURCE_DIR) + "/docs/optimization.md";
    std::ifstream in(path);
    EXPECT_TRUE(in.good()) << path;
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

std::vector<std::string> cells(const std::string& row)
{
    std::vector<std::string> out;
    std::stringstream s(row);
    std::string cell;
    std::getline(s, cell, '|'); // before the first bar
    while (std::getline(s, cell, '|')) {
        const size_t a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
        out.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
    }
    if (!out.empty() && out.back().empty())
        out.pop_back();
    return out;
}

std::vector<std::string> backticked(const std::string& text)
{
    std::vector<std::string> names;
    const std::regex name("`\"?([a-z_]+)\"?`");
    for (auto it = std::sregex_iterator(text.begin(), text.end(), name); it != std::sregex_iterator(); ++it)
        names.push_back((*it)[1]);
    return names;
}

struct Documented {
    bool bounds, inequalities, equalities;
    std::string library;
};

/// The rows of the page's table headed "| algorithm | bounds | c(x) <= 0 | h(x) = 0 | library |".
std::map<std::string, Documented> documented_algorithms(const std::string& page)
{
    std::map<std::string, Documented> out;
    std::stringstream s(page);
    std::string line;
    bool in_table = false;
    while (std::getline(s, line)) {
        if (line.rfind("| algorithm | bounds |", 0) == 0) {
            in_table = true;
            continue;
        }
        if (!in_table || line.rfind("| ---", 0) == 0)
            continue;
        if (line.rfind("|", 0) != 0)
            break;
        const std::vector<std::string> c = cells(line);
        EXPECT_EQ(c.size(), 5u) << line;
        if (c.size() != 5)
            continue;
        const auto yes = [&](const std::string& v) {
            EXPECT_TRUE(v == "yes" || v == "no") << line;
            return v == "yes";
        };
        for (const std::string& name : backticked(c[0])) {
            EXPECT_EQ(out.count(name), 0u) << name << " is listed twice";
            out[name] = { yes(c[1]), yes(c[2]), yes(c[3]), c[4] };
        }
    }
    return out;
}

} // namespace

TEST(OptimizerRegistry, TheDocsTableIsTheRegistry)
{
    const std::map<std::string, Documented> documented = documented_algorithms(read_page());
    ASSERT_FALSE(documented.empty()) << "no table headed '| algorithm | bounds |' in docs/optimization.md";
    std::set<std::string> registered;
    for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms()) {
        registered.insert(info.name);
        const auto it = documented.find(info.name);
        if (it == documented.end()) {
            ADD_FAILURE() << info.name << " is registered but not in docs/optimization.md's table";
            continue;
        }
        EXPECT_EQ(it->second.bounds, info.bounds) << info.name;
        EXPECT_EQ(it->second.inequalities, info.inequalities) << info.name;
        EXPECT_EQ(it->second.equalities, info.equalities) << info.name;
        EXPECT_NE(it->second.library.find(info.library), std::string::npos)
            << info.name << ": the docs say " << it->second.library << ", the table " << info.library;
    }
    for (const auto& [name, d] : documented)
        EXPECT_EQ(registered.count(name), 1u) << name << " is documented but not registered";
}

TEST(OptimizerRegistry, TheKeyTableNamesRegisteredAlgorithms)
{
    const std::string page = read_page();
    std::stringstream s(page);
    std::string line;
    std::set<std::string> named;
    while (std::getline(s, line))
        if (line.rfind("| `algorithm` |", 0) == 0)
            for (const std::string& name : backticked(cells(line).at(2)))
                named.insert(name);
    std::set<std::string> registered;
    for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms())
        registered.insert(info.name);
    EXPECT_EQ(named, registered) << "the `algorithm` row of docs/optimization.md's key table";
}

TEST(OptimizerRegistry, NamesRoundTripAndUnknownOnesListTheTable)
{
    for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms()) {
        EXPECT_EQ(parse_optimizer_algorithm(info.name, "optimizer.algorithm"), info.algorithm);
        EXPECT_EQ(to_string(info.algorithm), info.name);
        EXPECT_EQ(&optimizer_algorithm_info(info.algorithm), &info);
    }
    try {
        parse_optimizer_algorithm("newton", "optimizer.algorithm");
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("optimizer.algorithm"), std::string::npos) << what;
        for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms())
            EXPECT_NE(what.find("\"" + std::string(info.name) + "\""), std::string::npos) << what;
    }
}
