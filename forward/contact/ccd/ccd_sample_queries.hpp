#pragma once
/// @file ccd_sample_queries.hpp
/// Reader for the CCD benchmark of Wang et al. 2021 ("A Large Scale Benchmark
/// and an Inclusion-Based Algorithm for Continuous Collision Detection"), as
/// stored in tests/data/ccd-sample-queries (a copy of shared/data/ccd-sample-queries): CSV files of 8 rows per query,
/// each row "x_num,x_den,y_num,y_den,z_num,z_den,truth" with exact rational
/// coordinates and the exact ground truth (1: the primitives touch during
/// t in [0, 1]). Used by the CCD test and benchmark.

#include "forward/contact/ccd/ccd.hpp"

#include <array>
#include <string>
#include <vector>

namespace diffipc {

struct CCDQuery {
    /// true: edge-edge (rows ea0, ea1, eb0, eb1 at t0, then at t1);
    /// false: vertex-face (rows p, t0, t1, t2 at t0, then at t1).
    bool edge_edge = false;
    /// The 8 rows in file order (m).
    std::array<Eigen::Vector3d, 8> vertices;
    /// Exact answer: do the primitives touch for some t in [0, 1]?
    bool ground_truth = false;
};

/// @brief Read one CSV file.
/// Each integer is converted with strtod (correctly rounded) and the numerator
/// divided by the denominator. The result is exact when both integers are
/// exactly representable and the denominator is a power of two (true for
/// every coordinate of the sample queries); other coordinates are counted in
/// *inexact_coordinates (the quotient is then within one rounding of the
/// nearest double, not necessarily the nearest).
/// @param path       CSV file
/// @param edge_edge  the file holds edge-edge queries (else vertex-face)
/// @param inexact_coordinates  if non-null, incremented per inexact coordinate
/// @throws InputError naming the file and line on malformed input
std::vector<CCDQuery> read_ccd_queries(const std::string& path, bool edge_edge, long* inexact_coordinates = nullptr);

/// @brief Read every query of one benchmark folder (e.g. ".../unit-tests"):
/// vertex-face/*.csv, then edge-edge/*.csv, files in name order.
/// @throws InputError if the folder has neither subfolder
std::vector<CCDQuery> read_ccd_query_folder(const std::string& folder, long* inexact_coordinates = nullptr);

/// @brief The benchmark folders below `root` (those with a vertex-face/ or edge-edge/ subfolder), in
/// name order.
std::vector<std::string> ccd_query_folders(const std::string& root);

/// @brief Run the query with point_triangle_ccd or edge_edge_ccd.
CCDResult run_ccd_query(const CCDQuery& query, const CCDSettings& settings);

} // namespace diffipc
