#include "shape_opt/microstructure/cell_optimization.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "shape_opt/microstructure/cell_shape_map.hpp"
#include "shape_opt/remesh.hpp"

#include <algorithm>

namespace diffipc {

namespace {

    /// J on the reference mesh moved to x; stops the optimizer when an accepted iterate's mesh
    /// needs remeshing. A design with a beam thinner than the mesh size is rejected, so that
    /// every accepted design can be meshed anew.
    class MovedCellProblem : public OptimizationProblem {
    public:
        /// @param free the optimized variables' indices; the others keep their values in p
        MovedCellProblem(const CellObjective& objective, Mesh reference, const VectorXd& p, std::vector<Index> free,
            const CellOptimizationSettings& settings, CellOptimizationResult& result, const Timer& timer,
            int first_iteration, const std::function<void(const CellIteration&)>& progress)
            : m_objective(objective)
            , m_reference(std::move(reference))
            , m_map(objective.family(), p, m_reference, objective.mesh_settings().height)
            , m_p(p)
            , m_free(std::move(free))
            , m_settings(settings)
            , m_result(result)
            , m_timer(timer)
            , m_first(first_iteration)
            , m_progress(progress)
        {
        }

        Index size() const override { return Index(m_free.size()); }

        /// The design of the optimized variables' values z.
        VectorXd design(const VectorXd& z) const
        {
            VectorXd x = m_p;
            for (size_t i = 0; i < m_free.size(); ++i)
                x[m_free[i]] = z[Index(i)];
            return x;
        }
        /// The optimized variables' values of design x.
        VectorXd reduce(const VectorXd& x) const
        {
            VectorXd z(size());
            for (size_t i = 0; i < m_free.size(); ++i)
                z[Index(i)] = x[m_free[i]];
            return z;
        }

        bool evaluate(const VectorXd& z, OptimizationValues& out) override
        {
            ++m_result.evaluations;
            const VectorXd x = design(z);
            try {
                // a design that could not be meshed anew (a beam thinner than the mesh size) is out
                check_meshable(m_objective.family(), x, m_objective.mesh_settings());
                Mesh mesh = m_reference;
                mesh.rest_positions = m_map.moved(x);
                const double quality = min_quality(mesh.rest_positions, mesh.elements);
                if (!(quality > 0))
                    return reject(x, "the mesh moved to the design inverts an element");
                const MatrixXd velocity = m_map.moved_jacobian(x);
                const DesignValue e = m_objective.value(mesh, x, &velocity);
                if (!e.ok)
                    return reject(x, e.message);
                out.f = e.J;
                out.gradient = reduce(e.gradient);
                m_quality[x] = quality;
                return true;
            } catch (const InputError& e) { // the mesh cannot follow the design there
                return reject(x, e.what());
            } catch (const AdjointError& e) { // a run the adjoint cannot differentiate
                return reject(x, e.what());
            }
        }

        /// Why the last rejected design was rejected.
        std::string last_rejection() const
        {
            return m_result.rejections.empty() ? std::string() : m_result.rejections.back().reason;
        }

        bool iteration(const IterationInfo& info) override
        {
            CellIteration it;
            it.iteration = m_first + info.iteration;
            it.mesh = m_result.remeshes;
            it.J = info.values->f;
            it.gradient_norm = info.gradient_norm;
            it.x = design(*info.x);
            const auto q = m_quality.find(it.x);
            it.quality = q != m_quality.end() ? q->second : min_quality(m_map.moved(it.x), m_reference.elements);
            it.seconds = m_timer.seconds();
            m_last_iteration = info.iteration;
            // A restart's first entry repeats the last iterate on the new mesh.
            m_result.history.push_back(it);
            if (m_progress)
                m_progress(it);
            m_remesh = it.quality < m_settings.remesh_quality && info.iteration > 0;
            return !m_remesh;
        }

        bool needs_remesh() const { return m_remesh; }
        int last_iteration() const { return m_last_iteration; }

    private:
        /// Counts a rejected design and records why; false.
        bool reject(const VectorXd& x, const std::string& why)
        {
            m_result.rejections.push_back({ x, why });
            return false;
        }

        struct Less {
            bool operator()(const VectorXd& a, const VectorXd& b) const
            {
                return std::lexicographical_compare(a.data(), a.data() + a.size(), b.data(), b.data() + b.size());
            }
        };
        const CellObjective& m_objective;
        Mesh m_reference;
        CellShapeMap m_map;
        VectorXd m_p;
        std::vector<Index> m_free;
        const CellOptimizationSettings& m_settings;
        CellOptimizationResult& m_result;
        const Timer& m_timer;
        int m_first;
        const std::function<void(const CellIteration&)>& m_progress;
        std::map<VectorXd, double, Less> m_quality;
        bool m_remesh = false;
        int m_last_iteration = 0;
    };

} // namespace

CellOptimizationResult optimize_cell(const CellObjective& objective, const VectorXd& x0,
    const CellOptimizationSettings& settings, const std::function<void(const CellIteration&)>& progress)
{
    const CellFamily& family = objective.family();
    family.check(x0, "design");
    std::vector<bool> held(size_t(family.size()), false);
    for (size_t i = 0; i < settings.fixed.size(); ++i) {
        const auto& names = family.names();
        const auto found = std::find(names.begin(), names.end(), settings.fixed[i]);
        if (found == names.end())
            throw InputError("fixed[" + std::to_string(i) + "]", "no design variable \"" + settings.fixed[i] + "\"");
        held[size_t(found - names.begin())] = true;
    }
    std::vector<Index> free;
    for (Index j = 0; j < family.size(); ++j)
        if (!held[size_t(j)])
            free.push_back(j);
    if (free.empty())
        throw InputError("fixed", "every design variable is held: nothing to optimize");
    // Thickness bounds raised to what the mesh size can resolve at the narrowest width the run
    // may reach (check_meshable), unless x0 lies below that already.
    VectorXd lower = family.lower();
    const CellMeshSettings& mesh = objective.mesh_settings();
    const Index w = family.width_index();
    const double narrowest = std::min(held[size_t(w)] ? x0[w] : lower[w], 1.0);
    for (Index j = 0; j < family.size(); ++j)
        if (family.names()[size_t(j)].rfind("thickness", 0) == 0)
            lower[j] = std::min(std::max(lower[j], mesh.size / (0.5 * mesh.height * narrowest)), x0[j]);
    const Timer timer;
    CellOptimizationResult result;
    OptimizerSettings optimizer = settings.optimizer;
    VectorXd x = x0;
    Mesh reference = mesh_design(family, x, objective.mesh_settings());
    int done = 0; // iterations so far
    while (true) {
        MovedCellProblem problem(objective, reference, x, free, settings, result, timer, done, progress);
        optimizer.lower = problem.reduce(lower);
        optimizer.upper = problem.reduce(family.upper());
        optimizer.max_iterations = std::max(0, settings.optimizer.max_iterations - done);
        const OptimizerResult r = minimize(problem, problem.reduce(x), optimizer);
        x = problem.design(r.x);
        done += problem.last_iteration();
        result.reason = r.reason;
        result.message = r.message;
        if (r.reason == StopReason::INVALID_START)
            throw InputError("design", "the initial design cannot be simulated: " + problem.last_rejection());
        if (!problem.needs_remesh() || result.remeshes >= settings.max_remeshes
            || done >= settings.optimizer.max_iterations)
            break;
        reference = mesh_design(family, x, objective.mesh_settings());
        ++result.remeshes;
    }
    result.x = x;
    result.final = evaluate_new_mesh(objective, x);
    return result;
}

} // namespace diffipc
