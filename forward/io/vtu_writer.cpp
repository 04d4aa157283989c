#include "forward/io/vtu_writer.hpp"

#include "forward/common/error.hpp"
#include "forward/io/replace_file.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <ostream>
#include <stdexcept>
#include <type_traits>

namespace diffipc {

Index VtuGrid::add_point(const double* p, int dim)
{
    for (int c = 0; c < 3; ++c)
        points.push_back(c < dim ? p[c] : 0.0);
    return num_points() - 1;
}

void VtuGrid::add_cell(VtkCell type, const Index* cell_points, int count)
{
    connectivity.insert(connectivity.end(), cell_points, cell_points + count);
    offsets.push_back(std::int64_t(connectivity.size()));
    types.push_back(type);
}

void VtuGrid::add_cell(VtkCell type, std::initializer_list<Index> cell_points)
{
    add_cell(type, cell_points.begin(), int(cell_points.size()));
}

namespace {

    /// An array as the writer sees it: VTK type name, values, and how many tuples it holds.
    struct ArrayView {
        const char* type;
        std::string name; ///< empty: no Name attribute
        int components;
        const void* data;
        size_t count; ///< number of values
        size_t value_size;
        /// Writes value i as text.
        void (*print)(std::ostream&, const void*, size_t);
    };

    template <typename T> constexpr const char* vtk_type_name()
    {
        if constexpr (std::is_same_v<T, double>)
            return "Float64";
        else if constexpr (std::is_same_v<T, std::int64_t>)
            return "Int64";
        else if constexpr (std::is_same_v<T, std::int32_t>)
            return "Int32";
        else
            return "UInt8";
    }

    template <typename T> void print_value(std::ostream& out, const void* data, size_t i)
    {
        const T value = static_cast<const T*>(data)[i];
        if constexpr (std::is_same_v<T, double>) {
            // The shortest text that reads back as the same double.
            char buffer[32];
            const auto end = std::to_chars(buffer, buffer + sizeof buffer, value).ptr;
            out.write(buffer, end - buffer);
        } else {
            out << +value; // UInt8 as a number, not a character
        }
    }

    template <typename T> ArrayView view(const std::string& name, int components, const std::vector<T>& values)
    {
        return { vtk_type_name<T>(), name, components, values.data(), values.size(), sizeof(T), &print_value<T> };
    }

    ArrayView view(const VtuArray& a)
    {
        return std::visit([&](const auto& values) { return view(a.name, a.components, values); }, a.values);
    }

    void check_size(const ArrayView& a, Index tuples, const char* where)
    {
        if (a.components < 1 || a.count != size_t(tuples) * size_t(a.components))
            throw std::logic_error("write_vtu: " + std::string(where) + " array '" + a.name + "' has "
                + std::to_string(a.count) + " values, expected " + std::to_string(tuples) + " x "
                + std::to_string(a.components));
    }

    /// The XML of the file with every array either inline (ASCII) or as an offset into
    /// the appended block, whose arrays are collected in `appended` in file order.
    class Writer {
    public:
        Writer(std::ostream& out, VtuEncoding encoding)
            : m_out(out)
            , m_binary(encoding == VtuEncoding::BINARY)
        {
        }

        void array(const ArrayView& a)
        {
            m_out << "<DataArray type=\"" << a.type << '"';
            if (!a.name.empty())
                m_out << " Name=\"" << a.name << '"';
            m_out << " NumberOfComponents=\"" << a.components << '"';
            if (m_binary) {
                m_out << " format=\"appended\" offset=\"" << m_offset << "\"/>\n";
                m_offset += sizeof(std::uint64_t) + a.count * a.value_size;
                m_appended.push_back(a);
                return;
            }
            m_out << " format=\"ascii\">\n";
            for (size_t i = 0; i < a.count; ++i) {
                a.print(m_out, a.data, i);
                m_out << ((i + 1) % size_t(a.components) == 0 ? '\n' : ' ');
            }
            m_out << "</DataArray>\n";
        }

