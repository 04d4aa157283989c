#include "shape_opt/microstructure/cell_optimization.hpp"

#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "shape_opt/microstructure/cell_shape_map.hpp"
#include "shape_opt/remesh.hpp"

#include <algorithm>

namespace diffipc {

namespace {

    /// J on the reference mesh moved to x; stops the optimizer when an accepted iterate's mesh
    /// needs remeshing.
    class MovedCellProblem : public OptimizationProblem {
    public:
        MovedCellProblem(const CellDesign& design, Mesh reference, const VectorXd& p,
            const CellOptimizationSettings& settings, CellOptimizationResult& result, const Timer& timer,
            int first_iteration, const std::function<void(const CellIteration&)>& progress)
            : m_design(design)
            , m_reference(std::move(reference))
            , m_map(design.family(), p, m_reference, design.settings().mesh.height)
            , m_settings(settings)
            , m_result(result)
            , m_timer(timer)
            , m_first(first_iteration)
            , m_progress(progress)
        {
        }

        Index size() const override { return m_design.family().size(); }

        bool evaluate(const VectorXd& x, OptimizationValues& out) override
        {
            ++m_result.evaluations;
            try {
                Mesh mesh = m_reference;
                mesh.rest_positions = m_map.moved(x);
                const double quality = min_quality(mesh.rest_positions, mesh.elements);
                if (!(quality > 0)) {
                    ++m_result.rejected;
                    return false;
                }
                const MatrixXd velocity = m_map.moved_jacobian(x);
                const CellEvaluation e = m_design.evaluate_mesh(mesh, x, &velocity);
                if (!e.ok) {
                    ++m_result.rejected;
                    return false;
                }
                out.f = e.J;
                out.gradient = e.gradient;
                m_quality[x] = quality;
                return true;
            } catch (const InputError&) { // the mesh cannot follow the design there
                ++m_result.rejected;
                return false;
            }
        }

        bool iteration(const IterationInfo& info) override
        {
            CellIteration it;
            it.iteration = m_first + info.iteration;
            it.mesh = m_result.remeshes;
            it.J = info.values->f;
            it.gradient_norm = info.gradient_norm;
            it.x = *info.x;
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
        struct Less {
            bool operator()(const VectorXd& a, const VectorXd& b) const
            {
                return std::lexicographical_compare(a.data(), a.data() + a.size(), b.data(), b.data() + b.size());
            }
        };
        const CellDesign& m_design;
        Mesh m_reference;
        CellShapeMap m_map;
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

CellOptimizationResult optimize_cell(const CellDesign& design, const VectorXd& x0,
    const CellOptimizationSettings& settings, const std::function<void(const CellIteration&)>& progress)
{
    const CellFamily& family = design.family();
    family.check(x0, "design");
    const Timer timer;
    CellOptimizationResult result;
    OptimizerSettings optimizer = settings.optimizer;
    optimizer.lower = family.lower();
    optimizer.upper = family.upper();
    VectorXd x = x0;
    Mesh reference = mesh_design(family, x, design.settings().mesh);
    int done = 0; // iterations so far
    while (true) {
        MovedCellProblem problem(design, reference, x, settings, result, timer, done, progress);
        optimizer.max_iterations = std::max(0, settings.optimizer.max_iterations - done);
        const OptimizerResult r = minimize(problem, x, optimizer);
        x = r.x;
        done += problem.last_iteration();
        result.reason = r.reason;
        result.message = r.message;
        if (r.reason == StopReason::INVALID_START)
            throw InputError("design", "the initial design cannot be simulated: " + r.message);
        if (!problem.needs_remesh() || result.remeshes >= settings.max_remeshes
            || done >= settings.optimizer.max_iterations)
            break;
        reference = mesh_design(family, x, design.settings().mesh);
        ++result.remeshes;
    }
    result.x = x;
    result.final = design.evaluate(x, true);
    return result;
}

} // namespace diffipc
