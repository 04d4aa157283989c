#include "objectives/objective_json.hpp"

#include "forward/scene/json_field.hpp"
#include "objectives/body_force.hpp"
#include "objectives/boundary_smoothness.hpp"
#include "objectives/center_of_mass.hpp"
#include "objectives/combinators.hpp"
#include "objectives/compliance.hpp"
#include "objectives/elastic_energy.hpp"
#include "objectives/kinetic_energy.hpp"
#include "objectives/macro_gradient.hpp"
#include "objectives/macro_stress.hpp"
#include "objectives/marker_file.hpp"
#include "objectives/markers.hpp"
#include "objectives/reaction_force.hpp"
#include "objectives/state_tracking.hpp"
#include "objectives/stress_norm.hpp"
#include "objectives/time_aggregation.hpp"
#include "objectives/volume.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

namespace {
    /// Body index from a name or an index; -1 when the key is absent.
    int parse_body(const JsonField& j, const Simulator& sim)
    {
        if (!j.has("body"))
            return -1;
        const JsonField b = j["body"];
        const auto& bodies = sim.scene().bodies;
        if (b.json().is_string()) {
            const std::string name = b.string();
            for (size_t i = 0; i < bodies.size(); ++i)
                if (bodies[i].name == name)
                    return int(i);
            b.fail("no body named \"" + name + "\"");
        }
        const int index = b.integer(0);
        if (index >= int(bodies.size()))
            b.fail("body index " + std::to_string(index) + " out of range (the scene has "
                + std::to_string(bodies.size()) + " bodies)");
        return index;
    }

    std::vector<Index> parse_elements(const JsonField& j, const Simulator& sim)
    {
        const int body = parse_body(j, sim);
        if (body < 0)
            return {};
        try {
            return body_elements(sim.mesh(), body);
        } catch (const std::out_of_range&) {
            j["body"].fail("the body has no elements");
        }
    }

    /// The states a tracking objective compares: "steps" (each in 0..T) or, without it, 1..T.
    std::vector<int> parse_steps(const JsonField& j, const Simulator& sim, size_t num_targets)
    {
        const int T = sim.scene().time.steps;
        std::vector<int> steps;
        if (j.has("steps")) {
            const JsonField s = j["steps"];
            s.require_array(1);
            for (size_t i = 0; i < s.size(); ++i) {
                const int k = s.at(i).integer(0);
                if (k > T)
                    s.at(i).fail(
                        "step " + std::to_string(k) + " is beyond the scene's " + std::to_string(T) + " steps");
                steps.push_back(k);
            }
            if (steps.size() != num_targets)
                j["targets"].fail("expected one entry per listed step (" + std::to_string(steps.size()) + "), got "
                    + std::to_string(num_targets));
        } else {
            if (int(num_targets) != T)
                j["targets"].fail("without \"steps\", expected one entry per step of the scene (" + std::to_string(T)
                    + "), got " + std::to_string(num_targets));
            for (int k = 1; k <= T; ++k)
                steps.push_back(k);
        }
        return steps;
    }

    /// The "time" key: FINAL by default, a mode's name, or {"max_p": p}; p in `p`.
    TimeMode parse_time(const JsonField& j, double& p)
    {
        TimeMode mode = TimeMode::FINAL;
        p = 8;
        if (j.has("time")) {
            const JsonField t = j["time"];
            if (t.json().is_object()) {
                t.require_object({ "max_p" });
                mode = TimeMode::MAX_P;
                p = t["max_p"].number();
                if (p < 1)
                    t["max_p"].fail("must be at least 1, got " + t["max_p"].json().dump());
            } else {
                const std::string name = t.string();
                if (name == "max_p")
                    t.fail("write {\"max_p\": p} to give the exponent");
                mode = parse_time_mode(name, t.path());
            }
        }
        return mode;
    }

    std::unique_ptr<Objective> aggregate(std::unique_ptr<StateFunctional> f, const JsonField& j)
    {
        double p = 8;
        const TimeMode mode = parse_time(j, p);
        const bool include_initial = j.has("include_initial") ? j["include_initial"].boolean() : false;
        if (include_initial && mode != TimeMode::SUM && mode != TimeMode::MAX_P)
            j["include_initial"].fail("only applies to the \"sum\" and max_p time aggregations");
        return std::make_unique<TimeAggregation>(std::move(f), mode, p, include_initial);
    }

