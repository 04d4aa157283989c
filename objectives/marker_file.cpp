#include "objectives/marker_file.hpp"

#include "forward/common/error.hpp"

#include <Eigen/LU>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

namespace diffipc {

namespace {

    struct Row {
        int line = 0;
        VectorXd rest, position;
        double time = std::numeric_limits<double>::quiet_NaN();
    };

    std::string point_text(const VectorXd& p)
    {
        std::string s = "(";
        for (Index a = 0; a < p.size(); ++a)
            s += (a ? ", " : "") + format_number(p[a]);
        return s + ")";
    }

    std::vector<Row> read_rows(const std::string& path, int dim)
    {
        std::ifstream in(path);
        if (!in)
            throw InputError(path, "cannot open the marker file");
        std::vector<Row> rows;
        std::string line;
        int number = 0, width = -1;
        while (std::getline(in, line)) {
            ++number;
            if (const auto hash = line.find('#'); hash != std::string::npos)
                line.erase(hash);
            for (char& c : line)
                if (c == ',' || c == '\t' || c == ';')
                    c = ' ';
            std::istringstream fields(line);
            std::vector<double> values;
            std::string token;
            while (fields >> token) {
                char* end = nullptr;
                const double v = std::strtod(token.c_str(), &end);
                if (end == token.c_str() || *end != '\0')
                    throw InputError(path + ":" + std::to_string(number), "'" + token + "' is not a number");
                if (!std::isfinite(v))
                    throw InputError(path + ":" + std::to_string(number), "non-finite value '" + token + "'");
                values.push_back(v);
            }
            if (values.empty())
                continue;
            const int n = int(values.size());
            if (n != 2 * dim && n != 2 * dim + 1)
                throw InputError(path + ":" + std::to_string(number),
                    "expected " + std::to_string(2 * dim) + " numbers (rest and measured position) or "
                        + std::to_string(2 * dim + 1) + " (rest position, time, measured position), got "
                        + std::to_string(n));
            if (width >= 0 && n != width)
                throw InputError(path + ":" + std::to_string(number),
                    "has " + std::to_string(n) + " numbers, the rows before " + std::to_string(width)
                        + ": every row of a file has the same form");
            width = n;
            Row r;
            r.line = number;
            r.rest = Eigen::Map<const VectorXd>(values.data(), dim);
            if (n == 2 * dim)
                r.position = Eigen::Map<const VectorXd>(values.data() + dim, dim);
            else {
                r.time = values[size_t(dim)];
                r.position = Eigen::Map<const VectorXd>(values.data() + dim + 1, dim);
            }
            rows.push_back(std::move(r));
        }
        if (rows.empty())
            throw InputError(path, "no marker rows");
        return rows;
    }

} // namespace

MarkerData read_marker_file(const std::string& path, const Mesh& mesh, const Positions& rest, Index body_vertices,
    double dt, int steps, double vertex_tolerance)
{
    const int d = mesh.dim;
    const std::vector<Row> rows = read_rows(path, d);
    const bool transient = std::isfinite(rows.front().time);

    // The markers: the distinct rest positions, in the order of first appearance.
    MarkerData out;
    std::map<std::vector<double>, Index> index;
    std::vector<const Row*> first;
    for (const Row& r : rows) {
        const std::vector<double> key(r.rest.data(), r.rest.data() + d);
        if (index.emplace(key, Index(first.size())).second)
            first.push_back(&r);
        else if (!transient)
            throw InputError(path + ":" + std::to_string(r.line),
                "repeats the rest position " + point_text(r.rest) + " of line "
                    + std::to_string(first[size_t(index[key])]->line) + " (one row per marker in a static file)");
    }
    const Index M = Index(first.size());
    out.rest.resize(M, d);
    for (Index m = 0; m < M; ++m)
        out.rest.row(m) = first[size_t(m)]->rest.transpose();

    // The bodies' box, for the units check and the default tolerance.
    const Positions bodies = rest.topRows(body_vertices);
    const VectorXd lower = bodies.colwise().minCoeff().transpose(), upper = bodies.colwise().maxCoeff().transpose();
    const double diagonal = (upper - lower).norm();
    const double tolerance = vertex_tolerance > 0 ? vertex_tolerance : 1e-6 * diagonal;
    const double margin = 0.05 * diagonal;

    for (Index m = 0; m < M; ++m) {
        const VectorXd X = out.rest.row(m).transpose();
        const std::string where = path + ":" + std::to_string(first[size_t(m)]->line);
        if (((X.array() < lower.array() - margin) || (X.array() > upper.array() + margin)).any())
            throw InputError(where,
                "the marker at " + point_text(X) + " lies outside the mesh's bounding box " + point_text(lower) + " - "
                    + point_text(upper)
                    + " (positions are in metres: are the markers in millimetres, or the mesh placed elsewhere?)");
        // A vertex within the tolerance?
        Index nearest = -1;
        double nearest_distance = std::numeric_limits<double>::infinity();
        for (Index v = 0; v < body_vertices; ++v) {
            const double dist = (rest.row(v).transpose() - X).norm();
            if (dist < nearest_distance) {
                nearest_distance = dist;
                nearest = v;
            }
        }
        if (nearest >= 0 && nearest_distance <= tolerance) {
            out.markers.push_back(MarkerPoint::vertex(nearest));
            ++out.at_vertices;
            continue;
        }
        // Else the element that contains it: the largest smallest barycentric coordinate.
        Index best = -1;
        double best_min = -std::numeric_limits<double>::infinity();
        VectorXd best_weights;
        MatrixXd A(d, d);
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            const VectorXd x0 = rest.row(mesh.elements(e, 0)).transpose();
            for (int a = 0; a < d; ++a)
                A.col(a) = rest.row(mesh.elements(e, a + 1)).transpose() - x0;
            const VectorXd lambda = A.partialPivLu().solve(X - x0);
            VectorXd w(d + 1);
            w[0] = 1 - lambda.sum();
            w.tail(d) = lambda;
            if (!w.allFinite())
                continue;
            if (w.minCoeff() > best_min) {
                best_min = w.minCoeff();
                best = e;
                best_weights = w;
            }
        }
        // Inside, up to round-off relative to the element (a marker on a face or an edge).
        if (best < 0 || best_min < -1e-9) {
            // Measured points on the surface, rounded (scan data to 10 um), fall just outside:
            // the error names the key that attaches them.
            throw InputError(where,
                "the marker at " + point_text(X) + " lies outside the mesh (in no element; the nearest vertex is "
                    + format_number(nearest_distance) + " m away): the objective's \"vertex_tolerance\" (now "
                    + format_number(tolerance) + " m" + (vertex_tolerance > 0 ? "" : ", the default")
                    + ") above that distance attaches it to that vertex");
        }
        best_weights = best_weights.cwiseMax(0.0);
        best_weights /= best_weights.sum();
        // The sum is 1 to round-off after the division; make it exact for MarkerPoint's check.
        best_weights[0] = 1 - best_weights.tail(d).sum();
        out.markers.push_back(MarkerPoint::barycentric(
            mesh, best, std::vector<double>(best_weights.data(), best_weights.data() + d + 1)));
    }

