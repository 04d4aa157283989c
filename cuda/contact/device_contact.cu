#include "cuda/contact/device_contact.hpp"

#include "cuda/common/device.hpp"
#include "cuda/contact/pair_barrier.cuh"
#include "cuda/linalg/reduction.hpp"

#include <cub/device/device_reduce.cuh>
#include <cub/device/device_select.cuh>
#include <cuda_runtime.h>
#include <thrust/iterator/counting_iterator.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 128;
    constexpr double INF = std::numeric_limits<double>::infinity();

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// Grows a scratch array to at least n elements (never shrinks: no reallocation per call).
    template <typename T> void ensure(DeviceArray<T>& a, size_t n)
    {
        if (a.size() < n)
            a.resize(n + n / 2 + 64);
    }

    /// The candidates of one query and the plane pairs, indexed as one list k in the CPU's order:
    /// vertex-edge, vertex-face, edge-edge, then (plane q, plane vertex i) at q #PV + i.
    struct CandidateList {
        int dim;
        const int* ve; // 2 per pair
        const int* vf;
        const int* ee;
        size_t n_ve, n_vf, n_ee, n_plane;
        const int* edges; // #CE by 2
        const int* faces; // #CF by 3
        const int* plane_vertices; // #PV surface vertices of non-kinematic groups
        int num_plane_vertices;
        const int* plane_point; // #planes: the plane's mesh vertex
        const double* normals; // #planes * 3
        const double* rest; // #V * dim
        __host__ __device__ size_t size() const { return n_ve + n_vf + n_ee + n_plane; }
    };

    struct Candidate {
        ContactKind kind;
        int v[4];
        int plane;
    };

    __device__ Candidate load_candidate(const CandidateList& L, size_t k)
    {
        Candidate c;
        c.plane = -1;
        c.v[3] = -1;
        if (k < L.n_ve) {
            const int e = L.ve[2 * k + 1];
            c.kind = ContactKind::VERTEX_EDGE;
            c.v[0] = L.ve[2 * k];
            c.v[1] = L.edges[2 * e];
            c.v[2] = L.edges[2 * e + 1];
            return c;
        }
        k -= L.n_ve;
        if (k < L.n_vf) {
            const int f = L.vf[2 * k + 1];
            c.kind = ContactKind::VERTEX_FACE;
            c.v[0] = L.vf[2 * k];
            c.v[1] = L.faces[3 * f];
            c.v[2] = L.faces[3 * f + 1];
            c.v[3] = L.faces[3 * f + 2];
            return c;
        }
        k -= L.n_vf;
        if (k < L.n_ee) {
            const int a = L.ee[2 * k], b = L.ee[2 * k + 1];
            c.kind = ContactKind::EDGE_EDGE;
            c.v[0] = L.edges[2 * a];
            c.v[1] = L.edges[2 * a + 1];
            c.v[2] = L.edges[2 * b];
            c.v[3] = L.edges[2 * b + 1];
            return c;
        }
        k -= L.n_ee;
        c.kind = ContactKind::VERTEX_PLANE;
        c.plane = int(k / size_t(L.num_plane_vertices));
        c.v[0] = L.plane_vertices[k % size_t(L.num_plane_vertices)];
        c.v[1] = L.plane_point[c.plane];
        c.v[2] = -1;
        return c;
    }

    __device__ vec3 point_of(const double* x, int v, int dim)
    {
        const double* q = x + size_t(v) * dim;
        return vec3(q[0], q[1], dim == 3 ? q[2] : 0.0);
    }

    /// The candidate's vertices at x, its plane normal and its mollifier threshold at rest.
    __device__ void candidate_geometry(
        const CandidateList& L, const Candidate& c, const double* x, vec3* points, vec3& normal, double& eps_x)
    {
        const int nv = contact_num_vertices(c.kind);
        for (int a = 0; a < nv; ++a)
            points[a] = point_of(x, c.v[a], L.dim);
        normal = c.plane >= 0 ? vec3::load(L.normals + 3 * size_t(c.plane)) : vec3(0, 0, 0);
        eps_x = c.kind == ContactKind::EDGE_EDGE ? edge_edge_mollifier_threshold(point_of(L.rest, c.v[0], L.dim),
                    point_of(L.rest, c.v[1], L.dim), point_of(L.rest, c.v[2], L.dim), point_of(L.rest, c.v[3], L.dim))
                                                 : 0.0;
    }

    /// The CPU build_contacts' test with radius r: s < r^2 (s of the classified type), or for a plane
    /// pair h < r; `distance` is sqrt(s) (0 behind a plane), `gap2` (sqrt(max(s, 0)) - dmin)^2 with
    /// s = -1 behind a plane as the CPU stores it.
    __device__ bool classify(
        const CandidateList& L, size_t k, const double* x, double radius, double dmin, double& distance, double& gap2)
    {
        const Candidate c = load_candidate(L, k);
        vec3 points[4], normal;
        double eps_x;
        candidate_geometry(L, c, x, points, normal, eps_x);
        double s;
        bool active;
        if (c.kind == ContactKind::VERTEX_PLANE) {
            const double h = dot(points[0] - points[1], normal);
            active = h < radius;
            s = h > 0 ? h * h : -1.0;
        } else {
            double m;
            pair_distance(c.kind, points, normal, eps_x, -1, s, m, nullptr, nullptr, nullptr, nullptr);
            active = s < radius * radius;
        }
        distance = s < 0 ? 0.0 : sqrt(s);
        const double gap = sqrt(fmax(s, 0.0)) - dmin;
        gap2 = gap * gap;
        return active;
    }

    /// flags[k] = candidate k is active; gap2[k] its gap squared if active, else +inf.
    __global__ void classify_candidates(CandidateList L, const double* __restrict__ x, double radius, double dmin,
        unsigned char* __restrict__ flags, double* __restrict__ gap2)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= L.size())
            return;
        double d, g;
        const bool active = classify(L, k, x, radius, dmin, d, g);
        flags[k] = active ? 1 : 0;
        gap2[k] = active ? g : INFINITY;
    }

    /// distance[k] of the candidates within the radius, +inf for the others.
    __global__ void candidate_distances(
        CandidateList L, const double* __restrict__ x, double radius, double dmin, double* __restrict__ out)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= L.size())
            return;
        double d, g;
        out[k] = classify(L, k, x, radius, dmin, d, g) ? d : INFINITY;
    }

    /// energy[k] = the pair energy of an active candidate (the barrier m b(s - dmin^2, shat), +inf if it
    /// intersects; or the penalty's), 0 otherwise.
    __global__ void candidate_energies(CandidateList L, const double* __restrict__ x, double radius, double dmin,
        PairModel model, double* __restrict__ out)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= L.size())
            return;
        double d, g;
        if (!classify(L, k, x, radius, dmin, d, g)) {
            out[k] = 0.0;
            return;
        }
        const Candidate c = load_candidate(L, k);
        vec3 points[4], normal;
        double eps_x;
        candidate_geometry(L, c, x, points, normal, eps_x);
        out[k] = pair_energy(c.kind, L.dim, points, normal, eps_x, -1, model, nullptr, nullptr);
    }

    /// The kept candidates as pairs: kind, 4 vertices (-1 unused), plane.
    __global__ void gather_pairs(CandidateList L, const int* __restrict__ kept, int count, int* __restrict__ out)
    {
        const int t = blockIdx.x * blockDim.x + threadIdx.x;
        if (t >= count)
            return;
        const Candidate c = load_candidate(L, size_t(kept[t]));
        int* o = out + size_t(t) * 6;
        o[0] = int(c.kind);
        for (int a = 0; a < 4; ++a)
            o[1 + a] = c.v[a];
        o[5] = c.plane;
    }

    using Clock = std::chrono::steady_clock;

    void add_time(Clock::time_point start, double& total)
    {
        check_cuda(cudaDeviceSynchronize(), "synchronization at the end of a contact phase");
        total += std::chrono::duration<double>(Clock::now() - start).count();
    }

} // namespace

