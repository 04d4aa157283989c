#include "shape_opt/problem_parameters.hpp"

#include "forward/common/error.hpp"
#include "forward/scene/json_field.hpp"
#include "shape_opt/parametrization/map_json.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>

namespace diffipc {

namespace {

    using json = nlohmann::json;

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
    SimulationParameters canonical_gradient(const ParameterGradient& g, const SimulationParameters& at,
        bool young_poisson, const std::vector<char>& plane_stress)
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
                at.youngs_modulus, at.poisson_ratio, g.mu, g.lambda, d.youngs_modulus, d.poisson_ratio, plane_stress);
        return d;
    }

    /// The keys an entry of a type with this selection reads (docs/problem_format.md, "types that use it").
    std::vector<std::string> own_keys(Selection selection)
    {
        std::vector<std::string> keys { "type" };
        switch (selection) {
        case Selection::COMPONENTS:
            keys.insert(keys.end(), { "vertices", "components" });
            break;
        case Selection::ELEMENTS:
            keys.insert(keys.end(), { "per", "body" });
            break;
        case Selection::STATE:
            keys.insert(keys.end(), { "per", "body", "vertices" });
            break;
        case Selection::PRESCRIBED:
            break;
        case Selection::GROUPS:
            keys.insert(keys.end(), { "per", "group" });
            break;
        }
        keys.insert(keys.end(), { "maps", "initial", "lower", "upper" });
        return keys;
    }

    ParameterSpec parse_parameter(const Scene& scene, const Simulator& sim, const json& spec, const std::string& field)
    {
        if (!spec.is_object() || !spec.contains("type") || !spec["type"].is_string())
            throw InputError(field + ".type", "expected a parameter type (" + kind_names() + ")");
        const std::string type = spec["type"];
        // The keys of any type: the union of own_keys (one list, not a second one kept by hand).
        static const std::vector<std::string> known = [] {
            std::vector<std::string> all;
            for (const Selection s : { Selection::COMPONENTS, Selection::ELEMENTS, Selection::STATE,
                     Selection::PRESCRIBED, Selection::GROUPS })
                for (const std::string& k : own_keys(s))
                    if (std::find(all.begin(), all.end(), k) == all.end())
                        all.push_back(k);
            return all;
        }();
        for (const auto& [key, value] : spec.items())
            if (std::find(known.begin(), known.end(), key) == known.end()) {
                std::string list;
                for (const std::string& k : known)
                    list += (list.empty() ? "" : ", ") + k;
                throw InputError(field + "." + key, "unknown field (expected " + list + ")");
            }
        if (spec.contains("per") && !spec["per"].is_string())
            throw InputError(field + ".per", "expected a string");
        const KindTraits* t = nullptr;
        for (const KindTraits& k : KINDS)
            if (type == k.name)
                t = &k;
        if (!t)
            throw InputError(field + ".type", "unknown parameter type '" + type + "' (expected " + kind_names() + ")");
        // A key that another type uses is refused too: `body` on a shape entry once selected every body.
        const std::vector<std::string> own = own_keys(t->selection);
        for (const auto& [key, value] : spec.items())
            if (std::find(own.begin(), own.end(), key) == own.end()) {
                std::string list;
                for (const std::string& k : own)
                    list += (list.empty() ? "" : ", ") + k;
                throw InputError(field + "." + key,
                    "a \"" + type + "\" parameter does not use this key (its keys: " + list + ")"
                        + (key == "body" && t->selection == Selection::COMPONENTS
                                ? "; select a body's vertices with \"vertices\": {\"body\": name}"
                                : ""));
            }
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
                // An object iterates as its values: {} selected nothing, silently.
                const json& list = spec["components"];
                if (!list.is_array() || list.empty())
                    throw InputError(field + ".components",
                        "expected a non-empty list of component indices below the dimension, got "
                            + (list.is_array() ? std::string("an empty list")
                                               : "a JSON " + std::string(list.type_name())));
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
            p.per_mesh_item = mode == "element";
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
            } else {
                for (Index v : vertices)
                    for (int c = 0; c < d; ++c)
                        if (!prescribed.count(v * d + c))
                            p.targets.push_back({ v * d + c });
                p.per_mesh_item = true;
            }
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
            p.per_mesh_item = true; // the prescribed dofs are the mesh's
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

