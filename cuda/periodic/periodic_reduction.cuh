#pragma once
/// @file periodic_reduction.cuh
/// A periodic cell's map from its reduced unknowns to positions (forward/periodic/periodic_map.hpp),
///
///     x = X + P q,   (P q)_{v i} = w_{c(v) i} + sum_j lever_{v j} q_{(i j)},   lever_{v j} = (X_v - X_o)_j / L,
///
/// and its transpose, entry by entry: the device's kernels (device_periodic_map.hpp) and the CPU tests
/// call these same functions. q's layout is PeriodicMap's: class c's fluctuation component i at c dim + i,
/// then L G(i, j) at C dim + i dim + j (so that q is C + dim blocks of dim: the classes, then G's rows).
/// Compiles with nvcc and with a plain C++ compiler (forward/kernels/host_device.hpp).

#include "cuda/common/kernels.cuh"

namespace diffipc::gpu {

/// Plain pointers (device or host) to a periodic cell's map.
struct PeriodicView {
    int dim = 0, num_vertices = 0, num_classes = 0;
    const int* vertex_class = nullptr; ///< #V: each vertex's class
    const double* lever = nullptr; ///< #V dim: (X_v - X_o)_j / L
    const int* class_start = nullptr; ///< num_classes + 1 offsets into class_vertices
    const int* class_vertices = nullptr; ///< #V: each class's vertices, in increasing order
};

DIFFIPC_HD inline int num_reduced(const PeriodicView& m) { return m.num_classes * m.dim + m.dim * m.dim; }
/// Index in q of class c's fluctuation component i.
DIFFIPC_HD inline int fluctuation_dof(const PeriodicView& m, int c, int i) { return c * m.dim + i; }
/// Index in q of L G(i, j).
DIFFIPC_HD inline int macro_dof(const PeriodicView& m, int i, int j) { return m.num_classes * m.dim + i * m.dim + j; }

/// (P q)_{v i}: the class's fluctuation plus the macro gradient's lever terms in increasing j.
DIFFIPC_HD inline double expand_entry(const PeriodicView& m, const double* q, int v, int i)
{
    const int d = m.dim;
    double s = q[fluctuation_dof(m, m.vertex_class[v], i)];
    for (int j = 0; j < d; ++j)
        s += m.lever[v * d + j] * q[macro_dof(m, i, j)];
    return s;
}

/// (P^T g)_{c i}: the sum of g_{v i} over class c's vertices, in increasing vertex order.
DIFFIPC_HD inline double reduce_fluctuation(const PeriodicView& m, const double* g, int c, int i)
{
    double s = 0;
    for (int k = m.class_start[c]; k < m.class_start[c + 1]; ++k)
        s += g[m.class_vertices[k] * m.dim + i];
    return s;
}

/// Vertex v's term of (P^T g)_{(i j)} = sum_v g_{v i} lever_{v j} (summed by a deterministic reduction).
DIFFIPC_HD inline double macro_term(const PeriodicView& m, const double* g, int v, int i, int j)
{
    return g[v * m.dim + i] * m.lever[v * m.dim + j];
}

} // namespace diffipc::gpu
