#include "shape_opt/microstructure/cell_mesher.hpp"

#include "forward/common/error.hpp"
#include "forward/common/union_find.hpp"
#include "shape_opt/microstructure/cell_tiling.hpp"
#include "shape_opt/remesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <vector>

namespace diffipc {

Eigen::Vector2d cell_box_min(double width, double height)
{
    return Eigen::Vector2d(-0.5 * width * height, -0.5 * height);
}
Eigen::Vector2d cell_box_max(double width, double height)
{
    return Eigen::Vector2d(0.5 * width * height, 0.5 * height);
}

namespace {

    /// The root of phi on the segment a (phi_a) -> b (phi_b), phi_a and phi_b of opposite signs
    /// (Illinois regula falsi, to round-off).
    Eigen::Vector2d crossing(
        const CellSDF& sdf, const Eigen::Vector2d& a, double fa, const Eigen::Vector2d& b, double fb)
    {
        double ta = 0, tb = 1;
        int side = 0;
        for (int it = 0; it < 100; ++it) {
            const double t = (ta * fb - tb * fa) / (fb - fa);
            const double f = sdf.value(a + t * (b - a));
            if (f == 0 || tb - ta < 1e-15)
                return a + t * (b - a);
            if ((f < 0) == (fa < 0)) {
                ta = t;
                fa = f;
                if (side == -1)
                    fb *= 0.5;
                side = -1;
            } else {
                tb = t;
                fb = f;
                if (side == 1)
                    fa *= 0.5;
                side = 1;
            }
        }
        return a + 0.5 * (ta + tb) * (b - a);
    }

    /// y moved onto phi = 0 by Newton steps along grad phi.
    Eigen::Vector2d project(const CellSDF& sdf, Eigen::Vector2d y)
    {
        for (int it = 0; it < 8; ++it) {
            const double f = sdf.value(y);
            if (std::abs(f) < 1e-14)
                break;
            const Eigen::Vector2d g = sdf.gradient(y);
            if (g.squaredNorm() < 1e-20)
                break;
            y -= f * g / g.squaredNorm();
        }
        return y;
    }

    /// A point of the traced boundary: a grid node on the box's sides or a crossing on a grid edge.
    struct Point {
        Eigen::Vector2d y; ///< graph coordinates
        bool on_side = false; ///< on one of the box's sides
        bool corner = false; ///< a crossing on a side, or a corner of the box: the ends of pieces
    };

