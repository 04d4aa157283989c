#include "forward/io/trajectory_reader.hpp"

#include "forward/common/error.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cstring>
#include <type_traits>
#include <vector>

namespace diffipc {

namespace {

    /// An open trajectory file (read-only, SWMR), closed on every path out.
    class File {
    public:
        explicit File(const std::string& path)
            : m_path(path)
        {
            // Failures are reported as InputError naming the file, not as HDF5's error stack.
            H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
            m_id = H5Fopen(path.c_str(), H5F_ACC_RDONLY | H5F_ACC_SWMR_READ, H5P_DEFAULT);
            if (m_id < 0)
                throw InputError(path, "cannot open the trajectory (missing, or not an HDF5 file)");
        }
        ~File() { H5Fclose(m_id); }
        File(const File&) = delete;
        File& operator=(const File&) = delete;

        bool has(const char* name) const { return H5Lexists(m_id, name, H5P_DEFAULT) > 0; }

        /// Dimensions of dataset `name`.
        std::vector<hsize_t> dims(const std::string& name) const
        {
            const hid_t set = open(name);
            const hid_t space = H5Dget_space(set);
            const int rank = H5Sget_simple_extent_ndims(space);
            std::vector<hsize_t> out(size_t(std::max(rank, 0)));
            if (rank > 0)
                H5Sget_simple_extent_dims(space, out.data(), nullptr);
            H5Sclose(space);
            H5Dclose(set);
            if (rank < 0)
                throw InputError(m_path, "cannot read dataset '" + name + "'");
            return out;
        }

        /// Rows first .. first + rows - 1 (along the first axis) of dataset `name`, all of
        /// it if rows < 0.
        template <typename T> std::vector<T> read(const std::string& name, hsize_t first = 0, long rows = -1) const
        {
            const std::vector<hsize_t> extent = dims(name);
            if (extent.empty())
                throw InputError(m_path, "not a diffipc trajectory: dataset '" + name + "' has no rows");
            std::vector<hsize_t> start(extent.size(), 0), count = extent;
            start[0] = first;
            count[0] = rows < 0 ? extent[0] - std::min(first, extent[0]) : hsize_t(rows);
            if (first + count[0] > extent[0])
                throw InputError(m_path, "dataset '" + name + "' has fewer rows than the trajectory's steps");
            hsize_t values = 1;
            for (hsize_t c : count)
                values *= c;
            std::vector<T> out(static_cast<size_t>(values));
            if (values == 0)
                return out;
            const hid_t set = open(name);
            const hid_t file_space = H5Dget_space(set);
            const hid_t memory_space = H5Screate_simple(int(count.size()), count.data(), nullptr);
            herr_t status
                = H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
            const hid_t type = std::is_same_v<T, int> ? H5T_NATIVE_INT : H5T_NATIVE_DOUBLE;
            if (status >= 0)
                status = H5Dread(set, type, memory_space, file_space, H5P_DEFAULT, out.data());
            H5Sclose(memory_space);
            H5Sclose(file_space);
            H5Dclose(set);
            if (status < 0)
                throw InputError(m_path, "cannot read dataset '" + name + "'");
            return out;
        }

        /// The root attribute `name`, "" if absent.
        std::string attribute(const char* name) const
        {
            if (H5Aexists(m_id, name) <= 0)
                return "";
            const hid_t attribute = H5Aopen(m_id, name, H5P_DEFAULT);
            const hid_t type = H5Aget_type(attribute);
            std::string value(H5Tget_size(type), '\0');
            H5Aread(attribute, type, value.data());
            value.resize(std::strlen(value.c_str()));
            H5Tclose(type);
            H5Aclose(attribute);
            return value;
        }

    private:
        hid_t open(const std::string& name) const
        {
            const hid_t set = H5Dopen2(m_id, name.c_str(), H5P_DEFAULT);
            if (set < 0)
                throw InputError(m_path, "not a diffipc trajectory: no dataset '" + name + "'");
            return set;
        }

