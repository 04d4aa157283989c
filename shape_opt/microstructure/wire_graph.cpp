#include "shape_opt/microstructure/wire_graph.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace diffipc {

WireGraphFormat wire_graph_format(const std::string& path)
{
    // Pattern libraries are not consistent about case (a ".WIRE" read as OBJ would stay unscaled).
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext == ".wire" ? WireGraphFormat::WIRE : WireGraphFormat::OBJ;
}

WireGraph parse_wire_graph(const std::string& text, const std::string& name, WireGraphFormat format)
{
    const bool wire = format == WireGraphFormat::WIRE;
    std::vector<double> xy;
    double first_z = 0;
    int first_z_line = 0; // the line of the first node with a z (WIRE), 0 if none yet
    int first_xy_line = 0; // the line of the first node without a z (WIRE), 0 if none yet
    std::vector<std::pair<long, long>> edges;
    std::vector<int> edge_line;
    std::vector<long> nodes_before; // per edge: nodes read before its line (for relative indices)
    std::istringstream in(text);
    std::string line;
    int number = 0;
    auto fail
        = [&](int at, const std::string& what) { throw InputError(name, "line " + std::to_string(at) + ": " + what); };
    while (std::getline(in, line)) {
        ++number;
        std::istringstream record(line);
        std::string kind;
        if (!(record >> kind) || kind[0] == '#')
            continue;
        if (kind == "v") {
            double x = 0, y = 0;
            if (!(record >> x >> y) || !std::isfinite(x) || !std::isfinite(y))
                fail(number,
                    std::string("expected \"v x y ") + (wire ? "[z [w]]" : "[z]") + "\" with finite coordinates");
            if (wire) {
                // PyMesh's reader takes a fourth coordinate as homogeneous: (x, y, z) / w.
                double z = 0, w = 1;
                const bool has_z = bool(record >> z);
                if (has_z && (record >> w) && (!std::isfinite(w) || w == 0))
                    fail(number, "expected a finite, non-zero homogeneous coordinate w");
                if (has_z && !std::isfinite(z))
                    fail(number, "expected \"v x y [z [w]]\" with finite coordinates");
                // "v x y" nodes sit at z = 0, which a file that gives z elsewhere does not mean:
                // a mix is refused rather than guessed.
                if (has_z && first_xy_line != 0)
                    fail(number,
                        "\"v x y z\" after \"v x y\" on line " + std::to_string(first_xy_line)
                            + ": give every node of a .wire file a z, or none");
                if (!has_z && first_z_line != 0)
                    fail(number,
                        "\"v x y\" after \"v x y z\" on line " + std::to_string(first_z_line)
                            + ": give every node of a .wire file a z, or none");
                if (!has_z && first_xy_line == 0)
                    first_xy_line = number;
                x /= w;
                y /= w;
                z /= w;
                if (has_z && first_z_line == 0) {
                    first_z = z;
                    first_z_line = number;
                } else if (has_z && std::abs(z - first_z) > 1e-12 * std::max(1.0, std::abs(first_z)))
                    fail(number,
                        "z = " + format_number(z) + " differs from line " + std::to_string(first_z_line)
                            + "'s z = " + format_number(first_z)
                            + ": a 3D pattern; diffipc's cells are 2D (a .wire graph's nodes all in one plane z = "
                              "const, "
                              "or given as \"v x y\")");
                if (x < 0 || x > 1 || y < 0 || y > 1)
                    fail(number,
                        "node (" + format_number(x) + ", " + format_number(y)
                            + ") lies outside the unit cell [0, 1]^2 of a .wire pattern (read as y = 2 x - 1 into "
                              "diffipc's cell [-1, 1]^2); a graph whose nodes are already in [-1, 1]^2 is read as "
                              "OBJ: give it the extension .obj");
                x = 2 * x - 1;
                y = 2 * y - 1;
            } else if (std::abs(x) > 1 || std::abs(y) > 1)
                fail(number,
                    "node (" + format_number(x) + ", " + format_number(y) + ") lies outside the cell [-1, 1]^2");
            xy.push_back(x);
            xy.push_back(y);
        } else if (kind == "l") {
            std::vector<long> ids;
            std::string token;
            while (record >> token) {
                // "i" or "i/t": the vertex index comes first.
                long id = 0;
                try {
                    size_t used = 0;
                    id = std::stol(token, &used);
                    if (used < token.size() && token[used] != '/')
                        throw std::invalid_argument(token);
                } catch (const std::exception&) {
                    fail(number, "expected node indices after \"l\", got \"" + token + "\"");
                }
                ids.push_back(id);
            }
            if (ids.size() < 2)
                fail(number, "a line needs at least two node indices");
            for (size_t k = 0; k + 1 < ids.size(); ++k) {
                edges.emplace_back(ids[k], ids[k + 1]);
                edge_line.push_back(number);
                nodes_before.push_back(long(xy.size() / 2));
            }
        }
    }
    const long n = long(xy.size() / 2);
    WireGraph g;
    g.nodes = Eigen::Map<const Eigen::Matrix<double, -1, 2, Eigen::RowMajor>>(xy.data(), n, 2);
    g.edges.resize(Index(edges.size()), 2);
    for (size_t e = 0; e < edges.size(); ++e) {
        long ends[2] = { edges[e].first, edges[e].second };
        for (int k = 0; k < 2; ++k) {
            // OBJ indices are 1-based; negative ones count back from the last node read before.
            const long i = ends[k] > 0 ? ends[k] - 1 : nodes_before[e] + ends[k];
            if (ends[k] == 0 || i < 0 || i >= n)
                fail(edge_line[e],
                    "node index " + std::to_string(ends[k]) + " out of range (" + std::to_string(n) + " nodes)");
            g.edges(Index(e), k) = int(i);
        }
        if (g.edges(Index(e), 0) == g.edges(Index(e), 1))
            fail(edge_line[e], "an edge from node " + std::to_string(ends[0]) + " to itself");
    }
    if (g.edges.rows() == 0)
        throw InputError(name, "no edge (\"l\" records): a wire graph needs at least one");
    g.file = name;
    return g;
}

WireGraph read_wire_graph(const std::string& path)
{
    std::ifstream file(path);
    if (!file)
        throw InputError(path, "cannot open the wire graph file");
    std::stringstream text;
    text << file.rdbuf();
    return parse_wire_graph(text.str(), path, wire_graph_format(path));
}

} // namespace diffipc
