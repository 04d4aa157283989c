#include "objectives/objective.hpp"

#include <stdexcept>

namespace diffipc {

namespace {
    void check_state(const Trajectory& trajectory, int k)
    {
        if (k < 0 || k > num_steps(trajectory))
            throw std::out_of_range("state " + std::to_string(k) + " is outside the trajectory's 0.."
                + std::to_string(num_steps(trajectory)));
    }
    const VectorXd& held(const VectorXd& state, int k)
    {
        if (state.size() == 0)
            throw std::logic_error("state " + std::to_string(k)
                + " is not held (a record released by checkpointing, or missing from the objective's states_read())");
        return state;
    }
} // namespace

std::vector<int> Objective::states_read(int steps) const
{
    std::vector<int> k(size_t(steps) + 1);
    for (int i = 0; i <= steps; ++i)
        k[size_t(i)] = i;
    return k;
}

const VectorXd& state_positions(const Trajectory& trajectory, int k)
{
    check_state(trajectory, k);
    return held(k == 0 ? trajectory.initial_positions : trajectory.steps[size_t(k - 1)].positions, k);
}

const VectorXd& state_velocities(const Trajectory& trajectory, int k)
{
    check_state(trajectory, k);
    return held(k == 0 ? trajectory.initial_velocities : trajectory.steps[size_t(k - 1)].velocities, k);
}

double state_time(const Trajectory& trajectory, int k)
{
    check_state(trajectory, k);
    return k == 0 ? trajectory.initial_time : trajectory.steps[size_t(k - 1)].time;
}

VectorXd& gradient_block(VectorXd& block, Index n)
{
    if (block.size() == 0)
        block = VectorXd::Zero(n);
    else if (block.size() != n)
        throw std::logic_error(
            "gradient block of size " + std::to_string(block.size()) + " where " + std::to_string(n) + " is expected");
    return block;
}

std::vector<Index> body_elements(const Mesh& mesh, int body)
{
    std::vector<Index> elements;
    for (Index e = 0; e < mesh.num_elements(); ++e)
        if (body < 0 || mesh.element_body[e] == body)
            elements.push_back(e);
    if (elements.empty())
        throw std::out_of_range("the mesh has no element of body " + std::to_string(body));
    return elements;
}

} // namespace diffipc