struct DeviceContact::Impl {
    CollisionMeshData mesh;
    DeviceContactSettings settings;
    int dim = 0, nv = 0;
    DeviceBroadPhase broad_phase; // static queries (the step bound's broad phase keeps the segment)
    DeviceStepBound bound;
    DeviceBarrier barrier;
    DeviceArray<double> rest, normals;
    DeviceArray<int> plane_vertices, plane_point;
    int num_plane_vertices = 0, num_planes = 0;
    DeviceArray<unsigned char> flags;
    DeviceArray<double> values; // per candidate: gap2, distances or energies
    DeviceArray<int> kept, kept_count, kept_pairs;
    DeviceArray<unsigned char> cub_temp;
    DeviceArray<double> partials, scalar;
    int num_active = 0;
    std::vector<BarrierPair> active; // host copy of kept_pairs, made on request
    bool active_downloaded = true;
    double min_gap2 = INF;
    DeviceBsrMatrix hessian;
    DeviceContactTimes times;

    Impl(const CollisionMeshData& m, const std::vector<PlaneObstacle>& planes, const DeviceContactSettings& s)
        : mesh(m)
        , settings(s)
        , broad_phase(m)
        , bound(m, planes, StepBoundSettings { s.dhat, s.min_distance, s.ccd_max_iterations, s.ccd_rescaling })
    {
    }

