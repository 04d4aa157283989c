#include "shape_opt/reduced_functional.hpp"

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

    int body_index(const Scene& scene, const json& j, const std::string& field)
    {
        if (j.is_number_integer()) {
            const int b = j.get<int>();
            if (b < 0 || b >= int(scene.bodies.size()))
                throw InputError(field, "no body " + std::to_string(b));
            return b;
        }
        if (!j.is_string())
            throw InputError(field, "expected a body name or index");
        for (size_t b = 0; b < scene.bodies.size(); ++b)
            if (scene.bodies[b].name == j.get<std::string>())
                return int(b);
        throw InputError(field, "no body named '" + j.get<std::string>() + "'");
    }

    /// Vertices selected by "vertices": "all" | [indices] | {"body": name}; default all body vertices.
    std::vector<Index> select_vertices(const Scene& scene, const json& spec, const std::string& field)
    {
        std::vector<Index> out;
        const Mesh& mesh = scene.mesh;
        if (!spec.contains("vertices") || spec["vertices"] == "all") {
            for (Index v = 0; v < scene.body_vertices; ++v)
                out.push_back(v);
            return out;
        }
        const json& v = spec["vertices"];
        if (v.is_object() && v.contains("body")) {
            JsonField(v, field + ".vertices").require_object({ "body" });
            const int b = body_index(scene, v["body"], field + ".vertices.body");
            for (Index i = 0; i < scene.body_vertices; ++i)
                if (mesh.vertex_body[i] == b)
                    out.push_back(i);
            return out;
        }
        if (!v.is_array())
            throw InputError(field + ".vertices", "expected \"all\", a list of vertex indices or {\"body\": name}");
        for (size_t k = 0; k < v.size(); ++k) {
            if (!v[k].is_number_integer() || v[k].get<Index>() < 0 || v[k].get<Index>() >= mesh.num_vertices())
                throw InputError(field + ".vertices[" + std::to_string(k) + "]",
                    "expected a vertex index below " + std::to_string(mesh.num_vertices()));
            out.push_back(v[k].get<Index>());
        }
        return out;
    }

    std::string per(const json& spec, const std::string& field, const std::string& fallback)
    {
        const std::string p = spec.value("per", fallback);
        if (p != "element" && p != "body" && p != "vertex")
            throw InputError(field + ".per", "expected \"element\", \"body\" or \"vertex\"");
        return p;
    }

    using Kind = ParameterSpec::Kind;

    /// How a parameter's entries are selected in the file.
    enum class Selection {
        COMPONENTS, ///< rest-position components of vertices
        ELEMENTS, ///< per element or per body
        STATE, ///< dim-vectors per vertex or per body
        PRESCRIBED, ///< every prescribed dof at every step
        GROUPS ///< one per contact group
    };
    /// gradcheck's direction scale per variable (docs/problem_format.md "gradcheck").
    enum class Scale {
        LENGTH, ///< 1e-3 of the bounding-box diagonal
        RELATIVE, ///< 10% of the value
        BULK, ///< 10% of max(|lambda|, mu): lambda may be 0
        POISSON, ///< 0.01
        VELOCITY ///< 10% of the value, at least 0.01 m/s
    };
    /// E and nu, or mu and lambda: a problem parametrizes the elastic moduli one way.
    enum class Moduli { NONE, YOUNG_POISSON, LAME };

    /// Everything that differs between parameter kinds, in one place.
    struct KindTraits {
        Kind kind;
        const char* name; ///< "type" in the file
        Selection selection;
        /// The canonical block in SimulationParameters (values) and in the gradient of the same
        /// layout (canonical_gradient); nullptr for the prescribed matrix.
        VectorXd SimulationParameters::*block;
        bool ParameterRequest::*request;
        Scale scale;
        Moduli moduli;
    };

    using SP = SimulationParameters;
    using PR = ParameterRequest;
    const KindTraits KINDS[] = {
        { Kind::SHAPE, "shape", Selection::COMPONENTS, &SP::rest_positions, &PR::rest_positions, Scale::LENGTH,
            Moduli::NONE },
        { Kind::YOUNGS_MODULUS, "E", Selection::ELEMENTS, &SP::youngs_modulus, &PR::lame, Scale::RELATIVE,
            Moduli::YOUNG_POISSON },
        { Kind::POISSON_RATIO, "nu", Selection::ELEMENTS, &SP::poisson_ratio, &PR::lame, Scale::POISSON,
            Moduli::YOUNG_POISSON },
        { Kind::LAME_MU, "mu", Selection::ELEMENTS, &SP::mu, &PR::lame, Scale::RELATIVE, Moduli::LAME },
        { Kind::LAME_LAMBDA, "lambda", Selection::ELEMENTS, &SP::lambda, &PR::lame, Scale::BULK, Moduli::LAME },
        { Kind::DENSITY, "density", Selection::ELEMENTS, &SP::density, &PR::density, Scale::RELATIVE, Moduli::NONE },
        { Kind::INITIAL_VELOCITY, "initial_velocity", Selection::STATE, &SP::initial_velocity, &PR::initial_velocity,
            Scale::VELOCITY, Moduli::NONE },
        { Kind::INITIAL_DISPLACEMENT, "initial_displacement", Selection::STATE, &SP::initial_displacement,
            &PR::initial_displacement, Scale::LENGTH, Moduli::NONE },
        { Kind::PRESCRIBED, "prescribed", Selection::PRESCRIBED, nullptr, &PR::prescribed, Scale::LENGTH,
            Moduli::NONE },
        { Kind::FRICTION, "friction", Selection::GROUPS, &SP::friction, &PR::friction, Scale::RELATIVE, Moduli::NONE },
    };

    const KindTraits& traits(Kind kind)
    {
        for (const KindTraits& t : KINDS)
            if (t.kind == kind)
                return t;
        throw std::logic_error("reduced_functional: a parameter kind without traits");
    }

    std::string kind_names()
    {
        std::string out;
        for (const KindTraits& t : KINDS)
            out += (out.empty() ? "" : ", ") + std::string(t.name);
        return out;
    }

    /// Entry i of a kind's canonical block (the prescribed matrix row-major).
    double& canonical_entry(SimulationParameters& sp, const KindTraits& t, Index i)
    {
        if (!t.block) {
            const Index nd = sp.prescribed.cols();
            return sp.prescribed(i / nd, i % nd);
        }
        return (sp.*t.block)[i];
    }

    /// The same entry of a gradient; an empty block (no contribution) reads as 0.
    double gradient_entry(const SimulationParameters& dp, const KindTraits& t, Index i)
    {
        if (!t.block) {
            const Index nd = dp.prescribed.cols();
            return dp.prescribed.size() ? dp.prescribed(i / nd, i % nd) : 0.0;
        }
        const VectorXd& b = dp.*t.block;
        return b.size() ? b[i] : 0.0;
    }

    /// dJ/dp in the layout of SimulationParameters, so that one table serves values and
    /// derivatives; dJ/dE and dJ/dnu (at `at`) by the chain rule if `young_poisson`.
    SimulationParameters canonical_gradient(
        const ParameterGradient& g, const SimulationParameters& at, bool young_poisson)
    {
        SimulationParameters d;
        d.rest_positions = g.rest_positions;
        d.mu = g.mu;
        d.lambda = g.lambda;
        d.density = g.density;
        d.friction = g.friction;
        d.initial_displacement = g.initial_displacement;
        d.initial_velocity = g.initial_velocity;
        d.prescribed = g.prescribed;
        if (young_poisson)
            lame_to_young_poisson(
                at.youngs_modulus, at.poisson_ratio, g.mu, g.lambda, d.youngs_modulus, d.poisson_ratio);
        return d;
    }

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

    ParameterSpec parse_parameter(const Scene& scene, const Simulator& sim, const json& spec, const std::string& field)
    {
        if (!spec.is_object() || !spec.contains("type") || !spec["type"].is_string())
            throw InputError(field + ".type", "expected a parameter type (" + kind_names() + ")");
        const std::string type = spec["type"];
        for (const auto& [key, value] : spec.items()) {
            static const char* const known[] = { "type", "per", "body", "vertices", "components", "group" };
            if (std::find(std::begin(known), std::end(known), key) == std::end(known))
                throw InputError(
                    field + "." + key, "unknown field (expected type, per, body, vertices, components, group)");
        }
        if (spec.contains("per") && !spec["per"].is_string())
            throw InputError(field + ".per", "expected a string");
        const KindTraits* t = nullptr;
        for (const KindTraits& k : KINDS)
            if (type == k.name)
                t = &k;
        if (!t)
            throw InputError(field + ".type", "unknown parameter type '" + type + "' (expected " + kind_names() + ")");
        ParameterSpec p;
        p.kind = t->kind;
        p.name = type;
        p.field = field;
        const int d = scene.dim;
        const Mesh& mesh = scene.mesh;
        switch (t->selection) {
        case Selection::COMPONENTS: {
            std::vector<int> components;
            if (spec.contains("components")) {
                for (const auto& c : spec["components"]) {
                    if (!c.is_number_integer() || c.get<int>() < 0 || c.get<int>() >= d)
                        throw InputError(field + ".components", "expected component indices below the dimension");
                    components.push_back(c.get<int>());
                }
            } else
                for (int c = 0; c < d; ++c)
                    components.push_back(c);
            for (Index v : select_vertices(scene, spec, field))
                for (int c : components)
                    p.targets.push_back({ v * d + c });
            break;
        }
        case Selection::ELEMENTS: {
            const std::string mode = per(spec, field, "body");
            if (mode == "vertex")
                throw InputError(field + ".per", "material parameters are per \"element\" or per \"body\"");
            std::vector<int> bodies;
            if (spec.contains("body"))
                bodies.push_back(body_index(scene, spec["body"], field + ".body"));
            else
                for (int b = 0; b < int(scene.bodies.size()); ++b)
                    bodies.push_back(b);
            for (int b : bodies) {
                std::vector<Index> elements;
                for (Index e = 0; e < mesh.num_elements(); ++e)
                    if (mesh.element_body[e] == b)
                        elements.push_back(e);
                if (mode == "body")
                    p.targets.push_back(elements);
                else
                    for (Index e : elements)
                        p.targets.push_back({ e });
            }
            break;
        }
        case Selection::STATE: {
            if (!sim.dynamic() && t->kind == Kind::INITIAL_VELOCITY)
                throw InputError(field, "a static scene has no initial velocity");
            const std::string mode = per(spec, field, "body");
            if (mode == "element")
                throw InputError(field + ".per", "initial states are per \"body\" or per \"vertex\"");
            std::vector<Index> vertices;
            if (spec.contains("body")) {
                const int b = body_index(scene, spec["body"], field + ".body");
                for (Index v = 0; v < scene.body_vertices; ++v)
                    if (mesh.vertex_body[v] == b)
                        vertices.push_back(v);
            } else
                vertices = select_vertices(scene, spec, field);
            // A prescribed dof (Dirichlet or obstacle) keeps its prescribed initial state: a value
            // there would be dead. Whole-body selections skip those dofs; a listed vertex, or a
            // body component with no free dof left, is refused.
            const std::vector<Index> prescribed_list = sim.prescribed_dofs();
            const std::set<Index> prescribed(prescribed_list.begin(), prescribed_list.end());
            const bool listed = spec.contains("vertices") && spec["vertices"].is_array();
            for (Index v : vertices)
                for (int c = 0; listed && c < d; ++c)
                    if (prescribed.count(v * d + c))
                        throw InputError(field + ".vertices",
                            "vertex " + std::to_string(v) + " is prescribed in component " + std::to_string(c)
                                + " (Dirichlet or obstacle): its initial state is the prescription's");
            if (mode == "body") {
                for (int c = 0; c < d; ++c) {
                    std::vector<Index> dofs;
                    for (Index v : vertices)
                        if (!prescribed.count(v * d + c))
                            dofs.push_back(v * d + c);
                    if (dofs.empty())
                        throw InputError(field,
                            "component " + std::to_string(c)
                                + " of the selected vertices is prescribed everywhere (Dirichlet or obstacle): "
                                  "an initial state there has no effect");
                    p.targets.push_back(dofs);
                }
            } else
                for (Index v : vertices)
                    for (int c = 0; c < d; ++c)
                        if (!prescribed.count(v * d + c))
                            p.targets.push_back({ v * d + c });
            if (p.targets.empty())
                throw InputError(field, "every selected dof is prescribed: an initial state there has no effect");
            break;
        }
        case Selection::PRESCRIBED: {
            const Index nd = Index(sim.prescribed_dofs().size());
            if (nd == 0)
                throw InputError(field, "the scene has no prescribed dofs (Dirichlet or obstacles)");
            for (Index k = 0; k < Index(scene.time.steps) * nd; ++k)
                p.targets.push_back({ k });
            break;
        }
        case Selection::GROUPS: {
            if (!sim.friction())
                throw InputError(field, "the scene has no friction (no contact, or every coefficient is 0)");
            // Contact groups: the bodies, then the obstacles.
            const std::string mode = spec.value("per", std::string("group"));
            if (mode != "group" && mode != "global")
                throw InputError(field + ".per", "friction is per \"group\" (body or obstacle) or \"global\"");
            std::vector<Index> groups;
            if (spec.contains("group")) {
                const json& g = spec["group"];
                Index found = -1;
                if (g.is_number_integer() && g.get<Index>() >= 0 && g.get<Index>() < sim.num_groups())
                    found = g.get<Index>();
                for (size_t b = 0; g.is_string() && b < scene.bodies.size(); ++b)
                    if (scene.bodies[b].name == g.get<std::string>())
                        found = Index(b);
                for (size_t o = 0; g.is_string() && o < scene.obstacles.size(); ++o)
                    if (scene.obstacles[o].name == g.get<std::string>())
                        found = Index(scene.bodies.size() + o);
                if (found < 0)
                    throw InputError(field + ".group", "expected the name or index of a body or obstacle");
                groups.push_back(found);
            } else
                for (Index g = 0; g < sim.num_groups(); ++g)
                    groups.push_back(g);
            for (Index g : groups)
                if (!(sim.friction()->group_coefficients()[size_t(g)] > 0))
                    throw InputError(field,
                        "contact group " + std::to_string(g)
                            + " has friction coefficient 0, where a pair's coefficient sqrt(mu_a mu_b) "
                              "is not differentiable; start from a positive value");
            if (mode == "global") {
                // One value for the selected groups: they must start equal, or p = initial() would change the scene.
                const std::vector<double>& mu = sim.friction()->group_coefficients();
                for (Index g : groups)
                    if (mu[size_t(g)] != mu[size_t(groups.front())])
                        throw InputError(field + ".per",
                            "\"global\" needs the selected groups to share one coefficient ("
                                + std::to_string(mu[size_t(groups.front())]) + " and " + std::to_string(mu[size_t(g)])
                                + " differ)");
                p.targets.push_back(groups);
            } else
                for (Index g : groups)
                    p.targets.push_back({ g });
            break;
        }
        }
        if (p.targets.empty())
            throw InputError(field, "selects nothing");
        return p;
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
    if (!params.is_array() || params.empty())
        throw InputError("parameters", "expected a non-empty list");
    {
        SimulationParameters fixed;
        fixed.kappa = m_cases[0]->base.kappa;
        Simulator sim(m_cases[0]->scene, fixed);
        for (size_t k = 0; k < params.size(); ++k)
            m_parameters.push_back(
                parse_parameter(m_cases[0]->scene, sim, params[k], "parameters[" + std::to_string(k) + "]"));
    }
    // Friction and prescribed values index the first case's contact groups and
    // prescribed dofs per step: every case must have the same ones.
    for (const auto& p : m_parameters)
        for (size_t c = 1; c < m_cases.size(); ++c) {
            const SimulationParameters &a = m_cases[0]->base, &b = m_cases[c]->base;
            if ((p.kind == Kind::FRICTION && a.friction.size() != b.friction.size())
                || (p.kind == Kind::PRESCRIBED
                    && (a.prescribed.rows() != b.prescribed.rows() || a.prescribed.cols() != b.prescribed.cols())))
                throw InputError(p.field,
                    "every load case must have the same "
                        + std::string(p.kind == Kind::FRICTION ? "bodies and obstacles (contact groups)"
                                                               : "prescribed dofs and number of steps")
                        + " for this parameter");
        }
    // Every value is driven by one entry at most: a vertex or a block listed twice (in one
    // parameter or in two) would make the forward use the last entry while the gradient is
    // split over both.
    {
        std::map<std::pair<int, Index>, std::pair<size_t, size_t>> driver; // (kind, target) -> (parameter, entry)
        const int d = m_cases[0]->scene.dim;
        for (size_t k = 0; k < m_parameters.size(); ++k) {
            const ParameterSpec& p = m_parameters[k];
            for (size_t i = 0; i < p.targets.size(); ++i)
                for (const Index target : p.targets[i]) {
                    const auto [at, inserted]
                        = driver.emplace(std::make_pair(int(p.kind), target), std::make_pair(k, i));
                    if (inserted)
                        continue;
                    const bool per_dof = p.kind == Kind::SHAPE || p.kind == Kind::INITIAL_VELOCITY
                        || p.kind == Kind::INITIAL_DISPLACEMENT;
                    const std::string what = per_dof
                        ? "vertex " + std::to_string(target / d) + " component " + std::to_string(target % d)
                        : "value " + std::to_string(target);
                    throw InputError(p.field,
                        "'" + p.name + "' " + what + " is already a parameter (" + m_parameters[at->second.first].field
                            + ", entry " + std::to_string(at->second.second) + "): each value may be listed once");
                }
        }
    }
    // E and nu, or mu and lambda: SimulationParameters' mu and lambda override E and nu.
    Moduli moduli = Moduli::NONE;
    std::string moduli_field;
    for (const auto& p : m_parameters) {
        const KindTraits& t = traits(p.kind);
        if (t.moduli != Moduli::NONE) {
            if (moduli != Moduli::NONE && moduli != t.moduli)
                throw InputError(p.field + ".type",
                    "'" + p.name + "' cannot be combined with " + moduli_field
                        + ": parametrize the elastic moduli by E and nu or by the Lame parameters mu and lambda");
            if (moduli == Moduli::NONE)
                moduli_field = "'" + p.name + "' (" + p.field + ")";
            moduli = t.moduli;
        }
        m_offsets.push_back(m_size);
        m_size += Index(p.targets.size());
    }
    m_lame = moduli == Moduli::LAME;
    m_initial.resize(m_size);
    m_scales.resize(m_size);
    SimulationParameters base = m_cases[0]->base;
    const double length = [&] {
        const Positions& X = m_cases[0]->scene.mesh.rest_positions;
        return (X.colwise().maxCoeff() - X.colwise().minCoeff()).norm();
    }();
    for (size_t k = 0; k < m_parameters.size(); ++k) {
        const KindTraits& t = traits(m_parameters[k].kind);
        for (size_t i = 0; i < m_parameters[k].targets.size(); ++i) {
            const Index j = m_offsets[k] + Index(i), first = m_parameters[k].targets[i][0];
            const double v = canonical_entry(base, t, first);
            m_initial[j] = v;
            switch (t.scale) {
            case Scale::LENGTH:
                m_scales[j] = 1e-3 * length;
                break;
            case Scale::RELATIVE:
                m_scales[j] = 0.1 * std::abs(v);
                break;
            case Scale::BULK:
                m_scales[j] = 0.1 * std::max(std::abs(v), base.mu[first]);
                break;
            case Scale::POISSON:
                m_scales[j] = 0.01;
                break;
            case Scale::VELOCITY:
                m_scales[j] = std::max(0.1 * std::abs(v), 1e-2);
                break;
            }
        }
    }
    if (!m_lame)
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

std::vector<std::pair<std::string, Index>> ReducedFunctional::layout() const
{
    std::vector<std::pair<std::string, Index>> out;
    for (const auto& p : m_parameters)
        out.emplace_back(p.name, Index(p.targets.size()));
    return out;
}

Evaluation ReducedFunctional::evaluate(const VectorXd& p, bool gradient) const
{
    if (p.size() != m_size)
        throw InputError(
            "parameters", "expected " + std::to_string(m_size) + " values, got " + std::to_string(p.size()));
    for (Index i = 0; i < m_size; ++i)
        if (!std::isfinite(p[i]))
            throw InputError("parameters[" + std::to_string(i) + "]", "non-finite value");
    Evaluation out;
    if (gradient)
        out.gradient = VectorXd::Zero(m_size);
    ParameterRequest request;
    for (const auto& s : m_parameters)
        request.*traits(s.kind).request = true;
    for (const auto& lc : m_cases) {
        SimulationParameters sp = lc->base;
        for (size_t k = 0; k < m_parameters.size(); ++k)
            for (size_t i = 0; i < m_parameters[k].targets.size(); ++i)
                for (Index t : m_parameters[k].targets[i])
                    canonical_entry(sp, traits(m_parameters[k].kind), t) = p[m_offsets[k] + Index(i)];
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
        const SimulationParameters dJ = canonical_gradient(g, sp, request.lame && !m_lame);
        for (size_t k = 0; k < m_parameters.size(); ++k) {
            const KindTraits& t = traits(m_parameters[k].kind);
            for (size_t i = 0; i < m_parameters[k].targets.size(); ++i)
                for (Index target : m_parameters[k].targets[i])
                    out.gradient[m_offsets[k] + Index(i)] += gradient_entry(dJ, t, target);
        }
    }
    if (!std::isfinite(out.value))
        throw ObjectiveDomainError(
            "J = " + format_number(out.value) + ": the objective overflows (check its targets, weights and exponents)");
    if (gradient && !out.gradient.allFinite())
        throw AdjointError("no gradient: a non-finite derivative (check the objective's parameters)");
    return out;
}

} // namespace diffipc