    if (!transient) {
        Positions y(M, d);
        for (Index m = 0; m < M; ++m)
            y.row(m) = first[size_t(m)]->position.transpose();
        out.targets.push_back(y);
        return out;
    }
    // Transient: the rows by step.
    std::map<int, Positions> by_step;
    std::map<int, std::vector<char>> seen;
    for (const Row& r : rows) {
        const std::string where = path + ":" + std::to_string(r.line);
        const double k = r.time / dt;
        const int step = int(std::lround(k));
        if (!(std::abs(k - step) <= 1e-6) || step < 0 || step > steps)
            throw InputError(where,
                "time " + format_number(r.time) + " s is not a step of the scene (dt = " + format_number(dt) + " s, "
                    + std::to_string(steps) + " steps)");
        auto& block = by_step[step];
        auto& flags = seen[step];
        if (block.rows() == 0) {
            block = Positions::Zero(M, d);
            flags.assign(size_t(M), 0);
        }
        const Index m = index[std::vector<double>(r.rest.data(), r.rest.data() + d)];
        if (flags[size_t(m)])
            throw InputError(where, "a second row for the marker at " + point_text(r.rest) + " at this time");
        flags[size_t(m)] = 1;
        block.row(m) = r.position.transpose();
    }
    for (const auto& [step, flags] : seen)
        for (Index m = 0; m < M; ++m)
            if (!flags[size_t(m)])
                throw InputError(path,
                    "the marker at " + point_text(out.rest.row(m).transpose()) + " has no row at time "
                        + format_number(step * dt) + " s (step " + std::to_string(step) + ")");
    for (auto& [step, block] : by_step) {
        out.steps.push_back(step);
        out.targets.push_back(block);
    }
    return out;
}

} // namespace diffipc
