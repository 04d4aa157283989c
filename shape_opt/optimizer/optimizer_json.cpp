#include "shape_opt/optimizer/optimizer_json.hpp"

#include "forward/common/error.hpp"

#include <cstdio>

namespace diffipc {

OptimizerSettings parse_optimizer_settings(const JsonField& spec)
{
    OptimizerSettings s;
    if (spec.json().is_null())
        return s;
    spec.require_object({ "algorithm", "max_iterations", "max_seconds", "gradient_tolerance",
        "relative_gradient_tolerance", "x_tolerance", "f_tolerance", "constraint_tolerance", "lbfgs_memory", "options",
        "objective_target", "final_taylor_check" });
    if (spec.has("algorithm"))
        s.algorithm = parse_optimizer_algorithm(spec["algorithm"].string(), spec["algorithm"].path());
    if (spec.has("max_iterations"))
        s.max_iterations = spec["max_iterations"].integer(0);
    if (spec.has("lbfgs_memory"))
        s.lbfgs_memory = spec["lbfgs_memory"].integer(1);
    const auto nonnegative = [&](const char* key, double& value) {
        if (!spec.has(key))
            return;
        value = spec[key].number();
        if (!(value >= 0))
            spec[key].fail("must be at least 0, got " + format_number(value));
    };
    nonnegative("max_seconds", s.max_seconds);
    nonnegative("gradient_tolerance", s.gradient_tolerance);
    nonnegative("relative_gradient_tolerance", s.relative_gradient_tolerance);
    nonnegative("x_tolerance", s.x_tolerance);
    nonnegative("f_tolerance", s.f_tolerance);
    nonnegative("constraint_tolerance", s.constraint_tolerance);
    if (spec.has("objective_target"))
        s.objective_target = spec["objective_target"].number();
    if (spec.has("final_taylor_check")) {
        const JsonField check = spec["final_taylor_check"];
        if (check.json().is_boolean())
            s.final_taylor_check.enabled = check.boolean();
        else if (check.is_object()) {
            check.require_object({ "enabled", "step", "halvings", "seed" });
            if (check.has("enabled"))
                s.final_taylor_check.enabled = check["enabled"].boolean();
            if (check.has("step"))
                s.final_taylor_check.step = check["step"].positive();
            if (check.has("halvings"))
                s.final_taylor_check.halvings = check["halvings"].integer(2); // a verdict needs three steps
            if (check.has("seed"))
                s.final_taylor_check.seed = unsigned(check["seed"].integer(0));
        } else
            check.fail("expected true, false or an object {\"step\", \"halvings\", \"seed\", \"enabled\"}");
    }
    if (spec.has("options")) {
        const JsonField options = spec["options"];
        if (!options.is_object())
            options.fail("expected an object of library options");
        for (const auto& [key, value] : options.json().items()) {
            const JsonField o = options[key];
            if (value.is_string())
                s.options[key] = o.string();
            else if (value.is_number_integer())
                s.options[key] = std::to_string(value.get<long long>());
            else if (value.is_number()) {
                char text[32];
                std::snprintf(text, sizeof text, "%.17g", o.number()); // every digit: an option is exact
                s.options[key] = text;
            } else
                o.fail("expected a number or a string");
        }
    }
    return s;
}

} // namespace diffipc
