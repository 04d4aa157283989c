#pragma once
/// @file vtu_writer.hpp
/// VTK's XML unstructured-grid files (.vtu, one piece) and ParaView collection
/// indices (.pvd), ASCII or appended raw binary (docs/output_format.md "VTU frames").

#include "forward/common/types.hpp"
#include "forward/io/vtu_encoding.hpp"

#include <cstdint>
#include <initializer_list>
#include <string>
#include <variant>
#include <vector>

namespace diffipc {

/// VTK cell type codes (vtkCellType.h).
enum class VtkCell : std::uint8_t { VERTEX = 1, LINE = 3, TRIANGLE = 5, QUAD = 9, TETRA = 10 };

/// One named array: `components` values per point (or cell), tuple after tuple.
struct VtuArray {
    std::string name;
    int components = 1;
    std::variant<std::vector<double>, std::vector<std::int32_t>, std::vector<std::uint8_t>> values;
};

/// An unstructured grid as one VTU piece holds it.
struct VtuGrid {
    std::vector<double> points; ///< #P*3: x, y, z of each point (z = 0 in 2D)
    std::vector<std::int64_t> connectivity; ///< the cells' point indices, cell after cell
    std::vector<std::int64_t> offsets; ///< #C: end of each cell's indices in connectivity
    std::vector<VtkCell> types; ///< #C
    std::vector<VtuArray> point_data; ///< #P tuples each
    std::vector<VtuArray> cell_data; ///< #C tuples each

    Index num_points() const { return Index(points.size() / 3); }
    Index num_cells() const { return Index(types.size()); }
    /// @brief Appends a point and returns its index.
    /// @param p `dim` coordinates (m); z = 0 when dim = 2
    Index add_point(const double* p, int dim);
    /// @brief Appends a cell of `type` made of the given point indices.
    void add_cell(VtkCell type, std::initializer_list<Index> cell_points);
    void add_cell(VtkCell type, const Index* cell_points, int count);
};

/// @brief Writes `grid` to `path` (replaced whole, forward/io/replace_file.hpp).
/// ASCII: every array inline. BINARY: the arrays follow the XML in an AppendedData
/// block, each as a UInt64 byte count and its values in this machine's byte order
/// (the file's byte_order attribute). Points are Float64, connectivity and offsets
/// Int64, types UInt8.
/// @throws std::logic_error if an array's size does not match the grid (#P or #C
///         tuples of `components` values); InputError naming `path` if it cannot be written,
///         or (nothing written) if a point or a value of a Float64 array is not finite
void write_vtu(const std::string& path, const VtuGrid& grid, VtuEncoding encoding);

/// One data set of a collection: a file at a time, as part `part` of a multi-block.
struct PvdEntry {
    double time = 0; ///< s
    int part = 0; ///< 0: bodies, 1: obstacles
    std::string file; ///< relative to the .pvd
};

/// @brief ParaView collection index: each entry becomes a DataSet with its timestep,
/// part and file; ParaView groups the parts of one time into a multi-block data set.
/// @throws InputError naming `path` if it cannot be written
void write_pvd(const std::string& path, const std::vector<PvdEntry>& entries);

} // namespace diffipc
