#include "shape_opt/microstructure/cell_family.hpp"

#include "forward/common/error.hpp"
#include "forward/common/union_find.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/json_input.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

namespace diffipc {

std::string to_string(CellSymmetry symmetry)
{
    switch (symmetry) {
    case CellSymmetry::NONE:
        return "none";
    case CellSymmetry::REFLECTION_X:
        return "reflection_x";
    case CellSymmetry::REFLECTION_Y:
        return "reflection_y";
    case CellSymmetry::REFLECTION_XY:
        return "reflection_xy";
    }
    return "?";
}

namespace {

    constexpr double kMatch = 1e-9; ///< positions this close (modulo whole periods) are one point

    /// The symmetry's group as sign vectors: x -> (s_x x, s_y y).
    std::vector<Eigen::Vector2d> group(CellSymmetry symmetry)
    {
        std::vector<Eigen::Vector2d> g { { 1, 1 } };
        if (symmetry == CellSymmetry::REFLECTION_X || symmetry == CellSymmetry::REFLECTION_XY)
            g.emplace_back(-1, 1);
        if (symmetry == CellSymmetry::REFLECTION_Y || symmetry == CellSymmetry::REFLECTION_XY)
            g.emplace_back(1, -1);
        if (symmetry == CellSymmetry::REFLECTION_XY)
            g.emplace_back(-1, -1);
        return g;
    }

    /// d less the nearest whole-period (2) translation.
    Eigen::Vector2d wrap(const Eigen::Vector2d& d) { return d - 2.0 * (d / 2.0).array().round().matrix(); }