    std::unique_ptr<Objective> parse(const JsonField& j, const Simulator& sim);

    std::unique_ptr<Objective> parse_stress_norm(const JsonField& j, const Simulator& sim)
    {
        StressNormOptions o;
        if (j.has("p")) {
            o.p = j["p"].number();
            if (o.p < 1)
                j["p"].fail("must be at least 1, got " + j["p"].json().dump());
        }
        if (j.has("norm")) {
            const std::string norm = j["norm"].string();
            if (norm == "frobenius")
                o.norm = StressNormType::FROBENIUS;
            else if (norm == "von_mises")
                o.norm = StressNormType::VON_MISES;
            else
                j["norm"].fail("unknown norm \"" + norm + "\" (expected frobenius or von_mises)");
        }
        if (j.has("stress")) {
            const std::string stress = j["stress"].string();
            if (stress == "cauchy")
                o.stress = StressMeasure::CAUCHY;
            else if (stress == "first_piola")
                o.stress = StressMeasure::FIRST_PIOLA;
            else
                j["stress"].fail("unknown stress \"" + stress + "\" (expected cauchy or first_piola)");
        }
        if (j.has("normalized"))
            o.normalized = j["normalized"].boolean();
        o.elements = parse_elements(j, sim);
        return aggregate(std::make_unique<StressNorm>(o), j);
    }

    /// Per-marker weights from "weights" (one per marker, >= 0) or "sigma" (standard deviations,
    /// m: one number or one per marker; w = 1 / sigma^2); empty: all 1.
    VectorXd parse_marker_weights(const JsonField& j, Index M)
    {
        if (j.has("weights") && j.has("sigma"))
            j["sigma"].fail("give \"weights\" or \"sigma\", not both");
        VectorXd weights;
        if (j.has("weights")) {
            weights = j["weights"].vector(int(M));
            for (Index m = 0; m < M; ++m)
                if (weights[m] < 0)
                    j["weights"].at(size_t(m)).fail("must be nonnegative");
        } else if (j.has("sigma")) {
            const JsonField s = j["sigma"];
            const VectorXd sigma = s.json().is_array() ? s.vector(int(M)) : VectorXd::Constant(M, s.positive());
            for (Index m = 0; m < M; ++m)
                if (!(sigma[m] > 0))
                    s.fail("standard deviations must be positive");
            weights = sigma.array().square().inverse();
        }
        return weights;
    }

    /// Markers read from a file (objectives/marker_file.hpp).
    std::unique_ptr<Objective> parse_marker_file(const JsonField& j, const Simulator& sim)
    {
        for (const char* k : { "vertices", "points", "targets" })
            if (j.has(k))
                j[k].fail("not with \"file\": the file gives the markers and their positions");
        const Scene& scene = sim.scene();
        const double tolerance = j.has("vertex_tolerance") ? j["vertex_tolerance"].positive() : 0.0;
        MarkerData data = read_marker_file(j["file"].string(), sim.mesh(), sim.mesh().rest_positions,
            scene.body_vertices, scene.time.dt, scene.time.steps, tolerance);
        std::vector<int> steps = data.steps;
        if (steps.empty()) { // a static file: one measured state, "steps" or the last step
            if (j.has("steps")) {
                if (j["steps"].json().is_array() && j["steps"].size() != 1)
                    j["steps"].fail("a file without a time column holds one measured state: give one step");
                steps = parse_steps(j, sim, 1);
            } else
                steps = { scene.time.steps };
        } else if (j.has("steps"))
            j["steps"].fail("not with a file that has a time column: its times give the steps");
        const Index M = Index(data.markers.size());
        return std::make_unique<MarkerTracking>(
            std::move(data.markers), steps, std::move(data.targets), parse_marker_weights(j, M));
    }

