// diffipc-gmsh-remesh IN OUT: the gmsh part of remeshing (shape_opt/remesh.hpp), a program
// of its own that remesh.cpp runs. Two reasons: gmsh's ~80 shared libraries then cost their
// load time (0.3 s) only in runs that remesh, not at every start of the CLI and the Python
// module; and gmsh meshes faces inside OpenMP regions, where an error it throws ends the
// process: it ends this one, and the optimization goes on with the old mesh.
//
// IN (text): "dim size remesh_surface n m", then n lines of dim coordinates, then m lines of
// dim vertex indices (the boundary facets). OUT (text): "ok np ne", np lines of dim
// coordinates, ne lines of dim + 1 indices; or "error MESSAGE".

#include <gmsh.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

struct Failure : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// The boundary edges of a 2D domain chained into closed loops (vertex lists).
std::vector<std::vector<int>> boundary_loops(const int* facets, long m)
{
    std::multimap<int, long> from; // vertex -> edges starting there
    for (long f = 0; f < m; ++f)
        from.emplace(facets[2 * f], f);
    std::vector<char> used(static_cast<size_t>(m), 0);
    std::vector<std::vector<int>> loops;
    for (long start = 0; start < m; ++start) {
        if (used[size_t(start)])
            continue;
        std::vector<int> loop;
        long f = start;
        while (!used[size_t(f)]) {
            used[size_t(f)] = 1;
            loop.push_back(facets[2 * f]);
            const int next = facets[2 * f + 1];
            if (from.count(next) != 1)
                throw Failure("the boundary is not a set of simple closed curves at vertex " + std::to_string(next));
            f = from.find(next)->second;
        }
        if (f != start)
            throw Failure("a boundary curve does not close");
        loops.push_back(std::move(loop));
    }
    return loops;
}

double loop_area(const double* x, const std::vector<int>& loop)
{
    double area = 0;
    for (size_t i = 0; i < loop.size(); ++i) {
        const double* a = x + 2 * loop[i];
        const double* b = x + 2 * loop[(i + 1) % loop.size()];
        area += 0.5 * (a[0] * b[1] - b[0] * a[1]);
    }
    return area;
}

/// Whether point p lies inside the closed polygon `loop` (crossing number).
bool inside(const double* x, const std::vector<int>& loop, const double* p)
{
    bool in = false;
    for (size_t i = 0, j = loop.size() - 1; i < loop.size(); j = i++) {
        const double* a = x + 2 * loop[i];
        const double* b = x + 2 * loop[j];
        if ((a[1] > p[1]) != (b[1] > p[1]) && p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]))
            in = !in;
    }
    return in;
}

void mesh_2d(const double* x, const int* facets, long m, double size)
{
    const auto loops = boundary_loops(facets, m);
    std::map<int, int> point;
    for (long f = 0; f < 2 * m; ++f)
        if (!point.count(facets[f]))
            point[facets[f]] = gmsh::model::geo::addPoint(x[2 * facets[f]], x[2 * facets[f] + 1], 0, size);
    // Loops by nesting: a loop inside an even number of others bounds a surface (a domain may have
    // several pieces: a periodic cell cut by its box), one inside an odd number is a hole of the
    // smallest loop around it.
    const size_t n = loops.size();
    std::vector<int> depth(n, 0);
    std::vector<long> parent(n, -1);
    for (size_t k = 0; k < n; ++k)
        for (size_t o = 0; o < n; ++o)
            if (o != k && inside(x, loops[o], x + 2 * loops[k][0])) {
                ++depth[k];
                if (parent[k] < 0
                    || std::abs(loop_area(x, loops[o])) < std::abs(loop_area(x, loops[size_t(parent[k])])))
                    parent[k] = long(o);
            }
    std::vector<int> tags(n);
    for (size_t k = 0; k < n; ++k) {
        std::vector<int> lines;
        const auto& loop = loops[k];
        for (size_t i = 0; i < loop.size(); ++i)
            lines.push_back(gmsh::model::geo::addLine(point[loop[i]], point[loop[(i + 1) % loop.size()]]));
        tags[k] = gmsh::model::geo::addCurveLoop(lines);
    }
    for (size_t k = 0; k < n; ++k) {
        if (depth[k] % 2)
            continue;
        std::vector<int> curve_loops { tags[k] };
        for (size_t h = 0; h < n; ++h)
            if (depth[h] % 2 && parent[h] == long(k))
                curve_loops.push_back(tags[h]);
        gmsh::model::geo::addPlaneSurface(curve_loops);
    }
    gmsh::model::geo::synchronize();
    gmsh::model::mesh::generate(2);
}