ProblemParameters::ProblemParameters(
    const json& params, const Scene& scene, const Simulator& sim, const std::vector<const SimulationParameters*>& bases)
{
    if (!params.is_array() || params.empty())
        throw InputError("parameters", "expected a non-empty list");
    for (size_t k = 0; k < params.size(); ++k)
        m_entries.push_back(parse_parameter(scene, sim, params[k], "parameters[" + std::to_string(k) + "]"));
    // Friction and prescribed values index the first case's contact groups and
    // prescribed dofs per step: every case must have the same ones.
    for (const auto& p : m_entries)
        for (size_t c = 1; c < bases.size(); ++c) {
            const SimulationParameters &a = *bases[0], &b = *bases[c];
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
        const int d = scene.dim;
        for (size_t k = 0; k < m_entries.size(); ++k) {
            const ParameterSpec& p = m_entries[k];
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
                        "'" + p.name + "' " + what + " is already a parameter (" + m_entries[at->second.first].field
                            + ", entry " + std::to_string(at->second.second) + "): each value may be listed once");
                }
        }
    }
    // E and nu, or mu and lambda: SimulationParameters' mu and lambda override E and nu.
    Moduli moduli = Moduli::NONE;
    std::string moduli_field;
    for (const auto& p : m_entries) {
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
    SimulationParameters base = *bases[0]; // canonical_entry() reads a mutable block
    const double length = [&] {
        const Positions& X = scene.mesh.rest_positions;
        return (X.colwise().maxCoeff() - X.colwise().minCoeff()).norm();
    }();
    for (size_t k = 0; k < m_entries.size(); ++k) {
        const KindTraits& t = traits(m_entries[k].kind);
        for (size_t i = 0; i < m_entries[k].targets.size(); ++i) {
            const Index j = m_offsets[k] + Index(i), first = m_entries[k].targets[i][0];
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
    parse_maps(params, scene);
}

void ProblemParameters::parse_maps(const json& params, const Scene& scene)
{
    const int d = scene.dim;
    std::vector<std::unique_ptr<ParameterMap>> parts;
    std::vector<VectorXd> initials, lowers, uppers;
    for (size_t k = 0; k < m_entries.size(); ++k) {
        const ParameterSpec& entry = m_entries[k];
        const json& spec = params[k];
        EntryLayout layout;
        layout.size = Index(entry.targets.size());
        layout.name = entry.name;
        const bool material = entry.kind == Kind::YOUNGS_MODULUS || entry.kind == Kind::POISSON_RATIO
            || entry.kind == Kind::LAME_MU || entry.kind == Kind::LAME_LAMBDA || entry.kind == Kind::DENSITY;
        if (material
            && std::all_of(entry.targets.begin(), entry.targets.end(), [](const auto& t) { return t.size() == 1; })) {
            layout.kind = EntryLayout::Kind::PER_ELEMENT;
            for (const auto& t : entry.targets)
                layout.elements.push_back(t[0]);
        }
        if (entry.kind == Kind::SHAPE && layout.size == scene.body_vertices * d) {
            bool in_order = true;
            for (Index i = 0; i < layout.size && in_order; ++i)
                in_order = entry.targets[size_t(i)].size() == 1 && entry.targets[size_t(i)][0] == i;
            if (in_order)
                layout.kind = EntryLayout::Kind::ALL_BODY_POSITIONS;
        }
        std::unique_ptr<ParameterChain> chain;
        if (spec.contains("maps")) {
            m_has_maps = true;
            chain = std::make_unique<ParameterChain>(
                parse_entry_maps(JsonField(spec["maps"], entry.field + ".maps"), layout, scene));
        } else
            chain = std::make_unique<ParameterChain>(layout.size);
        // The start: "initial", else the inverse of the entry's values, else 0 if the maps give them there.
        const VectorXd p0 = m_initial.segment(m_offsets[k], layout.size);
        VectorXd x0;
        if (spec.contains("initial")) {
            const JsonField f(spec["initial"], entry.field + ".initial");
            x0 = f.json().is_array() ? f.vector(int(chain->in_size()))
                                     : VectorXd::Constant(chain->in_size(), f.number());
        } else if (chain->invertible())
            x0 = chain->inverse(p0, entry.field + ".maps");
        else {
            x0 = VectorXd::Zero(chain->in_size());
            const VectorXd at_zero = chain->apply(x0);
            if ((at_zero - p0).lpNorm<Eigen::Infinity>() > 1e-12 * std::max(1.0, p0.lpNorm<Eigen::Infinity>()))
                throw InputError(entry.field + ".maps",
                    "the maps have no inverse and do not give the scene's values at 0: give \"initial\" design values");
        }
        // Bounds of the design variables: a number for all or one per design value.
        const auto bound = [&](const char* key, double fallback) -> VectorXd {
            if (!spec.contains(key))
                return VectorXd::Constant(chain->in_size(), fallback);
            const JsonField f(spec[key], entry.field + "." + key);
            return f.json().is_array() ? f.vector(int(chain->in_size()))
                                       : VectorXd::Constant(chain->in_size(), f.number());
        };
        const VectorXd lower = bound("lower", -std::numeric_limits<double>::infinity());
        const VectorXd upper = bound("upper", std::numeric_limits<double>::infinity());
        for (Index i = 0; i < lower.size(); ++i) {
            if (!(lower[i] <= upper[i]))
                throw InputError(entry.field + ".lower",
                    "lower bound " + format_number(lower[i]) + " is above the upper bound " + format_number(upper[i])
                        + " (design value " + std::to_string(i) + ")");
            if (!(x0[i] >= lower[i] && x0[i] <= upper[i]))
                throw InputError(entry.field + (spec.contains("initial") ? ".initial" : ".lower"),
                    "the initial design value " + std::to_string(i) + " = " + format_number(x0[i])
                        + " is outside its bounds [" + format_number(lower[i]) + ", " + format_number(upper[i]) + "]");
        }
        lowers.push_back(lower);
        uppers.push_back(upper);
        m_design_sizes.push_back(chain->in_size());
        initials.push_back(x0);
        m_chains.push_back(chain.get());
        parts.push_back(std::move(chain));
    }
    m_design = std::make_unique<Concatenation>(std::move(parts));
    m_design_initial.resize(m_design->in_size());
    m_design_lower.resize(m_design->in_size());
    m_design_upper.resize(m_design->in_size());
    Index at = 0;
    for (size_t k = 0; k < initials.size(); ++k) {
        m_design_initial.segment(at, initials[k].size()) = initials[k];
        m_design_lower.segment(at, initials[k].size()) = lowers[k];
        m_design_upper.segment(at, initials[k].size()) = uppers[k];
        at += initials[k].size();
    }
}

namespace {
    /// The map of a shape entry's chain that follows a new mesh and its index there (nullptr if none).
    const RemeshableShape* find_remeshable_shape(const ParameterChain& chain, size_t& index)
    {
        for (size_t i = 0; i < chain.size(); ++i)
            if (const RemeshableShape* shape = chain.map(i).remeshable_shape()) {
                index = i;
                return shape;
            }
        return nullptr;
    }
} // namespace

std::string ProblemParameters::remesh_obstacle() const
{
    int shapes = 0;
    for (size_t k = 0; k < m_entries.size(); ++k) {
        if (m_entries[k].kind != Kind::SHAPE) {
            // Values per element, vertex or prescribed dof change in number with the mesh,
            // unless a map gathers them from values a remesh keeps (a per_body map).
            bool kept = false;
            for (size_t i = 0; i < m_chains[k]->size(); ++i)
                kept = kept || m_chains[k]->map(i).input_survives_remesh();
            if (m_entries[k].per_mesh_item && !kept)
                return m_entries[k].field
                    + ": its design variables are one per element, vertex or prescribed value, which a remesh "
                      "changes (use \"per\": \"body\" or a per_body map)";
            continue;
        }
        ++shapes;
        size_t at = 0;
        if (!find_remeshable_shape(*m_chains[k], at))
            return m_entries[k].field
                + ": a remesh keeps the design variables only with mesh-independent shape controls (a \"ffd\" map); "
                  "these depend on the mesh's vertices";
        if (at + 1 != m_chains[k]->size())
            return m_entries[k].field + ".maps: a remesh needs the \"" + m_chains[k]->map(at).name()
                + "\" map last (it gives the rest positions)";
    }
    if (shapes == 0)
        return "the problem has no \"shape\" parameter (a remesh renews a moving rest mesh)";
    if (shapes > 1)
        return "a remesh needs one \"shape\" parameter entry, the problem has " + std::to_string(shapes);
    return "";
}

ShapeLatticeInput ProblemParameters::shape_lattice_input(const VectorXd& x) const
{
    const std::string obstacle = remesh_obstacle();
    if (!obstacle.empty())
        throw std::runtime_error(obstacle);
    check_size(x, design_size(), "design", "the design");
    Index at = 0;
    for (size_t k = 0; k < m_entries.size(); ++k) {
        if (m_entries[k].kind == Kind::SHAPE) {
            const ParameterChain& chain = *m_chains[k];
            ShapeLatticeInput out;
            out.entry = k;
            out.mesh_input_key = find_remeshable_shape(chain, out.map)->mesh_input_key();
            out.design = x.segment(at, m_design_sizes[k]);
            // The lattice's input: the maps before it applied to the entry's design values.
            out.lattice = out.design;
            for (size_t i = 0; i < out.map; ++i)
                out.lattice = chain.map(i).apply(out.lattice);
            return out;
        }
        at += m_design_sizes[k];
    }
    throw std::logic_error("shape_lattice_input: no shape entry");
}

Positions ProblemParameters::pull_back_shape(const VectorXd& x, const Positions& current) const
{
    const ShapeLatticeInput in = shape_lattice_input(x);
    return m_chains[in.entry]->map(in.map).remeshable_shape()->pull_back(current, in.lattice);
}

std::vector<std::pair<std::string, Index>> ProblemParameters::design_layout() const
{
    std::vector<std::pair<std::string, Index>> out;
    for (size_t k = 0; k < m_entries.size(); ++k)
        out.emplace_back(m_entries[k].name, m_design_sizes[k]);
    return out;
}

std::vector<std::pair<std::string, Index>> ProblemParameters::layout() const
{
    std::vector<std::pair<std::string, Index>> out;
    for (const auto& p : m_entries)
        out.emplace_back(p.name, Index(p.targets.size()));
    return out;
}

ParameterRequest ProblemParameters::request() const
{
    ParameterRequest request;
    for (const auto& s : m_entries)
        request.*traits(s.kind).request = true;
    return request;
}

void ProblemParameters::apply(const VectorXd& p, SimulationParameters& sp) const
{
    for (size_t k = 0; k < m_entries.size(); ++k)
        for (size_t i = 0; i < m_entries[k].targets.size(); ++i)
            for (Index t : m_entries[k].targets[i])
                canonical_entry(sp, traits(m_entries[k].kind), t) = p[m_offsets[k] + Index(i)];
}

void ProblemParameters::add_gradient(const ParameterGradient& g, const SimulationParameters& at,
    const std::vector<char>& plane_stress, VectorXd& dJ_dp) const
{
    const SimulationParameters dJ = canonical_gradient(g, at, request().lame && !m_lame, plane_stress);
    for (size_t k = 0; k < m_entries.size(); ++k) {
        const KindTraits& t = traits(m_entries[k].kind);
        for (size_t i = 0; i < m_entries[k].targets.size(); ++i)
            for (Index target : m_entries[k].targets[i])
                dJ_dp[m_offsets[k] + Index(i)] += gradient_entry(dJ, t, target);
    }
}

} // namespace diffipc