    struct Segment {
        int from, to;
        bool side; ///< along the box's side (else on the contour)
    };

} // namespace

Mesh mesh_cell(const CellSDF& sdf, double width, const CellMeshSettings& settings)
{
    if (!(width > 0) || !(settings.height > 0) || !(settings.size > 0))
        throw std::invalid_argument("mesh_cell: width, height and size must be positive");
    const Eigen::Vector2d scale(0.5 * width * settings.height, 0.5 * settings.height); // X = scale .* y
    // Grid: spacing at most half the size and a third of the thinnest beam, in physical units.
    const double thinnest = sdf.parameters().thickness.minCoeff() * scale.minCoeff();
    const double spacing = std::min(0.5 * settings.size, thinnest / 3);
    const int nx = std::max(8, int(std::ceil(2 * scale.x() / spacing)));
    const int ny = std::max(8, int(std::ceil(2 * scale.y() / spacing)));
    auto grid = [&](int i, int j) { return Eigen::Vector2d(-1 + 2.0 * i / nx, -1 + 2.0 * j / ny); };
    MatrixXd f(nx + 1, ny + 1);
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            f(i, j) = sdf.value(grid(i, j));
    f.row(nx) = f.row(0);
    f.col(ny) = f.col(0);
    auto solid = [&](int i, int j) { return f(i, j) < 0; };
    if ((f.array() >= 0).all())
        throw InputError("design", "the cell has no solid at these parameters");

    std::vector<Point> points;
    std::map<std::array<int, 3>, int> ids; // (kind 0 node / 1 horizontal edge / 2 vertical edge, i, j)
    auto node = [&](int i, int j) {
        const auto [it, fresh] = ids.try_emplace({ 0, i, j }, int(points.size()));
        if (fresh) {
            const bool corner = (i == 0 || i == nx) && (j == 0 || j == ny);
            points.push_back({ grid(i, j), true, corner });
        }
        return it->second;
    };
    // The crossing on the horizontal edge (i, j)-(i+1, j) or vertical edge (i, j)-(i, j+1); the
    // top row's and right column's are the bottom row's and left column's, shifted.
    std::function<int(int, int, int)> cross = [&](int kind, int i, int j) -> int {
        const auto [it, fresh] = ids.try_emplace({ kind, i, j }, int(points.size()));
        if (!fresh)
            return it->second;
        const int id = it->second;
        points.emplace_back();
        Eigen::Vector2d y;
        if (kind == 1 && j == ny)
            y = points[size_t(cross(1, i, 0))].y + Eigen::Vector2d(0, 2);
        else if (kind == 2 && i == nx)
            y = points[size_t(cross(2, 0, j))].y + Eigen::Vector2d(2, 0);
        else {
            const int i2 = kind == 1 ? i + 1 : i, j2 = kind == 2 ? j + 1 : j;
            y = crossing(sdf, grid(i, j), f(i, j), grid(i2, j2), f(i2, j2));
            if (kind == 1)
                y.y() = grid(i, j).y(); // exactly on the grid line
            else
                y.x() = grid(i, j).x();
        }
        const bool on_side = (kind == 1 && (j == 0 || j == ny)) || (kind == 2 && (i == 0 || i == nx));
        points[size_t(id)] = { y, on_side, on_side };
        return id;
    };

    std::vector<Segment> segments;
    // Contour segments, cell by cell: walking a grid cell's perimeter counter-clockwise, each
    // crossing where the solid ends (an exit) joins the next crossing where it starts (an entry)
    // if the cell's centre is solid, else the previous one; solid on the segment's left.
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j) {
            const int ci[4] = { i, i + 1, i + 1, i }, cj[4] = { j, j, j + 1, j + 1 };
            std::vector<std::pair<int, bool>> crossings; // (point, is exit) in perimeter order
            for (int c = 0; c < 4; ++c) {
                const int d = (c + 1) % 4;
                const bool sa = solid(ci[c], cj[c]), sb = solid(ci[d], cj[d]);
                if (sa == sb)
                    continue;
                const int id = c == 0 ? cross(1, i, j)
                    : c == 1          ? cross(2, i + 1, j)
                    : c == 2          ? cross(1, i, j + 1)
                                      : cross(2, i, j);
                crossings.emplace_back(id, sa);
            }
            if (crossings.empty())
                continue;
            const size_t n = crossings.size(); // 2 or 4
            bool centre_solid = true;
            if (n == 4)
                centre_solid = sdf.value(grid(i, j) + Eigen::Vector2d(1.0 / nx, 1.0 / ny)) < 0;
            for (size_t k = 0; k < n; ++k) {
                if (!crossings[k].second)
                    continue;
                const size_t entry = centre_solid || n == 2 ? (k + 1) % n : (k + n - 1) % n;
                segments.push_back({ crossings[k].first, crossings[entry].first, false });
            }
        }
    // The box's sides, counter-clockwise (bottom +x, right +y, top -x, left -y), where solid.
    auto side_edge = [&](int i0, int j0, int i1, int j1, int kind, int ei, int ej) {
        const bool s0 = solid(i0, j0), s1 = solid(i1, j1);
        if (s0 && s1)
            segments.push_back({ node(i0, j0), node(i1, j1), true });
        else if (s0)
            segments.push_back({ node(i0, j0), cross(kind, ei, ej), true });
        else if (s1)
            segments.push_back({ cross(kind, ei, ej), node(i1, j1), true });
    };
    for (int i = 0; i < nx; ++i) {
        side_edge(i, 0, i + 1, 0, 1, i, 0);
        side_edge(i + 1, ny, i, ny, 1, i, ny);
    }
    for (int j = 0; j < ny; ++j) {
        side_edge(nx, j, nx, j + 1, 2, nx, j);
        side_edge(0, j + 1, 0, j, 2, 0, j);
    }

