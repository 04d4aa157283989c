#include "shape_opt/reduced_functional.hpp"

#include "shape_opt/case_distribution.hpp"
#include "shape_opt/problem_parameters.hpp"

#include "forward/scene/json_input.hpp"

#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/scene/json_field.hpp"
#include "objectives/objective_json.hpp"
#include "objectives/streamed.hpp"

#include <algorithm>
#include <atomic>
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

    /// into = the sorted union of into and from (the adjoint blocks of an Evaluation).
    void merge_blocks(std::vector<std::string>& into, const std::vector<std::string>& from)
    {
        for (const std::string& b : from)
            if (std::find(into.begin(), into.end(), b) == into.end())
                into.push_back(b);
        std::sort(into.begin(), into.end());
    }

} // namespace

ReducedFunctional::~ReducedFunctional() = default;
ReducedFunctional::ReducedFunctional(ReducedFunctional&&) noexcept = default;

namespace {

    uint64_t next_problem_id()
    {
        static std::atomic<uint64_t> next { 1 };
        return next++;
    }

} // namespace

ReducedFunctional ReducedFunctional::load(const std::string& path, const std::string& device)
{
    const json doc = parse_json_text(read_input_file(path, "problem file"), path);
    return ReducedFunctional(doc, std::filesystem::path(path).parent_path().string(), path, device);
}

namespace {

    /// Relative "file" paths of markers objectives made absolute against the problem's folder,
    /// wherever they sit (objective, load cases, constraints, combinators' terms).
    void absolute_marker_files(json& node, const std::string& base_directory)
    {
        if (node.is_object()) {
            if (node.contains("type") && node["type"] == "markers" && node.contains("file")
                && node["file"].is_string()) {
                const std::filesystem::path file = node["file"].get<std::string>();
                if (file.is_relative() && !file.empty())
                    node["file"] = std::filesystem::absolute(std::filesystem::path(base_directory) / file)
                                       .lexically_normal()
                                       .string();
            }
            for (auto& [key, value] : node.items())
                if (key != "scene")
                    absolute_marker_files(value, base_directory);
        } else if (node.is_array())
            for (auto& value : node)
                absolute_marker_files(value, base_directory);
    }

} // namespace

