#include "forward/io/trajectory_writer.hpp"

#include "forward/common/error.hpp"
#include "forward/io/hdf5_columns.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <type_traits>
#include <vector>

namespace diffipc {

namespace {

    /// One extendible dataset: rows of `row` shape along an unlimited first axis.
    struct Column {
        std::string name;
        hid_t type; // H5T_NATIVE_DOUBLE or H5T_NATIVE_INT
        std::vector<hsize_t> row; // trailing dimensions (empty: a scalar per row)
        bool state; // one row per state (the initial one first), else one per step
        std::function<const void*(const StepRecord&)> data;
        hid_t set = -1;
        hsize_t rows = 0; // rows in the file
        std::vector<unsigned char> pending; // rows appended since the last write, not yet in the file
        hsize_t pending_rows = 0;

        Column(std::string name_, hid_t type_, std::vector<hsize_t> row_, bool state_,
            std::function<const void*(const StepRecord&)> data_)
            : name(std::move(name_))
            , type(type_)
            , row(std::move(row_))
            , state(state_)
            , data(std::move(data_))
        {
        }
    };

    hsize_t row_size(const std::vector<hsize_t>& row)
    {
        hsize_t n = 1;
        for (hsize_t r : row)
            n *= r;
        return n;
    }

} // namespace

struct TrajectoryWriter::Impl {
    std::string path;
    hid_t file = -1;
    bool swmr = false;
    int steps = 0;
    std::vector<Column> columns;
    // Scalars of the step being appended, converted to the stored types.
    int status = 0;
    Index state_size = 0; // #V * dim: every state row

    /// The rows copy state_size values from each state vector: they must have that many.
    void check_state(const StepRecord& r, const std::string& what) const
    {
        if (r.positions.size() != state_size || r.velocities.size() != state_size
            || r.accelerations.size() != state_size)
            throw std::logic_error("TrajectoryWriter: " + what + " has state vectors of the wrong size (expected "
                + std::to_string(state_size) + " values each)");
    }

    [[noreturn]] void fail(const std::string& what) const
    {
        throw InputError(path, what + " (is the disk full or the file removed?)");
    }

