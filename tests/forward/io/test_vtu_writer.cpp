// VTU files (forward/io/vtu_writer.hpp) read back by hand: the ASCII arrays as text, the
// binary ones from the appended block at their offsets (a UInt64 byte count, then the
// values). tests/python/test_vtu.py reads the same files with meshio, an independent reader.

#include "forward/common/error.hpp"
#include "forward/io/vtu_writer.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <stdexcept>

using namespace diffipc;
namespace fs = std::filesystem;

namespace {

std::string read(const fs::path& path) { return test::read_file(path.string()); }

/// Two triangles and a vertex cell on four points, with a point and two cell arrays.
VtuGrid small_grid()
{
    VtuGrid g;
    const double p[4][2] = { { 0, 0 }, { 1, 0 }, { 1, 1 }, { 0.1, 1e-300 } };
    for (const auto& q : p)
        g.add_point(q, 2);
    g.add_cell(VtkCell::TRIANGLE, { 0, 1, 2 });
    g.add_cell(VtkCell::TRIANGLE, { 0, 2, 3 });
    g.add_cell(VtkCell::VERTEX, { 3 });
    g.point_data.push_back({ "force", 3, std::vector<double> { 1, 2, 3, 4, 5, 6, 7, 8, 9, -1.0 / 3, 0.1, 2e300 } });
    g.cell_data.push_back({ "body", 1, std::vector<std::int32_t> { 0, 1, -7 } });
    g.cell_data.push_back({ "tensor", 2, std::vector<double> { 1, 2, 3, 4, 5, 6 } });
    return g;
}

fs::path scratch(const std::string& name)
{
    const fs::path dir = fs::temp_directory_path() / "diffipc_vtu_writer";
    fs::create_directories(dir);
    return dir / name;
}

/// The values of the appended array `name` in `file` (raw encoding, UInt64 headers).
template <typename T> std::vector<T> appended_array(const std::string& file, const std::string& name)
{
    const std::regex tag("<DataArray type=\"\\w+\" Name=\"" + name
        + "\" NumberOfComponents=\"\\d+\" format=\"appended\" offset=\"(\\d+)\"/>");
    std::smatch m;
    if (!std::regex_search(file, m, tag))
        throw std::runtime_error("no appended array " + name);
    const size_t start = file.find("<AppendedData encoding=\"raw\">\n_");
    if (start == std::string::npos)
        throw std::runtime_error("no raw AppendedData block");
    const size_t at = start + std::strlen("<AppendedData encoding=\"raw\">\n_") + std::stoul(m[1]);
    std::uint64_t bytes;
    std::memcpy(&bytes, file.data() + at, sizeof bytes);
    std::vector<T> values(bytes / sizeof(T));
    std::memcpy(values.data(), file.data() + at + sizeof bytes, bytes);
    return values;
}

} // namespace

TEST(VtuWriter, BinaryArraysAreAppendedRawAtTheirOffsets)
{
    const fs::path path = scratch("binary.vtu");
    const VtuGrid g = small_grid();
    write_vtu(path.string(), g, VtuEncoding::BINARY);
    const std::string file = read(path);
    EXPECT_EQ(file.rfind("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\"", 0), 0u);
    EXPECT_NE(file.find("header_type=\"UInt64\""), std::string::npos);
    EXPECT_NE(file.find("<Piece NumberOfPoints=\"4\" NumberOfCells=\"3\">"), std::string::npos);
    EXPECT_EQ(appended_array<double>(file, "Points"), g.points);
    EXPECT_EQ(appended_array<std::int64_t>(file, "connectivity"), (std::vector<std::int64_t> { 0, 1, 2, 0, 2, 3, 3 }));
    EXPECT_EQ(appended_array<std::int64_t>(file, "offsets"), (std::vector<std::int64_t> { 3, 6, 7 }));
    EXPECT_EQ(appended_array<std::uint8_t>(file, "types"), (std::vector<std::uint8_t> { 5, 5, 1 }));
    EXPECT_EQ(appended_array<double>(file, "force"), std::get<std::vector<double>>(g.point_data[0].values));
    EXPECT_EQ(appended_array<std::int32_t>(file, "body"), (std::vector<std::int32_t> { 0, 1, -7 }));
    EXPECT_EQ(appended_array<double>(file, "tensor"), std::get<std::vector<double>>(g.cell_data[1].values));
    EXPECT_EQ(file.substr(file.size() - 28), "\n</AppendedData>\n</VTKFile>\n");
}