    void check_range(const CellFamily::Range& r, const std::string& field, bool positive)
    {
        if (!std::isfinite(r.lower) || !std::isfinite(r.upper) || r.lower > r.upper)
            throw InputError(field + ".bounds", "expected finite bounds with lower <= upper");
        if (positive && !(r.lower > 0))
            throw InputError(field + ".bounds", "the lower bound must be positive");
        if (!(r.initial >= r.lower && r.initial <= r.upper))
            throw InputError(field + ".initial", "the initial value must lie within the bounds");
    }

} // namespace

CellFamily::CellFamily(WireGraph graph, const Settings& settings, const std::string& field)
    : m_graph(std::move(graph))
    , m_settings(settings)
{
    check_range(settings.thickness, field + ".thickness", true);
    check_range(settings.blend, field + ".blend", true);
    check_range(settings.width, field + ".width", true);
    if (!(settings.offset_bound >= 0) || !std::isfinite(settings.offset_bound))
        throw InputError(field + ".offset.bound", "expected a finite number >= 0");
    const Index n = m_graph.nodes.rows(), m = m_graph.edges.rows();
    const std::vector<Eigen::Vector2d> g = group(settings.symmetry);
    auto node = [&](Index i) { return Eigen::Vector2d(m_graph.nodes.row(i).transpose()); };

    // Nodes: the images of node i under each group element (every node at that point modulo periods).
    // images[i][k]: the nodes at g_k(node i).
    std::vector<std::vector<std::vector<Index>>> images(size_t(n), std::vector<std::vector<Index>>(g.size()));
    UnionFind nodes(n);
    for (Index i = 0; i < n; ++i)
        for (size_t k = 0; k < g.size(); ++k) {
            const Eigen::Vector2d y = g[k].cwiseProduct(node(i));
            for (Index j = 0; j < n; ++j)
                if (wrap(node(j) - y).cwiseAbs().maxCoeff() < kMatch) {
                    images[size_t(i)][k].push_back(j);
                    nodes.join(i, j);
                }
            if (images[size_t(i)][k].empty())
                throw InputError(field + ".symmetry",
                    "the graph is not " + to_string(settings.symmetry) + "-symmetric: node " + std::to_string(i)
                        + " (0-based) has no mirror image");
        }
    // Per node: the sign by which it follows its orbit's first node, per axis (0: fixed).
    MatrixXd follow = MatrixXd::Zero(n, 2);
    std::vector<Eigen::Vector2d> free_axes(size_t(n), Eigen::Vector2d::Ones()); // per orbit root
    std::vector<std::vector<Eigen::Vector2d>> signs(
        static_cast<size_t>(n)); // per node: the signs g(root) reaches it by
    for (Index r = 0; r < n; ++r) {
        if (nodes.find(r) != r)
            continue;
        // Walk the orbit from r: a node reached from root-related node j by g_k follows with
        // sign(j) * g_k. Breadth-first over the images.
        std::vector<Index> queue { r };
        signs[size_t(r)].push_back(Eigen::Vector2d::Ones());
        for (size_t q = 0; q < queue.size(); ++q) {
            const Index j = queue[q];
            const Eigen::Vector2d sj = signs[size_t(j)].front();
            for (size_t k = 0; k < g.size(); ++k)
                for (Index i : images[size_t(j)][k]) {
                    const Eigen::Vector2d s = sj.cwiseProduct(g[k]);
                    if (signs[size_t(i)].empty())
                        queue.push_back(i);
                    signs[size_t(i)].push_back(s);
                }
        }
        // An axis is free if every node of the orbit follows along it with one sign and none sits
        // on the cell's boundary across it.
        for (Index i : queue)
            for (int c = 0; c < 2; ++c) {
                for (const Eigen::Vector2d& s : signs[size_t(i)])
                    if (s[c] != signs[size_t(i)].front()[c])
                        free_axes[size_t(r)][c] = 0;
                if (std::abs(std::abs(node(i)[c]) - 1) < kMatch)
                    free_axes[size_t(r)][c] = 0;
            }
        for (Index i : queue)
            follow.row(i) = signs[size_t(i)].front().cwiseProduct(free_axes[size_t(r)]).transpose();
    }

    // Edges: orbits of segments under the group, modulo whole periods.
    UnionFind edges(m);
    for (Index e = 0; e < m; ++e)
        for (const Eigen::Vector2d& s : g) {
            const Eigen::Vector2d a = s.cwiseProduct(node(m_graph.edges(e, 0)));
            const Eigen::Vector2d b = s.cwiseProduct(node(m_graph.edges(e, 1)));
            bool found = false;
            for (Index f = 0; f < m && !found; ++f) {
                const Eigen::Vector2d c = node(m_graph.edges(f, 0)), d = node(m_graph.edges(f, 1));
                for (const auto& [p, q] : { std::pair { c, d }, std::pair { d, c } }) {
                    const Eigen::Vector2d shift = p - a;
                    if (wrap(shift).cwiseAbs().maxCoeff() < kMatch && (q - b - shift).cwiseAbs().maxCoeff() < kMatch) {
                        edges.join(e, f);
                        found = true;
                    }
                }
            }
            if (!found)
                throw InputError(field + ".symmetry",
                    "the graph is not " + to_string(settings.symmetry) + "-symmetric: edge " + std::to_string(e)
                        + " (0-based) has no mirror image");
        }

    // The variables.
    std::vector<double> lower, upper, initial;
    std::vector<std::vector<std::pair<Index, double>>> rows; // per variable: (row of flatten(), coefficient)
    for (Index r = 0; r < n; ++r) {
        if (nodes.find(r) != r)
            continue;
        for (int c = 0; c < 2; ++c) {
            if (free_axes[size_t(r)][c] == 0)
                continue;
            m_names.push_back("node[" + std::to_string(r) + "]." + (c == 0 ? "x" : "y"));
            double lo = -settings.offset_bound, hi = settings.offset_bound;
            std::vector<std::pair<Index, double>> column;
            for (Index i = 0; i < n; ++i)
                if (nodes.find(i) == r) {
                    // node i moves by follow(i, c) u: keep it within [-1, 1]
                    const double s = follow(i, c), y = node(i)[c];
                    lo = std::max(lo, s > 0 ? -1 - y : y - 1);
                    hi = std::min(hi, s > 0 ? 1 - y : y + 1);
                    column.emplace_back(2 * i + c, s);
                }
            lower.push_back(lo);
            upper.push_back(hi);
            initial.push_back(0);
            rows.push_back(column);
        }
    }
    for (Index e = 0; e < m; ++e) {
        if (edges.find(e) != e)
            continue;
        m_names.push_back("thickness[" + std::to_string(e) + "]");
        lower.push_back(settings.thickness.lower);
        upper.push_back(settings.thickness.upper);
        initial.push_back(settings.thickness.initial);
        std::vector<std::pair<Index, double>> column;
        for (Index f = 0; f < m; ++f)
            if (edges.find(f) == e)
                column.emplace_back(2 * n + f, 1.0);
        rows.push_back(column);
    }
    for (const auto& [name, range, row] :
        { std::tuple { "blend", settings.blend, 2 * n + m }, std::tuple { "width", settings.width, Index(-1) } }) {
        m_names.push_back(name);
        lower.push_back(range.lower);
        upper.push_back(range.upper);
        initial.push_back(range.initial);
        rows.push_back(row < 0 ? std::vector<std::pair<Index, double>> {}
                               : std::vector<std::pair<Index, double>> { { row, 1.0 } });
    }
    m_lower = Eigen::Map<VectorXd>(lower.data(), Index(lower.size()));
    m_upper = Eigen::Map<VectorXd>(upper.data(), Index(upper.size()));
    m_initial = Eigen::Map<VectorXd>(initial.data(), Index(initial.size()));
    m_jacobian = MatrixXd::Zero(2 * n + m + 1, size());
    for (size_t v = 0; v < rows.size(); ++v)
        for (const auto& [row, coefficient] : rows[v])
            m_jacobian(row, Index(v)) = coefficient;
}

void CellFamily::check(const VectorXd& p, const std::string& field) const
{
    if (p.size() != size())
        throw InputError(
            field, "expected " + std::to_string(size()) + " design variables, got " + std::to_string(p.size()));
    for (Index v = 0; v < size(); ++v) {
        const double slack = 1e-12 * std::max(1.0, m_upper[v] - m_lower[v]);
        if (!std::isfinite(p[v]) || p[v] < m_lower[v] - slack || p[v] > m_upper[v] + slack)
            throw InputError(field + "." + m_names[size_t(v)],
                "value " + format_number(p[v]) + " outside its bounds [" + format_number(m_lower[v]) + ", "
                    + format_number(m_upper[v]) + "]");
    }
}

CellParameters CellFamily::cell_parameters(const VectorXd& p) const
{
    check(p, "design");
    return CellParameters::unflatten(m_jacobian * p, m_graph.nodes.rows(), m_graph.edges.rows());
}

namespace {