    // Chain into loops.
    std::vector<int> next_segment(points.size(), -1);
    for (size_t s = 0; s < segments.size(); ++s) {
        if (next_segment[size_t(segments[s].from)] != -1)
            throw std::logic_error("mesh_cell: the traced boundary is not manifold");
        next_segment[size_t(segments[s].from)] = int(s);
    }
    std::vector<char> used(segments.size(), 0);
    // Resampled boundary: physical positions and edges.
    std::vector<Eigen::Vector2d> out;
    std::vector<std::array<int, 2>> edges;
    std::map<int, int> out_id; // traced corner point -> output vertex
    auto emit_corner = [&](int p) {
        const auto [it, fresh] = out_id.try_emplace(p, int(out.size()));
        if (fresh)
            out.push_back(scale.cwiseProduct(points[size_t(p)].y));
        return it->second;
    };
    const double step = 0.9 * settings.size;
    // Samples of a contour polyline (closed: ys.back() == ys.front(), the last one left out):
    // uniform in arc length at most `step` apart, put on phi = 0; then, between two samples whose
    // chord's middle lies farther than size / 100 from phi = 0 (a blend's tight corner), that
    // middle put on phi = 0 too, recursively.
    const double sagitta = 0.01 * settings.size;
    std::function<void(const Eigen::Vector2d&, const Eigen::Vector2d&, int, std::vector<Eigen::Vector2d>&)> refine
        = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b, int depth, std::vector<Eigen::Vector2d>& to) {
              const Eigen::Vector2d mid = 0.5 * (a + b), on = project(sdf, mid);
              if (depth >= 12 || scale.cwiseProduct(on - mid).norm() <= sagitta)
                  return;
              refine(a, on, depth + 1, to);
              to.push_back(on);
              refine(on, b, depth + 1, to);
          };
    auto contour_samples = [&](const std::vector<Eigen::Vector2d>& ys, bool closed) {
        std::vector<double> arc(ys.size(), 0.0);
        for (size_t k = 1; k < ys.size(); ++k)
            arc[k] = arc[k - 1] + scale.cwiseProduct(ys[k] - ys[k - 1]).norm();
        const double length = arc.back();
        const int n = std::max(closed ? 3 : 1, int(std::ceil(length / step)));
        std::vector<Eigen::Vector2d> uniform { ys.front() };
        size_t m = 0;
        for (int q = 1; q < n; ++q) {
            const double target = length * q / n;
            while (m + 2 < arc.size() && arc[m + 1] < target)
                ++m;
            const double t = (target - arc[m]) / std::max(arc[m + 1] - arc[m], 1e-300);
            uniform.push_back(project(sdf, ys[m] + t * (ys[m + 1] - ys[m])));
        }
        uniform.push_back(ys.back());
        std::vector<Eigen::Vector2d> samples { uniform.front() };
        for (size_t q = 0; q + 1 < uniform.size(); ++q) {
            refine(uniform[q], uniform[q + 1], 0, samples);
            samples.push_back(uniform[q + 1]);
        }
        if (closed)
            samples.pop_back();
        return samples;
    };
    for (size_t start = 0; start < segments.size(); ++start) {
        if (used[start])
            continue;
        // The loop's segments from `start`, rotated to begin at a corner if it has one.
        std::vector<int> loop;
        for (int s = int(start); !used[size_t(s)]; s = next_segment[size_t(segments[size_t(s)].to)]) {
            if (s < 0)
                throw std::logic_error("mesh_cell: a traced boundary curve does not close");
            used[size_t(s)] = 1;
            loop.push_back(s);
        }
        auto starts_piece = [&](size_t k) {
            const Segment& s = segments[size_t(loop[k])];
            const Segment& prev = segments[size_t(loop[(k + loop.size() - 1) % loop.size()])];
            return points[size_t(s.from)].corner || s.side != prev.side;
        };
        size_t first = 0;
        while (first < loop.size() && !starts_piece(first))
            ++first;
        if (first == loop.size()) { // a closed contour inside the box: resample it whole
            std::vector<Eigen::Vector2d> ys;
            for (int s : loop)
                ys.push_back(points[size_t(segments[size_t(s)].from)].y);
            ys.push_back(ys.front());
            const std::vector<Eigen::Vector2d> samples = contour_samples(ys, true);
            const int base = int(out.size()), n = int(samples.size());
            for (int q = 0; q < n; ++q) {
                out.push_back(scale.cwiseProduct(samples[size_t(q)]));
                edges.push_back({ base + q, base + (q + 1) % n });
            }
            continue;
        }
        std::rotate(loop.begin(), loop.begin() + long(first), loop.end());
        // Pieces: runs of one kind between corners.
        size_t k = 0;
        while (k < loop.size()) {
            std::vector<int> piece { segments[size_t(loop[k])].from };
            const bool side = segments[size_t(loop[k])].side;
            do {
                piece.push_back(segments[size_t(loop[k])].to);
                ++k;
            } while (k < loop.size() && !starts_piece(k));
            const int a = emit_corner(piece.front()), b = emit_corner(piece.back());
            std::vector<int> chain { a };
            if (side) {
                // Straight, along one side: samples at t_lo + (t_hi - t_lo) q / n in the side's
                // coordinate, in increasing order whichever way the loop runs, so that opposite
                // sides get the same samples.
                const Eigen::Vector2d ya = points[size_t(piece.front())].y, yb = points[size_t(piece.back())].y;
                const int axis = std::abs(ya.x() - yb.x()) > std::abs(ya.y() - yb.y()) ? 0 : 1;
                const double lo = std::min(ya[axis], yb[axis]), hi = std::max(ya[axis], yb[axis]);
                const int n = std::max(1, int(std::ceil((hi - lo) * scale[axis] / step)));
                std::vector<int> inner;
                for (int q = 1; q < n; ++q) {
                    Eigen::Vector2d y = ya;
                    y[axis] = lo + (hi - lo) * q / n;
                    inner.push_back(int(out.size()));
                    out.push_back(scale.cwiseProduct(y));
                }
                if (ya[axis] > yb[axis])
                    std::reverse(inner.begin(), inner.end());
                chain.insert(chain.end(), inner.begin(), inner.end());
            } else {
                std::vector<Eigen::Vector2d> ys;
                for (int p : piece)
                    ys.push_back(points[size_t(p)].y);
                const std::vector<Eigen::Vector2d> samples = contour_samples(ys, false);
                for (size_t q = 1; q + 1 < samples.size(); ++q) {
                    chain.push_back(int(out.size()));
                    out.push_back(scale.cwiseProduct(samples[q]));
                }
            }
            chain.push_back(b);
            for (size_t q = 0; q + 1 < chain.size(); ++q)
                edges.push_back({ chain[q], chain[q + 1] });
        }
    }

    Positions x(Index(out.size()), 2);
    for (size_t v = 0; v < out.size(); ++v)
        x.row(Index(v)) = out[v].transpose();
    MatrixXi boundary(Index(edges.size()), 2);
    for (size_t e = 0; e < edges.size(); ++e)
        boundary.row(Index(e)) << edges[e][0], edges[e][1];
    Mesh mesh = remesh_domain(x, boundary, 2, settings.size, false, settings.seconds);
    check_cell_tiling(mesh, width, settings.height, sdf.graph().file);
    return mesh;
}

