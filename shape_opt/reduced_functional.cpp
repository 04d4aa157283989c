#include "shape_opt/reduced_functional.hpp"

#include "shape_opt/problem_parameters.hpp"

#include "forward/scene/json_input.hpp"

#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/scene/json_field.hpp"
#include "objectives/objective_json.hpp"
#include "objectives/streamed.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>

namespace diffipc {

struct ReducedFunctional::LoadCase {
    Scene scene;
    nlohmann::json objective;
    std::string field;
    double weight = 1;
    /// Canonical values of the scene; mu and lambda only if they are parameters (else E and nu drive them).
    SimulationParameters base;
};

namespace {

    using json = nlohmann::json;

    constexpr int MAX_GRADCHECK_HALVINGS = 60;

    /// The problem's optional "checkpointing": {"mode": "stride" (default) | "none", "stride": s >= 0}.
    CheckpointSettings parse_checkpointing(const JsonField& j)
    {
        j.require_object({ "mode", "stride" });
        CheckpointSettings c;
        c.mode = CheckpointSettings::Mode::STRIDE;
        if (j.has("mode")) {
            const std::string mode = j["mode"].string();
            if (mode == "none")
                c.mode = CheckpointSettings::Mode::NONE;
            else if (mode != "stride")
                j["mode"].fail("expected \"stride\" or \"none\", got \"" + mode + "\"");
        }
        if (j.has("stride"))
            c.stride = j["stride"].integer(0);
        return c;
    }

} // namespace

ReducedFunctional::~ReducedFunctional() = default;
ReducedFunctional::ReducedFunctional(ReducedFunctional&&) noexcept = default;

ReducedFunctional ReducedFunctional::load(const std::string& path)
{
    const json doc = parse_json_text(read_input_file(path, "problem file"), path);
    return ReducedFunctional(doc, std::filesystem::path(path).parent_path().string(), path);
}

ReducedFunctional::ReducedFunctional(const json& doc, const std::string& base_directory, const std::string& source)
{
    if (!doc.is_object())
        throw InputError(source, "a problem file is a JSON object");
    // Every key is known and has its kind (docs/problem_format.md); nothing is ignored.
    const JsonField root(doc, "");
    root.require_object({ "description", "scene", "objective", "weight", "parameters", "gradcheck", "checkpointing",
        "threads", "scenes" });
    if (doc.contains("scenes"))
        for (const char* k : { "scene", "objective", "weight" })
            if (doc.contains(k))
                throw InputError(k, "not allowed beside \"scenes\": each load case in scenes[] has its own");
    if (root.has("description"))
        root["description"].string();
    if (doc.contains("threads")) {
        const JsonField t(doc["threads"], "threads");
        set_threads(t.integer(1), ThreadSource::PROBLEM_FILE, "threads of " + source);
    }
    json cases = doc.contains("scenes") ? doc["scenes"] : json::array({ doc });
    if (!cases.is_array() || cases.empty())
        throw InputError("scenes", "expected a non-empty list of {\"scene\", \"objective\", \"weight\"}");
    for (size_t c = 0; c < cases.size(); ++c) {
        const std::string field = doc.contains("scenes") ? "scenes[" + std::to_string(c) + "]" : std::string();
        const auto key = [&](const std::string& k) { return field.empty() ? k : field + "." + k; };
        const json& jc = cases[c];
        if (!field.empty())
            JsonField(jc, field).require_object({ "scene", "objective", "weight", "description" });
        if (!jc.contains("scene"))
            throw InputError(key("scene"), "missing (a scene file path or an inline scene object)");
        auto lc = std::make_unique<LoadCase>();
        // A scene file's errors name the file; an inline scene's name its place in the problem
        // ("scenes[1].scene.bodies[0].material.E"), and so do the simulator's checks of either.
        const bool inline_scene = !jc["scene"].is_string();
        if (!jc["scene"].is_string() && !jc["scene"].is_object())
            throw InputError(key("scene"),
                "expected a scene file path or an inline scene object, got " + std::string(jc["scene"].type_name()));
        if (jc["scene"].is_string() && jc["scene"].get<std::string>().empty())
            throw InputError(key("scene"), "an empty path (give a scene file path or an inline scene object)");
        std::string scene_file;
        const auto in_case = [&](const InputError& e) {
            if (!inline_scene)
                return InputError(scene_file + (e.field().empty() ? "" : ": " + e.field()), e.message());
            return InputError(key("scene") + (e.field().empty() ? "" : "." + e.field()), e.message());
        };
        try {
            if (inline_scene)
                lc->scene = parse_scene(jc["scene"], base_directory, "");
            else {
                scene_file
                    = (std::filesystem::path(base_directory) / JsonField(jc["scene"], key("scene")).string()).string();
                lc->scene = load_scene(scene_file);
            }
        } catch (const InputError& e) {
            if (!inline_scene)
                throw;
            throw in_case(e);
        }
        if (!jc.contains("objective"))
            throw InputError(key("objective"), "missing");
        lc->objective = jc["objective"];
        lc->field = key("objective");
        lc->weight = jc.contains("weight") ? JsonField(jc["weight"], key("weight")).number() : 1.0;
        // The barrier stiffness is fixed during a differentiated run: an adaptive one is
        // chosen by a nominal run first (its largest value, kappa never decreases).
        SimulationParameters nominal;
        std::unique_ptr<Simulator> simulator;
        try {
            if (lc->scene.contact.enabled && lc->scene.contact.adaptive_kappa) {
                Simulator probe(lc->scene);
                probe.run();
                nominal.kappa = probe.contact()->kappa();
            }
            simulator = std::make_unique<Simulator>(lc->scene, nominal);
        } catch (const InputError& e) {
            throw in_case(e);
        }
        Simulator& sim = *simulator;
        if (sim.friction() && lc->scene.friction.iterations > 1)
            throw in_case(InputError("friction.iterations",
                "must be 1 in a problem: the adjoint differentiates friction lagged once at the start of each step"));
        parse_objective(lc->objective, lc->field, sim); // validates against the scene
        lc->base = sim.parameters();
        lc->base.kappa = nominal.kappa > 0 ? nominal.kappa : lc->base.kappa;
        if (c > 0
            && (lc->base.rest_positions.size() != m_cases[0]->base.rest_positions.size()
                || lc->base.density.size() != m_cases[0]->base.density.size()))
            throw InputError(key("scene"), "every load case must use the same mesh");

        m_cases.push_back(std::move(lc));
    }

    const json params = doc.value("parameters", json::array());
    {
        SimulationParameters fixed;
        fixed.kappa = m_cases[0]->base.kappa;
        const Simulator sim(m_cases[0]->scene, fixed);
        std::vector<const SimulationParameters*> bases;
        for (const auto& lc : m_cases)
            bases.push_back(&lc->base);
        m_parameters = std::make_unique<ProblemParameters>(params, m_cases[0]->scene, sim, bases);
    }
    if (!m_parameters->lame())
        for (auto& lc : m_cases) {
            lc->base.mu.resize(0);
            lc->base.lambda.resize(0);
        }
    if (doc.contains("gradcheck")) {
        const JsonField g(doc["gradcheck"], "gradcheck");
        g.require_object({ "directions", "seed", "step", "halvings" });
        if (g.has("directions"))
            m_check.directions = g["directions"].integer(1);
        if (g.has("seed"))
            m_check.seed = unsigned(g["seed"].integer(0));
        if (g.has("step"))
            m_check.step = g["step"].positive();
        if (g.has("halvings")) {
            // Past 60 halvings the step is below a double's resolution of any parameter.
            m_check.halvings = g["halvings"].integer(2);
            if (m_check.halvings > MAX_GRADCHECK_HALVINGS)
                g["halvings"].fail("must be at most " + std::to_string(MAX_GRADCHECK_HALVINGS) + ", got "
                    + std::to_string(m_check.halvings));
        }
    }
    if (doc.contains("checkpointing"))
        m_checkpointing = parse_checkpointing(JsonField(doc["checkpointing"], "checkpointing"));
}

Index ReducedFunctional::size() const { return m_parameters->size(); }
const VectorXd& ReducedFunctional::initial() const { return m_parameters->initial(); }
const VectorXd& ReducedFunctional::scales() const { return m_parameters->scales(); }
std::vector<std::pair<std::string, Index>> ReducedFunctional::layout() const { return m_parameters->layout(); }

Evaluation ReducedFunctional::evaluate(const VectorXd& p, bool gradient) const
{
    const Index n = m_parameters->size();
    if (p.size() != n)
        throw InputError("parameters", "expected " + std::to_string(n) + " values, got " + std::to_string(p.size()));
    for (Index i = 0; i < n; ++i)
        if (!std::isfinite(p[i]))
            throw InputError("parameters[" + std::to_string(i) + "]", "non-finite value");
    Evaluation out;
    if (gradient)
        out.gradient = VectorXd::Zero(n);
    const ParameterRequest request = m_parameters->request();
    for (const auto& lc : m_cases) {
        SimulationParameters sp = lc->base;
        m_parameters->apply(p, sp);
        Simulator sim(lc->scene, sp);
        const auto objective = parse_objective(lc->objective, lc->field, sim);
        ParameterGradient g;
        if (gradient && m_checkpointing.mode != CheckpointSettings::Mode::NONE) {
            // The forward runs inside checkpointed_gradient(); J comes from the adapter's copy of the states.
            StreamedObjectiveAdapter adapter(*objective, request, lc->weight);
            LoadCaseCheckpoint c;
            g = checkpointed_gradient(sim, adapter.streamed(), request, m_checkpointing, &c.records);
            c.objective_stored_states = adapter.stored_states();
            c.objective_stored_bytes = adapter.stored_bytes();
            out.value += lc->weight * adapter.value();
            out.forward_time += c.records.forward_time;
            out.adjoint_time += c.records.recompute_time + c.records.adjoint_time;
            out.checkpoints.push_back(c);
        } else {
            Timer tf;
            sim.run();
            out.forward_time += tf.seconds();
            const Trajectory& tr = sim.trajectory();
            if (tr.final_status != StepStatus::CONVERGED)
                throw AdjointError("no value and no gradient: " + tr.failure_message);
            out.value += lc->weight * objective->value(sim, tr);
            if (!gradient)
                continue;
            Timer ta;
            StateSeed seed;
            seed.resize(int(tr.steps.size()));
            objective->add_gradient(sim, tr, request, lc->weight, seed);
            g = adjoint_gradient(sim, seed, request);
            out.adjoint_time += ta.seconds();
        }
        m_parameters->add_gradient(g, sp, out.gradient);
    }
    if (!std::isfinite(out.value))
        throw ObjectiveDomainError(
            "J = " + format_number(out.value) + ": the objective overflows (check its targets, weights and exponents)");
    if (gradient && !out.gradient.allFinite())
        throw AdjointError("no gradient: a non-finite derivative (check the objective's parameters)");
    return out;
}

} // namespace diffipc
