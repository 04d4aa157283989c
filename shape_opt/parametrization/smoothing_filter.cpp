#include "shape_opt/parametrization/smoothing_filter.hpp"

#include "forward/common/error.hpp"

#include <cmath>
#include <unordered_map>
#include <vector>

namespace diffipc {

SmoothingFilter::SmoothingFilter(
    const MatrixXd& centroids, const VectorXd& volumes, double radius, const std::string& field)
{
    if (!(radius > 0) || !std::isfinite(radius))
        throw InputError(field, "the filter radius must be a positive length (m), got " + format_number(radius));
    const Index n = centroids.rows();
    const int dim = int(centroids.cols());
    if (volumes.size() != n)
        throw std::logic_error("SmoothingFilter: one volume per centroid");
    // Centroids binned in cells of size r: neighbours within r lie in the 3^dim cells around.
    MatrixXd lower = centroids.colwise().minCoeff();
    auto cell_of = [&](Index e) {
        Eigen::Vector3i c = Eigen::Vector3i::Zero();
        for (int a = 0; a < dim; ++a)
            c[a] = int(std::floor((centroids(e, a) - lower(0, a)) / radius));
        return c;
    };
    auto key = [](const Eigen::Vector3i& c) {
        return (int64_t(c[0]) * 73856093) ^ (int64_t(c[1]) * 19349663) ^ (int64_t(c[2]) * 83492791);
    };
    std::unordered_map<int64_t, std::vector<Index>> cells;
    for (Index e = 0; e < n; ++e)
        cells[key(cell_of(e))].push_back(e);

    std::vector<Eigen::Triplet<double, int>> triplets;
    for (Index e = 0; e < n; ++e) {
        const Eigen::Vector3i c = cell_of(e);
        std::vector<std::pair<Index, double>> row;
        double total = 0;
        for (int i = -1; i <= 1; ++i)
            for (int j = (dim > 1 ? -1 : 0); j <= (dim > 1 ? 1 : 0); ++j)
                for (int k = (dim > 2 ? -1 : 0); k <= (dim > 2 ? 1 : 0); ++k) {
                    const auto it = cells.find(key(c + Eigen::Vector3i(i, j, k)));
                    if (it == cells.end())
                        continue;
                    for (Index f : it->second) {
                        if (cell_of(f) != c + Eigen::Vector3i(i, j, k))
                            continue; // a hash collision
                        const double w
                            = volumes[f] * std::max(0.0, radius - (centroids.row(e) - centroids.row(f)).norm());
                        if (w > 0) {
                            row.emplace_back(f, w);
                            total += w;
                        }
                    }
                }
        for (const auto& [f, w] : row)
            triplets.emplace_back(int(e), int(f), w / total);
    }
    m_weights.resize(n, n);
    m_weights.setFromTriplets(triplets.begin(), triplets.end());
}

VectorXd SmoothingFilter::apply(const VectorXd& x) const
{
    check_size(x, in_size(), "design", "filter");
    return m_weights * x;
}

VectorXd SmoothingFilter::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", "filter");
    check_size(y_bar, out_size(), "design", "filter's gradient");
    return m_weights.transpose() * y_bar;
}

} // namespace diffipc
