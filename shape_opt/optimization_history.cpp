#include "shape_opt/optimization_history.hpp"

#include "forward/common/error.hpp"
#include "forward/io/hdf5_columns.hpp"
#include "forward/io/replace_file.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <type_traits>

namespace fs = std::filesystem;

namespace diffipc {

namespace {

    const char* const HISTORY_H5 = "history.h5";
    const char* const HISTORY_CSV = "history.csv";

    /// Per-iteration datasets of history.h5 besides x and constraints, in the CSV's order.
    const char* const DOUBLE_COLUMNS_AFTER[] = { "gradient_norm", "step_norm" };
    const char* const TIME_COLUMNS[] = { "evaluation_seconds", "optimizer_seconds", "wall_seconds" };

    std::string csv_number(double v)
    {
        char text[32];
        std::snprintf(text, sizeof text, "%.17g", v);
        return text;
    }

    /// A CSV field: quoted (RFC 4180) when it holds a comma, a quote or a line break.
    std::string csv_field(const std::string& text)
    {
        if (text.find_first_of(",\"\r\n") == std::string::npos)
            return text;
        std::string out = "\"";
        for (char c : text)
            out += c == '"' ? std::string("\"\"") : std::string(1, c);
        return out + "\"";
    }

    std::string csv_header(const HistoryHeader& header)
    {
        std::string line = "iteration,J";
        for (const std::string& name : header.constraint_names)
            line += "," + csv_field(name);
        return line
            + ",gradient_norm,step_norm,evaluations,rejected,evaluation_seconds,optimizer_seconds,wall_seconds\n";
    }

    std::string csv_row(const HistoryRow& r)
    {
        std::string line = std::to_string(r.iteration) + "," + csv_number(r.J);
        for (Index i = 0; i < r.constraints.size(); ++i)
            line += "," + csv_number(r.constraints[i]);
        line += "," + csv_number(r.gradient_norm) + "," + csv_number(r.step_norm) + "," + std::to_string(r.evaluations)
            + "," + std::to_string(r.rejected) + "," + csv_number(r.evaluation_seconds) + ","
            + csv_number(r.optimizer_seconds) + "," + csv_number(r.wall_seconds) + "\n";
        return line;
    }

    /// An HDF5 identifier closed with `close` when it goes out of scope.
    class Handle {
    public:
        Handle(hid_t id, herr_t (*close)(hid_t))
            : m_id(id)
            , m_close(close)
        {
        }
        ~Handle()
        {
            if (m_id >= 0)
                m_close(m_id);
        }
        Handle(const Handle&) = delete;
        Handle& operator=(const Handle&) = delete;
        operator hid_t() const { return m_id; }
        bool valid() const { return m_id >= 0; }

    private:
        hid_t m_id;
        herr_t (*m_close)(hid_t);
    };

    /// A variable-length UTF-8 string type (h5py reads it as str).
    hid_t string_type()
    {
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, H5T_VARIABLE);
        H5Tset_cset(type, H5T_CSET_UTF8);
        return type;
    }

