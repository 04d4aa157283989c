#pragma once
// The canonical parameter blocks (forward/simulation/parameters.hpp) as the
// finite-difference checks see them: names, directions applied to a set of
// parameters, gradient dot products, and the fourth-order central difference.
// Shared by the adjoint checks (adjoint_check.hpp) and the objectives' partial
// derivative checks (tests/objectives/objective_fd.hpp).

#include "adjoint/sensitivity.hpp"
#include "forward/simulation/parameters.hpp"
#include "forward/simulation/simulator.hpp"

#include <functional>
#include <vector>

namespace diffipc::test {

enum class Block {
    REST_POSITIONS,
    MU,
    LAMBDA,
    DENSITY,
    INITIAL_DISPLACEMENT,
    INITIAL_VELOCITY,
    PRESCRIBED,
    FRICTION,
    MACRO
};

inline const char* block_name(Block b)
{
    switch (b) {
    case Block::REST_POSITIONS:
        return "rest_positions";
    case Block::MU:
        return "mu";
    case Block::LAMBDA:
        return "lambda";
    case Block::DENSITY:
        return "density";
    case Block::INITIAL_DISPLACEMENT:
        return "initial_displacement";
    case Block::INITIAL_VELOCITY:
        return "initial_velocity";
    case Block::PRESCRIBED:
        return "prescribed";
    case Block::FRICTION:
        return "friction";
    case Block::MACRO:
        return "macro";
    }
    return "?";
}

/// The vector a block lives in, of parameters or of a gradient (both are laid out alike);
/// PRESCRIBED and MACRO are matrices and have none (nullptr).
template <typename Blocks> auto block_vector(Blocks& p, Block b) -> decltype(&p.mu)
{
    switch (b) {
    case Block::REST_POSITIONS:
        return &p.rest_positions;
    case Block::MU:
        return &p.mu;
    case Block::LAMBDA:
        return &p.lambda;
    case Block::DENSITY:
        return &p.density;
    case Block::INITIAL_DISPLACEMENT:
        return &p.initial_displacement;
    case Block::INITIAL_VELOCITY:
        return &p.initial_velocity;
    case Block::FRICTION:
        return &p.friction;
    case Block::PRESCRIBED:
    case Block::MACRO:
        break;
    }
    return nullptr;
}

/// dJ/dp . direction for one block (dir_matrix for PRESCRIBED and MACRO); 0 for an empty gradient block.
inline double block_dot(const ParameterGradient& g, Block b, const VectorXd& dir, const MatrixXd& dir_matrix)
{
    if (b == Block::PRESCRIBED)
        return g.prescribed.size() ? (g.prescribed.array() * dir_matrix.array()).sum() : 0.0;
    if (b == Block::MACRO)
        return g.macro.size() ? (g.macro.array() * dir_matrix.array()).sum() : 0.0;
    const VectorXd& v = *block_vector(g, b);
    return v.size() ? v.dot(dir) : 0.0;
}

/// base + h direction in one block (the other blocks as in base).
inline SimulationParameters perturbed(
    const SimulationParameters& base, Block b, const VectorXd& dir, const MatrixXd& dir_matrix, double h)
{
    SimulationParameters p = base;
    if (b == Block::PRESCRIBED)
        p.prescribed += h * dir_matrix;
    else if (b == Block::MACRO)
        p.macro_gradient += h * dir_matrix;
    else
        *block_vector(p, b) += h * dir;
    return p;
}

/// The adjoint request that covers `blocks`.
inline ParameterRequest request_for(const std::vector<Block>& blocks)
{
    ParameterRequest request;
    for (Block b : blocks) {
        request.rest_positions |= b == Block::REST_POSITIONS;
        request.lame |= b == Block::MU || b == Block::LAMBDA;
        request.density |= b == Block::DENSITY;
        request.initial_displacement |= b == Block::INITIAL_DISPLACEMENT;
        request.initial_velocity |= b == Block::INITIAL_VELOCITY;
        request.prescribed |= b == Block::PRESCRIBED;
        request.friction |= b == Block::FRICTION;
        request.macro |= b == Block::MACRO;
    }
    return request;
}

/// A rest-position direction (#V dim) that keeps a periodic cell's pairing (issue 14): each
/// vertex moves as its class representative. Unchanged for other scenes.
inline VectorXd keep_pairing(const Simulator& sim, VectorXd dir)
{
    if (!sim.periodic())
        return dir;
    const PeriodicPairing& p = sim.scene().periodic.pairing;
    const int d = sim.mesh().dim;
    for (Index v = 0; v < sim.mesh().num_vertices(); ++v)
        dir.segment(v * d, d) = dir.segment(Index(p.representative[p.vertex_class[v]]) * d, d);
    return dir;
}

/// Fourth-order central difference of f at 0 with step h.
inline double central_difference(const std::function<double(double)>& f, double h)
{
    return (8 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12 * h);
}

} // namespace diffipc::test
