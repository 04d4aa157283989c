// shape_opt/parametrization/map_json.hpp: a problem file's "maps". The map types it accepts are
// the ones docs/parametrizations.md documents (read from the one table the parser uses), the
// unknown-type error lists them, and the JSON forms of gather and concatenate build chains whose
// values and vector-Jacobian products are checked against hand-computed values and differences.

#include "shape_opt/parametrization/map_json.hpp"
#include "tests/shape_opt/parametrization/map_check.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>

using namespace diffipc;

namespace {

std::string read_docs()
{
    std::ifstream in(std::string(DIFFIPC_SOURCE_DIR) + "/docs/parametrizations.md");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

/// The rows of the markdown table whose header line is `header`, up to the first line that is
/// not a row.
std::vector<std::string> table_rows(const std::string& text, const std::string& header)
{
    const size_t at = text.find(header + "\n");
    if (at == std::string::npos)
        return {};
    std::vector<std::string> rows;
    std::istringstream lines(text.substr(at));
    std::string line;
    std::getline(lines, line); // the header
    std::getline(lines, line); // | --- |
    while (std::getline(lines, line) && !line.empty() && line[0] == '|')
        rows.push_back(line);
    return rows;
}

/// The first `name` in backquotes of a row: the map it is about.
std::string row_name(const std::string& row)
{
    std::smatch m;
    EXPECT_TRUE(std::regex_search(row, m, std::regex("^\\| `([a-z_]+)`"))) << row;
    return m.size() > 1 ? m[1].str() : "";
}

Scene beam_scene()
{
    // A 2 x 1 box of 4 x 2 cells: 16 triangles, 15 vertices.
    return parse_scene_text(R"({"dimension": 2, "bodies": [{"name": "b", "mesh": {"box": {"min": [0, 0],
        "max": [2, 1], "cells": [4, 2]}}, "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3,
        "density": 1000}}], "time": {"integrator": "static", "dt": 1, "steps": 1}})",
        ".", "test");
}

ParameterChain parse(const std::string& maps, const EntryLayout& layout, const Scene& scene)
{
    const nlohmann::json j = nlohmann::json::parse(maps);
    return parse_entry_maps(JsonField(j, "parameters[0].maps"), layout, scene);
}

EntryLayout per_element(const Scene& scene)
{
    EntryLayout layout;
    layout.kind = EntryLayout::Kind::PER_ELEMENT;
    layout.size = scene.mesh.elements.rows();
    layout.name = "E";
    for (Index e = 0; e < layout.size; ++e)
        layout.elements.push_back(e);
    return layout;
}

EntryLayout other(Index size)
{
    EntryLayout layout;
    layout.size = size;
    layout.name = "initial_velocity";
    return layout;
}

