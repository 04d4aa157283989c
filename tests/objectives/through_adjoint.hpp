#pragma once
// dJ/dp of an objective (given as problem-file JSON) through the adjoint against central
// differences of whole forward runs, one random direction per block, and optionally a Taylor
// test. Shared by the objectives' adjoint checks (reaction force, macro stress).

#include "adjoint/adjoint_check.hpp"
#include "objective_fd.hpp"
#include "objectives/objective_json.hpp"

namespace diffipc::test {

/// @param taylor_step > 0: also the Taylor test from this step (expect_taylor_rate, rate >= 1.9)
/// @param kappa fixed barrier stiffness for contact scenes (0: the scene's)
inline void check_through_adjoint(const nlohmann::json& scene_json, const nlohmann::json& objective_json,
    const std::vector<Block>& blocks, double fd_step, double tolerance, double taylor_step = 0, double kappa = 0)
{
    const Scene scene = make_scene(scene_json);
    SimulationParameters nominal;
    nominal.kappa = kappa;
    Simulator sim(scene, nominal);
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
    const auto J = parse_objective(objective_json, "objective", sim);
    StateSeed seed;
    seed.resize(sim.steps_done());
    const ParameterRequest request = request_for(blocks);
    J->add_gradient(sim, sim.trajectory(), request, 1.0, seed);
    const ParameterGradient grad = adjoint_gradient(sim, seed, request);
    const SimulationParameters base = sim.parameters();
    unsigned n = 500;
    for (Block b : blocks) {
        SCOPED_TRACE(block_name(b));
        VectorXd dir;
        MatrixXd dir_matrix;
        if (b == Block::PRESCRIBED || b == Block::MACRO) {
            const MatrixXd& values = b == Block::PRESCRIBED ? base.prescribed : base.macro_gradient;
            const VectorXd r = random_vector(values.size(), ++n) * 1e-3;
            dir_matrix = Eigen::Map<const MatrixXd>(r.data(), values.rows(), values.cols());
        } else if (b == Block::REST_POSITIONS)
            dir = keep_pairing(sim, random_vector(base.rest_positions.size(), ++n) * 1e-3);
        else
            dir = random_vector(block_vector(base, b)->size(), ++n).cwiseProduct(*block_vector(base, b));
        const auto Jh = [&](double h) {
            Simulator s(scene, perturbed(base, b, dir, dir_matrix, h));
            s.run();
            EXPECT_EQ(s.trajectory().final_status, StepStatus::CONVERGED);
            return parse_objective(objective_json, "objective", s)->value(s, s.trajectory());
        };
        const double fd = central_difference(Jh, fd_step);
        const double exact = block_dot(grad, b, dir, dir_matrix);
        const double J0 = J->value(sim, sim.trajectory());
        EXPECT_TRUE(fd_agrees(fd, exact, tolerance));
        EXPECT_GT(std::abs(fd), 1e-8 * std::abs(J0)) << "an empty check";
        if (taylor_step > 0)
            expect_taylor_rate(Jh, J0, exact, taylor_step, 1.9);
    }
}

} // namespace diffipc::test
