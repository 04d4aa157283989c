#pragma once
// Helpers of the GPU adjoint tests (tests/cuda/simulation): a random seed of dJ/dx at two steps, and
// the relative difference of two gradients.

#include "adjoint/adjoint.hpp"
#include "forward/simulation/simulator.hpp"

#include <algorithm>
#include <random>

namespace diffipc::test {

/// dJ/dx_k with entries uniform in [-1, 1] at the last step T and at T / 2 (the same for every run of a
/// scene: seeded with 7).
inline StateSeed random_position_seed(const Simulator& sim, int T)
{
    StateSeed seed;
    seed.resize(T);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int step : { T, T / 2 }) {
        VectorXd w(sim.mesh().num_dofs());
        for (Index i = 0; i < w.size(); ++i)
            w[i] = u(rng);
        seed.add_position(step, w);
    }
    return seed;
}

/// |a - b| / |b| (2-norms).
inline double relative_difference(const VectorXd& a, const VectorXd& b)
{
    return (a - b).norm() / std::max(b.norm(), 1e-300);
}

} // namespace diffipc::test