/// The InputError of parsing `maps`, or "" if it parses.
std::string error_of(const std::string& maps, const EntryLayout& layout, const Scene& scene)
{
    try {
        parse(maps, layout, scene);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST(MapJson, TheProblemFileTableOfTheDocsListsExactlyTheRegisteredTypes)
{
    // Before: the docs listed gather and concatenate, and problem files refused them.
    const std::string docs = read_docs();
    const std::vector<std::string> rows = table_rows(docs, "| map | keys | fits |");
    ASSERT_FALSE(rows.empty()) << "no '| map | keys | fits |' table in docs/parametrizations.md";
    std::set<std::string> documented;
    for (const std::string& row : rows)
        documented.insert(row_name(row));
    const std::vector<std::string> names = registered_map_types();
    const std::set<std::string> registered(names.begin(), names.end());
    EXPECT_EQ(registered.size(), names.size()) << "a type registered twice";
    EXPECT_EQ(documented, registered);
}

TEST(MapJson, EveryMapOfTheMathTableIsRegisteredOrSaysItIsNot)
{
    const std::vector<std::string> rows = table_rows(read_docs(), "| map | y = m(x) | VJP | inverse |");
    ASSERT_FALSE(rows.empty());
    const std::vector<std::string> names = registered_map_types();
    std::string all_rows;
    for (const std::string& row : rows) {
        all_rows += row;
        const std::string name = row_name(row);
        if (std::find(names.begin(), names.end(), name) == names.end())
            EXPECT_NE(row.find("not in problem files"), std::string::npos)
                << "'" << name << "' is documented as a map, but problem files do not accept it";
    }
    // Every registered type has its mathematics there (per_body as the gather it is).
    for (const std::string& name : names)
        EXPECT_NE(all_rows.find("`" + name + "`"), std::string::npos) << name;
}

TEST(MapJson, AnUnknownTypeListsTheRegisteredOnes)
{
    const Scene scene = beam_scene();
    const std::string message = error_of(R"([{"type": "mirror"}])", other(3), scene);
    EXPECT_NE(message.find("parameters[0].maps[0].type"), std::string::npos) << message;
    EXPECT_NE(message.find("unknown map type 'mirror' (known: "), std::string::npos) << message;
    for (const std::string& name : registered_map_types())
        EXPECT_NE(message.find(name), std::string::npos) << name << " missing from: " << message;
    // A key of another type is named with the keys this one takes.
    const std::string key = error_of(R"([{"type": "gather", "index": [0, 0, 0], "radius": 1}])", other(3), scene);
    EXPECT_NE(key.find("parameters[0].maps[0].radius"), std::string::npos) << key;
    EXPECT_NE(key.find("allowed: type, index"), std::string::npos) << key;
}

TEST(MapJson, GatherCopiesDesignValuesByIndex)
{
    const Scene scene = beam_scene();
    const ParameterChain chain = parse(R"([{"type": "gather", "index": [2, 0, 2, 1, 0]}])", other(5), scene);
    ASSERT_EQ(chain.in_size(), 3);
    ASSERT_EQ(chain.out_size(), 5);
    const Eigen::Vector3d x(10, 20, 30);
    EXPECT_EQ(chain.apply(x), (VectorXd(5) << 30, 10, 30, 20, 10).finished());
    VectorXd y_bar(5);
    y_bar << 1, 2, 4, 8, 16;
    EXPECT_EQ(chain.vjp(x, y_bar), Eigen::Vector3d(2 + 16, 8, 1 + 4));
    test::expect_vjp_matches_differences(chain, x);
    // The inverse reads each variable from its copies, which must agree.
    EXPECT_EQ(chain.inverse((VectorXd(5) << 30, 10, 30, 20, 10).finished(), "p"), VectorXd(x));
    EXPECT_THROW(chain.inverse((VectorXd(5) << 30, 10, 31, 20, 10).finished(), "p"), InputError);
}

TEST(MapJson, GatherErrorsNameTheIndex)
{
    const Scene scene = beam_scene();
    const std::string gap = error_of(R"([{"type": "gather", "index": [0, 2, 2]}])", other(3), scene);
    EXPECT_NE(gap.find("parameters[0].maps[0].index"), std::string::npos) << gap;
    EXPECT_NE(gap.find("design variable 1"), std::string::npos) << gap;
    const std::string count = error_of(R"([{"type": "gather", "index": [0, 1]}])", other(3), scene);
    EXPECT_NE(count.find("parameters[0].maps[0].index: gives 2 values where 3"), std::string::npos) << count;
    EXPECT_NE(
        error_of(R"([{"type": "gather", "index": [0, -1, 1]}])", other(3), scene).find("index[1]"), std::string::npos);
    EXPECT_NE(error_of(R"([{"type": "gather"}])", other(3), scene).find("index"), std::string::npos);
}

TEST(MapJson, GatherThenScaleMirrorsOneVariableOntoTwoValues)
{
    // The mirrored edges of docs/parametrizations.md: value j and j + n move oppositely.
    const Scene scene = beam_scene();
    const ParameterChain chain = parse(
        R"([{"type": "gather", "index": [0, 1, 0, 1]}, {"type": "scale", "scale": [-1, -1, 1, 1]}])", other(4), scene);
    const Eigen::Vector2d x(0.25, -0.5);
    EXPECT_EQ(chain.apply(x), Eigen::Vector4d(-0.25, 0.5, 0.25, -0.5));
    test::expect_vjp_matches_differences(chain, x);
}

TEST(MapJson, ConcatenateGivesPartsOfAPerElementEntryTheirOwnChains)
{
    const Scene scene = beam_scene();
    const EntryLayout layout = per_element(scene); // 16 elements
    // One log-space value for elements 0..5, a filtered log-space field on 6..15, then a scale.
    const ParameterChain chain = parse(R"([{"type": "concatenate", "parts": [
        {"size": 6, "maps": [{"type": "exp"}, {"type": "per_body"}]},
        {"maps": [{"type": "exp"}, {"type": "filter", "radius": 0.8}]}]}, {"type": "scale", "scale": 2}])",
        layout, scene);
    ASSERT_EQ(chain.in_size(), 1 + 10);
    ASSERT_EQ(chain.out_size(), 16);
    VectorXd x(11);
    x << std::log(3.0), 0.1, -0.2, 0.3, 0.0, 0.5, -0.1, 0.2, 0.4, -0.3, 0.05;
    const VectorXd y = chain.apply(x);
    for (Index e = 0; e < 6; ++e)
        EXPECT_NEAR(y[e], 6.0, 1e-12);
    // A filter's rows sum to 1: a constant part stays that constant.
    VectorXd flat = x;
    flat.tail(10).setConstant(std::log(5.0));
    EXPECT_TRUE(chain.apply(flat).tail(10).isApprox(VectorXd::Constant(10, 10.0), 1e-12));
    EXPECT_FALSE(y.tail(10).isApprox(2 * x.tail(10).array().exp().matrix(), 1e-3)); // it smooths
    test::expect_vjp_matches_differences(chain, x);
    // per_body and exp invert, the filter does not: no inverse of the whole.
    EXPECT_FALSE(chain.invertible());
    const ParameterChain invertible = parse(
        R"([{"type": "concatenate", "parts": [{"size": 6, "maps": [{"type": "per_body"}]}, {}]}])", layout, scene);
    ASSERT_EQ(invertible.in_size(), 1 + 10);
    VectorXd p = VectorXd::LinSpaced(16, 1, 16);
    p.head(6).setConstant(4);
    const VectorXd x0 = invertible.inverse(p, "p");
    EXPECT_EQ(invertible.apply(x0), p);
    test::expect_vjp_matches_differences(invertible, x0);
}