    std::unique_ptr<Objective> parse_markers(const JsonField& j, const Simulator& sim)
    {
        if (j.has("file"))
            return parse_marker_file(j, sim);
        if (j.has("vertex_tolerance"))
            j["vertex_tolerance"].fail("only applies with \"file\"");
        const Mesh& mesh = sim.mesh();
        const int d = mesh.dim;
        std::vector<MarkerPoint> markers;
        if (j.has("vertices")) {
            const JsonField v = j["vertices"];
            v.require_array(1);
            for (size_t i = 0; i < v.size(); ++i) {
                const int vertex = v.at(i).integer(0);
                if (vertex >= mesh.num_vertices())
                    v.at(i).fail("vertex " + std::to_string(vertex) + " out of range (the mesh has "
                        + std::to_string(mesh.num_vertices()) + " vertices)");
                markers.push_back(MarkerPoint::vertex(vertex));
            }
        }
        if (j.has("points")) {
            const JsonField p = j["points"];
            p.require_array(1);
            for (size_t i = 0; i < p.size(); ++i) {
                const JsonField point = p.at(i);
                point.require_object({ "element", "weights" });
                const int e = point["element"].integer(0);
                if (e >= mesh.num_elements())
                    point["element"].fail("element " + std::to_string(e) + " out of range (the mesh has "
                        + std::to_string(mesh.num_elements()) + " elements)");
                const VectorXd w = point["weights"].vector(d + 1);
                if (!(std::abs(w.sum() - 1) <= 1e-12))
                    point["weights"].fail("barycentric weights must sum to 1");
                markers.push_back(MarkerPoint::barycentric(mesh, e, std::vector<double>(w.data(), w.data() + d + 1)));
            }
        }
        if (markers.empty())
            j.fail("give marker \"vertices\" or \"points\"");
        const Index M = Index(markers.size());
        const JsonField t = j["targets"];
        t.require_array(1);
        std::vector<Positions> targets;
        for (size_t s = 0; s < t.size(); ++s) {
            const JsonField ts = t.at(s);
            ts.require_array();
            if (Index(ts.size()) != M)
                ts.fail("expected one target per marker (" + std::to_string(M) + "), got " + std::to_string(ts.size()));
            Positions y(M, d);
            for (Index m = 0; m < M; ++m)
                y.row(m) = ts.at(size_t(m)).vector(d).transpose();
            targets.push_back(y);
        }
        const std::vector<int> steps = parse_steps(j, sim, targets.size());
        return std::make_unique<MarkerTracking>(
            std::move(markers), steps, std::move(targets), parse_marker_weights(j, M));
    }

    std::unique_ptr<Objective> parse_center_of_mass(const JsonField& j, const Simulator& sim)
    {
        const int d = sim.mesh().dim;
        const JsonField t = j["targets"];
        t.require_array(1);
        Positions targets(Index(t.size()), d);
        for (size_t s = 0; s < t.size(); ++s)
            targets.row(Index(s)) = t.at(s).vector(d).transpose();
        const std::vector<int> steps = parse_steps(j, sim, t.size());
        const double weight = j.has("weight") ? j["weight"].positive() : 1.0;
        return std::make_unique<CenterOfMassTracking>(steps, targets, weight, parse_elements(j, sim));
    }

    /// The condition of a reaction force: "dirichlet" (an index into the scene's) or "obstacle"
    /// (a name or an index), as an index of Simulator::prescribing_condition().
    int parse_reaction_condition(const JsonField& j, const Simulator& sim)
    {
        const Scene& scene = sim.scene();
        if (j.has("dirichlet") == j.has("obstacle"))
            j.fail("give exactly one of \"dirichlet\" (an index into the scene's dirichlet list) and \"obstacle\"");
        if (j.has("dirichlet")) {
            const JsonField c = j["dirichlet"];
            const int index = c.integer(0);
            if (index >= int(scene.dirichlet.size()))
                c.fail("index " + std::to_string(index) + " out of range (the scene has "
                    + std::to_string(scene.dirichlet.size()) + " dirichlet conditions)");
            return index;
        }
        const JsonField o = j["obstacle"];
        const int first = int(scene.dirichlet.size());
        if (o.json().is_string()) {
            const std::string name = o.string();
            for (size_t i = 0; i < scene.obstacles.size(); ++i)
                if (scene.obstacles[i].name == name)
                    return first + int(i);
            o.fail("no obstacle named \"" + name + "\"");
        }
        const int index = o.integer(0);
        if (index >= int(scene.obstacles.size()))
            o.fail("index " + std::to_string(index) + " out of range (the scene has "
                + std::to_string(scene.obstacles.size()) + " obstacles)");
        return first + index;
    }

