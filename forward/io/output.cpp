#include "forward/io/output.hpp"

#include "forward/common/threads.hpp"
#include "forward/io/replace_file.hpp"

#include <nlohmann/json.hpp>

#include <cmath>

namespace diffipc {

nlohmann::json summary_json(const Simulator& simulator)
{
    const Trajectory& tr = simulator.trajectory();
    nlohmann::json j;
    j["status"] = to_string(tr.final_status);
    j["scene"] = simulator.scene().source;
    j["steps_requested"] = simulator.scene().time.steps;
    j["steps_committed"] = tr.committed();
    if (tr.failed_step > 0) {
        j["failed_step"] = tr.failed_step;
        j["failure"] = tr.failure_message;
    }
    j["counts"] = { { "vertices", simulator.mesh().num_vertices() }, { "elements", simulator.mesh().num_elements() },
        { "dofs", simulator.mesh().num_dofs() }, { "bodies", simulator.scene().bodies.size() },
        { "newton_iterations", tr.newton_iterations } };
    const StepTotals& totals = tr.totals;
    j["min_volume_ratio"] = totals.min_volume_ratio;
    j["max_residual"] = totals.max_residual;
    j["linear_fallbacks"] = totals.linear_fallbacks;
    j["line_search_cuts"] = totals.line_search_cuts;
    j["roundoff_limited_steps"] = totals.roundoff_limited_steps;
    if (simulator.scene().time.adaptive.enabled)
        j["load_stepping"] = { { "substepped_steps", totals.substepped_steps }, { "substeps", totals.substeps },
            { "cuts", totals.cuts }, { "control_steps", totals.control_steps },
            { "relaxation_steps", totals.relaxation_steps },
            { "min_increment", std::isfinite(totals.min_increment) ? totals.min_increment : 0.0 } };
    j["threads"] = to_json(thread_config());
    j["wall_time"]
        = { { "total", tr.wall_time }, { "assembly", tr.phases.assembly }, { "factorization", tr.phases.factorization },
              { "solve", tr.phases.solve }, { "line_search", tr.phases.line_search } };
    // The work per potential (Problem::work): a potential the scene does not need never runs.
    nlohmann::json potentials = nlohmann::json::object();
    for (const Problem::TermWork& w : simulator.problem().work())
        potentials[w.name] = { { "values", w.values }, { "gradients", w.gradients }, { "hessians", w.hessians },
            { "step_bounds", w.step_bounds }, { "time", w.time } };
    j["potentials"] = potentials;
    if (simulator.contact()) {
        const double min_distance = totals.min_distance;
        const int max_active = totals.max_active_contacts;
        j["contact"] = { { "min_distance",
                             std::isfinite(min_distance) ? nlohmann::json(min_distance) : nlohmann::json(nullptr) },
            { "max_active_contacts", max_active }, { "final_kappa", simulator.contact()->kappa() } };
        j["wall_time"]["broad_phase"] = tr.phases.broad_phase;
        j["wall_time"]["ccd"] = tr.phases.ccd;
        j["wall_time"]["barrier"] = tr.phases.barrier;
    }
    return j;
}

void write_json(const std::string& path, const nlohmann::json& value)
{
    write_replacing(path, [&](std::ostream& out) { out << value.dump(2) << '\n'; });
}

} // namespace diffipc