TEST(MapJson, ConcatenateErrorsNameThePart)
{
    const Scene scene = beam_scene();
    const EntryLayout layout = per_element(scene);
    const std::string over
        = error_of(R"([{"type": "concatenate", "parts": [{"size": 10}, {"size": 10}]}])", layout, scene);
    EXPECT_NE(over.find("parameters[0].maps[0].parts[1].size: the parts up to this one give 20 values where 16"),
        std::string::npos)
        << over;
    const std::string under = error_of(R"([{"type": "concatenate", "parts": [{"size": 10}]}])", layout, scene);
    EXPECT_NE(under.find("parameters[0].maps[0].parts: the parts give 10 values where 16"), std::string::npos) << under;
    const std::string none = error_of(R"([{"type": "concatenate", "parts": [{"size": 16}, {}]}])", layout, scene);
    EXPECT_NE(none.find("parameters[0].maps[0].parts[1]: the parts before it give all"), std::string::npos) << none;
    const std::string key = error_of(R"([{"type": "concatenate", "parts": [{"size": 16, "map": []}]}])", layout, scene);
    EXPECT_NE(key.find("parameters[0].maps[0].parts[0].map"), std::string::npos) << key;
    // A part's map is named by its path inside the part.
    const std::string inner
        = error_of(R"([{"type": "concatenate", "parts": [{"size": 6, "maps": [{"type": "exp", "scale": 1}]}, {}]}])",
            layout, scene);
    EXPECT_NE(inner.find("parameters[0].maps[0].parts[0].maps[0].scale"), std::string::npos) << inner;
    // Per-element maps inside a part need the part's values to be the entry's elements: not so
    // when a map other than exp or scale follows the concatenate, nor in an entry of other values.
    const std::string after = error_of(R"([{"type": "concatenate", "parts": [{"size": 16, "maps":
        [{"type": "filter", "radius": 0.5}]}]}, {"type": "gather", "index": [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12,
        13, 14, 15]}])",
        layout, scene);
    EXPECT_NE(after.find("parameters[0].maps[0].parts[0].maps[0]"), std::string::npos) << after;
    const std::string shape
        = error_of(R"([{"type": "concatenate", "parts": [{"maps": [{"type": "per_body"}]}]}])", other(16), scene);
    EXPECT_NE(shape.find("one value per element"), std::string::npos) << shape;
}