    void create(Column& c)
    {
        std::vector<hsize_t> dims { 0 }, max { H5S_UNLIMITED }, chunk { 0 };
        dims.insert(dims.end(), c.row.begin(), c.row.end());
        max.insert(max.end(), c.row.begin(), c.row.end());
        chunk.insert(chunk.end(), c.row.begin(), c.row.end());
        // About 64 KB per chunk, at least one row.
        chunk[0] = std::max<hsize_t>(1, 8192 / std::max<hsize_t>(1, row_size(c.row)));
        const hid_t space = H5Screate_simple(int(dims.size()), dims.data(), max.data());
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        H5Pset_chunk(dcpl, int(chunk.size()), chunk.data());
        c.set = H5Dcreate2(file, c.name.c_str(), c.type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
        H5Pclose(dcpl);
        H5Sclose(space);
        if (c.set < 0)
            fail("cannot create dataset '" + c.name + "'");
    }

    static size_t type_size(hid_t type) { return type == H5T_NATIVE_INT ? sizeof(int) : sizeof(double); }

    /// Queues one row; the rows reach the file in batches (write_pending), which keeps
    /// HDF5's per-call cost off runs of many small steps.
    void append_row(Column& c, const void* data)
    {
        const size_t bytes = size_t(row_size(c.row)) * type_size(c.type);
        const auto* begin = static_cast<const unsigned char*>(data);
        c.pending.insert(c.pending.end(), begin, begin + bytes);
        ++c.pending_rows;
    }

    void write_pending(Column& c)
    {
        if (c.pending_rows == 0)
            return;
        std::vector<hsize_t> dims { c.rows + c.pending_rows }, start { c.rows }, count { c.pending_rows };
        dims.insert(dims.end(), c.row.begin(), c.row.end());
        start.insert(start.end(), c.row.size(), 0);
        count.insert(count.end(), c.row.begin(), c.row.end());
        if (H5Dset_extent(c.set, dims.data()) < 0)
            fail("cannot extend dataset '" + c.name + "'");
        const hid_t file_space = H5Dget_space(c.set);
        const hid_t memory_space = H5Screate_simple(int(count.size()), count.data(), nullptr);
        herr_t status = H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
        if (status >= 0)
            status = H5Dwrite(c.set, c.type, memory_space, file_space, H5P_DEFAULT, c.pending.data());
        H5Sclose(memory_space);
        H5Sclose(file_space);
        if (status < 0)
            fail("cannot write dataset '" + c.name + "'");
        c.rows += c.pending_rows;
        c.pending_rows = 0;
        c.pending.clear();
    }

    void write_all_pending()
    {
        for (Column& c : columns)
            write_pending(c);
    }

    /// Steps held back before a batch write: up to 64, and at most about 4 MB.
    hsize_t batch_rows() const
    {
        size_t bytes = 0;
        for (const Column& c : columns)
            bytes += size_t(row_size(c.row)) * type_size(c.type);
        return std::max<hsize_t>(1, std::min<hsize_t>(64, hsize_t((4u << 20) / std::max<size_t>(1, bytes))));
    }

    void write_fixed(
        hid_t group, const std::string& name, hid_t type, const std::vector<hsize_t>& dims, const void* data)
    {
        const hid_t space = H5Screate_simple(int(dims.size()), dims.data(), nullptr);
        const hid_t set = H5Dcreate2(group, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        herr_t status = -1;
        if (set >= 0) {
            status = H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
            H5Dclose(set);
        }
        H5Sclose(space);
        if (status < 0)
            fail("cannot write dataset '" + name + "'");
    }

    void write_attribute(const std::string& name, const std::string& value)
    {
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, std::max<size_t>(1, value.size()));
        H5Tset_strpad(type, H5T_STR_NULLTERM);
        const hid_t space = H5Screate(H5S_SCALAR);
        const hid_t attribute = H5Acreate2(file, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT);
        herr_t status = -1;
        if (attribute >= 0) {
            status = H5Awrite(attribute, type, value.empty() ? "" : value.c_str());
            H5Aclose(attribute);
        }
        H5Sclose(space);
        H5Tclose(type);
        if (status < 0)
            fail("cannot write attribute '" + name + "'");
    }

    /// Closes everything; returns false if a close failed (data not on disk).
    bool close_all() { return close_hdf5_columns(columns, file); }
};

TrajectoryWriter::TrajectoryWriter(const std::string& path, const Mesh& mesh, const Trajectory& initial, bool contact,
    const std::vector<std::pair<std::string, std::string>>& attributes, bool load_stepping)
    : m_impl(std::make_unique<Impl>())
{
    Impl& m = *m_impl;
    m.path = path;
    // Failures are reported as InputError naming the file, not as HDF5's error stack on stderr.
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    H5Pset_libver_bounds(fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST); // needed by SWMR
    m.file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
    H5Pclose(fapl);
    if (m.file < 0)
        throw InputError(path, "cannot create HDF5 file");
    try {
        const hsize_t N = hsize_t(mesh.num_vertices()), d = hsize_t(mesh.dim);
        const auto vec = [](const VectorXd StepRecord::*member) {
            return [member](const StepRecord& r) -> const void* { return (r.*member).data(); };
        };
        const auto dbl = [](const double StepRecord::*member) {
            return [member](const StepRecord& r) -> const void* { return &(r.*member); };
        };
        const auto integer = [](const int StepRecord::*member) {
            return [member](const StepRecord& r) -> const void* { return &(r.*member); };
        };
        const hid_t D = H5T_NATIVE_DOUBLE, I = H5T_NATIVE_INT;
        Impl* impl = &m;
        m.columns = {
            { "time", D, {}, true, dbl(&StepRecord::time) },
            { "positions", D, { N, d }, true, vec(&StepRecord::positions) },
            { "velocities", D, { N, d }, true, vec(&StepRecord::velocities) },
            { "accelerations", D, { N, d }, true, vec(&StepRecord::accelerations) },
            { "status", I, {}, false, [impl](const StepRecord&) -> const void* { return &impl->status; } },
            { "newton_iterations", I, {}, false, integer(&StepRecord::newton_iterations) },
            { "line_search_cuts", I, {}, false, integer(&StepRecord::line_search_cuts) },
            { "residual", D, {}, false, dbl(&StepRecord::residual) },
            { "newton_step", D, {}, false, dbl(&StepRecord::newton_step) },
            { "min_volume_ratio", D, {}, false, dbl(&StepRecord::min_volume_ratio) },
            { "wall_time", D, {}, false, dbl(&StepRecord::wall_time) },
        };
        if (contact) {
            m.columns.push_back({ "friction_residual", D, {}, false, dbl(&StepRecord::friction_residual) });
            m.columns.push_back(
                { "ccd_time", D, {}, false, [](const StepRecord& r) -> const void* { return &r.phases.ccd; } });
            m.columns.push_back({ "broad_phase_time", D, {}, false,
                [](const StepRecord& r) -> const void* { return &r.phases.broad_phase; } });
            m.columns.push_back({ "min_distance", D, {}, false, dbl(&StepRecord::min_distance) });
            m.columns.push_back({ "active_contacts", I, {}, false, integer(&StepRecord::active_contacts) });
            m.columns.push_back({ "kappa", D, {}, false, dbl(&StepRecord::kappa) });
        }
        if (initial.macro_dim > 0) {
            const hsize_t dm = hsize_t(initial.macro_dim);
            m.columns.push_back({ "macro_gradient", D, { dm, dm }, false, vec(&StepRecord::macro_gradient) });
            m.columns.push_back({ "macro_stress", D, { dm, dm }, false, vec(&StepRecord::macro_stress) });
        }
        if (load_stepping) {
            m.columns.push_back({ "substeps", I, {}, false, integer(&StepRecord::substeps) });
            m.columns.push_back({ "cuts", I, {}, false, integer(&StepRecord::cuts) });
            m.columns.push_back({ "min_increment", D, {}, false, dbl(&StepRecord::min_increment) });
            m.columns.push_back({ "control_steps", I, {}, false, integer(&StepRecord::control_steps) });
            m.columns.push_back({ "relaxation_steps", I, {}, false, integer(&StepRecord::relaxation_steps) });
        }
        for (Column& c : m.columns)
            m.create(c);
        // Row 0 of the state datasets: the initial state.
        StepRecord first;
        first.time = initial.initial_time;
        first.positions = initial.initial_positions;
        first.velocities = initial.initial_velocities;
        first.accelerations = initial.initial_accelerations;
        m.state_size = Index(N * d);
        m.check_state(first, "the initial state");
        for (Column& c : m.columns)
            if (c.state)
                m.append_row(c, c.data(first));

        const hid_t group = H5Gcreate2(m.file, "mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        if (group < 0)
            m.fail("cannot create group 'mesh'");
        m.write_fixed(group, "rest_positions", D, { N, d }, mesh.rest_positions.data());
        m.write_fixed(group, "elements", I, { hsize_t(mesh.num_elements()), d + 1 }, mesh.elements.data());
        m.write_fixed(group, "body", I, { N }, mesh.vertex_body.data());
        m.write_fixed(group, "element_body", I, { hsize_t(mesh.num_elements()) }, mesh.element_body.data());
        H5Gclose(group);
        for (const auto& [name, value] : attributes)
            m.write_attribute(name, value);
        // From here on the structure is fixed and readers may open the file at any time.
        if (H5Fstart_swmr_write(m.file) < 0)
            m.fail("cannot start single-writer/multiple-reader mode");
        m.swmr = true;
        flush();
    } catch (...) {
        m.close_all();
        throw;
    }
}

TrajectoryWriter::~TrajectoryWriter()
{
    if (m_impl)
        m_impl->close_all();
}

void TrajectoryWriter::append(const StepRecord& record)
{
    Impl& m = *m_impl;
    if (m.file < 0)
        throw std::logic_error("TrajectoryWriter::append after close");
    if (!record.holds_state())
        throw std::logic_error("TrajectoryWriter::append: the record of step " + std::to_string(record.index)
            + " does not hold its state");
    m.check_state(record, "step " + std::to_string(record.index));
    m.status = int(record.status);
    for (Column& c : m.columns)
        m.append_row(c, c.data(record));
    ++m.steps;
    if (m.columns.back().pending_rows >= m.batch_rows())
        m.write_all_pending();
}

void TrajectoryWriter::flush()
{
    Impl& m = *m_impl;
    if (m.file < 0)
        return;
    m.write_all_pending();
    if (H5Fflush(m.file, H5F_SCOPE_LOCAL) < 0)
        m.fail("cannot flush the HDF5 file");
}

void TrajectoryWriter::close()
{
    Impl& m = *m_impl;
    if (m.file < 0)
        return;
    try {
        flush();
    } catch (...) {
        m.close_all();
        throw;
    }
    if (!m.close_all())
        m.fail("cannot close the HDF5 file");
}

int TrajectoryWriter::steps() const { return m_impl->steps; }
const std::string& TrajectoryWriter::path() const { return m_impl->path; }

void write_hdf5(
    const std::string& path, const Mesh& mesh, const Trajectory& trajectory, bool contact, bool load_stepping)
{
    TrajectoryWriter writer(path, mesh, trajectory, contact, {}, load_stepping);
    for (const StepRecord& r : trajectory.steps)
        writer.append(r);
    writer.close();
}

} // namespace diffipc