        /// The AppendedData block: each array as its byte count and raw values.
        void finish()
        {
            if (!m_binary)
                return;
            m_out << "<AppendedData encoding=\"raw\">\n_";
            for (const ArrayView& a : m_appended) {
                const std::uint64_t bytes = a.count * a.value_size;
                m_out.write(reinterpret_cast<const char*>(&bytes), sizeof bytes);
                m_out.write(static_cast<const char*>(a.data), std::streamsize(bytes));
            }
            m_out << "\n</AppendedData>\n";
        }

    private:
        std::ostream& m_out;
        bool m_binary;
        size_t m_offset = 0;
        std::vector<ArrayView> m_appended;
    };

    bool little_endian()
    {
        const std::uint16_t one = 1;
        unsigned char first;
        std::memcpy(&first, &one, 1);
        return first == 1;
    }

    /// A frame is a result: a NaN or an infinity in it (a stress overflowed at a huge
    /// deformation) is refused, naming the file, the array and the tuple, instead of written.
    void check_finite(const std::string& path, const std::string& what, const std::vector<double>& values,
        int components, const char* tuple)
    {
        for (size_t i = 0; i < values.size(); ++i)
            if (!std::isfinite(values[i]))
                throw InputError(path,
                    "not written: " + what + " is " + format_number(values[i]) + " at " + tuple + " "
                        + std::to_string(i / size_t(std::max(1, components)))
                        + " (the state, or a stress or force derived from it, overflowed)");
    }

} // namespace

void write_vtu(const std::string& path, const VtuGrid& grid, VtuEncoding encoding)
{
    const Index np = grid.num_points(), nc = grid.num_cells();
    if (grid.points.size() != size_t(np) * 3 || grid.offsets.size() != size_t(nc))
        throw std::logic_error("write_vtu: points or offsets do not match the grid");
    for (const VtuArray& a : grid.point_data)
        check_size(view(a), np, "point");
    for (const VtuArray& a : grid.cell_data)
        check_size(view(a), nc, "cell");
    check_finite(path, "a point's position", grid.points, 3, "point");
    for (const VtuArray& a : grid.point_data)
        if (const auto* v = std::get_if<std::vector<double>>(&a.values))
            check_finite(path, "point data '" + a.name + "'", *v, a.components, "point");
    for (const VtuArray& a : grid.cell_data)
        if (const auto* v = std::get_if<std::vector<double>>(&a.values))
            check_finite(path, "cell data '" + a.name + "'", *v, a.components, "cell");
    std::vector<std::uint8_t> types(grid.types.size());
    for (size_t c = 0; c < types.size(); ++c)
        types[c] = std::uint8_t(grid.types[c]);

    write_replacing(path, [&](std::ostream& out) {
        out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\""
            << (little_endian() ? "LittleEndian" : "BigEndian") << "\" header_type=\"UInt64\">\n"
            << "<UnstructuredGrid>\n<Piece NumberOfPoints=\"" << np << "\" NumberOfCells=\"" << nc << "\">\n";
        Writer w(out, encoding);
        out << "<Points>\n";
        w.array(view("Points", 3, grid.points));
        out << "</Points>\n<Cells>\n";
        w.array(view("connectivity", 1, grid.connectivity));
        w.array(view("offsets", 1, grid.offsets));
        w.array(view("types", 1, types));
        out << "</Cells>\n";
        // An empty <PointData/> or <CellData/> is left out: meshio refuses a file with one.
        if (!grid.point_data.empty()) {
            out << "<PointData>\n";
            for (const VtuArray& a : grid.point_data)
                w.array(view(a));
            out << "</PointData>\n";
        }
        if (!grid.cell_data.empty()) {
            out << "<CellData>\n";
            for (const VtuArray& a : grid.cell_data)
                w.array(view(a));
            out << "</CellData>\n";
        }
        out << "</Piece>\n</UnstructuredGrid>\n";
        w.finish();
        out << "</VTKFile>\n";
    });
}

void write_pvd(const std::string& path, const std::vector<PvdEntry>& entries)
{
    write_replacing(path, [&](std::ostream& out) {
        out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
        for (const PvdEntry& e : entries)
            out << "<DataSet timestep=\"" << std::setprecision(12) << e.time << "\" part=\"" << e.part << "\" file=\""
                << e.file << "\"/>\n";
        out << "</Collection>\n</VTKFile>\n";
    });
}

} // namespace diffipc
