#include "forward/mesh/gmsh_reader.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <array>
#include <fstream>
#include <sstream>
#include <unordered_map>
#include <vector>

namespace diffipc {

namespace {

    class LineReader {
    public:
        explicit LineReader(const std::string& path)
            : m_path(path)
            , m_in(path)
        {
            if (!m_in)
                throw InputError(path, "cannot open mesh file");
        }
        bool next(std::string& line)
        {
            while (std::getline(m_in, line)) {
                ++m_line;
                if (!line.empty() && line.back() == '\r')
                    line.pop_back();
                if (line.find_first_not_of(" \t") != std::string::npos)
                    return true;
            }
            return false;
        }
        std::string require(const char* what)
        {
            std::string line;
            if (!next(line))
                fail(std::string("unexpected end of file while reading ") + what);
            return line;
        }
        [[noreturn]] void fail(const std::string& message) const
        {
            throw InputError(m_path, "line " + std::to_string(m_line) + ": " + message);
        }

    private:
        std::string m_path;
        std::ifstream m_in;
        long m_line = 0;
    };

    template <typename T> std::vector<T> parse_numbers(LineReader& reader, const std::string& line, size_t at_least)
    {
        std::istringstream ss(line);
        std::vector<T> out;
        T value;
        while (ss >> value)
            out.push_back(value);
        if (!ss.eof() || out.size() < at_least)
            reader.fail("malformed line '" + line + "'");
        return out;
    }

    void skip_section(LineReader& reader, const std::string& name)
    {
        const std::string end = "$End" + name.substr(1);
        std::string line;
        while (reader.next(line))
            if (line.rfind(end, 0) == 0)
                return;
        reader.fail("section " + name + " is not closed");
    }

} // namespace

namespace {