    CandidateList list(const DeviceCandidates& c) const
    {
        const DeviceBroadPhase::MeshPointers p = broad_phase.mesh_pointers();
        CandidateList L;
        L.dim = dim;
        L.ve = c.vertex_edge;
        L.vf = c.vertex_face;
        L.ee = c.edge_edge;
        L.n_ve = c.num_vertex_edge;
        L.n_vf = c.num_vertex_face;
        L.n_ee = c.num_edge_edge;
        L.n_plane = size_t(num_planes) * size_t(num_plane_vertices);
        L.edges = p.edges;
        L.faces = p.faces;
        L.plane_vertices = plane_vertices.data();
        L.num_plane_vertices = num_plane_vertices;
        L.plane_point = plane_point.data();
        L.normals = normals.data();
        L.rest = rest.data();
        return L;
    }

    double active_radius() const { return settings.min_distance + settings.dhat; }

    /// The minimum of values[0, n) (+inf if n = 0), order-independent.
    double minimum(size_t n)
    {
        if (n == 0)
            return INF;
        size_t bytes = 0;
        check_cuda(cub::DeviceReduce::Min(nullptr, bytes, values.data(), scalar.data(), int(n)),
            "cub::DeviceReduce::Min (size query)");
        ensure(cub_temp, bytes);
        check_cuda(cub::DeviceReduce::Min(cub_temp.data(), bytes, values.data(), scalar.data(), int(n)),
            "cub::DeviceReduce::Min");
        double out = INF;
        detail::copy_device_to_host(&out, scalar.data(), sizeof(double));
        // cub's Min starts from the largest finite double: all +inf (no term) reads as that.
        return out == std::numeric_limits<double>::max() ? INF : out;
    }
};

DeviceContact::DeviceContact(const CollisionMeshData& mesh, const std::vector<double>& rest,
    const std::vector<PlaneObstacle>& planes, const DeviceContactSettings& settings)
{
    if (rest.size() != size_t(mesh.num_vertices) * size_t(mesh.dim))
        throw std::invalid_argument("DeviceContact: rest positions have " + std::to_string(rest.size())
            + " entries, expected #V * dim = " + std::to_string(size_t(mesh.num_vertices) * size_t(mesh.dim)));
    m_impl = std::make_unique<Impl>(mesh, planes, settings);
    Impl& d = *m_impl;
    d.dim = mesh.dim;
    d.nv = mesh.num_vertices;
    d.rest.upload(rest);
    std::vector<double> normals;
    std::vector<int> points;
    for (const PlaneObstacle& p : planes) {
        points.push_back(p.vertex);
        for (int k = 0; k < 3; ++k)
            normals.push_back(p.normal[k]);
    }
    d.num_planes = int(planes.size());
    d.normals.upload(normals);
    d.plane_point.upload(points);
    std::vector<int> plane_vertices; // the CPU's m_plane_vertices
    for (const int v : mesh.vertices) {
        const int g = mesh.vertex_group[size_t(v)];
        if (g >= 0 && !mesh.group_kinematic[size_t(g)])
            plane_vertices.push_back(v);
    }
    d.num_plane_vertices = int(plane_vertices.size());
    if (d.num_plane_vertices == 0)
        d.num_planes = 0; // no plane pairs (and no division by zero in load_candidate)
    d.plane_vertices.upload(plane_vertices);
    d.barrier.upload(d.dim, rest, normals);
    d.barrier.set_settings(BarrierSettings { settings.kappa, settings.dhat, settings.min_distance, settings.penalty });
    d.partials.resize(REDUCTION_PARTIALS);
    d.scalar.resize(1);
    d.kept_count.resize(1);
    d.hessian = d.barrier.make_hessian_matrix();
}