    /// {"type": "body_force", "body": name | index, "axis": "y", "time": "final" | "sum" | {"max_p": p}}.
    std::unique_ptr<Objective> parse_body_force(const JsonField& j, const Simulator& sim)
    {
        const int body = parse_body(j, sim);
        if (body < 0)
            j.fail("body_force needs \"body\"");
        const int d = sim.mesh().dim;
        const std::string axis = j["axis"].string();
        const int a = axis == "x" ? 0 : axis == "y" ? 1 : axis == "z" && d == 3 ? 2 : -1;
        if (a < 0)
            j["axis"].fail("expected " + std::string(d == 3 ? "x, y or z" : "x or y") + ", got \"" + axis + "\"");
        double p = 8;
        const TimeMode mode = parse_time(j, p);
        if (mode == TimeMode::TRAPEZOID)
            j["time"].fail("body_force takes final, sum or {\"max_p\": p}");
        return std::make_unique<BodyForce>(body, a, mode, p);
    }

    /// With "targets": the functional compared with them at the listed states ("steps", "weight"
    /// or "sigma"); without: aggregated in time ("time", "include_initial").
    std::unique_ptr<Objective> aggregate_or_track(
        std::unique_ptr<StateFunctional> functional, const JsonField& j, const Simulator& sim)
    {
        if (!j.has("targets")) {
            for (const char* key : { "steps", "weight", "sigma", "side" })
                if (j.has(key))
                    j[key].fail("only applies with \"targets\"");
            return aggregate(std::move(functional), j);
        }
        for (const char* key : { "time", "include_initial" })
            if (j.has(key))
                j[key].fail("does not apply with \"targets\" (the listed states are compared)");
        const JsonField t = j["targets"];
        t.require_array(1);
        std::vector<double> targets;
        for (size_t i = 0; i < t.size(); ++i)
            targets.push_back(t.at(i).number());
        const std::vector<int> steps = parse_steps(j, sim, targets.size());
        if (j.has("weight") && j.has("sigma"))
            j.fail("give at most one of \"weight\" and \"sigma\"");
        double weight = j.has("weight") ? j["weight"].positive() : 1.0;
        if (j.has("sigma"))
            weight = 1.0 / std::pow(j["sigma"].positive(), 2);
        TrackingSide side = TrackingSide::BOTH;
        if (j.has("side")) {
            const std::string s = j["side"].string();
            if (s == "above")
                side = TrackingSide::ABOVE;
            else if (s == "below")
                side = TrackingSide::BELOW;
            else if (s != "both")
                j["side"].fail("expected \"both\", \"above\" or \"below\", got \"" + s + "\"");
        }
        return std::make_unique<StateTracking>(std::move(functional), steps, std::move(targets), weight, side);
    }

    /// {"type": "macro_stress" | "macro_gradient", "component": "xx", "time": ... | "targets": ...}:
    /// a periodic cell's average stress or macro displacement gradient.
    std::unique_ptr<Objective> parse_macro(const JsonField& j, const Simulator& sim)
    {
        const std::string type = j["type"].string();
        if (!sim.periodic())
            j["type"].fail(type + " needs a periodic cell (the scene's \"periodic\")");
        const int d = sim.mesh().dim;
        const std::string c = j["component"].string();
        const std::string axes = std::string("xyz").substr(0, size_t(d));
        const size_t a = c.size() == 2 ? axes.find(c[0]) : std::string::npos;
        const size_t b = c.size() == 2 ? axes.find(c[1]) : std::string::npos;
        if (a == std::string::npos || b == std::string::npos)
            j["component"].fail("expected two of " + axes + " (row, column), got \"" + c + "\"");
        if (type == "macro_stress")
            return aggregate_or_track(std::make_unique<MacroStress>(int(a), int(b), d), j, sim);
        return aggregate_or_track(std::make_unique<MacroGradient>(int(a), int(b), d), j, sim);
    }

