#include "shape_opt/distribution.hpp"

#include "shape_opt/byte_buffer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <type_traits>

namespace diffipc {

std::vector<int> assign_cases(size_t cases, const std::vector<double>& costs, int processes)
{
    if (processes < 1)
        throw std::invalid_argument("assign_cases: processes must be >= 1, got " + std::to_string(processes));
    if (!costs.empty() && costs.size() != cases)
        throw std::invalid_argument(
            "assign_cases: " + std::to_string(costs.size()) + " costs for " + std::to_string(cases) + " load cases");
    for (size_t c = 0; c < costs.size(); ++c)
        if (!(costs[c] >= 0) || !std::isfinite(costs[c]))
            throw std::invalid_argument(
                "assign_cases: the cost of load case " + std::to_string(c) + " is negative or not finite");
    std::vector<int> owner(cases);
    if (costs.empty()) {
        for (size_t c = 0; c < cases; ++c)
            owner[c] = int(c % size_t(processes));
        return owner;
    }
    std::vector<size_t> order(cases);
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return costs[a] > costs[b]; });
    std::vector<double> load(size_t(processes), 0.0);
    for (const size_t c : order) {
        const size_t least = size_t(std::min_element(load.begin(), load.end()) - load.begin());
        owner[c] = int(least);
        load[least] += costs[c];
    }
    return owner;
}

namespace {

    // The checkpoint records are copied whole: a field added to them that is not a plain value fails here.
    static_assert(std::is_trivially_copyable<CheckpointStatistics>::value, "CheckpointStatistics is copied whole");

} // namespace

std::string pack_evaluation(const Evaluation& e)
{
    ByteWriter w;
    w.put(e.value);
    w.put(e.forward_time);
    w.put(e.adjoint_time);
    w.put_doubles(e.gradient.data(), size_t(e.gradient.size()));
    w.put_doubles(e.constraint_values.data(), size_t(e.constraint_values.size()));
    w.put(uint64_t(e.constraint_gradients.rows()));
    w.put(uint64_t(e.constraint_gradients.cols()));
    w.put_doubles(e.constraint_gradients.data(), size_t(e.constraint_gradients.size()));
    w.put(uint64_t(e.adjoint_blocks.size()));
    for (const std::string& b : e.adjoint_blocks) {
        w.put_string(b);
    }
    w.put(uint64_t(e.checkpoints.size()));
    for (const LoadCaseCheckpoint& c : e.checkpoints) {
        w.put(c.records);
        w.put(c.objective_stored_states);
        w.put(c.objective_stored_bytes);
    }
    return w.bytes;
}

Evaluation unpack_evaluation(const std::string& bytes)
{
    ByteReader r { bytes, "unpack_evaluation" };
    Evaluation e;
    e.value = r.get<double>("value");
    e.forward_time = r.get<double>("forward_time");
    e.adjoint_time = r.get<double>("adjoint_time");
    e.gradient.resize(Index(r.count("gradient", sizeof(double))));
    r.doubles(e.gradient.data(), uint64_t(e.gradient.size()), "gradient");
    e.constraint_values.resize(Index(r.count("constraint_values", sizeof(double))));
    r.doubles(e.constraint_values.data(), uint64_t(e.constraint_values.size()), "constraint_values");
    const uint64_t rows = r.get<uint64_t>("constraint_gradients"), cols = r.get<uint64_t>("constraint_gradients");
    const uint64_t entries = r.count("constraint_gradients", sizeof(double));
    if ((rows != 0 && cols > entries / rows) || rows * cols != entries)
        throw std::invalid_argument("unpack_evaluation: constraint_gradients of " + std::to_string(entries)
            + " entries in " + std::to_string(rows) + " x " + std::to_string(cols));
    e.constraint_gradients.resize(Index(rows), Index(cols));
    r.doubles(e.constraint_gradients.data(), entries, "constraint_gradients");
    const uint64_t blocks = r.count("adjoint_blocks", sizeof(uint64_t));
    for (uint64_t i = 0; i < blocks; ++i) {
        e.adjoint_blocks.push_back(r.string("adjoint_blocks"));
    }
    const uint64_t checkpoints = r.count("checkpoints", sizeof(CheckpointStatistics));
    for (uint64_t i = 0; i < checkpoints; ++i) {
        LoadCaseCheckpoint c;
        c.records = r.get<CheckpointStatistics>("checkpoints");
        c.objective_stored_states = r.get<int>("checkpoints");
        c.objective_stored_bytes = r.get<size_t>("checkpoints");
        e.checkpoints.push_back(c);
    }
    r.finish();
    return e;
}

} // namespace diffipc