    // Reads the simplices with `nodes_per` nodes (gmsh types 1: 2-node line,
    // 2: 3-node triangle, 4: 4-node tetrahedron) into `simplices` (compact vertex
    // indices) and their nodes into `positions`.
    void read_gmsh_simplices(const std::string& path, int dim, int nodes_per, Positions& positions, MatrixXi& out)
    {
        LineReader reader(path);
        const int simplex_type = nodes_per == 2 ? 1 : nodes_per == 3 ? 2 : 4;
        double version = 0;
        std::unordered_map<long, Eigen::Vector3d> nodes;
        std::vector<std::array<long, 4>> simplices;

        std::string line;
        while (reader.next(line)) {
            if (line.rfind("$MeshFormat", 0) == 0) {
                const std::string header = reader.require("$MeshFormat");
                std::istringstream ss(header);
                int file_type = -1;
                ss >> version >> file_type;
                if (!ss)
                    reader.fail("malformed $MeshFormat header");
                if (file_type != 0)
                    reader.fail("binary .msh files are not supported; save as ASCII");
                if (!(version >= 2.0 && version < 3.0) && !(version >= 4.1 && version < 5.0))
                    reader.fail("unsupported .msh version " + std::to_string(version) + " (2.x and 4.1 are supported)");
                skip_section(reader, "$MeshFormat");
            } else if (line.rfind("$Nodes", 0) == 0) {
                if (version == 0)
                    reader.fail("$Nodes before $MeshFormat");
                if (version < 3) {
                    const long n = parse_numbers<long>(reader, reader.require("$Nodes"), 1)[0];
                    for (long i = 0; i < n; ++i) {
                        const auto v = parse_numbers<double>(reader, reader.require("$Nodes"), 4);
                        nodes[long(v[0])] = Eigen::Vector3d(v[1], v[2], v[3]);
                    }
                } else {
                    const auto h = parse_numbers<long>(reader, reader.require("$Nodes"), 4);
                    for (long b = 0; b < h[0]; ++b) {
                        const auto bh = parse_numbers<long>(reader, reader.require("$Nodes"), 4);
                        const long parametric = bh[2], count = bh[3];
                        if (parametric != 0)
                            reader.fail("parametric node coordinates are not supported");
                        if (count < 0)
                            reader.fail("negative node count " + std::to_string(count) + " in a node block");
                        // The count is not trusted for an allocation: a block says 2^62 nodes and
                        // then ends; the lines are read (and the file runs out) one at a time.
                        std::vector<long> tags;
                        tags.reserve(size_t(std::min(count, 1L << 16)));
                        for (long i = 0; i < count; ++i)
                            tags.push_back(parse_numbers<long>(reader, reader.require("$Nodes"), 1)[0]);
                        for (long i = 0; i < count; ++i) {
                            const auto v = parse_numbers<double>(reader, reader.require("$Nodes"), 3);
                            nodes[tags[size_t(i)]] = Eigen::Vector3d(v[0], v[1], v[2]);
                        }
                    }
                }
                skip_section(reader, "$Nodes");
            } else if (line.rfind("$Elements", 0) == 0) {
                if (version == 0)
                    reader.fail("$Elements before $MeshFormat");
                if (version < 3) {
                    const long n = parse_numbers<long>(reader, reader.require("$Elements"), 1)[0];
                    for (long i = 0; i < n; ++i) {
                        const auto v = parse_numbers<long>(reader, reader.require("$Elements"), 3);
                        const long type = v[1], ntags = v[2];
                        if (type != simplex_type)
                            continue;
                        if (long(v.size()) != 3 + ntags + nodes_per)
                            reader.fail("element line has the wrong number of entries");
                        std::array<long, 4> s { -1, -1, -1, -1 };
                        for (int a = 0; a < nodes_per; ++a)
                            s[a] = v[size_t(3 + ntags + a)];
                        simplices.push_back(s);
                    }
                } else {
                    const auto h = parse_numbers<long>(reader, reader.require("$Elements"), 4);
                    for (long b = 0; b < h[0]; ++b) {
                        const auto bh = parse_numbers<long>(reader, reader.require("$Elements"), 4);
                        const long type = bh[2], count = bh[3];
                        for (long i = 0; i < count; ++i) {
                            const auto v = parse_numbers<long>(reader, reader.require("$Elements"), 2);
                            if (type != simplex_type)
                                continue;
                            if (long(v.size()) != 1 + nodes_per)
                                reader.fail("element line has the wrong number of nodes");
                            std::array<long, 4> s { -1, -1, -1, -1 };
                            for (int a = 0; a < nodes_per; ++a)
                                s[a] = v[size_t(1 + a)];
                            simplices.push_back(s);
                        }
                    }
                }
                skip_section(reader, "$Elements");
            } else if (line.rfind("$", 0) == 0 && line.rfind("$End", 0) != 0) {
                skip_section(reader, line);
            }
        }
        if (version == 0)
            throw InputError(path, "no $MeshFormat section: not a gmsh .msh file");
        if (simplices.empty())
            throw InputError(path,
                std::string("no ")
                    + (nodes_per == 2        ? "lines"
                            : nodes_per == 3 ? "triangles"
                                             : "tetrahedra")
                    + " found");

        std::unordered_map<long, int> index;
        std::vector<long> order;
        out.resize(Index(simplices.size()), nodes_per);
        for (size_t e = 0; e < simplices.size(); ++e)
            for (int a = 0; a < nodes_per; ++a) {
                const long tag = simplices[e][a];
                if (!nodes.count(tag))
                    throw InputError(path, "element refers to undefined node " + std::to_string(tag));
                auto [it, inserted] = index.emplace(tag, int(order.size()));
                if (inserted)
                    order.push_back(tag);
                out(Index(e), a) = it->second;
            }
        positions.resize(Index(order.size()), dim);
        for (size_t v = 0; v < order.size(); ++v)
            positions.row(Index(v)) = nodes.at(order[v]).head(dim).transpose();
    }

} // namespace

Mesh read_gmsh(const std::string& path, int dim)
{
    Mesh mesh;
    mesh.dim = dim;
    read_gmsh_simplices(path, dim, dim + 1, mesh.rest_positions, mesh.elements);
    mesh.vertex_body = VectorXi::Zero(mesh.num_vertices());
    mesh.element_body = VectorXi::Zero(mesh.num_elements());
    compute_boundary(mesh);
    return mesh;
}

Mesh read_gmsh_facets(const std::string& path, int dim)
{
    Mesh mesh;
    mesh.dim = dim;
    read_gmsh_simplices(path, dim, dim, mesh.rest_positions, mesh.boundary_facets);
    return mesh;
}

} // namespace diffipc