    std::unique_ptr<Objective> parse_reaction_force(const JsonField& j, const Simulator& sim)
    {
        if (sim.friction())
            j["type"].fail("reaction_force is not available in scenes with friction (a coefficient > 0)");
        const int condition = parse_reaction_condition(j, sim);
        const int d = sim.mesh().dim;
        const JsonField a = j["axis"];
        int axis = -1;
        if (a.json().is_string()) {
            const std::string name = a.string();
            axis = name == "x" ? 0 : name == "y" ? 1 : name == "z" && d == 3 ? 2 : -1;
            if (axis < 0)
                a.fail("expected " + std::string(d == 3 ? "x, y or z" : "x or y") + ", got \"" + name + "\"");
        } else {
            axis = a.integer(0);
            if (axis >= d)
                a.fail("axis " + std::to_string(axis) + " out of range for a " + std::to_string(d) + "D scene");
        }
        std::vector<Index> dofs = prescribed_dofs_of(sim, condition, axis);
        const std::string label = j.has("dirichlet")
            ? "dirichlet[" + std::to_string(condition) + "]"
            : sim.scene().obstacles[size_t(condition) - sim.scene().dirichlet.size()].name;
        if (dofs.empty())
            j[j.has("dirichlet") ? "dirichlet" : "obstacle"].fail("prescribes no dof along axis " + std::to_string(axis)
                + " (no vertex in its region, or that "
                  "component is free or taken by a later condition)");
        return aggregate_or_track(
            std::make_unique<ReactionForce>(std::move(dofs), label + "." + std::string(1, "xyz"[axis])), j, sim);
    }

    std::unique_ptr<Objective> parse_sum(const JsonField& j, const Simulator& sim)
    {
        const JsonField terms = j["terms"];
        terms.require_array(1);
        std::vector<WeightedSum::Term> parsed;
        for (size_t i = 0; i < terms.size(); ++i) {
            const JsonField term = terms.at(i);
            term.require_object({ "weight", "objective" });
            const double weight = term.has("weight") ? term["weight"].number() : 1.0;
            parsed.push_back({ weight, parse(term["objective"], sim) });
        }
        return std::make_unique<WeightedSum>(std::move(parsed));
    }

    std::unique_ptr<Objective> parse_power(const JsonField& j, const Simulator& sim)
    {
        const double q = j["q"].number();
        return std::make_unique<Power>(parse(j["objective"], sim), q);
    }

    std::unique_ptr<Objective> parse_constraint(const JsonField& j, const Simulator& sim)
    {
        if (j.has("upper") == j.has("lower"))
            j.fail("give exactly one of \"upper\" (objective <= bound) and \"lower\" (objective >= bound)");
        const bool upper = j.has("upper");
        const double bound = j[upper ? "upper" : "lower"].number();
        const double weight = j.has("weight") ? j["weight"].positive() : 1.0;
        return std::make_unique<SoftConstraint>(
            parse(j["objective"], sim), upper ? ConstraintSense::UPPER : ConstraintSense::LOWER, bound, weight);
    }

    std::unique_ptr<Objective> parse_volume(const JsonField& j, const Simulator& sim)
    {
        std::vector<Index> elements = parse_elements(j, sim);
        const std::string configuration = j.has("configuration") ? j["configuration"].string() : "current";
        if (configuration != "current" && configuration != "rest")
            j["configuration"].fail("expected \"current\" or \"rest\", got \"" + configuration + "\"");
        return aggregate(std::make_unique<Volume>(std::move(elements), configuration == "rest"), j);
    }

    using Builder = std::unique_ptr<Objective> (*)(const JsonField& j, const Simulator& sim);

    struct Entry {
        ObjectiveType type;
        Builder build; ///< called once the keys are checked against type.keys
    };