ReducedFunctional::ReducedFunctional(
    const json& document, const std::string& base_directory, const std::string& source, const std::string& device)
    : m_device(device)
    , m_source(source)
    , m_id(next_problem_id())
{
    if (!document.is_object())
        throw InputError(source, "a problem file is a JSON object");
    json doc = document;
    absolute_marker_files(doc, base_directory.empty() ? "." : base_directory);
    // Every key is known and has its kind (docs/problem_format.md); nothing is ignored.
    const JsonField root(doc, "");
    root.require_object({ "description", "scene", "objective", "weight", "parameters", "gradcheck", "checkpointing",
        "threads", "scenes", "constraints", "optimizer", "output", "remesh" });
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
        if (!device.empty()) { // before the nominal run below: it runs there too
            try {
                select_device(lc->scene, device, "device");
            } catch (const InputError& e) {
                throw in_case(e);
            }
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
        try {
            lc->base = sim.parameters(); // every step's prescribed values: time.steps may not fit
        } catch (const InputError& e) {
            throw in_case(e);
        }
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
    if (doc.contains("constraints"))
        parse_constraints(JsonField(doc["constraints"], "constraints"));
    if (doc.contains("optimizer")) {
        if (!doc["optimizer"].is_object())
            throw InputError("optimizer", "expected an object (docs/optimization.md)");
        m_optimizer = doc["optimizer"];
    }
    if (doc.contains("remesh")) {
        m_remesh = parse_remesh_settings(JsonField(doc["remesh"], "remesh"));
        if (const std::string why = m_parameters->remesh_obstacle(); !why.empty())
            throw InputError("remesh", why);
        const std::string vertices = vertex_selection(doc);
        if (!vertices.empty())
            throw InputError(
                "remesh", vertices + " selects vertices by index, which a remesh renumbers: select by region instead");
    }
    if (doc.contains("output") && !doc["output"].is_object())
        throw InputError("output", "expected an object (docs/optimization.md)");
    m_document = doc;
    m_base_directory = base_directory;
}

void ReducedFunctional::parse_constraints(const JsonField& list)
{
    list.require_array();
    for (size_t i = 0; i < list.size(); ++i) {
        const JsonField f = list.at(i);
        f.require_object({ "name", "objective", "case", "upper", "lower", "equals" });
        ConstraintSpec c;
        c.field = f.path();
        c.name = f.has("name") ? f["name"].string() : "constraint " + std::to_string(i);
        if (int(f.has("upper")) + int(f.has("lower")) + int(f.has("equals")) != 1)
            f.fail("give exactly one of \"upper\", \"lower\" or \"equals\"");
        c.kind = f.has("upper") ? ConstraintSpec::Kind::UPPER
            : f.has("lower")    ? ConstraintSpec::Kind::LOWER
                                : ConstraintSpec::Kind::EQUALS;
        c.bound = f[f.has("upper") ? "upper" : f.has("lower") ? "lower" : "equals"].number();
        if (f.has("case")) {
            const int k = f["case"].integer(0);
            if (k >= int(m_cases.size()))
                f["case"].fail("no load case " + std::to_string(k) + " (" + std::to_string(m_cases.size()) + " cases)");
            c.load_case = size_t(k);
        } else if (m_cases.size() > 1)
            f.fail("name the load case (\"case\": an index into scenes) the constraint is measured on");
        if (!f.has("objective"))
            f["objective"].fail("missing: the functional the constraint bounds (an objective, docs/objectives.md)");
        c.objective = f["objective"].json();
        {
            // Validated against its load case now, like the objectives.
            SimulationParameters fixed;
            fixed.kappa = m_cases[c.load_case]->base.kappa;
            const Simulator sim(m_cases[c.load_case]->scene, fixed);
            parse_objective(c.objective, c.field + ".objective", sim);
        }
        for (const ConstraintSpec& other : m_constraints)
            if (other.name == c.name)
                f["name"].fail("duplicate constraint name '" + c.name + "'");
        m_constraints.push_back(std::move(c));
    }
}

Index ReducedFunctional::size() const { return m_parameters->size(); }
const VectorXd& ReducedFunctional::initial() const { return m_parameters->initial(); }
const VectorXd& ReducedFunctional::scales() const { return m_parameters->scales(); }
std::vector<std::pair<std::string, Index>> ReducedFunctional::layout() const { return m_parameters->layout(); }
Index ReducedFunctional::design_size() const { return m_parameters->design_size(); }
const VectorXd& ReducedFunctional::design_initial() const { return m_parameters->design_initial(); }
std::vector<std::pair<std::string, Index>> ReducedFunctional::design_layout() const
{
    return m_parameters->design_layout();
}

bool ReducedFunctional::has_shape() const
{
    for (const ParameterSpec& e : m_parameters->entries())
        if (e.kind == ParameterSpec::Kind::SHAPE)
            return true;
    return false;
}

SimulationParameters ReducedFunctional::simulation_parameters_of(const VectorXd& p) const
{
    SimulationParameters sp = m_cases[0]->base;
    m_parameters->apply(p, sp);
    return sp;
}

VectorXd ReducedFunctional::rest_positions_of(const VectorXd& p) const
{
    return simulation_parameters_of(p).rest_positions.head(m_cases[0]->scene.body_vertices * m_cases[0]->scene.dim);
}

const Scene& ReducedFunctional::scene() const { return m_cases[0]->scene; }
const Scene& ReducedFunctional::scene(size_t c) const { return m_cases.at(c)->scene; }
size_t ReducedFunctional::load_cases() const { return m_cases.size(); }

Positions ReducedFunctional::pull_back_shape(const VectorXd& x, const Positions& current) const
{
    return m_parameters->pull_back_shape(x, current);
}

std::string ReducedFunctional::remesh_obstacle() const { return m_parameters->remesh_obstacle(); }

ShapeLatticeInput ReducedFunctional::shape_lattice_input(const VectorXd& x) const
{
    return m_parameters->shape_lattice_input(x);
}

const VectorXd& ReducedFunctional::design_lower() const { return m_parameters->design_lower(); }
const VectorXd& ReducedFunctional::design_upper() const { return m_parameters->design_upper(); }

VectorXd ReducedFunctional::parameters_of(const VectorXd& x) const
{
    if (x.size() != design_size())
        throw InputError(
            "design", "expected " + std::to_string(design_size()) + " values, got " + std::to_string(x.size()));
    for (Index i = 0; i < x.size(); ++i)
        if (!std::isfinite(x[i]))
            throw InputError("design[" + std::to_string(i) + "]", "non-finite value");
    return m_parameters->parameters_of(x);
}

VectorXd ReducedFunctional::design_gradient(const VectorXd& x, const VectorXd& dJ_dp) const
{
    if (x.size() != design_size() || dJ_dp.size() != size())
        throw InputError("design",
            "expected " + std::to_string(design_size()) + " design values and " + std::to_string(size())
                + " gradient values, got " + std::to_string(x.size()) + " and " + std::to_string(dJ_dp.size()));
    return m_parameters->design_gradient(x, dJ_dp);
}

void ReducedFunctional::check_parameters(const VectorXd& p) const
{
    const Index n = m_parameters->size();
    if (p.size() != n)
        throw InputError("parameters", "expected " + std::to_string(n) + " values, got " + std::to_string(p.size()));
    for (Index i = 0; i < n; ++i)
        if (!std::isfinite(p[i]))
            throw InputError("parameters[" + std::to_string(i) + "]", "non-finite value");
}

void ReducedFunctional::add_share(Evaluation& total, const Evaluation& share)
{
    const auto add = [](auto& to, const auto& from) {
        if (to.size() == 0)
            to = from;
        else if (from.size() != 0)
            to += from;
    };
    total.value += share.value;
    add(total.gradient, share.gradient);
    add(total.constraint_values, share.constraint_values);
    add(total.constraint_gradients, share.constraint_gradients);
    total.forward_time += share.forward_time;
    total.adjoint_time += share.adjoint_time;
    total.checkpoints.insert(total.checkpoints.end(), share.checkpoints.begin(), share.checkpoints.end());
    merge_blocks(total.adjoint_blocks, share.adjoint_blocks);
}

Evaluation ReducedFunctional::evaluate(const VectorXd& p, bool gradient, bool constraints) const
{
    if (m_distribution)
        return m_distribution->evaluate(*this, p, gradient, constraints);
    check_parameters(p);
    Evaluation out;
    for (size_t c = 0; c < m_cases.size(); ++c)
        add_share(out, evaluate_case(c, p, gradient, constraints));
    check_sum(out, gradient, constraints);
    return out;
}

void ReducedFunctional::check_sum(const Evaluation& out, bool gradient, bool constraints) const
{
    const int m = constraints ? int(m_constraints.size()) : 0;
    if (!std::isfinite(out.value))
        throw ObjectiveDomainError(
            "J = " + format_number(out.value) + ": the objective overflows (check its targets, weights and exponents)");
    for (int i = 0; i < m; ++i)
        if (!std::isfinite(out.constraint_values[i]))
            throw ObjectiveDomainError(m_constraints[size_t(i)].field + " = " + format_number(out.constraint_values[i])
                + ": the constraint's functional overflows");
    if (gradient && (!out.gradient.allFinite() || !out.constraint_gradients.allFinite()))
        throw AdjointError("no gradient: a non-finite derivative (check the objective's parameters)");
}

Evaluation ReducedFunctional::evaluate_case(size_t c, const VectorXd& p, bool gradient, bool constraints) const
{
    if (c >= m_cases.size())
        throw std::out_of_range("ReducedFunctional::evaluate_case: load case " + std::to_string(c) + " of "
            + std::to_string(m_cases.size()));
    check_parameters(p);
    const Index n = m_parameters->size();
    Evaluation out;
    if (gradient)
        out.gradient = VectorXd::Zero(n);
    const int m = constraints ? int(m_constraints.size()) : 0;
    out.constraint_values = VectorXd::Zero(m);
    if (gradient)
        out.constraint_gradients = MatrixXd::Zero(m, n);
    const ParameterRequest request = m_parameters->request();
    const LoadCase& lc = *m_cases[c];
    SimulationParameters sp = lc.base;
    m_parameters->apply(p, sp);
    // The functionals of this case: its objective (row -1), then the constraints on it.
    std::vector<int> rows { -1 };
    for (int i = 0; i < m; ++i)
        if (m_constraints[size_t(i)].load_case == c)
            rows.push_back(i);
    // Row -1 is the objective (weighted; its gradient adds to out.gradient), row i >= 0
    // constraint i (unweighted; its value and gradient fill row i).
    const auto functional = [&](int row, const Simulator& sim) {
        return row < 0 ? parse_objective(lc.objective, lc.field, sim)
                       : parse_objective(
                           m_constraints[size_t(row)].objective, m_constraints[size_t(row)].field + ".objective", sim);
    };
    const auto store = [&](int row, double value, const ParameterGradient* g, const Simulator& sim) {
        if (row < 0)
            out.value += lc.weight * value;
        else
            out.constraint_values[row] = value;
        if (!g)
            return;
        merge_blocks(out.adjoint_blocks, computed_blocks(*g));
        if (row < 0) {
            m_parameters->add_gradient(*g, sp, sim.plane_stress(), out.gradient);
            return;
        }
        VectorXd dg = VectorXd::Zero(n);
        m_parameters->add_gradient(*g, sp, sim.plane_stress(), dg);
        out.constraint_gradients.row(row) = dg.transpose();
    };
    if (gradient && m_checkpointing.mode != CheckpointSettings::Mode::NONE) {
        // The forward runs inside checkpointed_gradient(), once per functional; values come
        // from the adapter's copy of the states.
        for (const int row : rows) {
            Simulator sim(lc.scene, sp);
            const auto objective = functional(row, sim);
            StreamedObjectiveAdapter adapter(*objective, request, row < 0 ? lc.weight : 1.0);
            LoadCaseCheckpoint record;
            const ParameterGradient g
                = checkpointed_gradient(sim, adapter.streamed(), request, m_checkpointing, &record.records);
            record.objective_stored_states = adapter.stored_states();
            record.objective_stored_bytes = adapter.stored_bytes();
            out.forward_time += record.records.forward_time;
            out.adjoint_time += record.records.recompute_time + record.records.adjoint_time;
            if (row < 0)
                out.checkpoints.push_back(record);
            store(row, adapter.value(), &g, sim);
        }
        return out;
    }
    Simulator sim(lc.scene, sp);
    std::vector<std::unique_ptr<Objective>> objectives;
    for (const int row : rows)
        objectives.push_back(functional(row, sim));
    Timer tf;
    sim.run();
    out.forward_time += tf.seconds();
    const Trajectory& tr = sim.trajectory();
    if (tr.final_status != StepStatus::CONVERGED)
        throw AdjointError("no value and no gradient: " + tr.failure_message);
    // One backward sweep for all the functionals: each step's adjoint system is factorized once.
    std::vector<double> values;
    for (const auto& objective : objectives)
        values.push_back(objective->value(sim, tr));
    std::vector<ParameterGradient> gradients;
    if (gradient) {
        Timer ta;
        std::vector<StateSeed> seeds(rows.size());
        for (size_t r = 0; r < rows.size(); ++r) {
            seeds[r].resize(int(tr.steps.size()));
            objectives[r]->add_gradient(sim, tr, request, rows[r] < 0 ? lc.weight : 1.0, seeds[r]);
        }
        gradients = adjoint_gradients(sim, seeds, request);
        out.adjoint_time += ta.seconds();
    }
    for (size_t r = 0; r < rows.size(); ++r)
        store(rows[r], values[r], gradient ? &gradients[r] : nullptr, sim);
    return out;
}

} // namespace diffipc