TEST(VtuWriter, AsciiDoublesReadBackExactly)
{
    const fs::path path = scratch("ascii.vtu");
    write_vtu(path.string(), small_grid(), VtuEncoding::ASCII);
    const std::string file = read(path);
    EXPECT_EQ(file.find("AppendedData"), std::string::npos);
    EXPECT_NE(file.find("<DataArray type=\"Float64\" Name=\"force\" NumberOfComponents=\"3\" format=\"ascii\">\n"
                        "1 2 3\n4 5 6\n7 8 9\n-0.3333333333333333 0.1 2e+300\n</DataArray>"),
        std::string::npos)
        << file;
    EXPECT_NE(
        file.find("Name=\"Points\" NumberOfComponents=\"3\" format=\"ascii\">\n0 0 0\n1 0 0\n1 1 0\n0.1 1e-300 0\n"),
        std::string::npos);
    EXPECT_NE(file.find("Name=\"types\" NumberOfComponents=\"1\" format=\"ascii\">\n5\n5\n1\n"), std::string::npos);
    EXPECT_NE(file.find("Name=\"body\" NumberOfComponents=\"1\" format=\"ascii\">\n0\n1\n-7\n"), std::string::npos);
}

TEST(VtuWriter, EmptyDataSectionsAreLeftOut)
{
    // Before: an empty <PointData></PointData>, which meshio refuses (a rest design has cell data only).
    VtuGrid grid = small_grid();
    grid.point_data.clear();
    const fs::path path = scratch("no_point_data.vtu");
    write_vtu(path.string(), grid, VtuEncoding::BINARY);
    const std::string file = read(path);
    EXPECT_EQ(file.find("PointData"), std::string::npos);
    EXPECT_NE(file.find("<CellData>"), std::string::npos);
    grid.cell_data.clear();
    write_vtu(path.string(), grid, VtuEncoding::ASCII);
    EXPECT_EQ(read(path).find("CellData"), std::string::npos);
}

TEST(VtuWriter, ArraysOfTheWrongSizeAreRefused)
{
    VtuGrid g = small_grid();
    g.cell_data.push_back({ "short", 1, std::vector<double> { 1, 2 } });
    EXPECT_THROW(write_vtu(scratch("bad.vtu").string(), g, VtuEncoding::BINARY), std::logic_error);
    EXPECT_FALSE(fs::exists(scratch("bad.vtu")));
}

TEST(VtuWriter, CollectionListsTimesAndParts)
{
    const fs::path path = scratch("run.pvd");
    write_pvd(path.string(), { { 0.0, 0, "frame_0.vtu" }, { 0.0, 1, "obstacles_0.vtu" }, { 0.25, 0, "frame_5.vtu" } });
    EXPECT_EQ(read(path),
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n"
        "<DataSet timestep=\"0\" part=\"0\" file=\"frame_0.vtu\"/>\n"
        "<DataSet timestep=\"0\" part=\"1\" file=\"obstacles_0.vtu\"/>\n"
        "<DataSet timestep=\"0.25\" part=\"0\" file=\"frame_5.vtu\"/>\n</Collection>\n</VTKFile>\n");
}

TEST(VtuWriter, ANonFiniteValueIsRefusedNamingTheFileAndArray)
{
    // Before: written as "nan" (ASCII) or a NaN's bytes (binary), and the run exited 0.
    for (const double bad : { std::nan(""), std::numeric_limits<double>::infinity() }) {
        VtuGrid g = small_grid();
        std::get<std::vector<double>>(g.cell_data[1].values)[3] = bad; // tensor, cell 1
        const fs::path path = scratch("nan.vtu");
        fs::remove(path);
        try {
            write_vtu(path.string(), g, VtuEncoding::BINARY);
            FAIL() << "a non-finite value was written";
        } catch (const InputError& e) {
            EXPECT_EQ(e.field(), path.string());
            EXPECT_NE(std::string(e.what()).find("cell data 'tensor'"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("at cell 1"), std::string::npos) << e.what();
        }
        EXPECT_FALSE(fs::exists(path));
        g = small_grid();
        g.points[4] = bad; // point 1's y
        EXPECT_THROW(write_vtu(path.string(), g, VtuEncoding::ASCII), InputError);
        EXPECT_FALSE(fs::exists(path));
    }
}