DeviceContact::~DeviceContact() = default;

int DeviceContact::dim() const { return m_impl->dim; }
int DeviceContact::num_dofs() const { return m_impl->nv * m_impl->dim; }
const DeviceContactSettings& DeviceContact::settings() const { return m_impl->settings; }
double DeviceContact::kappa() const { return m_impl->settings.kappa; }

void DeviceContact::set_kappa(double kappa)
{
    Impl& d = *m_impl;
    d.settings.kappa = kappa;
    BarrierSettings b = d.barrier.settings();
    b.kappa = kappa;
    d.barrier.set_settings(b);
}

double DeviceContact::energy(const double* d_y, bool on_segment)
{
    Impl& d = *m_impl;
    DeviceCandidates candidates;
    if (on_segment && !d.settings.penalty) { // the penalty has no step bound, so no segment
        candidates = d.bound.segment_candidates();
    } else {
        const auto t = Clock::now();
        candidates = d.broad_phase.find(d_y, d_y, d.active_radius());
        add_time(t, d.times.broad_phase);
    }
    const auto t = Clock::now();
    const CandidateList L = d.list(candidates);
    const size_t n = L.size();
    double sum = 0;
    if (n > 0) {
        ensure(d.values, n);
        candidate_energies<<<grid(n), THREADS>>>(L, d_y, d.active_radius(), d.settings.min_distance,
            pair_model(d.settings.penalty, d.settings.dhat, d.settings.min_distance), d.values.data());
        check_launch("launch of the candidate barrier energies");
        deterministic_sum(d.values.data(), n, d.partials.data(), d.scalar.data());
        detail::copy_device_to_host(&sum, d.scalar.data(), sizeof(double));
    }
    const double before = d.times.barrier;
    add_time(t, d.times.barrier);
    d.times.energies += d.times.barrier - before;
    ++d.times.energy_count;
    return std::isfinite(sum) ? d.settings.kappa * sum : INF;
}

int DeviceContact::update_active(const double* d_x)
{
    Impl& d = *m_impl;
    auto t = Clock::now();
    const DeviceCandidates candidates = d.broad_phase.find(d_x, d_x, d.active_radius());
    add_time(t, d.times.broad_phase);
    t = Clock::now();
    const CandidateList L = d.list(candidates);
    const size_t n = L.size();
    d.num_active = 0;
    d.min_gap2 = INF;
    if (n > 0) {
        if (n > size_t(std::numeric_limits<int>::max()))
            throw std::runtime_error("DeviceContact: more candidate pairs than an int counts");
        ensure(d.flags, n);
        ensure(d.values, n);
        ensure(d.kept, n);
        classify_candidates<<<grid(n), THREADS>>>(
            L, d_x, d.active_radius(), d.settings.min_distance, d.flags.data(), d.values.data());
        check_launch("launch of the contact classification");
        // The active candidates' indices, in candidate order (a stable compaction).
        thrust::counting_iterator<int> indices(0);
        size_t bytes = 0;
        check_cuda(cub::DeviceSelect::Flagged(
                       nullptr, bytes, indices, d.flags.data(), d.kept.data(), d.kept_count.data(), int(n)),
            "cub::DeviceSelect::Flagged (size query)");
        ensure(d.cub_temp, bytes);
        check_cuda(cub::DeviceSelect::Flagged(
                       d.cub_temp.data(), bytes, indices, d.flags.data(), d.kept.data(), d.kept_count.data(), int(n)),
            "cub::DeviceSelect::Flagged of the active pairs");
        d.min_gap2 = d.minimum(n);
        detail::copy_device_to_host(&d.num_active, d.kept_count.data(), sizeof(int));
        if (d.num_active > 0) {
            ensure(d.kept_pairs, size_t(d.num_active) * 6);
            gather_pairs<<<grid(size_t(d.num_active)), THREADS>>>(L, d.kept.data(), d.num_active, d.kept_pairs.data());
            check_launch("launch of the active pairs' gather");
        }
    }
    // The pairs are prepared on the device; the host copy is made on request (active_pairs()).
    d.barrier.set_pairs_device(d.kept_pairs.data(), d.num_active);
    d.active_downloaded = false;
    d.hessian = d.barrier.make_hessian_matrix();
    const double before = d.times.barrier;
    add_time(t, d.times.barrier);
    d.times.active_sets += d.times.barrier - before;
    ++d.times.active_set_count;
    return d.num_active;
}

