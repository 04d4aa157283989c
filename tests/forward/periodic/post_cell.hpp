#pragma once
// A periodic cell whose beams touch across its boundary, for the tests of contact through
// periodic images (forward/periodic/contact_images.hpp): in the unit square, a column
// |x - 0| < 0.1 (across the x faces), a beam 0.3 < y < 0.7, and two stubby posts, 0.4 < x < 0.6
// up to y = 0.95 and 0.35 < x < 0.65 down to y = 0.05. The up post's top faces the next cell's
// down post across the face y = 1, 0.1 apart: compressing the cell along y closes that gap first,
// the narrower post's top pressing on the middle of the wider one's end (no corner on a corner;
// slender posts would buckle sideways under the contact, a bifurcation that finite differences
// of the solution cannot follow). 3D extrudes it over [0, 0.2] along z, a free axis (a periodic
// slab). Made from a structured box mesh by dropping the elements whose centroid lies outside,
// written as a gmsh file for scenes.

#include "forward/mesh/gmsh_writer.hpp"
#include "tests/forward/test_utils.hpp"

#include <cmath>
#include <string>
#include <vector>

namespace diffipc::test {

/// Whether (x, y) lies in the cell's solid, the pattern repeating with period 1.
inline bool in_post_cell(double x, double y)
{
    x -= std::floor(x);
    y -= std::floor(y);
    const bool column = x < 0.1 || x > 0.9;
    const bool beam = y > 0.3 && y < 0.7;
    const bool up = x > 0.4 && x < 0.6 && y > 0.7 && y < 0.95;
    const bool down = x > 0.35 && x < 0.65 && y > 0.05 && y < 0.3;
    return column || beam || up || down;
}

/// The post cell's mesh over `repeats` cells along y, its pattern shifted by `shift` along y
/// (a different cut of the same tiling); 20 cells per unit length in x and y (2 along z).
inline Mesh post_cell_mesh(int dim, int repeats = 1, double shift = 0)
{
    const int n = 20;
    VectorXd lo = VectorXd::Zero(dim), hi = VectorXd::Ones(dim);
    VectorXi cells = VectorXi::Constant(dim, n);
    hi[1] = repeats;
    cells[1] = n * repeats;
    if (dim == 3) {
        hi[2] = 0.2;
        cells[2] = 2;
    }
    const Mesh box = box_mesh(dim, lo, hi, cells);
    std::vector<Index> kept;
    for (Index e = 0; e < box.num_elements(); ++e) {
        Eigen::RowVectorXd c = Eigen::RowVectorXd::Zero(dim);
        for (int a = 0; a <= dim; ++a)
            c += box.rest_positions.row(box.elements(e, a)) / double(dim + 1);
        if (in_post_cell(c[0], c[1] + shift))
            kept.push_back(e);
    }
    std::vector<Index> index(static_cast<size_t>(box.num_vertices()), -1);
    Mesh m;
    m.dim = dim;
    m.elements.resize(Index(kept.size()), dim + 1);
    std::vector<Index> used;
    for (size_t k = 0; k < kept.size(); ++k)
        for (int a = 0; a <= dim; ++a) {
            const Index v = box.elements(kept[k], a);
            if (index[size_t(v)] < 0) {
                index[size_t(v)] = Index(used.size());
                used.push_back(v);
            }
            m.elements(Index(k), a) = int(index[size_t(v)]);
        }
    m.rest_positions.resize(Index(used.size()), dim);
    for (size_t k = 0; k < used.size(); ++k) {
        m.rest_positions.row(Index(k)) = box.rest_positions.row(used[k]);
        // Shear the grid along x by an amount that varies with y (and vanishes on the faces x = 0, 1
        // and y = 0, 1 of the pattern) so that the up post's top vertices do not sit exactly over
        // the down post's: aligned vertices put each point-edge pair on the boundary between its
        // distance types, where the barrier's Hessian jumps and the solution is not
        // differentiable in the parameters.
        // In 3D the same along z (a free axis there): else each vertex would lie over an edge.
        const double x = m.rest_positions(Index(k), 0), y = m.rest_positions(Index(k), 1) + shift;
        const double warp = 0.012 * std::sin(2 * M_PI * y) * std::pow(std::sin(M_PI * x), 2);
        m.rest_positions(Index(k), 0) += warp;
        if (dim == 3)
            m.rest_positions(Index(k), 2) += warp;
    }
    m.vertex_body = VectorXi::Zero(m.num_vertices());
    m.element_body = VectorXi::Zero(m.num_elements());
    return m;
}

/// A static scene of the post cell (neo-Hookean, E = 1e5 Pa, nu = 0.3) compressed along y by
/// G_yy = `strain` t over `steps` steps, G_xx free (the slab's free z carried by the fluctuation), contact with dhat =
/// 0.01 m and `kappa` (null: adaptive). Its mesh file is written to `path`.
inline nlohmann::json post_cell_scene(int dim, const std::string& path, double strain, int steps,
    const nlohmann::json& kappa = nullptr, int repeats = 1, double shift = 0)
{
    using json = nlohmann::json;
    write_gmsh(path, post_cell_mesh(dim, repeats, shift));
    json s;
    s["dimension"] = dim;
    s["bodies"] = { { { "name", "cell" }, { "mesh", { { "file", path } } },
        { "material", { { "model", "neo_hookean" }, { "E", 1e5 }, { "nu", 0.3 }, { "density", 1000 } } } } };
    const std::string yy = std::to_string(strain) + "*t";
    s["periodic"] = { { "gradient",
        dim == 2 ? json { { nullptr, 0 }, { 0, yy } } : json { { nullptr, 0, 0 }, { 0, yy, 0 }, { 0, 0, 0 } } } };
    if (dim == 3) // a slab: its faces z = 0, 0.2 are free
        s["periodic"]["axes"] = { "x", "y" };
    s["contact"] = { { "dhat", 0.01 } };
    if (!kappa.is_null())
        s["contact"]["kappa"] = kappa;
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 / steps }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-10 } };
    return s;
}

} // namespace diffipc::test