void mesh_3d(const double* x, const int* facets, long m, bool remesh_surface)
{
    std::map<int, std::size_t> node;
    std::vector<std::size_t> node_tags;
    std::vector<double> coords;
    for (long f = 0; f < 3 * m; ++f)
        if (!node.count(facets[f])) {
            const std::size_t tag = node.size() + 1;
            node[facets[f]] = tag;
            node_tags.push_back(tag);
            for (int c = 0; c < 3; ++c)
                coords.push_back(x[3 * facets[f] + c]);
        }
    std::vector<std::size_t> facet_tags, facet_nodes;
    for (long f = 0; f < m; ++f) {
        facet_tags.push_back(std::size_t(f) + 1);
        for (int a = 0; a < 3; ++a)
            facet_nodes.push_back(node[facets[3 * f + a]]);
    }
    gmsh::model::addDiscreteEntity(2, 1);
    gmsh::model::mesh::addNodes(2, 1, node_tags, coords);
    gmsh::model::mesh::addElementsByType(1, 2, facet_tags, facet_nodes);
    std::vector<int> surfaces { 1 };
    if (remesh_surface) {
        // Faces split where the surface bends by more than 40 degrees (a box's edges), each
        // parametrized on the old triangulation and meshed anew at the target size.
        gmsh::model::mesh::classifySurfaces(40 * M_PI / 180, true, true, M_PI);
        gmsh::model::mesh::createGeometry();
        gmsh::vectorpair entities;
        gmsh::model::getEntities(entities, 2);
        surfaces.clear();
        for (const auto& e : entities)
            surfaces.push_back(e.second);
    }
    const int shell = gmsh::model::geo::addSurfaceLoop(surfaces);
    gmsh::model::geo::addVolume({ shell });
    gmsh::model::geo::synchronize();
    gmsh::model::mesh::generate(3);
}

/// gmsh's nodes used by its simplices of dimension `dim`, renumbered from 0 in order of use.
void collect(int dim, std::vector<double>& points, std::vector<int>& elements)
{
    std::vector<std::size_t> node_tags, element_tags, element_nodes;
    std::vector<double> coords, parametric;
    gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1, true, false);
    gmsh::model::mesh::getElementsByType(dim == 2 ? 2 : 4, element_tags, element_nodes);
    if (element_tags.empty())
        throw Failure("gmsh made no elements");
    std::map<std::size_t, size_t> where;
    for (size_t i = 0; i < node_tags.size(); ++i)
        where[node_tags[i]] = i;
    std::map<std::size_t, int> index;
    points.clear();
    elements.clear();
    for (std::size_t tag : element_nodes) {
        auto [it, inserted] = index.emplace(tag, int(index.size()));
        if (inserted) {
            const auto w = where.find(tag);
            if (w == where.end())
                throw Failure("gmsh returned an element with an unknown node");
            for (int a = 0; a < dim; ++a)
                points.push_back(coords[3 * w->second + size_t(a)]);
        }
        elements.push_back(it->second);
    }
}

} // namespace

int main(int argc, char** argv)
{
    if (argc != 3) {
        std::fprintf(stderr, "usage: diffipc-gmsh-remesh IN OUT\n");
        return 2;
    }
    std::ofstream out(argv[2]);
    out << std::setprecision(17);
    try {
        std::ifstream in(argv[1]);
        int dim = 0, remesh_surface = 0;
        double size = 0;
        long n = 0, m = 0;
        if (!(in >> dim >> size >> remesh_surface >> n >> m) || (dim != 2 && dim != 3) || n <= 0 || m <= 0)
            throw Failure("cannot read the input file");
        std::vector<double> points(size_t(n * dim));
        std::vector<int> facets(size_t(m * dim));
        for (double& v : points)
            in >> v;
        for (int& v : facets)
            in >> v;
        if (!in)
            throw Failure("the input file ends early");
        for (int v : facets)
            if (v < 0 || v >= n)
                throw Failure("a facet names vertex " + std::to_string(v) + " of " + std::to_string(n));
        gmsh::initialize(0, nullptr, false);
        gmsh::option::setNumber("General.Terminal", 1);
        gmsh::option::setNumber("General.Verbosity", 2); // errors and warnings, to stderr
        gmsh::option::setNumber("Mesh.MeshSizeMax", size);
        gmsh::option::setNumber("Mesh.MeshSizeMin", 0);
        gmsh::option::setNumber("Mesh.OptimizeThreshold", 0.45);
        gmsh::model::add("diffipc_remesh");
        if (dim == 2)
            mesh_2d(points.data(), facets.data(), m, size);
        else
            mesh_3d(points.data(), facets.data(), m, remesh_surface != 0);
        std::vector<double> new_points;
        std::vector<int> new_elements;
        collect(dim, new_points, new_elements);
        gmsh::finalize();
        const size_t np = new_points.size() / size_t(dim), ne = new_elements.size() / size_t(dim + 1);
        out << "ok " << np << " " << ne << "\n";
        for (size_t v = 0; v < np; ++v)
            for (int a = 0; a < dim; ++a)
                out << new_points[v * size_t(dim) + size_t(a)] << (a + 1 < dim ? " " : "\n");
        for (size_t e = 0; e < ne; ++e)
            for (int a = 0; a <= dim; ++a)
                out << new_elements[e * size_t(dim + 1) + size_t(a)] << (a < dim ? " " : "\n");
        return out ? 0 : 1;
    } catch (const std::exception& e) {
        out << "error " << e.what() << "\n";
    } catch (const std::string& e) { // gmsh 4.8 throws its messages as strings
        out << "error gmsh: " << e << "\n";
    } catch (...) {
        out << "error gmsh failed\n";
    }
    return 1;
}
