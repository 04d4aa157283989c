#pragma once
#include <chrono>

namespace diffipc {

/// Wall-clock stopwatch; `add_to` accumulates the elapsed seconds into a phase counter.
class Timer {
public:
    Timer()
        : m_start(std::chrono::steady_clock::now())
    {
    }
    double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count(); }
    void add_to(double& accumulator) const { accumulator += seconds(); }

private:
    std::chrono::steady_clock::time_point m_start;
};

} // namespace diffipc
