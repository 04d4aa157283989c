#include "cuda/contact/host_barrier.hpp"

#include "cuda/contact/pair_barrier.cuh"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    /// The pair's vertices as 3D points (z = 0 in 2D) and its plane normal.
    void load_pair(const BarrierPairs& P, const std::vector<double>& normals, const std::vector<double>& x, int p,
        vec3* points, vec3& normal)
    {
        const int dim = P.dim, np = P.num_pairs;
        const int nv = contact_num_vertices(ContactKind(P.kind[size_t(p)]));
        for (int a = 0; a < nv; ++a) {
            const double* q = x.data() + size_t(P.vertices[size_t(a) * size_t(np) + size_t(p)]) * size_t(dim);
            points[a] = vec3(q[0], q[1], dim == 3 ? q[2] : 0.0);
        }
        const int plane = P.plane[size_t(p)];
        normal = plane >= 0 ? vec3::load(normals.data() + 3 * size_t(plane)) : vec3();
    }

} // namespace

void HostBarrier::set_mesh(int dim, const std::vector<double>& rest_positions, const std::vector<double>& plane_normals)
{
    if (dim != 2 && dim != 3)
        throw std::invalid_argument("HostBarrier: dim must be 2 or 3, not " + std::to_string(dim));
    if (rest_positions.size() % size_t(dim) != 0 || plane_normals.size() % 3 != 0)
        throw std::invalid_argument("HostBarrier: rest_positions must hold #V * dim values, plane_normals #planes * 3");
    m_dim = dim;
    m_rest = rest_positions;
    m_normals = plane_normals;
    set_pairs({});
}

void HostBarrier::set_pairs(const std::vector<BarrierPair>& pairs)
{
    m_pairs = prepare_barrier_pairs(m_dim, m_rest, int(m_normals.size() / 3), pairs);
}

void HostBarrier::check_x(size_t n) const
{
    if (n != m_rest.size())
        throw std::invalid_argument("HostBarrier: x has " + std::to_string(n)
            + " entries, expected #V * dim = " + std::to_string(m_rest.size()));
}

PairModel HostBarrier::model() const { return pair_model(m_settings.penalty, m_settings.dhat, m_settings.dmin); }

double HostBarrier::energy(const std::vector<double>& x) const
{
    check_x(x.size());
    const PairModel pair_model = model();
    double sum = 0;
    vec3 points[4], normal;
    for (int p = 0; p < m_pairs.num_pairs; ++p) {
        load_pair(m_pairs, m_normals, x, p, points, normal);
        sum += pair_energy(ContactKind(m_pairs.kind[size_t(p)]), m_dim, points, normal, m_pairs.eps_x[size_t(p)], -1,
            pair_model, nullptr, nullptr);
    }
    return std::isfinite(sum) ? m_settings.kappa * sum : std::numeric_limits<double>::infinity();
}

std::vector<double> HostBarrier::gradient(const std::vector<double>& x, double weight) const
{
    check_x(x.size());
    const int dim = m_dim, np = m_pairs.num_pairs, L = 4 * dim;
    const PairModel pair_model = model();
    // Per-pair local gradients, item-major (pair p's vertex a at (p 4 + a) dim).
    std::vector<double> local(size_t(np) * size_t(L), 0.0);
    vec3 points[4], normal;
    for (int p = 0; p < np; ++p) {
        load_pair(m_pairs, m_normals, x, p, points, normal);
        pair_energy(ContactKind(m_pairs.kind[size_t(p)]), dim, points, normal, m_pairs.eps_x[size_t(p)], -1, pair_model,
            local.data() + size_t(p) * size_t(L), nullptr);
    }
    const double scale = weight * m_settings.kappa;
    std::vector<double> g(x.size(), 0.0);
    for (int v : m_pairs.rows)
        for (int i = 0; i < dim; ++i) {
            double acc = g[size_t(v) * size_t(dim) + size_t(i)];
            for (int c = m_pairs.vertex_offsets[size_t(v)]; c < m_pairs.vertex_offsets[size_t(v) + 1]; ++c)
                acc += scale * local[size_t(m_pairs.vertex_codes[size_t(c)]) * size_t(dim) + size_t(i)];
            g[size_t(v) * size_t(dim) + size_t(i)] = acc;
        }
    return g;
}

HostBsrMatrix HostBarrier::hessian(const std::vector<double>& x, bool project, double weight) const
{
    check_x(x.size());
    const int dim = m_dim, np = m_pairs.num_pairs, L = 4 * dim;
    const PairModel pair_model = model();
    const double scale = weight * m_settings.kappa;
    // Per-pair local Hessians, n by n row-major at stride L^2 (n = #vertices * dim <= L).
    std::vector<double> local(size_t(np) * size_t(L * L), 0.0);
    vec3 points[4], normal;
    for (int p = 0; p < np; ++p) {
        load_pair(m_pairs, m_normals, x, p, points, normal);
        pair_energy_hessian(ContactKind(m_pairs.kind[size_t(p)]), dim, points, normal, m_pairs.eps_x[size_t(p)],
            pair_model, project, scale, local.data() + size_t(p) * size_t(L * L));
    }
    HostBsrMatrix H;
    H.block_size = dim;
    H.num_block_rows = m_pairs.num_vertices;
    H.row_offsets = m_pairs.row_offsets;
    H.col_indices = m_pairs.col_indices;
    H.values.assign(m_pairs.col_indices.size() * size_t(dim * dim), 0.0);
    for (int s = 0; s < m_pairs.num_slots(); ++s)
        for (int i = 0; i < dim; ++i)
            for (int k = 0; k < dim; ++k) {
                double acc = 0;
                for (int c = m_pairs.slot_offsets[size_t(s)]; c < m_pairs.slot_offsets[size_t(s) + 1]; ++c) {
                    const int code = m_pairs.slot_codes[size_t(c)];
                    const int p = code / 16, a = (code / 4) % 4, b = code % 4;
                    const int n = contact_num_vertices(ContactKind(m_pairs.kind[size_t(p)])) * dim;
                    acc += local[size_t(p) * size_t(L * L) + size_t((a * dim + i) * n + b * dim + k)];
                }
                H.values[size_t(s) * size_t(dim * dim) + size_t(i * dim + k)] = acc;
            }
    return H;
}

} // namespace diffipc::gpu