int DeviceContact::num_active() const { return m_impl->num_active; }

const std::vector<BarrierPair>& DeviceContact::active_pairs() const
{
    Impl& d = *m_impl;
    if (!d.active_downloaded) {
        std::vector<int> host(size_t(d.num_active) * 6);
        if (!host.empty())
            detail::copy_device_to_host(host.data(), d.kept_pairs.data(), host.size() * sizeof(int));
        d.active.resize(size_t(d.num_active));
        for (int p = 0; p < d.num_active; ++p) {
            const int* o = host.data() + size_t(p) * 6;
            BarrierPair& q = d.active[size_t(p)];
            q.kind = o[0];
            for (int a = 0; a < 4; ++a)
                q.vertices[a] = o[1 + a];
            q.plane = o[5];
        }
        d.active_downloaded = true;
    }
    return d.active;
}
double DeviceContact::min_active_gap_squared() const { return m_impl->min_gap2; }

void DeviceContact::add_gradient(const double* d_x, double weight, double* d_g) const
{
    const auto t = Clock::now();
    m_impl->barrier.add_gradient_device(d_x, weight, d_g);
    add_time(t, m_impl->times.barrier);
}

void DeviceContact::add_barrier_gradient(const double* d_x, double weight, double* d_g) const
{
    const double kappa = m_impl->settings.kappa;
    if (!(kappa > 0))
        throw std::logic_error("DeviceContact::add_barrier_gradient: kappa must be positive");
    m_impl->barrier.add_gradient_device(d_x, weight / kappa, d_g);
}

void DeviceContact::assemble_hessian(const double* d_x, double weight, bool project)
{
    Impl& d = *m_impl;
    const auto t = Clock::now();
    d.hessian.set_zero();
    d.barrier.add_hessian_device(d_x, weight, project, d.hessian);
    add_time(t, d.times.barrier);
}

const DeviceBsrMatrix& DeviceContact::hessian() const { return m_impl->hessian; }

StepBoundResult DeviceContact::max_step(const double* d_x, const double* d_p)
{
    if (m_impl->settings.penalty)
        return StepBoundResult {}; // the penalty baseline has no CCD: every step is admissible (alpha 1)
    const auto t = Clock::now();
    StepBoundResult r = m_impl->bound.max_step(d_x, d_p);
    add_time(t, m_impl->times.ccd);
    return r;
}

double DeviceContact::min_distance(const double* d_x, double radius)
{
    Impl& d = *m_impl;
    const double r = std::max(radius, d.active_radius());
    auto t = Clock::now();
    const DeviceCandidates candidates = d.broad_phase.find(d_x, d_x, r);
    add_time(t, d.times.broad_phase);
    t = Clock::now();
    const CandidateList L = d.list(candidates);
    const size_t n = L.size();
    double best = INF;
    if (n > 0) {
        ensure(d.values, n);
        candidate_distances<<<grid(n), THREADS>>>(L, d_x, r, d.settings.min_distance, d.values.data());
        check_launch("launch of the candidate distances");
        best = d.minimum(n);
    }
    add_time(t, d.times.barrier);
    return best;
}

const DeviceContactTimes& DeviceContact::times() const { return m_impl->times; }
void DeviceContact::reset_times() { m_impl->times = {}; }

} // namespace diffipc::gpu
