#include "forward/io/output.hpp"

#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iomanip>
#include <limits>

namespace diffipc {

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

namespace {
    /// Writes `path` through a temporary file in the same directory, renamed over it once
    /// complete: a reader (or a run killed meanwhile) sees the old file or the new one,
    /// never half of one. A failed write (a full disk) is an InputError naming the file.
    void write_replacing(const std::string& path, const std::function<void(std::ostream&)>& write)
    {
        const std::string temporary = path + ".tmp";
        {
            std::ofstream out(temporary, std::ios::trunc);
            if (!out)
                throw InputError(path, "cannot write file");
            write(out);
            out.flush();
            if (!out) {
                out.close();
                std::remove(temporary.c_str());
                throw InputError(path, "cannot write file (is the disk full?)");
            }
            out.close();
            if (out.fail()) {
                std::remove(temporary.c_str());
                throw InputError(path, "cannot write file (is the disk full?)");
            }
        }
        if (std::rename(temporary.c_str(), path.c_str()) != 0) {
            std::remove(temporary.c_str());
            throw InputError(path, "cannot replace file");
        }
    }
} // namespace

void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& entries)
{
    write_replacing(path, [&](std::ostream& out) {
        out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
        for (const auto& [t, file] : entries)
            out << "<DataSet timestep=\"" << std::setprecision(12) << t << "\" file=\"" << file << "\"/>\n";
        out << "</Collection>\n</VTKFile>\n";
    });
}

nlohmann::json summary_json(const Simulator& simulator)
{
    const Trajectory& tr = simulator.trajectory();
    nlohmann::json j;
    j["status"] = to_string(tr.final_status);
    j["scene"] = simulator.scene().source;
    j["steps_requested"] = simulator.scene().time.steps;
    j["steps_committed"] = tr.committed();
    if (tr.failed_step > 0) {
        j["failed_step"] = tr.failed_step;
        j["failure"] = tr.failure_message;
    }
    j["counts"] = { { "vertices", simulator.mesh().num_vertices() }, { "elements", simulator.mesh().num_elements() },
        { "dofs", simulator.mesh().num_dofs() }, { "bodies", simulator.scene().bodies.size() },
        { "newton_iterations", tr.newton_iterations } };
    const StepTotals& totals = tr.totals;
    j["min_volume_ratio"] = totals.min_volume_ratio;
    j["max_residual"] = totals.max_residual;
    j["linear_fallbacks"] = totals.linear_fallbacks;
    j["roundoff_limited_steps"] = totals.roundoff_limited_steps;
    j["threads"] = to_json(thread_config());
    j["wall_time"]
        = { { "total", tr.wall_time }, { "assembly", tr.phases.assembly }, { "factorization", tr.phases.factorization },
              { "solve", tr.phases.solve }, { "line_search", tr.phases.line_search } };
    if (simulator.contact()) {
        const double min_distance = totals.min_distance;
        const int max_active = totals.max_active_contacts;
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
    write_replacing(path, [&](std::ostream& out) { out << value.dump(2) << '\n'; });
}

} // namespace diffipc