    /// Every objective type, its keys and its builder: the factory, registered_objective_types()
    /// and the "unknown objective type" message all read this one list.
    const std::vector<Entry>& registry()
    {
        static const std::vector<Entry> entries = {
            { { "stress_norm", { "p", "norm", "stress", "normalized", "body", "time", "include_initial" } },
                parse_stress_norm },
            { { "elastic_energy", { "body", "time", "include_initial" } },
                [](const JsonField& j, const Simulator& sim) -> std::unique_ptr<Objective> {
                    return aggregate(std::make_unique<ElasticEnergy>(parse_elements(j, sim)), j);
                } },
            { { "compliance", { "time", "include_initial" } },
                [](const JsonField& j, const Simulator&) -> std::unique_ptr<Objective> {
                    return aggregate(std::make_unique<Compliance>(), j);
                } },
            { { "volume", { "body", "time", "include_initial", "configuration" } }, parse_volume },
            { { "kinetic_energy", { "body", "time", "include_initial" } },
                [](const JsonField& j, const Simulator& sim) -> std::unique_ptr<Objective> {
                    return aggregate(std::make_unique<KineticEnergy>(parse_elements(j, sim)), j);
                } },
            // One key list for both forms; parse_markers refuses the keys of the other form.
            { { "markers",
                  { "vertices", "points", "targets", "steps", "weights", "sigma", "file", "vertex_tolerance" } },
                parse_markers },
            { { "center_of_mass", { "targets", "steps", "weight", "body" } }, parse_center_of_mass },
            { { "reaction_force",
                  { "dirichlet", "obstacle", "axis", "targets", "steps", "weight", "sigma", "side", "time",
                      "include_initial" } },
                parse_reaction_force },
            { { "body_force", { "body", "axis", "time" } }, parse_body_force },
            { { "macro_stress",
                  { "component", "time", "include_initial", "targets", "steps", "weight", "sigma", "side" } },
                parse_macro },
            { { "macro_gradient",
                  { "component", "time", "include_initial", "targets", "steps", "weight", "sigma", "side" } },
                parse_macro },
            { { "boundary_smoothness", { "body" } },
                [](const JsonField& j, const Simulator& sim) -> std::unique_ptr<Objective> {
                    return std::make_unique<BoundarySmoothness>(sim.scene(), parse_body(j, sim));
                } },
            { { "sum", { "terms" } }, parse_sum },
            { { "power", { "q", "objective" } }, parse_power },
            { { "constraint", { "objective", "upper", "lower", "weight" } }, parse_constraint },
        };
        return entries;
    }

    /// JsonField::require_object with a list known only at run time (same message).
    void require_keys(const JsonField& j, const ObjectiveType& type)
    {
        std::string list = "type";
        for (const std::string& key : type.keys)
            list += ", " + key;
        for (auto it = j.json().begin(); it != j.json().end(); ++it) {
            if (it.key() == "type" || std::find(type.keys.begin(), type.keys.end(), it.key()) != type.keys.end())
                continue;
            const std::string key = it.key().empty() ? "\"\"" : it.key();
            throw InputError(
                j.path().empty() ? key : j.path() + "." + key, "unknown field (allowed here: " + list + ")");
        }
    }

    std::unique_ptr<Objective> parse(const JsonField& j, const Simulator& sim)
    {
        if (!j.is_object())
            j.fail("expected an objective object with a \"type\"");
        const JsonField type_field = j["type"];
        const std::string type = type_field.string();
        const std::vector<Entry>& entries = registry();
        for (const Entry& entry : entries)
            if (entry.type.name == type) {
                require_keys(j, entry.type);
                return entry.build(j, sim);
            }
        std::string expected;
        for (size_t i = 0; i < entries.size(); ++i)
            expected += (i == 0 ? "" : i + 1 == entries.size() ? " or " : ", ") + entries[i].type.name;
        type_field.fail("unknown objective type \"" + type + "\" (expected " + expected + ")");
    }
} // namespace

std::unique_ptr<Objective> parse_objective(const nlohmann::json& j, const std::string& field, const Simulator& sim)
{
    return parse(JsonField(j, field), sim);
}

const std::vector<ObjectiveType>& registered_objective_types()
{
    static const std::vector<ObjectiveType> types = [] {
        std::vector<ObjectiveType> t;
        for (const Entry& entry : registry())
            t.push_back(entry.type);
        return t;
    }();
    return types;
}

} // namespace diffipc