void check_cell_tiling(const Mesh& mesh, double width, double height, const std::string& file)
{
    // The tiling must hold together: one piece once opposite sides are glued, with solid on
    // both a vertical and a horizontal side.
    const Eigen::Vector2d lo = cell_box_min(width, height), hi = cell_box_max(width, height);
    const double tol = 1e-9 * height;
    const Index nv = mesh.rest_positions.rows();
    UnionFind pieces_of(nv);
    auto join = [&](Index a, Index b) { pieces_of.join(a, b); };
    for (Index e = 0; e < mesh.elements.rows(); ++e)
        for (int a = 1; a < 3; ++a)
            join(mesh.elements(e, 0), mesh.elements(e, a));
    bool touches[2] = { false, false };
    for (int axis = 0; axis < 2; ++axis) {
        std::map<long long, Index> low; // vertices on the low side by their other coordinate
        for (Index v = 0; v < nv; ++v)
            if (std::abs(mesh.rest_positions(v, axis) - lo[axis]) < tol) {
                low.emplace(std::llround(mesh.rest_positions(v, 1 - axis) / tol), v);
                touches[axis] = true;
            }
        for (Index v = 0; v < nv; ++v)
            if (std::abs(mesh.rest_positions(v, axis) - hi[axis]) < tol) {
                const long long key = std::llround(mesh.rest_positions(v, 1 - axis) / tol);
                for (long long k = key - 1; k <= key + 1; ++k)
                    if (auto it = low.find(k); it != low.end())
                        join(v, it->second);
            }
    }
    if (!touches[0] || !touches[1])
        throw InputError("design",
            std::string("the solid does not reach the cell's ") + (touches[0] ? "top and bottom" : "left and right")
                + " sides: the tiling does not hold together along " + (touches[0] ? "y" : "x"));
    Index pieces = 0;
    for (Index v = 0; v < nv; ++v)
        pieces += pieces_of.find(v) == v;
    if (pieces > 1)
        throw InputError("design",
            "the solid falls apart into " + std::to_string(pieces)
                + " pieces that do not connect across the cell's sides (a beam too thin or nodes too far apart)");

    // One piece once opposite sides are glued is a connected solid on the torus, not a connected
    // tiling: a beam from the centre to a corner is one piece on the torus and tiles into separate
    // strokes. In the 3 x 3 tiling, the middle copy's solid must be one piece (its bits cut off by
    // its sides join their beams in the neighbouring copies) that also holds the middle copy's
    // neighbours along x and y; then, by translation, the infinite tiling is one piece. The outer
    // copies are not asked to be whole: their bits on the 3 x 3 block's border belong to copies
    // outside it.
    const CellTiling tiling(mesh, width, height, 3, 3);
    const Mesh& tiled = tiling.mesh();
    UnionFind tiled_pieces(tiled.num_vertices());
    for (Index e = 0; e < tiled.num_elements(); ++e)
        for (int a = 1; a < 3; ++a)
            tiled_pieces.join(tiled.elements(e, 0), tiled.elements(e, a));
    const Index ne = mesh.num_elements();
    auto copy_vertex = [&](int i, int j, Index e, int a) { return tiled.elements((Index(i) * 3 + j) * ne + e, a); };
    const Index root = tiled_pieces.find(copy_vertex(1, 1, 0, 0));
    // A neighbour holds with the middle copy if any of its elements does (the middle copy being
    // one piece, so is the neighbour, its translate): no one element will do, as it may lie in a
    // bit on the block's border that belongs to a copy outside the block (the cap of a beam
    // ending on a side), and gmsh decides which element comes first.
    const auto joined = [&](int i, int j) {
        for (Index e = 0; e < ne; ++e)
            if (tiled_pieces.find(copy_vertex(i, j, e, 0)) == root)
                return true;
        return false;
    };
    bool whole = joined(2, 1) && joined(1, 2);
    for (Index e = 0; e < ne && whole; ++e)
        for (int a = 0; a < 3; ++a)
            whole = whole && tiled_pieces.find(copy_vertex(1, 1, e, a)) == root;
    if (!whole)
        throw InputError(file.empty() ? "design" : file,
            "the cell's 3 x 3 tiling is not one connected solid: its solid connects to itself across the cell's "
            "sides but not to its copies in the neighbouring cells (a beam from the centre to a corner tiles into "
            "separate strokes); join the graph's beams across opposite sides of the cell (a node on a side and its "
            "image on the opposite side)");
}

void check_meshable(
    const CellFamily& family, const VectorXd& p, const CellMeshSettings& settings, const std::string& field)
{
    family.check(p, field);
    const double width = p[family.width_index()];
    for (Index v = 0; v < family.size(); ++v) {
        const std::string& name = family.names()[size_t(v)];
        if (name.rfind("thickness", 0) != 0)
            continue;
        const double extent = p[v] * 0.5 * settings.height * std::min(width, 1.0);
        if (extent < settings.size)
            throw InputError(field + "." + name,
                "the beam is " + format_number(extent) + " m thick at width " + format_number(width)
                    + ", thinner than the mesh size " + format_number(settings.size)
                    + " m: raise the thickness's lower bound or refine the mesh");
    }
}

Mesh mesh_design(
    const CellFamily& family, const VectorXd& p, const CellMeshSettings& settings, const std::string& field)
{
    check_meshable(family, p, settings, field);
    const double width = p[family.width_index()];
    return mesh_cell(CellSDF(family.graph(), family.cell_parameters(p)), width, settings);
}

} // namespace diffipc