    CellFamily::Range parse_range(const JsonField& f, CellFamily::Range r)
    {
        f.require_object({ "initial", "bounds" });
        if (f.has("bounds")) {
            const VectorXd b = f["bounds"].vector(2);
            r.lower = b[0];
            r.upper = b[1];
        }
        r.initial = f.number_or("initial", r.initial);
        return r;
    }

} // namespace

CellFamily parse_cell_family(const JsonField& f, const std::string& base_directory)
{
    f.require_object({ "graph", "symmetry", "offset", "thickness", "blend", "width", "description" });
    CellFamily::Settings s;
    if (f.has("symmetry")) {
        const std::string name = f["symmetry"].string();
        bool known = false;
        for (CellSymmetry c :
            { CellSymmetry::NONE, CellSymmetry::REFLECTION_X, CellSymmetry::REFLECTION_Y, CellSymmetry::REFLECTION_XY })
            if (to_string(c) == name) {
                s.symmetry = c;
                known = true;
            }
        if (!known)
            f["symmetry"].fail(
                "unknown symmetry \"" + name + "\" (expected none, reflection_x, reflection_y or reflection_xy)");
    }
    if (f.has("offset")) {
        f["offset"].require_object({ "bound" });
        s.offset_bound = f["offset"].number_or("bound", s.offset_bound);
    }
    if (f.has("thickness"))
        s.thickness = parse_range(f["thickness"], s.thickness);
    if (f.has("blend"))
        s.blend = parse_range(f["blend"], s.blend);
    if (f.has("width"))
        s.width = parse_range(f["width"], s.width);
    std::filesystem::path graph = f["graph"].string();
    if (graph.is_relative() && !base_directory.empty())
        graph = std::filesystem::path(base_directory) / graph;
    return CellFamily(read_wire_graph(graph.string()), s, f.path());
}

CellFamily read_cell_family(const std::string& path)
{
    const nlohmann::json j = parse_json_text(read_input_file(path, "cell family file"), path);
    return parse_cell_family(JsonField(j, path), std::filesystem::path(path).parent_path().string());
}

} // namespace diffipc
