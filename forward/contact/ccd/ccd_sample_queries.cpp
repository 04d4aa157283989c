#include "forward/contact/ccd/ccd_sample_queries.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace diffipc {

namespace {

    std::string trim(const std::string& s)
    {
        const size_t b = s.find_first_not_of(" \t\r\n");
        if (b == std::string::npos)
            return "";
        const size_t e = s.find_last_not_of(" \t\r\n");
        return s.substr(b, e - b + 1);
    }

    /// Is the integer string exactly the (integer-valued) double x? glibc prints
    /// integer-valued doubles exactly with %.0f.
    bool represents_exactly(const std::string& digits, double x)
    {
        std::string s = digits;
        bool negative = false;
        if (!s.empty() && (s[0] == '-' || s[0] == '+')) {
            negative = s[0] == '-';
            s.erase(0, 1);
        }
        s.erase(0, std::min(s.find_first_not_of('0'), s.size() - 1));
        if (negative && s != "0")
            s = "-" + s;
        char buffer[400];
        std::snprintf(buffer, sizeof(buffer), "%.0f", x);
        return s == buffer;
    }

    bool is_power_of_two(double x)
    {
        int exponent;
        return x > 0 && std::frexp(x, &exponent) == 0.5;
    }

} // namespace

std::vector<CCDQuery> read_ccd_queries(const std::string& path, bool edge_edge, long* inexact_coordinates)
{
    std::ifstream in(path);
    if (!in)
        throw InputError(path, "cannot open the CCD query file");
    std::vector<CCDQuery> queries;
    std::string line;
    int line_number = 0, row = 0;
    CCDQuery query;
    query.edge_edge = edge_edge;
    while (std::getline(in, line)) {
        ++line_number;
        line = trim(line);
        if (line.empty())
            continue;
        const std::string where = path + ":" + std::to_string(line_number);
        std::vector<std::string> fields;
        std::stringstream ss(line);
        for (std::string f; std::getline(ss, f, ',');)
            fields.push_back(trim(f));
        if (fields.size() != 7)
            throw InputError(where, "expected 7 comma-separated integers, got " + std::to_string(fields.size()));
        for (int c = 0; c < 3; ++c) {
            double value[2];
            for (int k = 0; k < 2; ++k) {
                const std::string& f = fields[size_t(2 * c + k)];
                char* end = nullptr;
                value[k] = std::strtod(f.c_str(), &end);
                if (f.empty() || *end != '\0' || f.find_first_of(".eE") != std::string::npos)
                    throw InputError(where, "not an integer: '" + f + "'");
            }
            if (!(value[1] > 0) || !std::isfinite(value[0]) || !std::isfinite(value[1]))
                throw InputError(where, "denominators must be positive and both integers finite");
            const double x = value[0] / value[1];
            const bool exact = represents_exactly(fields[size_t(2 * c)], value[0])
                && represents_exactly(fields[size_t(2 * c + 1)], value[1]) && is_power_of_two(value[1])
                && (x == 0 || std::abs(x) >= std::numeric_limits<double>::min());
            if (!exact && inexact_coordinates)
                ++*inexact_coordinates;
            query.vertices[size_t(row)][c] = x;
        }
        if (fields[6] != "0" && fields[6] != "1")
            throw InputError(where, "the ground truth column must be 0 or 1, got '" + fields[6] + "'");
        const bool truth = fields[6] == "1";
        if (row == 0)
            query.ground_truth = truth;
        else if (truth != query.ground_truth)
            throw InputError(where, "the ground truth differs between the rows of one query");
        if (++row == 8) {
            queries.push_back(query);
            row = 0;
        }
    }
    if (row != 0)
        throw InputError(path, "the number of rows is not a multiple of 8");
    return queries;
}

std::vector<CCDQuery> read_ccd_query_folder(const std::string& folder, long* inexact_coordinates)
{
    namespace fs = std::filesystem;
    std::vector<CCDQuery> all;
    bool found = false;
    for (const bool edge_edge : { false, true }) {
        const fs::path dir = fs::path(folder) / (edge_edge ? "edge-edge" : "vertex-face");
        if (!fs::is_directory(dir))
            continue;
        found = true;
        std::vector<fs::path> files;
        for (const auto& entry : fs::directory_iterator(dir))
            if (entry.is_regular_file() && entry.path().extension() == ".csv")
                files.push_back(entry.path());
        std::sort(files.begin(), files.end());
        for (const fs::path& f : files) {
            std::vector<CCDQuery> q = read_ccd_queries(f.string(), edge_edge, inexact_coordinates);
            all.insert(all.end(), q.begin(), q.end());
        }
    }
    if (!found)
        throw InputError(folder, "no vertex-face or edge-edge subfolder of CCD queries");
    return all;
}

CCDResult run_ccd_query(const CCDQuery& query, const CCDSettings& settings)
{
    const auto& v = query.vertices;
    if (query.edge_edge)
        return edge_edge_ccd(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], settings);
    return point_triangle_ccd(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], settings);
}

std::vector<std::string> ccd_query_folders(const std::string& root)
{
    namespace fs = std::filesystem;
    std::vector<std::string> folders;
    for (const auto& entry : fs::directory_iterator(root))
        if (entry.is_directory()
            && (fs::is_directory(entry.path() / "vertex-face") || fs::is_directory(entry.path() / "edge-edge")))
            folders.push_back(entry.path().string());
    std::sort(folders.begin(), folders.end());
    return folders;
}

} // namespace diffipc
