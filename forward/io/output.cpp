#include "forward/io/output.hpp"

#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"

#include <Eigen/Dense>
#include <hdf5.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>

namespace diffipc {

namespace {

    class H5File {
    public:
        explicit H5File(const std::string& path)
            : m_path(path)
        {
            m_id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
            if (m_id < 0)
                throw InputError(path, "cannot create HDF5 file");
        }
        ~H5File()
        {
            if (m_id >= 0)
                H5Fclose(m_id);
        }
        hid_t id() const { return m_id; }
        const std::string& path() const { return m_path; }

    private:
        std::string m_path;
        hid_t m_id = -1;
    };

    template <typename T> hid_t h5_type();
    template <> hid_t h5_type<double>() { return H5T_NATIVE_DOUBLE; }
    template <> hid_t h5_type<int>() { return H5T_NATIVE_INT; }

    template <typename T>
    void write_dataset(
        const H5File& file, hid_t group, const std::string& name, const std::vector<hsize_t>& dims, const T* data)
    {
        const hid_t space = H5Screate_simple(int(dims.size()), dims.data(), nullptr);
        const hid_t set = H5Dcreate2(group, name.c_str(), h5_type<T>(), space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        herr_t status = -1;
        if (set >= 0) {
            status = H5Dwrite(set, h5_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
            H5Dclose(set);
        }
        H5Sclose(space);
        if (status < 0)
            throw InputError(file.path(), "cannot write dataset '" + name + "'");
    }

} // namespace

void write_hdf5(const std::string& path, const Mesh& mesh, const Trajectory& trajectory, bool contact)
{
    H5File file(path);
    const hid_t root = file.id();
    const hsize_t T = trajectory.steps.size(), N = hsize_t(mesh.num_vertices()), d = hsize_t(mesh.dim);

    std::vector<double> time { trajectory.initial_time };
    std::vector<double> positions(
        trajectory.initial_positions.data(), trajectory.initial_positions.data() + trajectory.initial_positions.size());
    std::vector<double> velocities(trajectory.initial_velocities.data(),
        trajectory.initial_velocities.data() + trajectory.initial_velocities.size());
    std::vector<int> status, iterations;
    std::vector<double> residual, step, volume, wall;
    for (const auto& s : trajectory.steps) {
        time.push_back(s.time);
        positions.insert(positions.end(), s.positions.data(), s.positions.data() + s.positions.size());
        velocities.insert(velocities.end(), s.velocities.data(), s.velocities.data() + s.velocities.size());
        status.push_back(int(s.status));
        iterations.push_back(s.newton_iterations);
        residual.push_back(s.residual);
        step.push_back(s.newton_step);
        volume.push_back(s.min_volume_ratio);
        wall.push_back(s.wall_time);
    }
    write_dataset(file, root, "time", { T + 1 }, time.data());
    write_dataset(file, root, "positions", { T + 1, N, d }, positions.data());
    write_dataset(file, root, "velocities", { T + 1, N, d }, velocities.data());
    write_dataset(file, root, "status", { T }, status.data());
    write_dataset(file, root, "newton_iterations", { T }, iterations.data());
    write_dataset(file, root, "residual", { T }, residual.data());
    write_dataset(file, root, "newton_step", { T }, step.data());
    write_dataset(file, root, "min_volume_ratio", { T }, volume.data());
    write_dataset(file, root, "wall_time", { T }, wall.data());
    if (contact) {
        std::vector<double> min_distance, kappa, ccd, broad;
        std::vector<int> active;
        for (const auto& s : trajectory.steps) {
            min_distance.push_back(s.min_distance);
            kappa.push_back(s.kappa);
            active.push_back(s.active_contacts);
            ccd.push_back(s.phases.ccd);
            broad.push_back(s.phases.broad_phase);
        }
        std::vector<double> friction_residual;
        for (const auto& s : trajectory.steps)
            friction_residual.push_back(s.friction_residual);
        write_dataset(file, root, "friction_residual", { T }, friction_residual.data());
        write_dataset(file, root, "ccd_time", { T }, ccd.data());
        write_dataset(file, root, "broad_phase_time", { T }, broad.data());
        write_dataset(file, root, "min_distance", { T }, min_distance.data());
        write_dataset(file, root, "active_contacts", { T }, active.data());
        write_dataset(file, root, "kappa", { T }, kappa.data());
    }
    if (!trajectory.steps.empty() && trajectory.steps.front().accelerations.size()) {
        std::vector<double> acc(trajectory.initial_accelerations.data(),
            trajectory.initial_accelerations.data() + trajectory.initial_accelerations.size());
        for (const auto& s : trajectory.steps)
            acc.insert(acc.end(), s.accelerations.data(), s.accelerations.data() + s.accelerations.size());
        write_dataset(file, root, "accelerations", { T + 1, N, d }, acc.data());
    }

    const hid_t group = H5Gcreate2(root, "mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (group < 0)
        throw InputError(path, "cannot create group 'mesh'");
    write_dataset(file, group, "rest_positions", { N, d }, mesh.rest_positions.data());
    write_dataset(file, group, "elements", { hsize_t(mesh.num_elements()), d + 1 }, mesh.elements.data());
    write_dataset(file, group, "body", { N }, mesh.vertex_body.data());
    write_dataset(file, group, "element_body", { hsize_t(mesh.num_elements()) }, mesh.element_body.data());
    H5Gclose(group);
}

void write_vtu(const std::string& path, const Simulator& simulator, const VectorXd& x, const VectorXd& v)
{
    const Mesh& mesh = simulator.mesh();
    const int d = mesh.dim;
    std::ofstream out(path);
    if (!out)
        throw InputError(path, "cannot write VTU file");
    out << std::setprecision(10);
    const Index nv = mesh.num_vertices(), ne = mesh.num_elements();
    out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
        << "<UnstructuredGrid>\n<Piece NumberOfPoints=\"" << nv << "\" NumberOfCells=\"" << ne << "\">\n";
    auto point_vectors = [&](const VectorXd& a, bool relative) {
        for (Index i = 0; i < nv; ++i) {
            for (int c = 0; c < 3; ++c)
                out << (c < d ? a[i * d + c] - (relative ? mesh.rest_positions(i, c) : 0.0) : 0.0) << ' ';
            out << '\n';
        }
    };
    out << "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    point_vectors(x, false);
    out << "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
    for (Index e = 0; e < ne; ++e) {
        for (int a = 0; a <= d; ++a)
            out << mesh.elements(e, a) << ' ';
        out << '\n';
    }
    out << "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
    for (Index e = 0; e < ne; ++e)
        out << (e + 1) * (d + 1) << '\n';
    out << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (Index e = 0; e < ne; ++e)
        out << (d == 2 ? 5 : 10) << '\n';
    out << "</DataArray>\n</Cells>\n<PointData Vectors=\"displacement\">\n"
        << "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    point_vectors(x, true);
    out << "</DataArray>\n<DataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    point_vectors(v, false);
    out << "</DataArray>\n</PointData>\n<CellData>\n<DataArray type=\"Int32\" Name=\"body\" format=\"ascii\">\n";
    for (Index e = 0; e < ne; ++e)
        out << mesh.element_body[e] << '\n';
    out << "</DataArray>\n<DataArray type=\"Float64\" Name=\"volume_ratio\" format=\"ascii\">\n";
    const Positions P = unflatten(x, d);
    for (Index e = 0; e < ne; ++e)
        out << signed_volume(P, mesh.elements, e) / simulator.space().rest_volume(e) << '\n';
    out << "</DataArray>\n<DataArray type=\"Float64\" Name=\"von_mises\" format=\"ascii\">\n";
    // von Mises of the Cauchy stress sigma = P F^T / J.
    const MatrixXd stresses = simulator.elastic().element_stresses(x);
    for (Index e = 0; e < ne; ++e) {
        Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
        Eigen::MatrixXd F(d, d), Pm(d, d);
        simulator.space().deformation_gradient(e, x, F.data());
        F.transposeInPlace(); // row-major fill into a column-major matrix
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                Pm(i, j) = stresses(e, i * d + j);
        sigma.topLeftCorner(d, d) = Pm * F.transpose() / F.determinant();
        const Eigen::Matrix3d dev = sigma - sigma.trace() / 3.0 * Eigen::Matrix3d::Identity();
        out << std::sqrt(1.5 * dev.squaredNorm()) << '\n';
    }
    out << "</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    if (!out)
        throw InputError(path, "error while writing VTU file");
}

void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries)
{
    std::ofstream out(path);
    if (!out)
        throw InputError(path, "cannot write PVD file");
    out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
    for (const auto& [t, file] : entries)
        out << "<DataSet timestep=\"" << std::setprecision(12) << t << "\" file=\"" << file << "\"/>\n";
    out << "</Collection>\n</VTKFile>\n";
}

nlohmann::json summary_json(const Simulator& simulator)
{
    const Trajectory& tr = simulator.trajectory();
    nlohmann::json j;
    j["status"] = to_string(tr.final_status);
    j["scene"] = simulator.scene().source;
    j["steps_requested"] = simulator.scene().time.steps;
    j["steps_committed"] = tr.steps.size();
    if (tr.failed_step > 0) {
        j["failed_step"] = tr.failed_step;
        j["failure"] = tr.failure_message;
    }
    j["counts"] = { { "vertices", simulator.mesh().num_vertices() }, { "elements", simulator.mesh().num_elements() },
        { "dofs", simulator.mesh().num_dofs() }, { "bodies", simulator.scene().bodies.size() },
        { "newton_iterations", tr.newton_iterations } };
    double min_ratio = 1, max_residual = 0;
    int fallbacks = 0, roundoff = 0;
    for (const auto& s : tr.steps) {
        roundoff += s.roundoff_limited;
        min_ratio = std::min(min_ratio, s.min_volume_ratio);
        max_residual = std::max(max_residual, s.residual);
        fallbacks += s.linear_fallbacks;
    }
    j["min_volume_ratio"] = min_ratio;
    j["max_residual"] = max_residual;
    j["linear_fallbacks"] = fallbacks;
    j["roundoff_limited_steps"] = roundoff;
    j["threads"] = to_json(thread_config());
    j["wall_time"]
        = { { "total", tr.wall_time }, { "assembly", tr.phases.assembly }, { "factorization", tr.phases.factorization },
              { "solve", tr.phases.solve }, { "line_search", tr.phases.line_search } };
    if (simulator.contact()) {
        double min_distance = std::numeric_limits<double>::infinity();
        int max_active = 0;
        for (const auto& s : tr.steps) {
            min_distance = std::min(min_distance, s.min_distance);
            max_active = std::max(max_active, s.active_contacts);
        }
        j["contact"] = { { "min_distance",
                             std::isfinite(min_distance) ? nlohmann::json(min_distance) : nlohmann::json(nullptr) },
            { "max_active_contacts", max_active }, { "final_kappa", simulator.contact()->kappa() } };
        j["wall_time"]["broad_phase"] = tr.phases.broad_phase;
        j["wall_time"]["ccd"] = tr.phases.ccd;
        j["wall_time"]["barrier"] = tr.phases.barrier;
    }
    return j;
}

void write_json(const std::string& path, const nlohmann::json& value)
{
    std::ofstream out(path);
    if (!out)
        throw InputError(path, "cannot write file");
    out << value.dump(2) << '\n';
}

} // namespace diffipc