        std::string m_path;
        hid_t m_id = -1;
    };

    /// States (positions, velocities, accelerations) of file rows first .. first + rows - 1,
    /// given to `use(row, x, v, a)`; a row that is not finite is an error naming its step.
    template <typename Use>
    void read_state_rows(const File& file, const StoredTrajectory& st, hsize_t first, hsize_t rows, Use use)
    {
        const Index size = st.vertices * st.dim;
        const std::vector<double> x = file.read<double>("positions", first, long(rows));
        const std::vector<double> v = file.read<double>("velocities", first, long(rows));
        const std::vector<double> a = file.read<double>("accelerations", first, long(rows));
        for (hsize_t k = 0; k < rows; ++k) {
            const auto state = [&](const std::vector<double>& data) {
                return VectorXd(Eigen::Map<const VectorXd>(data.data() + k * size_t(size), size));
            };
            VectorXd xk = state(x), vk = state(v);
            if (!xk.allFinite() || !vk.allFinite())
                throw InputError(st.path,
                    first + k == 0 ? std::string("the initial state is not finite")
                                   : "step " + std::to_string(first + k) + " is not a converged, finite state");
            use(first + k, std::move(xk), std::move(vk), state(a));
        }
    }

} // namespace

StoredTrajectory read_trajectory(const std::string& path, int last_states)
{
    const File file(path);
    StoredTrajectory out;
    out.path = path;
    const std::vector<double> time = file.read<double>("time");
    if (time.empty())
        throw InputError(path, "not a diffipc trajectory: 'time' is empty");
    const std::vector<hsize_t> dims = file.dims("positions");
    if (dims.size() != 3 || dims[0] < 1)
        throw InputError(path, "not a diffipc trajectory: 'positions' is not [T+1, N, d]");
    const std::vector<int> status = file.read<int>("status");
    const std::vector<int> iterations = file.read<int>("newton_iterations");
    // Files written before the line search's cuts were recorded lack them (read as 0).
    const std::vector<int> cuts_ls
        = file.has("line_search_cuts") ? file.read<int>("line_search_cuts") : std::vector<int>();
    const std::vector<double> residual = file.read<double>("residual");
    const std::vector<double> newton_step = file.read<double>("newton_step");
    const std::vector<double> volume = file.read<double>("min_volume_ratio");
    const std::vector<double> wall = file.read<double>("wall_time");
    out.contact = file.has("kappa");
    std::vector<double> kappa, min_distance, friction_residual;
    std::vector<int> active;
    if (out.contact) {
        kappa = file.read<double>("kappa");
        min_distance = file.read<double>("min_distance");
        active = file.read<int>("active_contacts");
        friction_residual = file.read<double>("friction_residual");
    }
    // A file read while (or after) its writer appended may have datasets one batch apart:
    // the steps are those that every dataset has.
    size_t T = std::min({ size_t(dims[0]) - 1, time.size() - 1, status.size(), iterations.size(), residual.size(),
        newton_step.size(), volume.size(), wall.size() });
    for (const char* name : { "velocities", "accelerations" }) {
        const std::vector<hsize_t> d = file.dims(name);
        if (d.size() != 3 || d[0] < 1 || d[1] != dims[1] || d[2] != dims[2])
            throw InputError(path, std::string("not a diffipc trajectory: '") + name + "' is not [T+1, N, d]");
        T = std::min(T, size_t(d[0]) - 1);
    }
    if (out.contact)
        T = std::min({ T, kappa.size(), min_distance.size(), active.size(), friction_residual.size() });
    if (!cuts_ls.empty())
        T = std::min(T, cuts_ls.size());
    // Automatic load stepping (written when the scene enables it).
    std::vector<int> substeps, cuts, control_steps, relaxation_steps;
    std::vector<double> min_increment;
    if (file.has("substeps")) {
        substeps = file.read<int>("substeps");
        cuts = file.read<int>("cuts");
        min_increment = file.read<double>("min_increment");
        T = std::min({ T, substeps.size(), cuts.size(), min_increment.size() });
        if (file.has("control_steps")) { // files written before displacement control lack it
            control_steps = file.read<int>("control_steps");
            relaxation_steps = file.read<int>("relaxation_steps");
            T = std::min({ T, control_steps.size(), relaxation_steps.size() });
        }
    }
    // Periodic cells: G and the cell-average stress per step, d^2 values each.
    std::vector<double> macro_gradient, macro_stress;
    const size_t dd = size_t(dims[2] * dims[2]);
    if (file.has("macro_gradient")) {
        macro_gradient = file.read<double>("macro_gradient");
        macro_stress = file.read<double>("macro_stress");
        T = std::min({ T, macro_gradient.size() / dd, macro_stress.size() / dd });
    }
    out.vertices = Index(dims[1]);
    out.dim = int(dims[2]);

    Trajectory& tr = out.trajectory;
    tr.initial_time = time[0];
    tr.macro_dim = macro_gradient.empty() ? 0 : out.dim;
    read_state_rows(file, out, 0, 1, [&](hsize_t, VectorXd x, VectorXd v, VectorXd a) {
        tr.initial_positions = std::move(x);
        tr.initial_velocities = std::move(v);
        tr.initial_accelerations = std::move(a);
    });
    for (size_t k = 1; k <= T; ++k) {
        StepRecord r;
        r.index = int(k);
        r.time = time[k];
        r.status = StepStatus(status[k - 1]);
        r.newton_iterations = iterations[k - 1];
        r.line_search_cuts = cuts_ls.empty() ? 0 : cuts_ls[k - 1];
        r.residual = residual[k - 1];
        r.newton_step = newton_step[k - 1];
        r.min_volume_ratio = volume[k - 1];
        r.wall_time = wall[k - 1];
        if (out.contact) {
            r.kappa = kappa[k - 1];
            r.min_distance = min_distance[k - 1];
            r.active_contacts = active[k - 1];
            r.friction_residual = friction_residual[k - 1];
        }
        if (!substeps.empty()) {
            r.substeps = substeps[k - 1];
            r.cuts = cuts[k - 1];
            r.min_increment = min_increment[k - 1];
            r.control_steps = control_steps.empty() ? 0 : control_steps[k - 1];
            r.relaxation_steps = relaxation_steps.empty() ? 0 : relaxation_steps[k - 1];
        }
        if (!macro_gradient.empty()) {
            r.macro_gradient = Eigen::Map<const VectorXd>(macro_gradient.data() + (k - 1) * dd, Index(dd));
            r.macro_stress = Eigen::Map<const VectorXd>(macro_stress.data() + (k - 1) * dd, Index(dd));
        }
        if (r.status != StepStatus::CONVERGED)
            throw InputError(path, "step " + std::to_string(k) + " is not a converged, finite state");
        tr.newton_iterations += r.newton_iterations;
        tr.wall_time += r.wall_time;
        tr.totals.add(r);
        tr.steps.push_back(std::move(r));
    }
    const int kept = last_states < 0 ? int(T) : std::min(last_states, int(T));
    if (kept > 0)
        read_states(out, int(T) - kept + 1, int(T));
    out.scene = file.attribute("scene");
    return out;
}

void read_states(StoredTrajectory& stored, int first, int last)
{
    Trajectory& tr = stored.trajectory;
    if (first < 1 || last > tr.committed() || first > last)
        throw std::out_of_range("read_states: steps " + std::to_string(first) + " .. " + std::to_string(last)
            + " of a trajectory of " + std::to_string(tr.committed()));
    const File file(stored.path);
    read_state_rows(
        file, stored, hsize_t(first), hsize_t(last - first + 1), [&](hsize_t k, VectorXd x, VectorXd v, VectorXd a) {
            StepRecord& r = tr.step(int(k));
            r.positions = std::move(x);
            r.velocities = std::move(v);
            r.accelerations = std::move(a);
        });
}

} // namespace diffipc