    bool write_string_attribute(hid_t object, const char* name, const std::string& value)
    {
        const Handle type(string_type(), H5Tclose);
        const Handle space(H5Screate(H5S_SCALAR), H5Sclose);
        const Handle attribute(H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
        const char* text = value.c_str();
        return attribute.valid() && H5Awrite(attribute, type, &text) >= 0;
    }

    bool write_strings_attribute(hid_t object, const char* name, const std::vector<std::string>& values)
    {
        const Handle type(string_type(), H5Tclose);
        const hsize_t count = values.size();
        const Handle space(H5Screate_simple(1, &count, nullptr), H5Sclose);
        const Handle attribute(H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
        std::vector<const char*> texts;
        for (const std::string& v : values)
            texts.push_back(v.c_str());
        const char* none = "";
        return attribute.valid() && H5Awrite(attribute, type, texts.empty() ? &none : texts.data()) >= 0;
    }

    template <typename T> bool write_number_attribute(hid_t object, const char* name, T value)
    {
        const hid_t memory_type = std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_LLONG;
        const hid_t file_type = std::is_same_v<T, double> ? H5T_IEEE_F64LE : H5T_STD_I64LE;
        const Handle space(H5Screate(H5S_SCALAR), H5Sclose);
        const Handle attribute(H5Acreate2(object, name, file_type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
        return attribute.valid() && H5Awrite(attribute, memory_type, &value) >= 0;
    }

    /// Reads attributes and datasets of an open file, naming the file in every error.
    class Reader {
    public:
        Reader(const std::string& path, const std::string& what)
            : m_path(path)
            , m_what(what)
        {
        }

        [[noreturn]] void fail(const std::string& why) const { throw InputError(m_path, why); }

        bool has_attribute(hid_t object, const char* name) const { return H5Aexists(object, name) > 0; }

        std::string string_attribute(hid_t object, const char* name) const
        {
            if (!has_attribute(object, name))
                fail("not " + m_what + ": no attribute '" + name + "'");
            const Handle attribute(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
            const Handle type(H5Aget_type(attribute), H5Tclose);
            if (H5Tget_class(type) != H5T_STRING)
                fail("attribute '" + std::string(name) + "' is not a string");
            if (H5Tis_variable_str(type) > 0) {
                const Handle memory(string_type(), H5Tclose);
                char* text = nullptr;
                if (H5Aread(attribute, memory, &text) < 0)
                    fail("cannot read attribute '" + std::string(name) + "'");
                std::string value = text ? text : "";
                H5free_memory(text);
                return value;
            }
            std::string value(H5Tget_size(type), '\0');
            if (H5Aread(attribute, type, value.data()) < 0)
                fail("cannot read attribute '" + std::string(name) + "'");
            value.resize(std::strlen(value.c_str()));
            return value;
        }

        std::vector<std::string> strings_attribute(hid_t object, const char* name) const
        {
            if (!has_attribute(object, name))
                fail("not " + m_what + ": no attribute '" + name + "'");
            const Handle attribute(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
            const Handle space(H5Aget_space(attribute), H5Sclose);
            const hssize_t count = H5Sget_simple_extent_npoints(space);
            if (count < 0)
                fail("cannot read attribute '" + std::string(name) + "'");
            std::vector<std::string> values;
            if (count == 0)
                return values;
            const Handle memory(string_type(), H5Tclose);
            std::vector<char*> texts(size_t(count), nullptr);
            if (H5Aread(attribute, memory, texts.data()) < 0)
                fail("cannot read attribute '" + std::string(name) + "' (expected variable-length strings)");
            for (char* t : texts)
                values.push_back(t ? t : "");
            H5Dvlen_reclaim(memory, space, H5P_DEFAULT, texts.data());
            return values;
        }

        template <typename T> T number_attribute(hid_t object, const char* name) const
        {
            if (!has_attribute(object, name))
                fail("not " + m_what + ": no attribute '" + name + "'");
            const Handle attribute(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
            T value {};
            const hid_t memory_type = std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_LLONG;
            if (H5Aread(attribute, memory_type, &value) < 0)
                fail("cannot read attribute '" + std::string(name) + "'");
            return value;
        }

        std::vector<hsize_t> dims(hid_t object, const std::string& name) const
        {
            if (H5Lexists(object, name.c_str(), H5P_DEFAULT) <= 0)
                fail("not " + m_what + ": no dataset '" + name + "'");
            const Handle set(H5Dopen2(object, name.c_str(), H5P_DEFAULT), H5Dclose);
            const Handle space(H5Dget_space(set), H5Sclose);
            const int rank = H5Sget_simple_extent_ndims(space);
            if (rank < 0)
                fail("cannot read dataset '" + name + "'");
            std::vector<hsize_t> out(static_cast<size_t>(rank));
            if (rank > 0)
                H5Sget_simple_extent_dims(space, out.data(), nullptr);
            return out;
        }

        /// The first `rows` rows of dataset `name` (all of it when rows < 0), row-major.
        template <typename T>
        std::vector<T> read(
            hid_t object, const std::string& name, const std::vector<hsize_t>& expected_trailing, long rows = -1) const
        {
            std::vector<hsize_t> extent = dims(object, name);
            if (extent.size() != expected_trailing.size() + 1
                || !std::equal(expected_trailing.begin(), expected_trailing.end(), extent.begin() + 1))
                fail("dataset '" + name + "' has the wrong shape");
            if (rows >= 0) {
                if (hsize_t(rows) > extent[0])
                    fail("dataset '" + name + "' has fewer rows than expected");
                extent[0] = hsize_t(rows);
            }
            hsize_t values = 1;
            for (hsize_t e : extent)
                values *= e;
            std::vector<T> out(static_cast<size_t>(values));
            if (values == 0)
                return out;
            const Handle set(H5Dopen2(object, name.c_str(), H5P_DEFAULT), H5Dclose);
            const Handle file_space(H5Dget_space(set), H5Sclose);
            const Handle memory_space(H5Screate_simple(int(extent.size()), extent.data(), nullptr), H5Sclose);
            const std::vector<hsize_t> start(extent.size(), 0);
            const hid_t type = std::is_same_v<T, int> ? H5T_NATIVE_INT : H5T_NATIVE_DOUBLE;
            if (H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, extent.data(), nullptr) < 0
                || H5Dread(set, type, memory_space, file_space, H5P_DEFAULT, out.data()) < 0)
                fail("cannot read dataset '" + name + "'");
            return out;
        }

    private:
        std::string m_path, m_what;
    };

    /// One extendible per-iteration dataset: a scalar or a row of `width` values per iteration.
    struct Column {
        std::string name;
        hid_t type; ///< H5T_NATIVE_DOUBLE or H5T_NATIVE_INT
        long width; ///< -1: a scalar per iteration
        hid_t set = -1;
    };

    void write_vector(Reader& errors, hid_t group, const char* name, const VectorXd& v)
    {
        const hsize_t n = hsize_t(v.size());
        const Handle space(H5Screate_simple(1, &n, nullptr), H5Sclose);
        const Handle set(
            H5Dcreate2(group, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
        if (!set.valid() || (n > 0 && H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0))
            errors.fail("cannot write dataset '" + std::string(name) + "'");
    }

    /// rows x cols, row-major in the file.
    void write_matrix(Reader& errors, hid_t group, const char* name, const MatrixXd& m)
    {
        const hsize_t dims[2] = { hsize_t(m.rows()), hsize_t(m.cols()) };
        const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rows = m;
        const Handle space(H5Screate_simple(2, dims, nullptr), H5Sclose);
        const Handle set(
            H5Dcreate2(group, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
        if (!set.valid()
            || (rows.size() > 0 && H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, rows.data()) < 0))
            errors.fail("cannot write dataset '" + std::string(name) + "'");
    }

    VectorXd read_vector(const Reader& r, hid_t group, const char* name, Index n)
    {
        const std::vector<double> v = r.read<double>(group, name, {}, long(n));
        if (r.dims(group, name)[0] != hsize_t(n))
            r.fail("dataset '" + std::string(name) + "' has the wrong size");
        return Eigen::Map<const VectorXd>(v.data(), Index(v.size()));
    }

    MatrixXd read_matrix(const Reader& r, hid_t group, const char* name, Index rows, Index cols)
    {
        const std::vector<double> v = r.read<double>(group, name, { hsize_t(cols) }, long(rows));
        if (r.dims(group, name)[0] != hsize_t(rows))
            r.fail("dataset '" + std::string(name) + "' has the wrong shape");
        return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            v.data(), rows, cols);
    }

    /// f (an attribute), the gradient, the constraints and their Jacobians in group `name`.
    void write_values(Reader& errors, hid_t file, const char* name, const OptimizationValues& v)
    {
        const Handle group(H5Gcreate2(file, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
        if (!group.valid() || !write_number_attribute(group, "f", v.f))
            errors.fail("cannot write group '" + std::string(name) + "'");
        write_vector(errors, group, "gradient", v.gradient);
        write_vector(errors, group, "inequality", v.inequality);
        write_matrix(errors, group, "inequality_jacobian", v.inequality_jacobian);
        write_vector(errors, group, "equality", v.equality);
        write_matrix(errors, group, "equality_jacobian", v.equality_jacobian);
    }

    OptimizationValues read_values(const Reader& r, hid_t file, const char* name, Index n)
    {
        if (H5Lexists(file, name, H5P_DEFAULT) <= 0)
            r.fail("not an optimizer state: no group '" + std::string(name) + "'");
        const Handle group(H5Gopen2(file, name, H5P_DEFAULT), H5Gclose);
        OptimizationValues v;
        v.f = r.number_attribute<double>(group, "f");
        v.gradient = read_vector(r, group, "gradient", n);
        const Index mc = Index(r.dims(group, "inequality").at(0)), mh = Index(r.dims(group, "equality").at(0));
        v.inequality = read_vector(r, group, "inequality", mc);
        v.equality = read_vector(r, group, "equality", mh);
        // Without constraints the Jacobians are 0 x 0, as the problems return them.
        const auto jacobian = [&](const char* dataset, Index m) {
            const std::vector<hsize_t> d = r.dims(group, dataset);
            if (d.size() != 2)
                r.fail("dataset '" + std::string(dataset) + "' has the wrong shape");
            return m == 0 ? MatrixXd(Index(d[0]), Index(d[1])) : read_matrix(r, group, dataset, m, n);
        };
        v.inequality_jacobian = jacobian("inequality_jacobian", mc);
        v.equality_jacobian = jacobian("equality_jacobian", mh);
        return v;
    }

} // namespace

struct HistoryWriter::Impl {
    std::string h5_path, csv_path;
    hid_t file = -1;
    std::vector<Column> columns;
    hsize_t rows = 0;
    Index n = 0, m = 0;
    std::ofstream csv;

    [[noreturn]] void fail(const std::string& what) const
    {
        throw InputError(h5_path, what + " (is the disk full or the file removed?)");
    }

    void create(Column& c)
    {
        const int rank = c.width < 0 ? 1 : 2;
        const hsize_t width = hsize_t(std::max(0L, c.width));
        const hsize_t dims[2] = { 0, width }, max[2] = { H5S_UNLIMITED, width };
        // About 64 KB per chunk, at least one row (a chunk may be wider than a row of width 0).
        const hsize_t chunk[2]
            = { std::max<hsize_t>(1, 8192 / std::max<hsize_t>(1, width)), std::max<hsize_t>(1, width) };
        const Handle space(H5Screate_simple(rank, dims, max), H5Sclose);
        const Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
        H5Pset_chunk(dcpl, rank, chunk);
        const hid_t file_type = c.type == H5T_NATIVE_INT ? H5T_STD_I32LE : H5T_IEEE_F64LE;
        c.set = H5Dcreate2(file, c.name.c_str(), file_type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
        if (c.set < 0)
            fail("cannot create dataset '" + c.name + "'");
    }

    void write_row(Column& c, const void* data)
    {
        const int rank = c.width < 0 ? 1 : 2;
        const hsize_t width = hsize_t(std::max(0L, c.width));
        const hsize_t dims[2] = { rows + 1, width }, start[2] = { rows, 0 }, count[2] = { 1, width };
        if (H5Dset_extent(c.set, dims) < 0)
            fail("cannot extend dataset '" + c.name + "'");
        if (rank == 2 && width == 0)
            return;
        const Handle file_space(H5Dget_space(c.set), H5Sclose);
        const Handle memory_space(H5Screate_simple(rank, count, nullptr), H5Sclose);
        if (H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0
            || H5Dwrite(c.set, c.type, memory_space, file_space, H5P_DEFAULT, data) < 0)
            fail("cannot write dataset '" + c.name + "'");
    }

    void append_h5(const HistoryRow& r)
    {
        if (r.x.size() != n || r.constraints.size() != m)
            throw std::logic_error("HistoryWriter: a row of iteration " + std::to_string(r.iteration) + " has "
                + std::to_string(r.x.size()) + " design variables and " + std::to_string(r.constraints.size())
                + " constraint values, the history " + std::to_string(n) + " and " + std::to_string(m));
        const double doubles[]
            = { r.J, r.gradient_norm, r.step_norm, r.evaluation_seconds, r.optimizer_seconds, r.wall_seconds };
        const int ints[] = { r.iteration, r.evaluations, r.rejected };
        // Column order: iteration, x, J, constraints, gradient_norm, step_norm, evaluations,
        // rejected, evaluation_seconds, optimizer_seconds, wall_seconds.
        const void* data[] = { &ints[0], r.x.data(), &doubles[0], r.constraints.data(), &doubles[1], &doubles[2],
            &ints[1], &ints[2], &doubles[3], &doubles[4], &doubles[5] };
        for (size_t i = 0; i < columns.size(); ++i)
            write_row(columns[i], data[i]);
        ++rows;
    }

    void flush_h5()
    {
        if (H5Fflush(file, H5F_SCOPE_LOCAL) < 0)
            fail("cannot flush the HDF5 file");
    }

    bool close_h5() { return close_hdf5_columns(columns, file); }
};

HistoryWriter::HistoryWriter(
    const std::string& directory, const HistoryHeader& header, const std::vector<HistoryRow>& rows)
    : m_impl(std::make_unique<Impl>())
{
    Impl& m = *m_impl;
    m.h5_path = (fs::path(directory) / HISTORY_H5).string();
    m.csv_path = (fs::path(directory) / HISTORY_CSV).string();
    m.n = header.design_size;
    m.m = Index(header.constraint_names.size());
    const std::string temporary = m.h5_path + ".tmp";

    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); // errors as InputError naming the file
    {
        const Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
        H5Pset_libver_bounds(fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST); // needed by SWMR
        m.file = H5Fcreate(temporary.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
    }
    if (m.file < 0)
        throw InputError(m.h5_path, "cannot create HDF5 file");
    try {
        const hid_t D = H5T_NATIVE_DOUBLE, I = H5T_NATIVE_INT;
        m.columns = { { "iteration", I, -1 }, { "x", D, long(m.n) }, { "J", D, -1 }, { "constraints", D, long(m.m) },
            { DOUBLE_COLUMNS_AFTER[0], D, -1 }, { DOUBLE_COLUMNS_AFTER[1], D, -1 }, { "evaluations", I, -1 },
            { "rejected", I, -1 }, { TIME_COLUMNS[0], D, -1 }, { TIME_COLUMNS[1], D, -1 }, { TIME_COLUMNS[2], D, -1 } };
        for (Column& c : m.columns)
            m.create(c);
        if (!write_string_attribute(m.file, "problem", header.problem)
            || !write_string_attribute(m.file, "algorithm", header.algorithm)
            || !write_number_attribute<long long>(m.file, "design_size", header.design_size)
            || !write_strings_attribute(m.file, "constraint_names", header.constraint_names))
            m.fail("cannot write the root attributes");
        {
            const Handle set(H5Dopen2(m.file, "constraints", H5P_DEFAULT), H5Dclose);
            if (!write_strings_attribute(set, "names", header.constraint_names))
                m.fail("cannot write the attribute 'names' of 'constraints'");
        }
        for (const HistoryRow& r : rows)
            m.append_h5(r);
        // From here on the structure is fixed and readers may open the file at any time.
        if (H5Fstart_swmr_write(m.file) < 0)
            m.fail("cannot start single-writer/multiple-reader mode");
        m.flush_h5();
        std::string text = csv_header(header);
        for (const HistoryRow& r : rows)
            text += csv_row(r);
        write_replacing(m.csv_path, [&](std::ostream& out) { out << text; });
        // The open file goes on under its final name.
        if (std::rename(temporary.c_str(), m.h5_path.c_str()) != 0)
            throw InputError(m.h5_path, "cannot replace the file (" + std::string(std::strerror(errno)) + ")");
    } catch (...) {
        m.close_h5();
        std::remove(temporary.c_str());
        throw;
    }
    m.csv.open(m.csv_path, std::ios::app | std::ios::binary);
    if (!m.csv) {
        m.close_h5();
        throw InputError(m.csv_path, "cannot append to the file");
    }
}

HistoryWriter::~HistoryWriter()
{
    if (m_impl)
        m_impl->close_h5();
}

void HistoryWriter::append(const HistoryRow& row)
{
    Impl& m = *m_impl;
    if (m.file < 0)
        throw std::logic_error("HistoryWriter::append after close");
    m.append_h5(row);
    m.flush_h5();
    m.csv << csv_row(row);
    m.csv.flush();
    if (!m.csv)
        throw InputError(m.csv_path, "cannot write (is the disk full?)");
}

void HistoryWriter::close()
{
    Impl& m = *m_impl;
    if (m.csv.is_open()) {
        m.csv.close();
        if (m.csv.fail())
            throw InputError(m.csv_path, "cannot write (is the disk full?)");
    }
    if (m.file < 0)
        return;
    if (!m.close_h5())
        m.fail("cannot close the HDF5 file");
}

int HistoryWriter::rows() const { return int(m_impl->rows); }

StoredHistory read_history(const std::string& path)
{
    StoredHistory out;
    out.path = path;
    const Reader r(path, "a diffipc optimization history");
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    if (std::error_code ec; !fs::is_regular_file(path, ec))
        throw InputError(path, "no such file");
    // SWMR: a history whose writer was killed is still marked as open for writing.
    const Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY | H5F_ACC_SWMR_READ, H5P_DEFAULT), H5Fclose);
    if (!file.valid())
        throw InputError(path, "cannot open the history (not an HDF5 file?)");
    HistoryHeader& h = out.header;
    h.problem = r.string_attribute(file, "problem");
    h.algorithm = r.string_attribute(file, "algorithm");
    const long long n = r.number_attribute<long long>(file, "design_size");
    if (n < 0)
        r.fail("attribute 'design_size' is negative");
    h.design_size = Index(n);
    h.constraint_names = r.strings_attribute(file, "constraint_names");
    const hsize_t m = h.constraint_names.size();

    // Every dataset is extended and written in turn: a killed writer may leave some a row
    // longer than others. The complete rows are those every dataset has.
    const char* const names[] = { "iteration", "x", "J", "constraints", "gradient_norm", "step_norm", "evaluations",
        "rejected", "evaluation_seconds", "optimizer_seconds", "wall_seconds" };
    hsize_t rows = ~hsize_t(0);
    for (const char* name : names)
        rows = std::min(rows, r.dims(file, name).at(0));
    const long K = long(rows);
    const std::vector<int> iteration = r.read<int>(file, "iteration", {}, K);
    const std::vector<double> x = r.read<double>(file, "x", { hsize_t(n) }, K);
    const std::vector<double> J = r.read<double>(file, "J", {}, K);
    const std::vector<double> g = r.read<double>(file, "constraints", { m }, K);
    const std::vector<double> gradient_norm = r.read<double>(file, "gradient_norm", {}, K);
    const std::vector<double> step_norm = r.read<double>(file, "step_norm", {}, K);
    const std::vector<int> evaluations = r.read<int>(file, "evaluations", {}, K);
    const std::vector<int> rejected = r.read<int>(file, "rejected", {}, K);
    const std::vector<double> evaluation_seconds = r.read<double>(file, "evaluation_seconds", {}, K);
    const std::vector<double> optimizer_seconds = r.read<double>(file, "optimizer_seconds", {}, K);
    const std::vector<double> wall_seconds = r.read<double>(file, "wall_seconds", {}, K);
    for (long k = 0; k < K; ++k) {
        HistoryRow row;
        row.iteration = iteration[size_t(k)];
        row.x = Eigen::Map<const VectorXd>(x.data() + k * n, Index(n));
        row.J = J[size_t(k)];
        row.constraints = Eigen::Map<const VectorXd>(g.data() + k * Index(m), Index(m));
        row.gradient_norm = gradient_norm[size_t(k)];
        row.step_norm = step_norm[size_t(k)];
        row.evaluations = evaluations[size_t(k)];
        row.rejected = rejected[size_t(k)];
        row.evaluation_seconds = evaluation_seconds[size_t(k)];
        row.optimizer_seconds = optimizer_seconds[size_t(k)];
        row.wall_seconds = wall_seconds[size_t(k)];
        if (k > 0 && row.iteration != out.rows.back().iteration + 1)
            r.fail("row " + std::to_string(k) + " has iteration " + std::to_string(row.iteration) + " after "
                + std::to_string(out.rows.back().iteration) + " (rows are consecutive iterations from 0)");
        if (k == 0 && row.iteration != 0)
            r.fail("the first row has iteration " + std::to_string(row.iteration) + ", not 0");
        out.rows.push_back(std::move(row));
    }
    return out;
}

void write_run_state(const std::string& path, const RunState& state)
{
    const std::string temporary = path + ".tmp";
    Reader errors(path, "an optimizer state");
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    const OptimizerCheckpoint& c = state.checkpoint;
    try {
        {
            const Handle file(H5Fcreate(temporary.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
            if (!file.valid())
                errors.fail("cannot create HDF5 file");
            bool ok = write_string_attribute(file, "algorithm", to_string(c.algorithm))
                && write_number_attribute<long long>(file, "iteration", c.iteration)
                && write_number_attribute<long long>(file, "design_size", c.x.size())
                && write_number_attribute(file, "gradient_norm", c.gradient_norm)
                && write_number_attribute(file, "step_norm", c.step_norm)
                && write_number_attribute(file, "previous_f", c.previous_f)
                && write_number_attribute(file, "initial_gradient_norm", c.initial_gradient_norm)
                && write_number_attribute<long long>(file, "evaluations", c.evaluations)
                && write_number_attribute<long long>(file, "rejected", c.rejected)
                && write_number_attribute(file, "evaluation_seconds", c.evaluation_seconds)
                && write_number_attribute(file, "optimizer_seconds", c.optimizer_seconds)
                && write_number_attribute(file, "optimizer_cpu_seconds", c.optimizer_cpu_seconds)
                && write_number_attribute(file, "elapsed_seconds", c.elapsed_seconds)
                && write_number_attribute<long long>(file, "has_best", c.has_best ? 1 : 0)
                && write_number_attribute<long long>(file, "best_evaluation", c.best_evaluation)
                && write_number_attribute<long long>(file, "best_iteration", c.best_iteration)
                && write_number_attribute<long long>(file, "steps_checked", c.steps_checked)
                && write_number_attribute<long long>(file, "jumps_found", c.jumps_found)
                && write_number_attribute(file, "objective_scale", state.objective_scale)
                && write_string_attribute(file, "last_rejection", state.last_rejection);
            if (!ok)
                errors.fail("cannot write the attributes");
            write_vector(errors, file, "x", c.x);
            write_values(errors, file, "values", c.values);
            if (c.has_best) {
                write_vector(errors, file, "best_x", c.best_x);
                write_values(errors, file, "best_values", c.best_values);
            }
            MatrixXd s(Index(c.lbfgs_pairs.size()), c.x.size()), y(Index(c.lbfgs_pairs.size()), c.x.size());
            for (size_t i = 0; i < c.lbfgs_pairs.size(); ++i) {
                s.row(Index(i)) = c.lbfgs_pairs[i].s.transpose();
                y.row(Index(i)) = c.lbfgs_pairs[i].y.transpose();
            }
            write_matrix(errors, file, "lbfgs_s", s);
            write_matrix(errors, file, "lbfgs_y", y);
            // One row per StepJump: iteration, change, predicted, first_order, step_norm.
            MatrixXd jumps(Index(c.jumps.size()), 5);
            for (size_t i = 0; i < c.jumps.size(); ++i) {
                const StepJump& j = c.jumps[i];
                jumps.row(Index(i)) << double(j.iteration), j.change, j.predicted, j.first_order, j.step_norm;
            }
            write_matrix(errors, file, "jumps", jumps);
            if (H5Fflush(file, H5F_SCOPE_LOCAL) < 0)
                errors.fail("cannot write (is the disk full?)");
        }
        if (std::rename(temporary.c_str(), path.c_str()) != 0)
            errors.fail("cannot replace the file (" + std::string(std::strerror(errno)) + ")");
    } catch (...) {
        std::remove(temporary.c_str());
        throw;
    }
}

RunState read_run_state(const std::string& path)
{
    const Reader r(path, "an optimizer state");
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    if (std::error_code ec; !fs::is_regular_file(path, ec))
        throw InputError(path, "no such file");
    const Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file.valid())
        throw InputError(path, "cannot open the optimizer state (not an HDF5 file?)");
    RunState state;
    OptimizerCheckpoint& c = state.checkpoint;
    c.algorithm = parse_optimizer_algorithm(r.string_attribute(file, "algorithm"), path + ": algorithm");
    c.iteration = int(r.number_attribute<long long>(file, "iteration"));
    const long long n = r.number_attribute<long long>(file, "design_size");
    if (n < 0)
        r.fail("attribute 'design_size' is negative");
    c.gradient_norm = r.number_attribute<double>(file, "gradient_norm");
    c.step_norm = r.number_attribute<double>(file, "step_norm");
    c.previous_f = r.number_attribute<double>(file, "previous_f");
    c.initial_gradient_norm = r.number_attribute<double>(file, "initial_gradient_norm");
    c.evaluations = int(r.number_attribute<long long>(file, "evaluations"));
    c.rejected = int(r.number_attribute<long long>(file, "rejected"));
    c.evaluation_seconds = r.number_attribute<double>(file, "evaluation_seconds");
    c.optimizer_seconds = r.number_attribute<double>(file, "optimizer_seconds");
    c.optimizer_cpu_seconds = r.number_attribute<double>(file, "optimizer_cpu_seconds");
    c.elapsed_seconds = r.number_attribute<double>(file, "elapsed_seconds");
    c.has_best = r.number_attribute<long long>(file, "has_best") != 0;
    state.objective_scale = r.number_attribute<double>(file, "objective_scale");
    state.last_rejection = r.string_attribute(file, "last_rejection");
    c.x = read_vector(r, file, "x", Index(n));
    c.values = read_values(r, file, "values", Index(n));
    if (c.has_best) {
        c.best_x = read_vector(r, file, "best_x", Index(n));
        c.best_values = read_values(r, file, "best_values", Index(n));
    }
    // States written before the best point's provenance and the step checks were kept lack these.
    if (r.has_attribute(file, "best_evaluation"))
        c.best_evaluation = int(r.number_attribute<long long>(file, "best_evaluation"));
    if (r.has_attribute(file, "best_iteration"))
        c.best_iteration = int(r.number_attribute<long long>(file, "best_iteration"));
    if (r.has_attribute(file, "steps_checked"))
        c.steps_checked = int(r.number_attribute<long long>(file, "steps_checked"));
    if (r.has_attribute(file, "jumps_found"))
        c.jumps_found = int(r.number_attribute<long long>(file, "jumps_found"));
    if (H5Lexists(file, "jumps", H5P_DEFAULT) > 0) {
        const MatrixXd jumps = read_matrix(r, file, "jumps", Index(r.dims(file, "jumps").at(0)), 5);
        for (Index i = 0; i < jumps.rows(); ++i)
            c.jumps.push_back({ int(jumps(i, 0)), jumps(i, 1), jumps(i, 2), jumps(i, 3), jumps(i, 4) });
    }
    const hsize_t pairs = r.dims(file, "lbfgs_s").at(0);
    const MatrixXd s = read_matrix(r, file, "lbfgs_s", Index(pairs), Index(n));
    const MatrixXd y = read_matrix(r, file, "lbfgs_y", Index(pairs), Index(n));
    for (Index i = 0; i < Index(pairs); ++i)
        c.lbfgs_pairs.push_back({ s.row(i).transpose(), y.row(i).transpose() });
    if (!(state.objective_scale > 0) || !std::isfinite(state.objective_scale))
        r.fail("attribute 'objective_scale' must be a finite number > 0");
    return state;
}

} // namespace diffipc
